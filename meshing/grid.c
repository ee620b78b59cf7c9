/* grid: triangulates organized scans on their angular grid, dropping cells across depth
 * discontinuities, at grazing angles and across angular gaps (see grid.h). */
#include "meshing/grid.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "common/vec.h"

enum { KEEP = 0, DROP_DEPTH = 1, DROP_GRAZING = 2 };

typedef struct grid_ctx {
    const rs_cloud *c;
    const double *o; /* scanner centre of the current scan */
    double *range;   /* per point: distance to its scanner, 0 when unusable */
    double *dir;     /* per point: unit direction from its scanner */
    double max_ratio, cos_graze;
    uint32_t *tris; /* triangles as cloud point indices */
    size_t ntris, cap;
} grid_ctx;

static rs_v3 point(const grid_ctx *g, size_t i)
{
    return rs_v3_make(g->c->xyz[3 * i], g->c->xyz[3 * i + 1], g->c->xyz[3 * i + 2]);
}

/* Tests triangle (i, j, k); when kept, writes it into out wound counter-clockwise seen from
 * the scanner (normal toward it) and sets *flip if the given order had to be turned. */
static int tri_test(const grid_ctx *g, size_t i, size_t j, size_t k, uint32_t out[3], int *flip)
{
    double r0 = g->range[i], r1 = g->range[j], r2 = g->range[k];
    double rmin = fmin(r0, fmin(r1, r2)), rmax = fmax(r0, fmax(r1, r2));
    if (rmax - rmin > g->max_ratio * rmin) return DROP_DEPTH;
    rs_v3 a = point(g, i), b = point(g, j), c = point(g, k);
    rs_v3 n = rs_v3_cross(rs_v3_sub(b, a), rs_v3_sub(c, a));
    rs_v3 centroid = rs_v3_scale(rs_v3_add(rs_v3_add(a, b), c), 1.0 / 3.0);
    rs_v3 to_scanner = rs_v3_sub(rs_v3_make(g->o[0], g->o[1], g->o[2]), centroid);
    double dot = rs_v3_dot(n, to_scanner), norm = rs_v3_len(n) * rs_v3_len(to_scanner);
    if (!(norm > 0) || fabs(dot) < g->cos_graze * norm) return DROP_GRAZING;
    *flip = dot < 0;
    out[0] = (uint32_t)i;
    out[1] = (uint32_t)(*flip ? k : j);
    out[2] = (uint32_t)(*flip ? j : k);
    return KEEP;
}

static int push_tri(grid_ctx *g, const uint32_t t[3])
{
    if (g->ntris == g->cap) {
        size_t cap = g->cap ? 2 * g->cap : 1 << 16;
        uint32_t *tris = realloc(g->tris, cap * 3 * sizeof *tris);
        if (!tris) return -1;
        g->tris = tris;
        g->cap = cap;
    }
    memcpy(g->tris + 3 * g->ntris++, t, 3 * sizeof *t);
    return 0;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median angle (rad) between the rays of valid neighbours one step apart along columns
 * (dc = 1) or rows (dr = 1), from at most about 20000 evenly spread pairs; 0 if none. */
static double median_step(const grid_ctx *g, const rs_scan *s, int dc, int dr)
{
    size_t ncells = (size_t)(s->cols - dc) * (size_t)(s->rows - dr);
    if (s->cols - dc <= 0 || s->rows - dr <= 0) return 0;
    size_t stride = ncells / 20000 + 1, n = 0;
    double *ang = malloc((ncells / stride + 1) * sizeof *ang);
    if (!ang) return 0;
    for (size_t k = 0; k < ncells; k += stride) {
        size_t col = k / (size_t)(s->rows - dr), row = k % (size_t)(s->rows - dr);
        size_t i = s->first + col * (size_t)s->rows + row;
        size_t j = i + (size_t)dc * (size_t)s->rows + (size_t)dr;
        if (g->range[i] > 0 && g->range[j] > 0) {
            const double *u = g->dir + 3 * i, *v = g->dir + 3 * j;
            double d = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
            ang[n++] = acos(fmax(-1.0, fmin(1.0, d)));
        }
    }
    double med = 0;
    if (n) {
        qsort(ang, n, sizeof *ang, cmp_double);
        med = ang[n / 2];
    }
    free(ang);
    return med;
}

/* True when the rays of two valid points are further apart than cos_max allows. */
static int gap(const grid_ctx *g, size_t i, size_t j, double cos_max)
{
    if (!(g->range[i] > 0) || !(g->range[j] > 0)) return 0;
    const double *u = g->dir + 3 * i, *v = g->dir + 3 * j;
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2] < cos_max;
}

/* Median of the ranges of at most about 20000 evenly spread valid points of s; 0 if none. */
static double median_range(const grid_ctx *g, const rs_scan *s)
{
    size_t n = (size_t)s->cols * (size_t)s->rows, stride = n / 20000 + 1, k = 0;
    double *r = malloc((n / stride + 1) * sizeof *r), med = 0;
    if (!r) return 0;
    for (size_t i = 0; i < n; i += stride)
        if (g->range[s->first + i] > 0) r[k++] = g->range[s->first + i];
    if (k) {
        qsort(r, k, sizeof *r, cmp_double);
        med = r[k / 2];
    }
    free(r);
    return med;
}

int rs_grid_stride(const rs_cloud *c, int s, const rs_grid_opts *o, double col_step, double row_step,
                   double median_range_m)
{
    const rs_scan *sc = &c->scans[s];
    double k = 1;
    /* About two triangles per cell with returns at full resolution, k^2 fewer at stride k. */
    size_t n = (size_t)sc->cols * (size_t)sc->rows, valid = 0;
    for (size_t i = sc->first; i < sc->first + n; i++) valid += c->valid[i] != 0;
    double tris = 2.0 * (double)valid;
    if (tris < RS_GRID_MIN_TRIANGLES) return 1;
    if (o->target_faces > 0) {
        k = floor(sqrt(tris / (RS_GRID_MARGIN * (double)o->target_faces)));
    } else if (o->target_edge_m > 0 && median_range_m > 0 && fmax(col_step, row_step) > 0) {
        /* Triangle count goes with the inverse square of the edge: sqrt(margin) shorter edges. */
        k = floor(o->target_edge_m / (sqrt(RS_GRID_MARGIN) * median_range_m * fmax(col_step, row_step)));
    }
    k = fmin(k, floor(sqrt(tris / RS_GRID_MIN_TRIANGLES)));
    int lim = sc->cols < sc->rows ? sc->cols : sc->rows;
    if (!(k >= 1)) k = 1;
    if (k > lim / 8.0) k = lim / 8 > 1 ? lim / 8 : 1; /* keep a grid: at least 8 cells across */
    return (int)k;
}

/* The grid lines used at stride k among n: 0, k, 2k, ... and the last one; returns the count. */
static int lattice(int n, int k, int *out)
{
    int m = 0;
    for (int i = 0; i < n; i += k) out[m++] = i;
    if (n > 0 && out[m - 1] != n - 1) out[m++] = n - 1;
    return m;
}

int rs_grid_lattice(int n, int k, int *out)
{
    return lattice(n, k, out);
}

static int triangulate_scan(grid_ctx *g, const rs_scan *s, int sidx, const rs_grid_opts *o, rs_grid_stats *st)
{
    g->o = s->position;
    double col_step = median_step(g, s, 1, 0), row_step = median_step(g, s, 0, 1);
    int stride = rs_grid_stride(g->c, sidx, o, col_step, row_step, o->target_edge_m > 0 ? median_range(g, s) : 0);
    st->stride = stride;
    int *cl = malloc(((size_t)s->cols + 2) * sizeof *cl), *rl = malloc(((size_t)s->rows + 2) * sizeof *rl);
    if (!cl || !rl) {
        free(cl);
        free(rl);
        return -1;
    }
    int ncl = lattice(s->cols, stride, cl), nrl = lattice(s->rows, stride, rl);
    size_t R = (size_t)s->rows;
    /* The last column joins the first when the sweep closes (a full turn); otherwise the gap
     * test drops that seam. A cell spans (next - this) grid steps: the gap limit scales with it. */
    int ncol_cells = ncl >= 3 ? ncl : ncl - 1;
    for (int ci = 0; ci < ncol_cells; ci++) {
        int ca = cl[ci], cb = cl[(ci + 1) % ncl];
        int span_c = ci + 1 < ncl ? cb - ca : 1;
        double ac = o->max_gap_factor * span_c * col_step;
        double cos_col = col_step > 0 && ac < M_PI ? cos(ac) : -2;
        size_t c0 = s->first + (size_t)ca * R, c1 = s->first + (size_t)cb * R;
        for (int ri = 0; ri + 1 < nrl; ri++) {
            size_t r = (size_t)rl[ri], rn = (size_t)rl[ri + 1];
            double ar = o->max_gap_factor * (double)(rn - r) * row_step;
            double cos_row = row_step > 0 && ar < M_PI ? cos(ar) : -2;
            size_t q[4] = {c0 + r, c1 + r, c1 + rn, c0 + rn}; /* 00 10 11 01, around the cell */
            int ok[4], nok = 0;
            for (int k = 0; k < 4; k++) nok += ok[k] = g->range[q[k]] > 0;
            st->cells++;
            if (nok < 3) {
                st->cells_no_return++;
                continue;
            }
            if (gap(g, q[0], q[1], cos_col) || gap(g, q[3], q[2], cos_col) || gap(g, q[0], q[3], cos_row) ||
                gap(g, q[1], q[2], cos_row)) {
                st->dropped_gap++;
                continue;
            }
            uint32_t t[2][2][3];
            int res[2][2], flip[2][2] = {{0, 0}, {0, 0}}, kept[2] = {0, 0}, nsplit;
            if (nok == 3) {
                size_t v[3];
                for (int k = 0, n = 0; k < 4; k++)
                    if (ok[k]) v[n++] = q[k];
                res[0][0] = tri_test(g, v[0], v[1], v[2], t[0][0], &flip[0][0]);
                res[0][1] = -1;
                nsplit = 1;
            } else {
                /* Split A along 00-11, split B along 10-01; keep the one that keeps more. */
                res[0][0] = tri_test(g, q[0], q[1], q[2], t[0][0], &flip[0][0]);
                res[0][1] = tri_test(g, q[0], q[2], q[3], t[0][1], &flip[0][1]);
                res[1][0] = tri_test(g, q[0], q[1], q[3], t[1][0], &flip[1][0]);
                res[1][1] = tri_test(g, q[1], q[2], q[3], t[1][1], &flip[1][1]);
                nsplit = 2;
            }
            for (int sp = 0; sp < nsplit; sp++) kept[sp] = (res[sp][0] == KEEP) + (res[sp][1] == KEEP);
            int best = 0;
            if (nsplit == 2) {
                rs_v3 d_a = rs_v3_sub(point(g, q[2]), point(g, q[0])), d_b = rs_v3_sub(point(g, q[3]), point(g, q[1]));
                if (kept[1] > kept[0] || (kept[1] == kept[0] && rs_v3_dot(d_b, d_b) < rs_v3_dot(d_a, d_a))) best = 1;
            }
            for (int k = 0; k < 2; k++) {
                int r2 = res[best][k];
                if (r2 == DROP_DEPTH) st->dropped_depth++;
                if (r2 == DROP_GRAZING) st->dropped_grazing++;
                if (r2 != KEEP) continue;
                if (push_tri(g, t[best][k]) != 0) {
                    free(cl);
                    free(rl);
                    return -1;
                }
                st->triangles++;
                st->flipped += flip[best][k];
            }
        }
    }
    free(cl);
    free(rl);
    return 0;
}

rs_mesh *rs_grid_triangulate(const rs_cloud *c, const rs_grid_opts *o, rs_grid_stats *st, rs_err *err)
{
    rs_grid_stats local;
    if (!st) st = &local;
    memset(st, 0, sizeof *st);
    if (c->nscans == 0) {
        rs_err_set(err, RS_ERR_INPUT, NULL, 0, "the cloud has no scan grid; triangulation needs an organized scan");
        return NULL;
    }
    if (c->npoints >= UINT32_MAX) {
        rs_err_set(err, RS_ERR_INPUT, NULL, 0, "%zu points; at most %u are supported", c->npoints, UINT32_MAX - 1);
        return NULL;
    }
    grid_ctx g = {.c = c, .max_ratio = o->max_depth_ratio, .cos_graze = cos(o->max_grazing_rad)};
    rs_mesh *m = NULL;
    uint32_t *remap = NULL;
    g.range = calloc(c->npoints ? c->npoints : 1, sizeof *g.range);
    g.dir = calloc(c->npoints ? 3 * c->npoints : 1, sizeof *g.dir);
    if (!g.range || !g.dir) goto nomem;
    for (int s = 0; s < c->nscans; s++) {
        const rs_scan *sc = &c->scans[s];
        size_t n = (size_t)sc->cols * (size_t)sc->rows;
        for (size_t i = sc->first; i < sc->first + n; i++) {
            if (!c->valid[i]) continue;
            double d[3], r2 = 0;
            for (int j = 0; j < 3; j++) {
                d[j] = c->xyz[3 * i + j] - sc->position[j];
                r2 += d[j] * d[j];
            }
            if (!(r2 > 0) || !isfinite(r2)) continue; /* a point at the scanner has no ray */
            g.range[i] = sqrt(r2);
            for (int j = 0; j < 3; j++) g.dir[3 * i + j] = d[j] / g.range[i];
        }
    }
    for (int s = 0; s < c->nscans; s++)
        if (triangulate_scan(&g, &c->scans[s], s, o, st) != 0) goto nomem;

    /* Vertices: the points that some triangle uses, in point order. */
    remap = malloc((c->npoints ? c->npoints : 1) * sizeof *remap);
    if (!remap) goto nomem;
    for (size_t i = 0; i < c->npoints; i++) remap[i] = UINT32_MAX;
    for (size_t k = 0; k < 3 * g.ntris; k++) remap[g.tris[k]] = 0;
    size_t nv = 0;
    for (size_t i = 0; i < c->npoints; i++)
        if (remap[i] == 0) remap[i] = (uint32_t)nv++;
    m = rs_mesh_new(nv, g.ntris);
    if (!m) goto nomem;
    for (size_t i = 0; i < c->npoints; i++)
        if (remap[i] != UINT32_MAX)
            for (int j = 0; j < 3; j++) m->verts[3 * remap[i] + j] = (float)c->xyz[3 * i + j];
    for (size_t k = 0; k < 3 * g.ntris; k++) m->tris[k] = remap[g.tris[k]];
    goto out;
nomem:
    rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory triangulating %zu points", c->npoints);
out:
    free(g.range);
    free(g.dir);
    free(g.tris);
    free(remap);
    return m;
}
