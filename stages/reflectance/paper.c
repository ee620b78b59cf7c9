/* paper: dense kernel with brute-force pairwise visibility (see paper.h). */
#include "stages/reflectance/paper.h"

#include <stdlib.h>
#include "common/log.h"

/* Möller-Trumbore: 1 when the open segment o + t d, t in (eps, 1 - eps), crosses the triangle. */
static int segment_hits(rs_v3 o, rs_v3 d, rs_v3 a, rs_v3 b, rs_v3 c)
{
    const double eps = 1e-6;
    rs_v3 e1 = rs_v3_sub(b, a), e2 = rs_v3_sub(c, a);
    rs_v3 p = rs_v3_cross(d, e2);
    double det = rs_v3_dot(e1, p);
    if (fabs(det) < 1e-18) return 0;
    double inv = 1.0 / det;
    rs_v3 s = rs_v3_sub(o, a);
    double u = rs_v3_dot(s, p) * inv;
    if (u < 0 || u > 1) return 0;
    rs_v3 q = rs_v3_cross(s, e1);
    double v = rs_v3_dot(d, q) * inv;
    if (v < 0 || u + v > 1) return 0;
    double t = rs_v3_dot(e2, q) * inv;
    return t > eps && t < 1 - eps;
}

int rs_paper_kernel(const rs_mesh *mesh, float **K_out, double *pairs_tested, rs_err *err)
{
    size_t m = mesh->nfaces;
    float *K = calloc(m * m, sizeof *K);
    rs_v3 *cen = malloc(m * sizeof *cen), *nrm = malloc(m * sizeof *nrm);
    double *area = malloc(m * sizeof *area);
    if (!K || !cen || !nrm || !area) {
        free(K);
        free(cen);
        free(nrm);
        free(area);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for a dense %zu x %zu kernel", m, m);
    }
    for (size_t f = 0; f < m; f++) rs_mesh_face(mesh, f, &cen[f], &nrm[f], &area[f]);
    double tested = 0;
    rs_progress *prog = rs_progress_start("reflectance: paper kernel (pairwise visibility)", m);
#pragma omp parallel for schedule(dynamic, 4) reduction(+ : tested)
    for (size_t i = 0; i < m; i++) {
        for (size_t j = i + 1; j < m; j++) {
            rs_v3 r = rs_v3_sub(cen[j], cen[i]);
            double d2 = rs_v3_dot(r, r);
            if (!(d2 > 0)) continue;
            double cos_i = rs_v3_dot(nrm[i], r) / sqrt(d2), cos_j = -rs_v3_dot(nrm[j], r) / sqrt(d2);
            if (cos_i <= 0 || cos_j <= 0) continue;
            int visible = 1;
            for (size_t k = 0; k < m && visible; k++) {
                if (k == i || k == j) continue;
                const uint32_t *t = mesh->tris + 3 * k;
                if (segment_hits(cen[i], r, rs_mesh_vert(mesh, t[0]), rs_mesh_vert(mesh, t[1]),
                                 rs_mesh_vert(mesh, t[2])))
                    visible = 0;
            }
            tested += 1;
            if (!visible) continue;
            double g = cos_i * cos_j / d2; /* symmetric part; times the emitter's area */
            K[i * m + j] = (float)(g * area[j]);
            K[j * m + i] = (float)(g * area[i]);
        }
        rs_progress_add(prog, 1);
    }
    rs_progress_end(prog);
    free(cen);
    free(nrm);
    free(area);
    *K_out = K;
    *pairs_tested = tested;
    return 0;
}
