/* truth_match: which truth part each result facet lies on (nearest truth triangle of seven
 * points per facet, majority vote), and how enclosed each facet is (rays against the mesh). */
#include <float.h>
#include <stdlib.h>
#include <string.h>
#include "pipeline/truth.h"
#include "common/sampling.h"
#include "common/scene.h"

double rs_eval_point_tri_dist(rs_v3 p, rs_v3 a, rs_v3 b, rs_v3 c)
{
    /* Voronoi regions of the triangle's vertices, edges and face, in that order. */
    rs_v3 ab = rs_v3_sub(b, a), ac = rs_v3_sub(c, a), ap = rs_v3_sub(p, a), q;
    double d1 = rs_v3_dot(ab, ap), d2 = rs_v3_dot(ac, ap);
    if (d1 <= 0 && d2 <= 0) return rs_v3_len(ap);
    rs_v3 bp = rs_v3_sub(p, b);
    double d3 = rs_v3_dot(ab, bp), d4 = rs_v3_dot(ac, bp);
    if (d3 >= 0 && d4 <= d3) return rs_v3_len(bp);
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        q = rs_v3_add(a, rs_v3_scale(ab, d1 / (d1 - d3)));
        return rs_v3_len(rs_v3_sub(p, q));
    }
    rs_v3 cp = rs_v3_sub(p, c);
    double d5 = rs_v3_dot(ab, cp), d6 = rs_v3_dot(ac, cp);
    if (d6 >= 0 && d5 <= d6) return rs_v3_len(cp);
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        q = rs_v3_add(a, rs_v3_scale(ac, d2 / (d2 - d6)));
        return rs_v3_len(rs_v3_sub(p, q));
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        q = rs_v3_add(b, rs_v3_scale(rs_v3_sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6))));
        return rs_v3_len(rs_v3_sub(p, q));
    }
    double den = va + vb + vc;
    if (!(den > 0)) { /* degenerate triangle: nearest of its three edges' ends */
        double m = rs_v3_len(ap);
        if (rs_v3_len(bp) < m) m = rs_v3_len(bp);
        if (rs_v3_len(cp) < m) m = rs_v3_len(cp);
        return m;
    }
    q = rs_v3_add(a, rs_v3_add(rs_v3_scale(ab, vb / den), rs_v3_scale(ac, vc / den)));
    return rs_v3_len(rs_v3_sub(p, q));
}

typedef struct {
    float lo[3], hi[3];
} aabb;

/* Squared distance from p to a box: a lower bound of the distance to the triangle inside. */
static double aabb_dist2(const aabb *b, rs_v3 p)
{
    double pc[3] = {p.x, p.y, p.z}, s = 0;
    for (int k = 0; k < 3; k++) {
        double d = pc[k] < b->lo[k] ? b->lo[k] - pc[k] : (pc[k] > b->hi[k] ? pc[k] - b->hi[k] : 0);
        s += d * d;
    }
    return s;
}

/* Nearest truth triangle of p (first of equals), or -1 beyond tol_m. Brute force with a box
 * test: truth meshes are boxes and small parts (hundreds of triangles), not scans. */
static long nearest_tri(const rs_mesh *t, const aabb *boxes, rs_v3 p, double tol_m)
{
    double best = tol_m;
    long arg = -1;
    for (size_t f = 0; f < t->nfaces; f++) {
        if (aabb_dist2(&boxes[f], p) > best * best) continue;
        const uint32_t *v = t->tris + 3 * f;
        double d = rs_eval_point_tri_dist(p, rs_mesh_vert(t, v[0]), rs_mesh_vert(t, v[1]), rs_mesh_vert(t, v[2]));
        if (d < best || (arg < 0 && d <= best)) {
            best = d;
            arg = (long)f;
        }
    }
    return arg;
}

void rs_eval_match_free(rs_eval_match *m)
{
    if (!m) return;
    free(m->part);
    free(m->truth_rgb);
    free(m->interior);
    memset(m, 0, sizeof *m);
}

int rs_eval_match_facets(const rs_mesh *res, const rs_mesh *truth, const int *truth_part, const double *truth_rgb,
                         double tol_m, rs_eval_match *out, rs_err *err)
{
    size_t nf = res->nfaces;
    memset(out, 0, sizeof *out);
    out->part = malloc((nf + 1) * sizeof *out->part);
    out->truth_rgb = calloc(3 * nf + 1, sizeof *out->truth_rgb);
    out->interior = calloc(nf + 1, 1);
    aabb *boxes = malloc((truth->nfaces + 1) * sizeof *boxes);
    if (!out->part || !out->truth_rgb || !out->interior || !boxes) {
        free(boxes);
        rs_eval_match_free(out);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory matching %zu facets", nf);
    }
    for (size_t f = 0; f < truth->nfaces; f++)
        for (int k = 0; k < 3; k++) {
            float lo = FLT_MAX, hi = -FLT_MAX;
            for (int j = 0; j < 3; j++) {
                float x = truth->verts[3 * truth->tris[3 * f + j] + k];
                lo = x < lo ? x : lo;
                hi = x > hi ? x : hi;
            }
            boxes[f].lo[k] = lo;
            boxes[f].hi[k] = hi;
        }
#pragma omp parallel for schedule(dynamic, 64)
    for (size_t f = 0; f < nf; f++) {
        const uint32_t *v = res->tris + 3 * f;
        rs_v3 c[3] = {rs_mesh_vert(res, v[0]), rs_mesh_vert(res, v[1]), rs_mesh_vert(res, v[2])};
        rs_v3 cen = rs_v3_scale(rs_v3_add(c[0], rs_v3_add(c[1], c[2])), 1.0 / 3.0);
        rs_v3 pts[7];
        pts[0] = cen;
        for (int i = 0; i < 3; i++) {
            rs_v3 mid = rs_v3_scale(rs_v3_add(c[i], c[(i + 1) % 3]), 0.5);
            pts[1 + i] = rs_v3_add(c[i], rs_v3_scale(rs_v3_sub(cen, c[i]), 0.15));
            pts[4 + i] = rs_v3_add(mid, rs_v3_scale(rs_v3_sub(cen, mid), 0.15));
        }
        long tri[7];
        int part[7];
        for (int i = 0; i < 7; i++) {
            tri[i] = nearest_tri(truth, boxes, pts[i], tol_m);
            part[i] = tri[i] >= 0 ? truth_part[tri[i]] : -1;
        }
        out->part[f] = -1;
        if (tri[0] < 0) continue; /* the centroid is off the truth: unmatched */
        int best = -1, best_n = 0;
        for (int i = 0; i < 7; i++) {
            if (part[i] < 0) continue;
            int n = 0;
            for (int j = 0; j < 7; j++) n += part[j] == part[i];
            if (n > best_n || (n == best_n && part[i] < best)) {
                best = part[i];
                best_n = n;
            }
        }
        out->part[f] = best;
        out->interior[f] = best_n == 7;
        for (int i = 0; i < 7; i++)
            if (part[i] == best) {
                memcpy(out->truth_rgb + 3 * f, truth_rgb + 3 * tri[i], 3 * sizeof(double));
                break;
            }
    }
    free(boxes);
    return 0;
}

int rs_eval_enclosure(const rs_mesh *mesh, double *out, rs_err *err)
{
    enum { RAYS = 64 };
    rs_scene *s = rs_scene_new(mesh, err);
    if (!s) return -1;
#pragma omp parallel for schedule(dynamic, 64)
    for (size_t f = 0; f < mesh->nfaces; f++) {
        rs_v3 cen, n;
        double area;
        rs_mesh_face(mesh, f, &cen, &n, &area);
        out[f] = 0;
        if (rs_v3_len(n) == 0) continue;
        rs_ray rays[RAYS];
        rs_hit hits[RAYS];
        rs_v3 org = rs_v3_add(cen, rs_v3_scale(n, rs_scene_offset(s, cen)));
        for (int k = 0; k < RAYS; k++) {
            /* 8 x 8 strata centres: deterministic, the same for every run and thread count */
            double x = ((k % 8) + 0.5) / 8, y = ((k / 8) + 0.5) / 8;
            rays[k].org = org;
            rays[k].dir = rs_cosine_hemisphere(n, x, y);
            rays[k].tnear = 0;
            rays[k].tfar = INFINITY;
        }
        rs_scene_intersect(s, rays, hits, RAYS);
        int hit = 0;
        for (int k = 0; k < RAYS; k++) hit += hits[k].face != RS_NO_HIT;
        out[f] = (double)hit / RAYS;
    }
    rs_scene_free(s);
    return 0;
}
