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

/* The cap's rim and layout, found step by step by rs_nadir_cap_coarse. */
typedef struct {
    rs_v3 P;         /* the scanner */
    int cols;        /* lattice columns (rs_grid_lattice) */
    rs_v3 *rim;      /* per column: its lowest valid point among the lattice's rows, where has[] */
    double *rim_el;  /* that point's elevation seen from P */
    int *has;        /* the column reaches below MAX_RIM_ELEVATION */
    size_t nrim;     /* columns that do */
    double *steps;   /* the lattice's elevation steps at the rim */
    size_t nsteps;   /* how many were measured */
    double plane[3]; /* the ground: z = plane[0] x + plane[1] y + plane[2] */
    int K;           /* rings, the rim's included */
    int m;           /* rim columns per inner column */
    int nin;         /* inner columns */
    int *src;        /* per inner column: the first rim column of its group, -1 when none */
    size_t nv;       /* the cap's vertices, the centre last */
} cap_layout;

/* The rim on the grid's lattice (rs_grid_lattice), so that it welds to the grid mesh: each
 * column's lowest valid point when it looks down far enough, and the lattice's elevation step
 * there. cl, rl: the lattice's columns and (nrl) rows. */
static void find_rim(const rs_cloud *c, const rs_scan *sc, const int *cl, const int *rl, int nrl, cap_layout *L)
{
    int rows = sc->rows;
    rs_v3 P = L->P;
    for (int col = 0; col < L->cols; col++) {
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
        L->rim[col] = rs_v3_make(c->xyz[3 * i], c->xyz[3 * i + 1], c->xyz[3 * i + 2]);
        L->rim_el[col] = best_el;
        L->has[col] = 1;
        L->nrim++;
        /* the lattice's elevation step, from this column's two lowest neighbouring rows */
        int nb = best + 1 < nrl ? best + 1 : best - 1;
        size_t j = sc->first + (size_t)cl[col] * rows + (nb >= 0 ? rl[nb] : 0);
        if (nb >= 0 && c->valid[j]) {
            double el2 = elevation(rs_v3_sub(rs_v3_make(c->xyz[3 * j], c->xyz[3 * j + 1], c->xyz[3 * j + 2]), P));
            if (fabs(el2 - best_el) > 0) L->steps[L->nsteps++] = fabs(el2 - best_el);
        }
    }
}

/* The plane through the rim, into L->plane: 0 when the ground below is flat within max_rms_m,
 * level within MAX_TILT_COS and below the scanner; 1 when not (st->why_not says so); -1 when
 * out of memory. */
static int rim_plane(cap_layout *L, double max_rms_m, rs_nadir_stats *st)
{
    size_t nrim = L->nrim;
    double *plane = L->plane;
    rs_v3 P = L->P;
    rs_v3 *pts = malloc(nrim * sizeof *pts);
    if (!pts) return -1;
    size_t k = 0;
    for (int col = 0; col < L->cols; col++)
        if (L->has[col]) pts[k++] = L->rim[col];
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
        return 1;
    }
    return 0;
}

/* Rings from the rim down to the nadir, spaced like the grid's rows (L->K); with spacing_m > 0,
 * fewer (rings about spacing_m apart) and, inside the rim, every m-th column (the rim keeps
 * all of them): a flat cap needs no more vertices than the facets it becomes. Sorts L->steps. */
static void ring_layout(cap_layout *L, double spacing_m)
{
    double *steps = L->steps;
    size_t nsteps = L->nsteps, nrim = L->nrim;
    int cols = L->cols;
    rs_v3 P = L->P;
    for (size_t i = 1; i < nsteps; i++) /* median step, by insertion sort (few hundred) */
        for (size_t j = i; j > 0 && steps[j - 1] > steps[j]; j--) {
            double t = steps[j];
            steps[j] = steps[j - 1];
            steps[j - 1] = t;
        }
    double step = steps[nsteps / 2];
    double mean_el = 0;
    for (int col = 0; col < cols; col++)
        if (L->has[col]) mean_el += L->rim_el[col] / nrim;
    int K = (int)ceil((mean_el + M_PI / 2) / step);
    if (K < 1) K = 1;
    if (K > 4096) K = 4096;
    int m = 1;
    if (spacing_m > 0) {
        double radius = 0;
        for (int col = 0; col < cols; col++)
            if (L->has[col]) {
                double dx = L->rim[col].x - P.x, dy = L->rim[col].y - P.y;
                radius += sqrt(dx * dx + dy * dy) / nrim;
            }
        int Ks = (int)ceil(radius / spacing_m);
        if (Ks < K) K = Ks < 1 ? 1 : Ks;
        double rim_gap = 2 * M_PI * radius / cols;
        m = rim_gap > 0 ? (int)floor(spacing_m / rim_gap) : 1;
        if (m > cols / 8) m = cols / 8;
        if (m < 1 || K == 1) m = 1;
    }
    L->K = K;
    L->m = m;
    L->nin = (cols + m - 1) / m;
    L->nv = m == 1 ? (size_t)cols * K + 1 : (size_t)cols + (size_t)(K - 1) * L->nin + 1;
}

/* Each inner column takes its azimuth and rim elevation from the first rim point of its group. */
static int group_sources(cap_layout *L)
{
    int m = L->m, nin = L->nin, cols = L->cols;
    int *src = L->src = malloc((size_t)nin * sizeof *src);
    if (!src) return -1;
    for (int g = 0; g < nin; g++) {
        src[g] = -1;
        for (int col = g * m; col < cols && col < (g + 1) * m && src[g] < 0; col++)
            if (L->has[col]) src[g] = col;
    }
    return 0;
}

/* The cap's vertices: the rim as the cloud has it, the rings on the plane below, the centre
 * below the scanner. */
static void place_vertices(const cap_layout *L, rs_mesh *cap)
{
    int m = L->m, K = L->K, cols = L->cols, nin = L->nin;
    const int *src = L->src, *has = L->has;
    const rs_v3 *rim = L->rim;
    const double *rim_el = L->rim_el, *plane = L->plane;
    rs_v3 P = L->P;
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
    float *centre = cap->verts + 3 * (L->nv - 1);
    centre[0] = (float)P.x, centre[1] = (float)P.y;
    centre[2] = (float)(plane[0] * P.x + plane[1] * P.y + plane[2]);
}

/* Quads between rings k and k + 1 of neighbouring columns (wrapping around), a fan at the
 * centre; each triangle wound so that its normal faces the scanner. With m > 1 the rim's
 * columns of a group fan to the group's inner vertex, then a triangle closes to the next.
 * Returns the number of triangles. */
static size_t cap_faces(const cap_layout *L, rs_mesh *cap)
{
    int m = L->m, K = L->K, cols = L->cols, nin = L->nin;
    const int *src = L->src, *has = L->has;
    rs_v3 P = L->P;
    size_t nf = 0;
    uint32_t ctr = (uint32_t)(L->nv - 1);
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
    return nf;
}

rs_mesh *rs_nadir_cap_coarse(const rs_cloud *c, int s, double max_rms_m, int stride, double spacing_m,
                             rs_nadir_stats *st, rs_err *err)
{
    memset(st, 0, sizeof *st);
    const rs_scan *sc = &c->scans[s];
    cap_layout L = {0};
    L.P = rs_v3_make(sc->position[0], sc->position[1], sc->position[2]);
    if (stride < 1) stride = 1;
    int *cl = malloc(((size_t)sc->cols + 2) * sizeof *cl), *rl = malloc(((size_t)sc->rows + 2) * sizeof *rl);
    int nrl = rl ? rs_grid_lattice(sc->rows, stride, rl) : 0;
    L.cols = cl ? rs_grid_lattice(sc->cols, stride, cl) : 0;
    L.rim = malloc(((size_t)L.cols + 1) * sizeof *L.rim);
    L.rim_el = calloc((size_t)L.cols + 1, sizeof *L.rim_el);
    L.steps = malloc(((size_t)L.cols + 1) * sizeof *L.steps);
    L.has = calloc((size_t)L.cols + 1, sizeof *L.has);
    rs_mesh *cap = NULL;
    if (!cl || !rl || !L.rim || !L.rim_el || !L.steps || !L.has) goto oom;
    find_rim(c, sc, cl, rl, nrl, &L);
    st->ring_points = L.nrim;
    if (L.nrim < MIN_RIM_SHARE * L.cols || L.nsteps == 0) {
        snprintf(st->why_not, sizeof st->why_not, "only %zu of %d columns reach below -20 degrees", L.nrim, L.cols);
        goto done;
    }
    int flat = rim_plane(&L, max_rms_m, st);
    if (flat < 0) goto oom;
    if (flat > 0) goto done;
    ring_layout(&L, spacing_m);
    size_t nf_max =
        L.m == 1 ? (size_t)L.cols * (2 * (size_t)L.K) : (size_t)L.cols + (size_t)L.nin * (2 * (size_t)L.K + 1);
    cap = rs_mesh_new(L.nv, nf_max);
    if (!cap || group_sources(&L) != 0) goto oom;
    place_vertices(&L, cap);
    cap->nfaces = cap_faces(&L, cap);
    st->triangles = cap->nfaces;
    goto done;
oom:
    rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the nadir cap");
    rs_mesh_free(cap);
    cap = NULL;
done:
    free(cl);
    free(rl);
    free(L.rim);
    free(L.rim_el);
    free(L.steps);
    free(L.has);
    free(L.src);
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
