/* truth: the truth mesh and the albedo error measures (see truth.h). */
#include "pipeline/truth.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/faceprop.h"

void rs_truth_free(rs_truth *t)
{
    rs_mesh_free(t->mesh);
    rs_ply_free(t->ply);
    free(t->part);
    free(t->rgb);
    memset(t, 0, sizeof *t);
}

/* The float albedo red, green, blue of every truth face into t->rgb, each in (0, 1]. */
static int read_rgb(rs_truth *t, const char *path, rs_err *err)
{
    /* Truth albedo is float `red green blue` (docs/DESIGN.md, section Reference scenes), not uchar sRGB. */
    const char *names[3] = {"red", "green", "blue"};
    double *v = malloc((t->nt + 1) * sizeof *v);
    if (!v) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    int rc = 0;
    for (int c = 0; c < 3 && rc == 0; c++) {
        rc = rs_faceprop_get(t->ply, path, names[c], t->nt, v, err);
        for (size_t f = 0; f < t->nt && rc == 0; f++) {
            if (!(v[f] > 0 && v[f] <= 1)) {
                rc = rs_err_set(err, RS_ERR_INPUT, path, 0, "face %zu: %s = %g: expected a truth albedo in (0, 1]", f,
                                names[c], v[f]);
                break;
            }
            t->rgb[3 * f + c] = v[f];
        }
    }
    free(v);
    return rc;
}

int rs_truth_read(const char *path, rs_truth *t, rs_err *err)
{
    memset(t, 0, sizeof *t);
    if (!(t->mesh = rs_mesh_read(path, &t->ply, err))) return -1;
    t->nt = t->mesh->nfaces;
    double *part = malloc((t->nt + 1) * sizeof *part);
    t->part = malloc((t->nt + 1) * sizeof *t->part);
    t->rgb = malloc((3 * t->nt + 1) * sizeof *t->rgb);
    int rc = part && t->part && t->rgb ? 0 : rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    if (rc == 0) rc = rs_faceprop_get(t->ply, path, "part", t->nt, part, err);
    if (rc == 0) rc = read_rgb(t, path, err);
    for (size_t f = 0; f < t->nt && rc == 0; f++) {
        if (!(part[f] >= 0 && part[f] < 100000 && part[f] == floor(part[f]))) {
            rc =
                rs_err_set(err, RS_ERR_INPUT, path, 0, "face %zu: part = %g: expected an integer 0..99999", f, part[f]);
            break;
        }
        t->part[f] = (int)part[f];
        if (t->part[f] + 1 > t->nparts) t->nparts = t->part[f] + 1;
    }
    free(part);
    if (rc != 0) rs_truth_free(t);
    return rc;
}

void rs_truth_facet_error(const double *a, const double *t, double *rel, double *sgn)
{
    *rel = *sgn = 0;
    for (int c = 0; c < 3; c++) {
        double tc = t[c] > 1e-6 ? t[c] : 1e-6;
        *rel += fabs(a[c] - t[c]) / tc / 3;
        *sgn += (a[c] - t[c]) / tc / 3;
    }
}

static const double *g_sort_key;
static int cmp_idx(const void *a, const void *b)
{
    size_t i = *(const size_t *)a, j = *(const size_t *)b;
    double x = g_sort_key[i], y = g_sort_key[j];
    return x < y ? -1 : x > y ? 1 : (i > j) - (i < j);
}

void rs_truth_stats_of(const double *rel, const double *sgn, const double *area, const uint8_t *mask, size_t nf,
                       size_t *idx, rs_truth_stats *out)
{
    memset(out, 0, sizeof *out);
    size_t n = 0;
    double w = 0, sr = 0, sb = 0;
    for (size_t f = 0; f < nf; f++)
        if (mask[f]) {
            idx[n++] = f;
            w += area[f];
            sr += rel[f] * area[f];
            sb += sgn[f] * area[f];
        }
    if (n == 0 || !(w > 0)) return;
    g_sort_key = rel;
    qsort(idx, n, sizeof *idx, cmp_idx);
    double q[2] = {0.5, 0.95}, val[2];
    for (int k = 0; k < 2; k++) {
        double cw = 0;
        size_t i = 0;
        for (; i < n; i++) {
            cw += area[idx[i]];
            if (cw / w >= q[k]) break;
        }
        val[k] = rel[idx[i < n ? i : n - 1]];
    }
    out->facets = n;
    out->area = w;
    out->mean_rel = sr / w;
    out->median_rel = val[0];
    out->p95_rel = val[1];
    out->bias_rel = sb / w;
}

void rs_truth_unshift(rs_mesh *res, const rs_ply *res_ply)
{
    const char *origin = rs_ply_find_comment(res_ply, "rhoscan_origin");
    double o[3];
    if (!origin || sscanf(origin, "%lf %lf %lf", &o[0], &o[1], &o[2]) != 3) return;
    for (size_t v = 0; v < res->nverts; v++)
        for (int j = 0; j < 3; j++) res->verts[3 * v + j] = (float)(res->verts[3 * v + j] + o[j]);
}
