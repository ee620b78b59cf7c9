/* unorganized: normals, surface reconstruction and clean-up of unorganized clouds with PCL
 * (see unorganized.h). */
#include "meshing/unorganized.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/pcl_bridge.h"

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* Median and 90th percentile of the nearest-neighbour distance, from at most 20000 points. */
static int spacing(const float *xyz, size_t n, double *med, double *p90, rs_err *err)
{
    size_t stride = n / 20000 + 1, k = (n + stride - 1) / stride;
    float *q = malloc(k * 3 * sizeof *q), *d = malloc(k * sizeof *d);
    if (!q || !d) {
        free(q);
        free(d);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    }
    for (size_t i = 0; i < k; i++) memcpy(q + 3 * i, xyz + 3 * (i * stride), 3 * sizeof *q);
    int rc = rs_pcl_nearest(xyz, n, q, k, 1, d, NULL, err);
    if (rc == 0) {
        qsort(d, k, sizeof *d, cmp_float);
        *med = d[k / 2];
        *p90 = d[(size_t)(0.9 * (double)(k - 1))];
    }
    free(q);
    free(d);
    return rc;
}

/* Poisson closes the surface far beyond the data and bulges past the edges of open surfaces.
 * A face stays where its centroid lies near the data as the nearest point p saw it: within
 * TRIM_REACH * r of p, r = max(p's distance to its own nearest neighbour, the octree cell: a
 * denser cloud than the octree resolves must not cut the surface into pieces), and within
 * TRIM_NORMAL * r of p's tangent plane (a bulge past an open edge curls away from the plane of
 * the last points; between points the surface lies on it to the noise). Measured on the
 * shuffled reference scans (docs/BENCHMARKS.md): a reach of 2.5 or less cuts step_park, whose
 * spacing varies 1 to 4 cm with range, into pieces the simplifier cannot join; a tangent
 * tolerance of 0.5 leaves two_planes_sky's bulges (p95 35 mm against 18 mm at 0.25). Returns
 * the count of faces removed, or (size_t)-1. */
#define TRIM_REACH  3.0
#define TRIM_NORMAL 0.25
static size_t trim(rs_mesh *m, const float *xyz, const float *nrm, size_t n, double cell_m, rs_err *err)
{
    size_t nf = m->nfaces ? m->nfaces : 1;
    float *cen = malloc(nf * 3 * sizeof *cen), *d = malloc(nf * sizeof *d), *gap = malloc(n * sizeof *gap);
    uint32_t *near = malloc(nf * sizeof *near);
    size_t removed = (size_t)-1;
    if (!cen || !d || !gap || !near) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    for (size_t f = 0; f < m->nfaces; f++)
        for (int j = 0; j < 3; j++)
            cen[3 * f + j] = (m->verts[3 * (size_t)m->tris[3 * f] + j] + m->verts[3 * (size_t)m->tris[3 * f + 1] + j] +
                              m->verts[3 * (size_t)m->tris[3 * f + 2] + j]) /
                3.0f;
    if (rs_pcl_nearest(xyz, n, xyz, n, 1, gap, NULL, err) != 0 ||
        rs_pcl_nearest(xyz, n, cen, m->nfaces, 0, d, near, err) != 0)
        goto out;
    size_t kept = 0;
    for (size_t f = 0; f < m->nfaces; f++) {
        if (near[f] == UINT32_MAX) continue;
        const float *p = xyz + 3 * (size_t)near[f], *np = nrm + 3 * (size_t)near[f];
        double r = gap[near[f]] > cell_m ? gap[near[f]] : cell_m, h = 0;
        for (int j = 0; j < 3; j++) h += (cen[3 * f + j] - p[j]) * np[j];
        if (d[f] <= TRIM_REACH * r && fabs(h) <= TRIM_NORMAL * r)
            memmove(m->tris + 3 * kept++, m->tris + 3 * f, 3 * sizeof *m->tris);
    }
    removed = m->nfaces - kept;
    m->nfaces = kept;
out:
    free(cen);
    free(d);
    free(gap);
    free(near);
    return removed;
}

static uint32_t root(uint32_t *parent, uint32_t v)
{
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
}

/* Trimming leaves crumbs: islands of a few faces off the data's edges. Drops every connected
 * piece (faces sharing vertices) with fewer than min_faces faces. Returns the count of faces
 * removed, or (size_t)-1. MIN_PIECE_FACES: some 5 x 5 octree cells, smaller than any part worth
 * a facet of its own at survey facet sizes. */
#define MIN_PIECE_FACES 50
static size_t drop_pieces(rs_mesh *m, size_t min_faces, rs_err *err)
{
    uint32_t *parent = malloc((m->nverts ? m->nverts : 1) * sizeof *parent);
    size_t *count = calloc(m->nverts ? m->nverts : 1, sizeof *count);
    if (!parent || !count) {
        free(parent);
        free(count);
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        return (size_t)-1;
    }
    for (size_t v = 0; v < m->nverts; v++) parent[v] = (uint32_t)v;
    for (size_t f = 0; f < m->nfaces; f++)
        for (int j = 1; j < 3; j++) {
            uint32_t a = root(parent, m->tris[3 * f]), b = root(parent, m->tris[3 * f + j]);
            if (a != b) parent[a < b ? b : a] = a < b ? a : b;
        }
    for (size_t f = 0; f < m->nfaces; f++) count[root(parent, m->tris[3 * f])]++;
    size_t kept = 0;
    for (size_t f = 0; f < m->nfaces; f++)
        if (count[root(parent, m->tris[3 * f])] >= min_faces)
            memmove(m->tris + 3 * kept++, m->tris + 3 * f, 3 * sizeof *m->tris);
    size_t removed = m->nfaces - kept;
    m->nfaces = kept;
    free(parent);
    free(count);
    return removed;
}

/* Drops unused vertices (keeping order). */
static rs_mesh *compact(const float *verts, size_t nverts, const uint32_t *tris, size_t ntris, rs_err *err)
{
    uint32_t *remap = malloc((nverts ? nverts : 1) * sizeof *remap);
    if (!remap) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        return NULL;
    }
    for (size_t v = 0; v < nverts; v++) remap[v] = UINT32_MAX;
    for (size_t k = 0; k < 3 * ntris; k++) remap[tris[k]] = 0;
    size_t nv = 0;
    for (size_t v = 0; v < nverts; v++)
        if (remap[v] == 0) remap[v] = (uint32_t)nv++;
    rs_mesh *m = rs_mesh_new(nv, ntris);
    if (m) {
        for (size_t v = 0; v < nverts; v++)
            if (remap[v] != UINT32_MAX) memcpy(m->verts + 3 * (size_t)remap[v], verts + 3 * v, 3 * sizeof(float));
        for (size_t k = 0; k < 3 * ntris; k++) m->tris[k] = remap[tris[k]];
    } else {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    }
    free(remap);
    return m;
}

rs_mesh *rs_unorg_mesh(const rs_cloud *c, const rs_unorg_opts *o, rs_unorg_stats *st, rs_err *err)
{
    memset(st, 0, sizeof *st);
    if (!c->has_viewpoint && !c->normals_up && !c->normal) {
        rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                   "an unorganized cloud needs its scanner position to orient the surface: "
                   "expected [ingest] scanner_position = X Y Z (world frame, metres)");
        return NULL;
    }
    size_t first = c->npoints - rs_cloud_unorganized(c), n = 0;
    for (size_t i = first; i < c->npoints; i++) n += c->valid[i] != 0;
    if (n < 3 || n >= UINT32_MAX) {
        rs_err_set(err, RS_ERR_INPUT, NULL, 0, "%zu unorganized points; expected 3 to %u", n, UINT32_MAX - 1);
        return NULL;
    }
    st->points = n;
    float *xyz = malloc(n * 3 * sizeof *xyz), *vp = malloc(n * 3 * sizeof *vp), *nrm = malloc(n * 3 * sizeof *nrm);
    float *pv = NULL;
    uint32_t *tris = NULL;
    rs_mesh *m = NULL;
    if (!xyz || !vp || !nrm) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu points", n);
        goto out;
    }
    size_t k = 0;
    for (size_t i = first; i < c->npoints; i++) {
        if (!c->valid[i]) continue;
        for (int j = 0; j < 3; j++) {
            xyz[3 * k + j] = (float)c->xyz[3 * i + j];
            /* No viewpoint: one straight above each point, so that its normal points up. */
            vp[3 * k + j] = c->has_viewpoint ? (float)c->viewpoint[j] : xyz[3 * k + j] + (j == 2);
        }
        k++;
    }
    if (spacing(xyz, n, &st->spacing_median_m, &st->spacing_p90_m, err) != 0) goto out;
    if (c->normal) { /* the file's own (E57 nor:, PLY nx ny nz), oriented as given */
        k = 0;
        for (size_t i = first; i < c->npoints; i++)
            if (c->valid[i]) memcpy(nrm + 3 * k++, c->normal + 3 * i, 3 * sizeof *nrm);
        st->normals_given = 1;
    } else if (rs_pcl_normals(xyz, n, o->normal_neighbours, vp, o->threads, nrm, err) != 0) {
        goto out;
    }
    for (size_t i = 0; i < n; i++)
        st->points_no_normal += nrm[3 * i] == 0 && nrm[3 * i + 1] == 0 && nrm[3 * i + 2] == 0;

    size_t ntris = 0;
    if (!o->poisson) {
        st->max_edge_m = o->max_edge_m > 0 ? o->max_edge_m : 8 * st->spacing_p90_m;
        if (rs_pcl_greedy(xyz, nrm, n, st->max_edge_m, 2.5, 100, &tris, &ntris, err) != 0) goto out;
        st->faces_raw = ntris;
        m = compact(xyz, n, tris, ntris, err);
    } else {
        size_t nv;
        if (rs_pcl_poisson(xyz, nrm, n, o->poisson_depth, &pv, &nv, &tris, &ntris, err) != 0) goto out;
        st->faces_raw = ntris;
        rs_mesh tmp = {nv, ntris, pv, tris};
        float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (size_t i = 0; i < n; i++)
            for (int j = 0; j < 3; j++) {
                lo[j] = fminf(lo[j], xyz[3 * i + j]);
                hi[j] = fmaxf(hi[j], xyz[3 * i + j]);
            }
        /* PCL's octree spans 1.1 times the largest side of the bounding box. */
        double side = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
        st->cell_m = 1.1 * side / ldexp(1.0, o->poisson_depth);
        size_t removed = trim(&tmp, xyz, nrm, n, st->cell_m, err);
        if (removed == (size_t)-1) goto out;
        st->faces_trimmed = removed;
        removed = drop_pieces(&tmp, MIN_PIECE_FACES, err);
        if (removed == (size_t)-1) goto out;
        st->faces_pieces = removed;
        /* Poisson winds with its own convention: turn every face toward the scanner's side. */
        for (size_t f = 0; f < tmp.nfaces; f++) {
            rs_v3 cen, nf;
            rs_mesh_face(&tmp, f, &cen, &nf, NULL);
            rs_v3 to = c->has_viewpoint ? rs_v3_sub(rs_v3_make(c->viewpoint[0], c->viewpoint[1], c->viewpoint[2]), cen)
                                        : rs_v3_make(0, 0, 1);
            if (rs_v3_dot(nf, to) < 0) {
                uint32_t t = tmp.tris[3 * f + 1];
                tmp.tris[3 * f + 1] = tmp.tris[3 * f + 2];
                tmp.tris[3 * f + 2] = t;
            }
        }
        m = compact(pv, nv, tris, tmp.nfaces, err);
    }
    if (m && m->nfaces == 0) {
        rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                   "surface reconstruction of %zu points gave no triangle (median spacing "
                   "%.3g m); expected a scan of surfaces",
                   n, st->spacing_median_m);
        rs_mesh_free(m);
        m = NULL;
    }
out:
    free(xyz);
    free(vp);
    free(nrm);
    free(pv);
    free(tris);
    return m;
}
