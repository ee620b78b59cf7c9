/* nadir: the cap below a scanner (see nadir.h). */
#include "meshing/nadir.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "meshing/grid.h"
#include "common/linsolve.h"
#include "common/vec.h"

#define MIN_RIM_SHARE     0.8   /* of the columns must have a point below the scanner */
#define MAX_RIM_ELEVATION -0.35 /* rad (-20 degrees): the rim must look down */
#define MAX_TILT_COS      0.866 /* the fitted plane within 30 degrees of horizontal */

static double elevation(rs_v3 d)
{
    return atan2(d.z, sqrt(d.x * d.x + d.y * d.y));
}

/* Least-squares plane z = k[0] x + k[1] y + k[2] through n points; 0 on success. */
static int fit_plane(const rs_v3 *p, size_t n, double k[3])
{
    double A[9] = {0};
    k[0] = k[1] = k[2] = 0;
    for (size_t i = 0; i < n; i++) {
        double r[3] = {p[i].x, p[i].y, 1};
        for (int a = 0; a < 3; a++) {
            for (int b = 0; b < 3; b++) A[3 * a + b] += r[a] * r[b];
            k[a] += r[a] * p[i].z;
        }
    }
    return rs_solve_dense(A, k, 3);
}

rs_mesh *rs_nadir_cap(const rs_cloud *c, int s, double max_rms_m, rs_nadir_stats *st, rs_err *err)
{
    return rs_nadir_cap_coarse(c, s, max_rms_m, 1, 0, st, err);
}

/* Index of the cap's vertex of lattice column i (or of group i / m inside) on ring r: with
 * m == 1 column by column (K per column), else the rim first, then ring after ring. */
static uint32_t vid(int m, int K, int ncl, int nin, int i, int r)
{
    if (m == 1) return (uint32_t)((size_t)i * K + r);
    return r == 0 ? (uint32_t)i : (uint32_t)(ncl + (size_t)(r - 1) * nin + i / m);
}

/* Appends triangle (a, b, c) to cap, wound so that its normal faces P; drops it when degenerate. */
static void add_tri(rs_mesh *cap, size_t *nf, rs_v3 P, uint32_t a, uint32_t b, uint32_t c)
{
    rs_v3 p0 = rs_mesh_vert(cap, a), p1 = rs_mesh_vert(cap, b), p2 = rs_mesh_vert(cap, c);
    rs_v3 n = rs_v3_cross(rs_v3_sub(p1, p0), rs_v3_sub(p2, p0));
    if (rs_v3_len(n) == 0) return;
    uint32_t *out = cap->tris + 3 * (*nf)++;
    int flip = rs_v3_dot(n, rs_v3_sub(P, p0)) < 0;
    out[0] = a;
    out[1] = flip ? c : b;
    out[2] = flip ? b : c;
}

rs_mesh *rs_nadir_cap_coarse(const rs_cloud *c, int s, double max_rms_m, int stride, double spacing_m,
                             rs_nadir_stats *st, rs_err *err)
{
    memset(st, 0, sizeof *st);
    const rs_scan *sc = &c->scans[s];
    rs_v3 P = rs_v3_make(sc->position[0], sc->position[1], sc->position[2]);
    int rows = sc->rows;
    if (stride < 1) stride = 1;
    int *cl = malloc(((size_t)sc->cols + 2) * sizeof *cl), *rl = malloc(((size_t)rows + 2) * sizeof *rl);
    int cols = cl ? rs_grid_lattice(sc->cols, stride, cl) : 0, nrl = rl ? rs_grid_lattice(rows, stride, rl) : 0;
    rs_v3 *rim = malloc(((size_t)cols + 1) * sizeof *rim);
    double *rim_el = calloc((size_t)cols + 1, sizeof *rim_el), *steps = malloc(((size_t)cols + 1) * sizeof *steps);
    int *has = calloc((size_t)cols + 1, sizeof *has);
    rs_mesh *cap = NULL;
    if (!cl || !rl || !rim || !rim_el || !steps || !has) goto oom;
    size_t nrim = 0, nsteps = 0;
    /* The rim on the grid's lattice (rs_grid_lattice), so that it welds to the grid mesh. */
    for (int col = 0; col < cols; col++) {
        int best = -1;
        double best_el = 0;
        for (int ri = 0; ri < nrl; ri++) {
            size_t i = sc->first + (size_t)cl[col] * rows + rl[ri];
            if (!c->valid[i]) continue;
            double el = elevation(rs_v3_sub(rs_v3_make(c->xyz[3 * i], c->xyz[3 * i + 1], c->xyz[3 * i + 2]), P));
            if (best < 0 || el < best_el) {
                best = ri;
                best_el = el;
            }
        }
        if (best < 0 || best_el > MAX_RIM_ELEVATION) continue;
        size_t i = sc->first + (size_t)cl[col] * rows + rl[best];
        rim[col] = rs_v3_make(c->xyz[3 * i], c->xyz[3 * i + 1], c->xyz[3 * i + 2]);
        rim_el[col] = best_el;
        has[col] = 1;
        nrim++;
        /* the lattice's elevation step, from this column's two lowest neighbouring rows */
        int nb = best + 1 < nrl ? best + 1 : best - 1;
        size_t j = sc->first + (size_t)cl[col] * rows + (nb >= 0 ? rl[nb] : 0);
        if (nb >= 0 && c->valid[j]) {
            double el2 = elevation(rs_v3_sub(rs_v3_make(c->xyz[3 * j], c->xyz[3 * j + 1], c->xyz[3 * j + 2]), P));
            if (fabs(el2 - best_el) > 0) steps[nsteps++] = fabs(el2 - best_el);
        }
    }
    st->ring_points = nrim;
    if (nrim < MIN_RIM_SHARE * cols || nsteps == 0) {
        snprintf(st->why_not, sizeof st->why_not, "only %zu of %d columns reach below -20 degrees", nrim, cols);
        goto done;
    }
    rs_v3 *pts = malloc(nrim * sizeof *pts);
    if (!pts) goto oom;
    size_t k = 0;
    for (int col = 0; col < cols; col++)
        if (has[col]) pts[k++] = rim[col];
    double plane[3] = {0, 0, 0};
    int bad = fit_plane(pts, nrim, plane);
    double ss = 0;
    for (size_t i = 0; !bad && i < nrim; i++) {
        double r = pts[i].z - (plane[0] * pts[i].x + plane[1] * pts[i].y + plane[2]);
        ss += r * r;
    }
    free(pts);
    st->rms_m = bad ? INFINITY : sqrt(ss / nrim);
    double tilt_cos = 1 / sqrt(1 + plane[0] * plane[0] + plane[1] * plane[1]);
    if (bad || st->rms_m > max_rms_m || tilt_cos < MAX_TILT_COS || P.z <= plane[0] * P.x + plane[1] * P.y + plane[2]) {
        snprintf(st->why_not, sizeof st->why_not,
                 "the ground below is not a plane under the scanner "
                 "(rim RMS %.3g m, limit %.3g m)",
                 st->rms_m, max_rms_m);
        goto done;
    }
    /* Rings from the rim down to the nadir, spaced like the grid's rows. */
    for (size_t i = 1; i < nsteps; i++) /* median step, by insertion sort (few hundred) */
        for (size_t j = i; j > 0 && steps[j - 1] > steps[j]; j--) {
            double t = steps[j];
            steps[j] = steps[j - 1];
            steps[j - 1] = t;
        }
    double step = steps[nsteps / 2];
    double mean_el = 0;
    for (int col = 0; col < cols; col++)
        if (has[col]) mean_el += rim_el[col] / nrim;
    int K = (int)ceil((mean_el + M_PI / 2) / step);
    if (K < 1) K = 1;
    if (K > 4096) K = 4096;
    /* A flat cap needs no more vertices than the facets it becomes: with spacing_m, rings about
     * spacing_m apart and, inside the rim, every m-th column (the rim keeps all of them). */
    int m = 1;
    if (spacing_m > 0) {
        double radius = 0;
        for (int col = 0; col < cols; col++)
            if (has[col]) {
                double dx = rim[col].x - P.x, dy = rim[col].y - P.y;
                radius += sqrt(dx * dx + dy * dy) / nrim;
            }
        int Ks = (int)ceil(radius / spacing_m);
        if (Ks < K) K = Ks < 1 ? 1 : Ks;
        double rim_gap = 2 * M_PI * radius / cols;
        m = rim_gap > 0 ? (int)floor(spacing_m / rim_gap) : 1;
        if (m > cols / 8) m = cols / 8;
        if (m < 1 || K == 1) m = 1;
    }
    int nin = (cols + m - 1) / m;
    size_t nv = m == 1 ? (size_t)cols * K + 1 : (size_t)cols + (size_t)(K - 1) * nin + 1;
    size_t nf_max = m == 1 ? (size_t)cols * (2 * (size_t)K) : (size_t)cols + (size_t)nin * (2 * (size_t)K + 1);
    cap = rs_mesh_new(nv, nf_max);
    if (!cap) goto oom;
    /* Each inner column takes its azimuth and rim elevation from the first rim point of its group. */
    int *src = malloc((size_t)nin * sizeof *src);
    if (!src) goto oom;
    for (int g = 0; g < nin; g++) {
        src[g] = -1;
        for (int col = g * m; col < cols && col < (g + 1) * m && src[g] < 0; col++)
            if (has[col]) src[g] = col;
    }
    for (int col = 0; col < cols; col++) {
        int g = col / m, sg = src[g] >= 0 ? src[g] : col;
        rs_v3 d0 = has[sg] ? rs_v3_sub(rim[sg], P) : rs_v3_make(1, 0, 0);
        double az = atan2(d0.y, d0.x);
        for (int r = 0; r < K; r++) {
            if (r > 0 && col % m) continue;
            rs_v3 q;
            if (r == 0) {
                q = has[col] ? rim[col] : P;
            } else {
                double el = rim_el[sg] - r * (rim_el[sg] + M_PI / 2) / K;
                rs_v3 d = rs_v3_make(cos(el) * cos(az), cos(el) * sin(az), sin(el));
                double t = (plane[0] * P.x + plane[1] * P.y + plane[2] - P.z) / (d.z - plane[0] * d.x - plane[1] * d.y);
                q = rs_v3_add(P, rs_v3_scale(d, t));
            }
            float *v = cap->verts + 3 * (size_t)vid(m, K, cols, nin, col, r);
            if (r == 0 && has[col]) { /* bit-identical to the cloud's point for welding */
                v[0] = (float)rim[col].x, v[1] = (float)rim[col].y, v[2] = (float)rim[col].z;
            } else {
                v[0] = (float)q.x, v[1] = (float)q.y, v[2] = (float)q.z;
            }
        }
    }
    float *centre = cap->verts + 3 * (nv - 1);
    centre[0] = (float)P.x, centre[1] = (float)P.y;
    centre[2] = (float)(plane[0] * P.x + plane[1] * P.y + plane[2]);
    /* Quads between rings k and k + 1 of neighbouring columns (wrapping around), a fan at the
     * centre; each triangle wound so that its normal faces the scanner. With m > 1 the rim's
     * columns of a group fan to the group's inner vertex, then a triangle closes to the next. */
    size_t nf = 0;
    uint32_t ctr = (uint32_t)(nv - 1);
    for (int col = 0; col < cols; col++) {
        int c2 = (col + 1) % cols;
        if (m > 1) {
            int g = col / m, g2 = (g + 1) % nin;
            if (K > 1 && has[col] && has[c2] && src[g] >= 0)
                add_tri(cap, &nf, P, (uint32_t)col, (uint32_t)c2, vid(m, K, cols, nin, col, 1));
            if (c2 % m == 0 && has[c2] && src[g] >= 0 && src[g2] >= 0)
                add_tri(cap, &nf, P, (uint32_t)c2, vid(m, K, cols, nin, c2, 1), vid(m, K, cols, nin, col, 1));
            if (col % m) continue;
            c2 = g2 * m;
            if (src[g] < 0 || src[g2] < 0) continue;
        } else if (!has[col] || !has[c2]) {
            continue;
        }
        for (int r = m > 1 ? 1 : 0; r < K; r++) {
            uint32_t a = vid(m, K, cols, nin, col, r), b = vid(m, K, cols, nin, c2, r);
            if (r + 1 < K) {
                uint32_t a2 = vid(m, K, cols, nin, col, r + 1), b2 = vid(m, K, cols, nin, c2, r + 1);
                add_tri(cap, &nf, P, a, b, b2);
                add_tri(cap, &nf, P, a, b2, a2);
            } else {
                add_tri(cap, &nf, P, a, b, ctr);
            }
        }
    }
    free(src);
    cap->nfaces = nf;
    st->triangles = nf;
    goto done;
oom:
    rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the nadir cap");
    rs_mesh_free(cap);
    cap = NULL;
done:
    free(cl);
    free(rl);
    free(rim);
    free(rim_el);
    free(steps);
    free(has);
    return cap;
}

typedef struct {
    float p[3];
    uint32_t index;
} keyed_vertex;

static int cmp_keyed(const void *x, const void *y)
{
    const keyed_vertex *a = x, *b = y;
    int c = memcmp(a->p, b->p, sizeof a->p);
    return c ? c : (a->index > b->index) - (a->index < b->index);
}

rs_mesh *rs_mesh_merge_welded(const rs_mesh *a, const rs_mesh *b)
{
    keyed_vertex *keys = malloc((a->nverts ? a->nverts : 1) * sizeof *keys);
    uint32_t *map = malloc((b->nverts ? b->nverts : 1) * sizeof *map);
    rs_mesh *m = NULL;
    if (!keys || !map) goto out;
    for (size_t v = 0; v < a->nverts; v++) {
        memcpy(keys[v].p, a->verts + 3 * v, sizeof keys[v].p);
        keys[v].index = (uint32_t)v;
    }
    qsort(keys, a->nverts, sizeof *keys, cmp_keyed);
    size_t nv = a->nverts;
    for (size_t v = 0; v < b->nverts; v++) {
        keyed_vertex q;
        memcpy(q.p, b->verts + 3 * v, sizeof q.p);
        q.index = 0;
        size_t lo = 0, hi = a->nverts; /* first key >= (p, 0) */
        while (lo < hi) {
            size_t mid = (lo + hi) / 2;
            if (cmp_keyed(&keys[mid], &q) < 0)
                lo = mid + 1;
            else
                hi = mid;
        }
        map[v] = lo < a->nverts && memcmp(keys[lo].p, q.p, sizeof q.p) == 0 ? keys[lo].index : (uint32_t)nv++;
    }
    m = rs_mesh_new(nv, a->nfaces + b->nfaces);
    if (!m) goto out;
    memcpy(m->verts, a->verts, a->nverts * 3 * sizeof *m->verts);
    for (size_t v = 0; v < b->nverts; v++)
        if (map[v] >= a->nverts) memcpy(m->verts + 3 * (size_t)map[v], b->verts + 3 * v, 3 * sizeof *m->verts);
    memcpy(m->tris, a->tris, a->nfaces * 3 * sizeof *m->tris);
    for (size_t f = 0; f < 3 * b->nfaces; f++) m->tris[3 * a->nfaces + f] = map[b->tris[f]];
out:
    free(keys);
    free(map);
    return m;
}
