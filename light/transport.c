/* transport: reading the sparse kernel (see transport.h). */
#include "light/transport.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/par.h"
#include "common/ply.h"
#include "common/vec.h"

/* Record by record from the file (rs_ply_read_records): the kernel is held once, as
 * uint32 / float columns, never as the PLY module's doubles (4e7 entries at 10^6 facets). */
typedef struct {
    rs_transport *t;
    const char *path;
    int row, col, k, ku; /* property indices in the element */
    double last_row;
} read_ctx;

static int expected_props(const char *path, rs_err *err)
{
    return rs_err_set(err, RS_ERR_INPUT, path, 0, "expected element 'transport' with properties row, col, k, k_unseen");
}

static int find_props(read_ctx *c, const rs_ply_element *el)
{
    c->row = c->col = c->k = c->ku = -1;
    for (int i = 0; i < el->nprops; i++) {
        const char *n = el->props[i].name;
        int *slot = !strcmp(n, "row") ? &c->row
            : !strcmp(n, "col")       ? &c->col
            : !strcmp(n, "k")         ? &c->k
            : !strcmp(n, "k_unseen")  ? &c->ku
                                      : NULL;
        if (slot && !el->props[i].is_list) *slot = i;
    }
    return c->row >= 0 && c->col >= 0 && c->k >= 0 && c->ku >= 0 ? 0 : -1;
}

static int read_entry(void *ctx, const rs_ply_element *el, size_t e, double *v, rs_err *err)
{
    read_ctx *c = ctx;
    rs_transport *t = c->t;
    if (strcmp(el->name, "transport") != 0) return 0;
    if (e == 0) {
        size_t n = el->count;
        if (find_props(c, el) != 0) return expected_props(c->path, err);
        if (!(t->col = malloc(n * sizeof *t->col)) || !(t->k = malloc(n * sizeof *t->k)) ||
            !(t->k_unseen = malloc(n * sizeof *t->k_unseen)))
            return rs_err_set(err, RS_ERR_SYSTEM, c->path, 0, "out of memory for %zu entries", n);
        t->nentries = n;
    }
    double r = v[c->row], col = v[c->col], k = v[c->k], ku = v[c->ku];
    size_t nfaces = t->nfaces;
    if (!(r >= 0 && r < (double)nfaces && col >= 0 && col < (double)nfaces) || r < c->last_row)
        return rs_err_set(err, RS_ERR_INPUT, c->path, 0,
                          "entry %zu: row %.0f, col %.0f: expected indices below %zu with rows in order "
                          "(rerun irradiance)",
                          e, r, col, nfaces);
    if (!(isfinite(k) && k >= 0 && isfinite(ku) && ku >= 0))
        return rs_err_set(err, RS_ERR_INPUT, c->path, 0, "entry %zu: weights must be finite and >= 0", e);
    c->last_row = r;
    t->row_start[(size_t)r + 1]++;
    t->col[e] = (uint32_t)col;
    t->k[e] = (float)k;
    t->k_unseen[e] = (float)ku;
    return 0;
}

rs_transport *rs_transport_read(const char *path, size_t nfaces, rs_err *err)
{
    rs_transport *t = calloc(1, sizeof *t);
    if (!t || !(t->row_start = calloc(nfaces + 1, sizeof *t->row_start))) {
        free(t);
        rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory for %zu facets", nfaces);
        return NULL;
    }
    t->nfaces = nfaces;
    read_ctx c = {t, path, -1, -1, -1, -1, 0};
    rs_ply *head = NULL;
    if (rs_ply_read_records(path, read_entry, &c, &head, err) != 0) goto fail;
    /* An empty or missing element never reached the callback: check the header. */
    const rs_ply_element *el = rs_ply_find_element(head, "transport");
    if (!el || find_props(&c, el) != 0) {
        expected_props(path, err);
        goto fail;
    }
    if (!t->col &&
        (!(t->col = malloc(sizeof *t->col)) || !(t->k = malloc(sizeof *t->k)) ||
         !(t->k_unseen = malloc(sizeof *t->k_unseen)))) {
        rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
        goto fail;
    }
    for (size_t f = 0; f < nfaces; f++) t->row_start[f + 1] += t->row_start[f];
    rs_ply_free(head);
    return t;
fail:
    rs_ply_free(head);
    rs_transport_free(t);
    return NULL;
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
 * the order (or thread count) in which facets are updated, nor on how the rows are split over
 * MPI ranks (common/par.h): each rank updates its share of the rows, the ranks exchange the new
 * L (allgather, 24 bytes a facet) and take the largest change over all of them. */
int rs_transport_solve(const rs_transport *K, const double *rho, const double *esky, double *L, double *G, double tol,
                       int max_iter, double *residual)
{
    size_t nf = K->nfaces, lo, hi;
    rs_par_range(nf, &lo, &hi);
    double *next = malloc(3 * nf * sizeof *next);
    if (rs_par_any(!next)) {
        free(next);
        return -1;
    }
    for (size_t i = 0; i < 3 * nf; i++) L[i] = rho[i] * esky[i] / M_PI;
    int it, failed = 0;
    *residual = 0;
    rs_err err;
    rs_err_clear(&err);
    for (it = 1; it <= max_iter; it++) {
        double change = 0, scale = 0;
#pragma omp parallel for schedule(static) reduction(max : change, scale)
        for (size_t i = lo; i < hi; i++) {
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
        if (rs_par_allgather_range(next, nf, 3 * sizeof *next, &err) != 0) {
            failed = 1;
            break;
        }
        change = rs_par_max(change);
        scale = rs_par_max(scale);
        memcpy(L, next, 3 * nf * sizeof *L);
        *residual = scale > 0 ? change / scale : 0;
        if (*residual < tol) break;
    }
    /* G of the last sweep, every rank's rows. */
    if (!failed && rs_par_allgather_range(G, nf, 3 * sizeof *G, &err) != 0) failed = 1;
    free(next);
    if (failed) return -1;
    return it > max_iter ? max_iter : it;
}
