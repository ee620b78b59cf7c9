/* meshreport: facet count, edge-length statistics, boundary loops, non-manifold edges and
 * scan-point distances of a mesh (see meshreport.h). */
#include "meshing/meshreport.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "meshing/meshdist.h"

typedef struct edge_key {
    uint32_t a, b; /* a < b */
} edge_key;

static int cmp_edge(const void *x, const void *y)
{
    const edge_key *p = x, *q = y;
    if (p->a != q->a) return p->a < q->a ? -1 : 1;
    return (p->b > q->b) - (p->b < q->b);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static uint32_t find(uint32_t *parent, uint32_t v)
{
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
}

int rs_mesh_edge_census(const rs_mesh *m, size_t *edges, size_t *boundary, size_t *nonmanifold, size_t *loops)
{
    size_t n = 3 * m->nfaces;
    edge_key *e = malloc((n ? n : 1) * sizeof *e);
    uint32_t *parent = malloc((m->nverts ? m->nverts : 1) * sizeof *parent);
    uint8_t *on_border = calloc(m->nverts ? m->nverts : 1, 1);
    if (!e || !parent || !on_border) {
        free(e);
        free(parent);
        free(on_border);
        return -1;
    }
    for (size_t f = 0; f < m->nfaces; f++)
        for (int j = 0; j < 3; j++) {
            uint32_t a = m->tris[3 * f + j], b = m->tris[3 * f + (j + 1) % 3];
            e[3 * f + j].a = a < b ? a : b;
            e[3 * f + j].b = a < b ? b : a;
        }
    qsort(e, n, sizeof *e, cmp_edge);
    for (size_t v = 0; v < m->nverts; v++) parent[v] = (uint32_t)v;
    *edges = *boundary = *nonmanifold = 0;
    /* Boundary loops: the components of the graph of boundary edges. */
    for (size_t i = 0; i < n;) {
        size_t j = i;
        while (j < n && e[j].a == e[i].a && e[j].b == e[i].b) j++;
        (*edges)++;
        if (j - i == 1) {
            (*boundary)++;
            on_border[e[i].a] = on_border[e[i].b] = 1;
            uint32_t ra = find(parent, e[i].a), rb = find(parent, e[i].b);
            if (ra != rb) parent[ra] = rb;
        } else if (j - i > 2) {
            (*nonmanifold)++;
        }
        i = j;
    }
    *loops = 0;
    for (size_t v = 0; v < m->nverts; v++) *loops += on_border[v] && find(parent, (uint32_t)v) == v;
    free(e);
    free(parent);
    free(on_border);
    return 0;
}

int rs_mesh_quality_measure(const rs_mesh *m, const double *pts, size_t npts, size_t max_points, double max_dist_m,
                            rs_mesh_quality *q, rs_err *err)
{
    memset(q, 0, sizeof *q);
    q->faces = m->nfaces;
    q->verts = m->nverts;
    size_t n;
    double *len = rs_mesh_edge_lengths(m, &n);
    if (n) {
        double sum = 0;
        for (size_t i = 0; i < n; i++) sum += len[i];
        qsort(len, n, sizeof *len, cmp_double);
        q->edge_mean_m = sum / (double)n;
        q->edge_median_m = len[n / 2];
        q->edge_p5_m = len[(size_t)(0.05 * (double)(n - 1))];
        q->edge_p95_m = len[(size_t)(0.95 * (double)(n - 1))];
        q->edge_min_m = len[0];
        q->edge_max_m = len[n - 1];
    }
    free(len);
    if (rs_mesh_edge_census(m, &q->edges, &q->boundary_edges, &q->nonmanifold_edges, &q->boundary_loops) != 0)
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory measuring %zu faces", m->nfaces);
    if (!pts || npts == 0 || max_points == 0 || m->nfaces == 0) return 0;

    rs_meshdist *md = rs_meshdist_new(m, err);
    if (!md) return -1;
    size_t stride = npts > max_points ? (npts + max_points - 1) / max_points : 1, k = (npts + stride - 1) / stride;
    double *d = malloc(k * sizeof *d);
    if (!d) {
        rs_meshdist_free(md);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    }
#pragma omp parallel for schedule(dynamic, 1024)
    for (size_t i = 0; i < k; i++) {
        double v = rs_meshdist_query(md, pts + 3 * (i * stride), max_dist_m, NULL);
        d[i] = isfinite(v) ? v : max_dist_m;
    }
    double sum = 0;
    size_t near = 0;
    for (size_t i = 0; i < k; i++) {
        sum += d[i];
        near += d[i] <= 0.02;
    }
    qsort(d, k, sizeof *d, cmp_double);
    q->points_tested = k;
    q->dist_mean_m = sum / (double)k;
    q->dist_p95_m = d[(size_t)(0.95 * (double)(k - 1))];
    q->within_2cm = (double)near / (double)k;
    free(d);
    rs_meshdist_free(md);
    return 0;
}

void rs_mesh_quality_json(const rs_mesh_quality *q, rs_json *obj)
{
    rs_json_set_int(obj, "faces", (long long)q->faces);
    rs_json_set_int(obj, "vertices", (long long)q->verts);
    rs_json_set_int(obj, "edges", (long long)q->edges);
    rs_json_set_num(obj, "edge_mean_m", q->edge_mean_m);
    rs_json_set_num(obj, "edge_median_m", q->edge_median_m);
    rs_json_set_num(obj, "edge_p5_m", q->edge_p5_m);
    rs_json_set_num(obj, "edge_p95_m", q->edge_p95_m);
    rs_json_set_num(obj, "edge_min_m", q->edge_min_m);
    rs_json_set_num(obj, "edge_max_m", q->edge_max_m);
    rs_json_set_int(obj, "boundary_edges", (long long)q->boundary_edges);
    rs_json_set_int(obj, "boundary_loops", (long long)q->boundary_loops);
    rs_json_set_int(obj, "nonmanifold_edges", (long long)q->nonmanifold_edges);
    rs_json_set_int(obj, "points_tested", (long long)q->points_tested);
    if (q->points_tested) {
        rs_json_set_num(obj, "point_dist_mean_m", q->dist_mean_m);
        rs_json_set_num(obj, "point_dist_p95_m", q->dist_p95_m);
        rs_json_set_num(obj, "points_within_2cm", q->within_2cm);
    }
}
