/* transport: reading the sparse kernel (see transport.h). */
#include "transport.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "ply.h"
#include "vec.h"

rs_transport *rs_transport_read(const char *path, size_t nfaces, rs_err *err)
{
    rs_ply *ply = rs_ply_read(path, err);
    if (!ply) return NULL;
    rs_transport *t = NULL;
    rs_ply_element *el = rs_ply_find_element(ply, "transport");
    rs_ply_prop *row = el ? rs_ply_find_prop(el, "row") : NULL, *col = el ? rs_ply_find_prop(el, "col") : NULL,
                *k = el ? rs_ply_find_prop(el, "k") : NULL, *ku = el ? rs_ply_find_prop(el, "k_unseen") : NULL;
    if (!row || !col || !k || !ku || row->is_list || col->is_list || k->is_list || ku->is_list) {
        rs_err_set(err, RS_ERR_INPUT, path, 0, "expected element 'transport' with properties row, col, k, k_unseen");
        goto out;
    }
    size_t n = el->count;
    t = calloc(1, sizeof *t);
    if (!t || !(t->row_start = calloc(nfaces + 1, sizeof *t->row_start)) ||
        !(t->col = malloc((n ? n : 1) * sizeof *t->col)) || !(t->k = malloc((n ? n : 1) * sizeof *t->k)) ||
        !(t->k_unseen = malloc((n ? n : 1) * sizeof *t->k_unseen))) {
        rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory for %zu entries", n);
        goto fail;
    }
    t->nfaces = nfaces;
    t->nentries = n;
    double last_row = 0;
    for (size_t e = 0; e < n; e++) {
        double r = row->data[e], c = col->data[e];
        if (!(r >= 0 && r < (double)nfaces && c >= 0 && c < (double)nfaces) || r < last_row) {
            rs_err_set(err, RS_ERR_INPUT, path, 0,
                       "entry %zu: row %.0f, col %.0f: expected indices below %zu with rows in order "
                       "(rerun irradiance)", e, r, c, nfaces);
            goto fail;
        }
        if (!(isfinite(k->data[e]) && k->data[e] >= 0 && isfinite(ku->data[e]) && ku->data[e] >= 0)) {
            rs_err_set(err, RS_ERR_INPUT, path, 0, "entry %zu: weights must be finite and >= 0", e);
            goto fail;
        }
        last_row = r;
        t->row_start[(size_t)r + 1]++;
        t->col[e] = (uint32_t)c;
        t->k[e] = (float)k->data[e];
        t->k_unseen[e] = (float)ku->data[e];
    }
    for (size_t f = 0; f < nfaces; f++) t->row_start[f + 1] += t->row_start[f];
    goto out;
fail:
    rs_transport_free(t);
    t = NULL;
out:
    rs_ply_free(ply);
    return t;
}

void rs_transport_free(rs_transport *t)
{
    if (!t) return;
    free(t->row_start);
    free(t->col);
    free(t->k);
    free(t->k_unseen);
    free(t);
}

/* Jacobi iteration: every sweep uses the previous sweep's L, so the result does not depend on
 * the order (or thread count) in which facets are updated. */
int rs_transport_solve(const rs_transport *K, const double *rho, const double *esky, double *L,
                         double *G, double tol, int max_iter, double *residual)
{
    size_t nf = K->nfaces;
    double *next = malloc(3 * nf * sizeof *next);
    if (!next) return -1;
    for (size_t i = 0; i < 3 * nf; i++) L[i] = rho[i] * esky[i] / M_PI;
    int it;
    *residual = 0;
    for (it = 1; it <= max_iter; it++) {
        double change = 0, scale = 0;
#pragma omp parallel for schedule(static) reduction(max : change, scale)
        for (size_t i = 0; i < nf; i++) {
            double g[3] = {0, 0, 0};
            for (size_t e = K->row_start[i]; e < K->row_start[i + 1]; e++)
                for (int ch = 0; ch < 3; ch++) g[ch] += K->k[e] * L[3 * K->col[e] + ch];
            for (int ch = 0; ch < 3; ch++) {
                double v = rho[3 * i + ch] * (esky[3 * i + ch] + g[ch]) / M_PI;
                next[3 * i + ch] = v;
                G[3 * i + ch] = g[ch];
                change = fmax(change, fabs(v - L[3 * i + ch]));
                scale = fmax(scale, fabs(v));
            }
        }
        memcpy(L, next, 3 * nf * sizeof *L);
        *residual = scale > 0 ? change / scale : 0;
        if (*residual < tol) break;
    }
    free(next);
    return it > max_iter ? max_iter : it;
}

