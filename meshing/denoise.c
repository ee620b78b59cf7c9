/* denoise: bilateral normal filtering (Zheng, Fu, Au, Tai 2011, "Bilateral Normal Filtering for
 * Mesh Denoising") and Sun et al. 2007's vertex update; exports rs_denoise_apply (denoise.h). */
#include "meshing/denoise.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

void rs_denoise_defaults(rs_denoise_opts *o)
{
    o->normal_iterations = 3;
    o->vertex_iterations = 10;
    o->sigma_r_deg = 10;
    o->sigma_s_edges = 1;
    o->max_move_m = 0.005;
}

/* Compressed rows: row i is idx[start[i] .. start[i + 1]). */
typedef struct csr {
    size_t *start;
    uint32_t *idx;
} csr;

static void csr_free(csr *c)
{
    free(c->start);
    free(c->idx);
}

/* The faces around each vertex. */
static int vertex_faces(const rs_mesh *m, csr *vf)
{
    vf->start = calloc(m->nverts + 1, sizeof *vf->start);
    vf->idx = malloc((m->nfaces ? 3 * m->nfaces : 1) * sizeof *vf->idx);
    if (!vf->start || !vf->idx) return -1;
    for (size_t k = 0; k < 3 * m->nfaces; k++) vf->start[m->tris[k] + 1]++;
    for (size_t v = 0; v < m->nverts; v++) vf->start[v + 1] += vf->start[v];
    size_t *fill = malloc((m->nverts ? m->nverts : 1) * sizeof *fill);
    if (!fill) return -1;
    memcpy(fill, vf->start, m->nverts * sizeof *fill);
    for (size_t f = 0; f < m->nfaces; f++)
        for (int j = 0; j < 3; j++) vf->idx[fill[m->tris[3 * f + j]]++] = (uint32_t)f;
    free(fill);
    return 0;
}

/* The faces sharing a vertex with each face (itself included): the filter's neighbourhood. */
static int face_neighbours(const rs_mesh *m, const csr *vf, csr *ff)
{
    size_t cap = 16 * m->nfaces + 16, n = 0;
    uint32_t *stamp = malloc((m->nfaces ? m->nfaces : 1) * sizeof *stamp);
    ff->start = malloc((m->nfaces + 1) * sizeof *ff->start);
    ff->idx = malloc(cap * sizeof *ff->idx);
    if (!stamp || !ff->start || !ff->idx) {
        free(stamp);
        return -1;
    }
    for (size_t f = 0; f < m->nfaces; f++) stamp[f] = UINT32_MAX;
    for (size_t f = 0; f < m->nfaces; f++) {
        ff->start[f] = n;
        for (int j = 0; j < 3; j++) {
            uint32_t v = m->tris[3 * f + j];
            for (size_t k = vf->start[v]; k < vf->start[v + 1]; k++) {
                uint32_t g = vf->idx[k];
                if (stamp[g] == (uint32_t)f) continue;
                stamp[g] = (uint32_t)f;
                if (n == cap) {
                    uint32_t *grown = realloc(ff->idx, 2 * cap * sizeof *grown);
                    if (!grown) {
                        free(stamp);
                        return -1;
                    }
                    ff->idx = grown;
                    cap *= 2;
                }
                ff->idx[n++] = g;
            }
        }
    }
    ff->start[m->nfaces] = n;
    free(stamp);
    return 0;
}

/* Centroid, unit normal (zero when degenerate) and area of face f at positions x. */
static void face_geom(const rs_mesh *m, const double *x, size_t f, rs_v3 *c, rs_v3 *n, double *area)
{
    const uint32_t *t = m->tris + 3 * f;
    rs_v3 a = rs_v3_make(x[3 * t[0]], x[3 * t[0] + 1], x[3 * t[0] + 2]);
    rs_v3 b = rs_v3_make(x[3 * t[1]], x[3 * t[1] + 1], x[3 * t[1] + 2]);
    rs_v3 d = rs_v3_make(x[3 * t[2]], x[3 * t[2] + 1], x[3 * t[2] + 2]);
    rs_v3 cr = rs_v3_cross(rs_v3_sub(b, a), rs_v3_sub(d, a));
    double len = rs_v3_len(cr);
    if (c) *c = rs_v3_scale(rs_v3_add(rs_v3_add(a, b), d), 1.0 / 3.0);
    if (n) *n = len > 0 ? rs_v3_scale(cr, 1 / len) : rs_v3_make(0, 0, 0);
    if (area) *area = 0.5 * len;
}

static int check_opts(const rs_denoise_opts *o, rs_err *err)
{
    if (o->normal_iterations < 1 || o->normal_iterations > 1000)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "[mesh] denoise_iterations = %d; expected 1 to 1000",
                          o->normal_iterations);
    if (o->vertex_iterations < 1 || o->vertex_iterations > 1000)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "[mesh] denoise_vertex_iterations = %d; expected 1 to 1000",
                          o->vertex_iterations);
    if (!(o->sigma_r_deg > 0 && o->sigma_r_deg <= 90))
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                          "[mesh] denoise_sigma_r_deg = %g; expected more than 0 and at "
                          "most 90 degrees",
                          o->sigma_r_deg);
    if (!(o->sigma_s_edges > 0 && o->sigma_s_edges <= 100))
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                          "[mesh] denoise_sigma_s = %g; expected more than 0 and at most "
                          "100 mean edge lengths",
                          o->sigma_s_edges);
    if (!(o->max_move_m > 0 && isfinite(o->max_move_m)))
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "[mesh] denoise_max_move = %g; expected a distance above 0 m",
                          o->max_move_m);
    return 0;
}

/* Bilateral filter of the face normals n (in place), iterated: each pass weighs a neighbour by
 * its area, a Gaussian of the centroids' distance and a Gaussian of the normals' difference
 * |n_i - n_j| = 2 sin(angle / 2), so that across a crease well above sigma_r nothing mixes. */
static int filter_normals(const rs_mesh *m, const csr *ff, const rs_v3 *cen, const double *area, rs_v3 *n,
                          const rs_denoise_opts *o, double sigma_s)
{
    rs_v3 *next = malloc((m->nfaces ? m->nfaces : 1) * sizeof *next);
    if (!next) return -1;
    double sr = 2 * sin(0.5 * o->sigma_r_deg * M_PI / 180), ks = -0.5 / (sigma_s * sigma_s), kr = -0.5 / (sr * sr);
    for (int it = 0; it < o->normal_iterations; it++) {
        for (size_t f = 0; f < m->nfaces; f++) {
            rs_v3 sum = rs_v3_make(0, 0, 0);
            for (size_t k = ff->start[f]; k < ff->start[f + 1]; k++) {
                uint32_t g = ff->idx[k];
                rs_v3 dc = rs_v3_sub(cen[f], cen[g]), dn = rs_v3_sub(n[f], n[g]);
                double w = area[g] * exp(ks * rs_v3_dot(dc, dc) + kr * rs_v3_dot(dn, dn));
                sum = rs_v3_add(sum, rs_v3_scale(n[g], w));
            }
            double len = rs_v3_len(sum);
            next[f] = len > 0 ? rs_v3_scale(sum, 1 / len) : n[f];
        }
        memcpy(n, next, m->nfaces * sizeof *n);
    }
    free(next);
    return 0;
}

int rs_denoise_apply(rs_mesh *m, const rs_denoise_opts *o, rs_denoise_stats *st, rs_err *err)
{
    memset(st, 0, sizeof *st);
    if (check_opts(o, err) != 0) return -1;
    if (m->nfaces == 0) return 0;
    csr vf = {0}, ff = {0};
    double *x = malloc(3 * m->nverts * sizeof *x), *x0 = malloc(3 * m->nverts * sizeof *x0);
    double *area = malloc(m->nfaces * sizeof *area);
    rs_v3 *cen = malloc(m->nfaces * sizeof *cen), *n = malloc(m->nfaces * sizeof *n);
    rs_v3 *acc = malloc(m->nverts * sizeof *acc);
    int rc = -1;
    if (!x || !x0 || !area || !cen || !n || !acc || vertex_faces(m, &vf) != 0 || face_neighbours(m, &vf, &ff) != 0) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory denoising %zu faces", m->nfaces);
        goto out;
    }
    for (size_t k = 0; k < 3 * m->nverts; k++) x[k] = x0[k] = m->verts[k];

    /* sigma_s in mean edge lengths (each face's three edges; inner edges count twice, which
     * does not move the mean much). */
    double esum = 0;
    for (size_t f = 0; f < m->nfaces; f++) {
        face_geom(m, x, f, &cen[f], &n[f], &area[f]);
        for (int j = 0; j < 3; j++) {
            const float *a = m->verts + 3 * (size_t)m->tris[3 * f + j];
            const float *b = m->verts + 3 * (size_t)m->tris[3 * f + (j + 1) % 3];
            esum += sqrt((double)(a[0] - b[0]) * (a[0] - b[0]) + (double)(a[1] - b[1]) * (a[1] - b[1]) +
                         (double)(a[2] - b[2]) * (a[2] - b[2]));
        }
    }
    double sigma_s = o->sigma_s_edges * esum / (3.0 * (double)m->nfaces);
    st->sigma_s_m = sigma_s;
    if (!(sigma_s > 0)) {
        rc = 0;
        goto out;
    }
    if (filter_normals(m, &ff, cen, area, n, o, sigma_s) != 0) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory denoising %zu faces", m->nfaces);
        goto out;
    }

    /* Sun et al. 2007: each vertex moves by the mean over its faces of the offset along the
     * filtered normal to the face's plane through its current centroid, so the faces turn
     * toward the filtered normals; the step is held within max_move of the start. */
    for (int it = 0; it < o->vertex_iterations; it++) {
        if (it > 0)
            for (size_t f = 0; f < m->nfaces; f++) face_geom(m, x, f, &cen[f], NULL, NULL);
        for (size_t v = 0; v < m->nverts; v++) acc[v] = rs_v3_make(0, 0, 0);
        for (size_t f = 0; f < m->nfaces; f++) {
            if (rs_v3_dot(n[f], n[f]) == 0) continue;
            for (int j = 0; j < 3; j++) {
                uint32_t v = m->tris[3 * f + j];
                rs_v3 p = rs_v3_make(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
                acc[v] = rs_v3_add(acc[v], rs_v3_scale(n[f], rs_v3_dot(n[f], rs_v3_sub(cen[f], p))));
            }
        }
        for (size_t v = 0; v < m->nverts; v++) {
            size_t deg = vf.start[v + 1] - vf.start[v];
            if (!deg) continue;
            double d[3] = {x[3 * v] + acc[v].x / (double)deg - x0[3 * v],
                           x[3 * v + 1] + acc[v].y / (double)deg - x0[3 * v + 1],
                           x[3 * v + 2] + acc[v].z / (double)deg - x0[3 * v + 2]};
            double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            double s = len > o->max_move_m ? o->max_move_m / len : 1;
            for (int j = 0; j < 3; j++) x[3 * v + j] = x0[3 * v + j] + s * d[j];
        }
    }

    double sum2 = 0;
    for (size_t v = 0; v < m->nverts; v++) {
        for (int j = 0; j < 3; j++) m->verts[3 * v + j] = (float)x[3 * v + j];
        double d2 = 0;
        for (int j = 0; j < 3; j++) {
            double dj = (double)m->verts[3 * v + j] - x0[3 * v + j];
            d2 += dj * dj;
        }
        sum2 += d2;
        st->moved += d2 > 0;
        st->clamped += sqrt(d2) >= o->max_move_m * (1 - 1e-6);
        if (sqrt(d2) > st->max_move_m) st->max_move_m = sqrt(d2);
    }
    st->rms_move_m = m->nverts ? sqrt(sum2 / (double)m->nverts) : 0;
    rc = 0;
out:
    csr_free(&vf);
    csr_free(&ff);
    free(x);
    free(x0);
    free(area);
    free(cen);
    free(n);
    free(acc);
    return rc;
}
