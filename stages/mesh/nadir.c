/* nadir: the cap below a scanner (see nadir.h). */
#include "nadir.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "linsolve.h"
#include "vec.h"

#define MIN_RIM_SHARE 0.8        /* of the columns must have a point below the scanner */
#define MAX_RIM_ELEVATION -0.35  /* rad (-20 degrees): the rim must look down */
#define MAX_TILT_COS 0.866       /* the fitted plane within 30 degrees of horizontal */

static double elevation(rs_v3 d) { return atan2(d.z, sqrt(d.x * d.x + d.y * d.y)); }

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
    memset(st, 0, sizeof *st);
    const rs_scan *sc = &c->scans[s];
    rs_v3 P = rs_v3_make(sc->position[0], sc->position[1], sc->position[2]);
    int cols = sc->cols, rows = sc->rows;
    rs_v3 *rim = malloc((size_t)cols * sizeof *rim);
    double *rim_el = malloc((size_t)cols * sizeof *rim_el), *steps = malloc((size_t)cols * sizeof *steps);
    int *has = calloc((size_t)cols, sizeof *has);
    rs_mesh *cap = NULL;
    if (!rim || !rim_el || !steps || !has) goto oom;
    size_t nrim = 0, nsteps = 0;
    for (int col = 0; col < cols; col++) {
        int best = -1, next = -1;
        double best_el = 0;
        for (int row = 0; row < rows; row++) {
            size_t i = sc->first + (size_t)col * rows + row;
            if (!c->valid[i]) continue;
            double el = elevation(rs_v3_sub(rs_v3_make(c->xyz[3 * i], c->xyz[3 * i + 1], c->xyz[3 * i + 2]), P));
            if (best < 0 || el < best_el) {
                next = best;
                best = row;
                best_el = el;
            }
        }
        if (best < 0 || best_el > MAX_RIM_ELEVATION) continue;
        size_t i = sc->first + (size_t)col * rows + best;
        rim[col] = rs_v3_make(c->xyz[3 * i], c->xyz[3 * i + 1], c->xyz[3 * i + 2]);
        rim_el[col] = best_el;
        has[col] = 1;
        nrim++;
        (void)next;
        /* the grid's elevation step, from this column's two lowest neighbouring rows */
        int nb = best + 1 < rows ? best + 1 : best - 1;
        size_t j = sc->first + (size_t)col * rows + nb;
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
    if (bad || st->rms_m > max_rms_m || tilt_cos < MAX_TILT_COS ||
        P.z <= plane[0] * P.x + plane[1] * P.y + plane[2]) {
        snprintf(st->why_not, sizeof st->why_not, "the ground below is not a plane under the scanner "
                 "(rim RMS %.3g m, limit %.3g m)", st->rms_m, max_rms_m);
        goto done;
    }
    /* Rings from the rim down to the nadir, spaced like the grid's rows. */
    for (size_t i = 1; i < nsteps; i++)      /* median step, by insertion sort (few hundred) */
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
    size_t nv = (size_t)cols * K + 1, nf_max = (size_t)cols * (2 * (size_t)K);
    cap = rs_mesh_new(nv, nf_max);
    if (!cap) goto oom;
    for (int col = 0; col < cols; col++) {
        rs_v3 d0 = has[col] ? rs_v3_sub(rim[col], P) : rs_v3_make(1, 0, 0);
        double az = atan2(d0.y, d0.x);
        for (int r = 0; r < K; r++) {
            rs_v3 q;
            if (r == 0) {
                q = has[col] ? rim[col] : P;
            } else {
                double el = rim_el[col] - r * (rim_el[col] + M_PI / 2) / K;
                rs_v3 d = rs_v3_make(cos(el) * cos(az), cos(el) * sin(az), sin(el));
                double t = (plane[0] * P.x + plane[1] * P.y + plane[2] - P.z) / (d.z - plane[0] * d.x - plane[1] * d.y);
                q = rs_v3_add(P, rs_v3_scale(d, t));
            }
            float *v = cap->verts + 3 * ((size_t)col * K + r);
            if (r == 0 && has[col]) {          /* bit-identical to the cloud's point for welding */
                v[0] = (float)rim[col].x, v[1] = (float)rim[col].y, v[2] = (float)rim[col].z;
            } else {
                v[0] = (float)q.x, v[1] = (float)q.y, v[2] = (float)q.z;
            }
        }
    }
    float *centre = cap->verts + 3 * (size_t)cols * K;
    centre[0] = (float)P.x, centre[1] = (float)P.y;
    centre[2] = (float)(plane[0] * P.x + plane[1] * P.y + plane[2]);
    /* Quads between rings k and k + 1 of neighbouring columns (wrapping around), a fan at the
     * centre; each triangle wound so that its normal faces the scanner. */
    size_t nf = 0;
    uint32_t ctr = (uint32_t)((size_t)cols * K);
    for (int col = 0; col < cols; col++) {
        int c2 = (col + 1) % cols;
        if (!has[col] || !has[c2]) continue;
        for (int r = 0; r < K; r++) {
            uint32_t a = (uint32_t)((size_t)col * K + r), b = (uint32_t)((size_t)c2 * K + r);
            uint32_t tri[2][3];
            int nt;
            if (r + 1 < K) {
                uint32_t a2 = a + 1, b2 = b + 1;
                tri[0][0] = a, tri[0][1] = b, tri[0][2] = b2;
                tri[1][0] = a, tri[1][1] = b2, tri[1][2] = a2;
                nt = 2;
            } else {
                tri[0][0] = a, tri[0][1] = b, tri[0][2] = ctr;
                nt = 1;
            }
            for (int t = 0; t < nt; t++) {
                rs_v3 p0 = rs_mesh_vert(cap, tri[t][0]), p1 = rs_mesh_vert(cap, tri[t][1]),
                      p2 = rs_mesh_vert(cap, tri[t][2]);
                rs_v3 n = rs_v3_cross(rs_v3_sub(p1, p0), rs_v3_sub(p2, p0));
                if (rs_v3_len(n) == 0) continue;
                uint32_t *out = cap->tris + 3 * nf++;
                int flip = rs_v3_dot(n, rs_v3_sub(P, p0)) < 0;
                out[0] = tri[t][0];
                out[1] = flip ? tri[t][2] : tri[t][1];
                out[2] = flip ? tri[t][1] : tri[t][2];
            }
        }
    }
    cap->nfaces = nf;
    st->triangles = nf;
    goto done;
oom:
    rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the nadir cap");
    rs_mesh_free(cap);
    cap = NULL;
done:
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
        size_t lo = 0, hi = a->nverts;             /* first key >= (p, 0) */
        while (lo < hi) {
            size_t mid = (lo + hi) / 2;
            if (cmp_keyed(&keys[mid], &q) < 0) lo = mid + 1;
            else hi = mid;
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
