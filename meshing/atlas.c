/* atlas: charts by region growing over shared edges, orthographic projection, shelf packing
 * into power-of-two pages (atlas.h). Deterministic: charts grow from the lowest unassigned face
 * in breadth-first order over the sorted edge list. */
#include "meshing/atlas.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    uint64_t key; /* min vertex << 32 | max vertex */
    uint32_t face;
} atlas_edge;

static int edge_cmp(const void *a, const void *b)
{
    const atlas_edge *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return x->face < y->face ? -1 : (x->face > y->face);
}

/* Neighbours across shared edges in CSR form: adj[start[f] .. start[f + 1]). */
typedef struct {
    uint32_t *start, *adj;
} atlas_adjacency;

static int build_adjacency(const rs_mesh *m, atlas_adjacency *A)
{
    size_t nf = m->nfaces, ne = 3 * nf;
    atlas_edge *e = malloc(ne * sizeof *e);
    A->start = calloc(nf + 1, sizeof *A->start);
    if (!e || !A->start) {
        free(e);
        return -1;
    }
    for (size_t f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++) {
            uint64_t a = m->tris[3 * f + k], b = m->tris[3 * f + (k + 1) % 3];
            e[3 * f + k].key = a < b ? (a << 32 | b) : (b << 32 | a);
            e[3 * f + k].face = (uint32_t)f;
        }
    qsort(e, ne, sizeof *e, edge_cmp);
    /* Count pairs within runs of equal keys, then fill. */
    for (int pass = 0; pass < 2; pass++) {
        uint32_t *fill = NULL;
        if (pass == 1) {
            for (size_t f = 0; f < nf; f++) A->start[f + 1] += A->start[f];
            A->adj = malloc(((size_t)A->start[nf] + 1) * sizeof *A->adj);
            fill = malloc((nf + 1) * sizeof *fill);
            if (!A->adj || !fill) {
                free(fill);
                free(e);
                return -1;
            }
            memcpy(fill, A->start, nf * sizeof *fill);
        }
        for (size_t i = 0; i < ne;) {
            size_t j = i;
            while (j < ne && e[j].key == e[i].key) j++;
            for (size_t p = i; p < j; p++)
                for (size_t q = i; q < j; q++)
                    if (p != q && e[p].face != e[q].face) {
                        if (pass == 0)
                            A->start[e[p].face + 1]++;
                        else
                            A->adj[fill[e[p].face]++] = e[q].face;
                    }
            i = j;
        }
        free(fill);
    }
    free(e);
    return 0;
}

/* The chart's frame from its normal: eu horizontal for walls, along +x for floors and roofs. */
static void chart_frame(rs_atlas_chart *c, rs_v3 n)
{
    c->normal = n;
    rs_v3 up = rs_v3_make(0, 0, 1);
    if (fabs(n.z) < 0.9)
        c->eu = rs_v3_norm(rs_v3_cross(up, n));
    else
        c->eu = rs_v3_norm(rs_v3_cross(n, rs_v3_make(0, 1, 0)));
    c->ev = rs_v3_cross(n, c->eu);
}

/* Grows the charts: face_chart and faces filled, charts allocated with frame and face range. */
static int grow_charts(const rs_mesh *m, double cos_max, rs_atlas *a)
{
    size_t nf = m->nfaces;
    atlas_adjacency A = {0};
    if (build_adjacency(m, &A) != 0) return -1;
    a->charts = malloc(nf * sizeof *a->charts);
    if (!a->charts) {
        free(A.start);
        free(A.adj);
        return -1;
    }
    for (size_t f = 0; f < nf; f++) a->face_chart[f] = UINT32_MAX;
    size_t nq = 0;
    for (size_t seed = 0; seed < nf; seed++) {
        if (a->face_chart[seed] != UINT32_MAX) continue;
        rs_v3 c0, n0;
        double area;
        rs_mesh_face(m, seed, &c0, &n0, &area);
        int degenerate = rs_v3_len(n0) < 0.5;
        rs_atlas_chart *c = &a->charts[a->ncharts];
        memset(c, 0, sizeof *c);
        chart_frame(c, degenerate ? rs_v3_make(0, 0, 1) : n0);
        c->origin = rs_mesh_vert(m, m->tris[3 * seed]);
        c->first = nq;
        uint32_t id = (uint32_t)a->ncharts++;
        a->face_chart[seed] = id;
        a->faces[nq++] = (uint32_t)seed;
        for (size_t q = c->first; q < nq && !degenerate; q++) {
            uint32_t f = a->faces[q];
            for (uint32_t k = A.start[f]; k < A.start[f + 1]; k++) {
                uint32_t g = A.adj[k];
                if (a->face_chart[g] != UINT32_MAX) continue;
                rs_v3 cg, ng;
                rs_mesh_face(m, g, &cg, &ng, &area);
                if (rs_v3_len(ng) > 0.5 && rs_v3_dot(ng, n0) < cos_max) continue;
                a->face_chart[g] = id;
                a->faces[nq++] = g;
            }
        }
        c->count = nq - c->first;
    }
    free(A.start);
    free(A.adj);
    return 0;
}

static void chart_st(const rs_atlas_chart *c, rs_v3 p, double *s, double *t)
{
    rs_v3 d = rs_v3_sub(p, c->origin);
    *s = rs_v3_dot(d, c->eu);
    *t = rs_v3_dot(d, c->ev);
}

/* Turns the chart's (eu, ev) about its normal to the angle, in 3-degree steps over a quarter
 * turn, whose bounding rectangle of the corners is smallest: an oblique wall or a rotated yard
 * then packs without the empty triangles of an axis-aligned box. */
static void chart_orient(const rs_mesh *m, const rs_atlas *a, rs_atlas_chart *c)
{
    double best = INFINITY, best_ang = 0;
    for (int step = 0; step < 30; step++) {
        double ang = step * (M_PI / 60), ca = cos(ang), sa = sin(ang);
        rs_v3 eu = rs_v3_add(rs_v3_scale(c->eu, ca), rs_v3_scale(c->ev, sa));
        rs_v3 ev = rs_v3_cross(c->normal, eu);
        double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
        for (size_t q = c->first; q < c->first + c->count; q++)
            for (int k = 0; k < 3; k++) {
                rs_v3 d = rs_v3_sub(rs_mesh_vert(m, m->tris[3 * (size_t)a->faces[q] + k]), c->origin);
                double s = rs_v3_dot(d, eu), t = rs_v3_dot(d, ev);
                lo[0] = fmin(lo[0], s);
                hi[0] = fmax(hi[0], s);
                lo[1] = fmin(lo[1], t);
                hi[1] = fmax(hi[1], t);
            }
        double area = (hi[0] - lo[0]) * (hi[1] - lo[1]);
        if (area < best * (1 - 1e-9)) {
            best = area;
            best_ang = ang;
        }
    }
    double ca = cos(best_ang), sa = sin(best_ang);
    c->eu = rs_v3_norm(rs_v3_add(rs_v3_scale(c->eu, ca), rs_v3_scale(c->ev, sa)));
    c->ev = rs_v3_cross(c->normal, c->eu);
}

/* Extent of each chart in metres (s range, t range) into ext[4 * ncharts]: smin smax tmin tmax. */
static void chart_extents(const rs_mesh *m, rs_atlas *a, double *ext)
{
    for (size_t ci = 0; ci < a->ncharts; ci++) {
        rs_atlas_chart *c = &a->charts[ci];
        if (c->count > 1) chart_orient(m, a, c);
        double *x = ext + 4 * ci;
        x[0] = x[2] = INFINITY;
        x[1] = x[3] = -INFINITY;
        for (size_t q = c->first; q < c->first + c->count; q++)
            for (int k = 0; k < 3; k++) {
                double s, t;
                chart_st(c, rs_mesh_vert(m, m->tris[3 * (size_t)a->faces[q] + k]), &s, &t);
                x[0] = fmin(x[0], s);
                x[1] = fmax(x[1], s);
                x[2] = fmin(x[2], t);
                x[3] = fmax(x[3], t);
            }
    }
}

static const double *g_rect_h; /* for the sort: each chart's packed height */

static int rect_cmp(const void *pa, const void *pb)
{
    uint32_t a = *(const uint32_t *)pa, b = *(const uint32_t *)pb;
    if (g_rect_h[a] != g_rect_h[b]) return g_rect_h[a] > g_rect_h[b] ? -1 : 1;
    return a < b ? -1 : (a > b);
}

/* Shelf packing of the charts at texel size tx into pages of side `side`: sets each chart's
 * w, h, page, x0, y0 and returns the number of pages (0 when a chart does not fit a page). */
static int pack(rs_atlas *a, const double *ext, double tx, int side, uint32_t *order, double *rh)
{
    int g = a->gutter;
    for (size_t ci = 0; ci < a->ncharts; ci++) {
        rs_atlas_chart *c = &a->charts[ci];
        c->w = (int)ceil((ext[4 * ci + 1] - ext[4 * ci]) / tx) + 1;
        c->h = (int)ceil((ext[4 * ci + 3] - ext[4 * ci + 2]) / tx) + 1;
        if (c->w + 2 * g > side || c->h + 2 * g > side) return 0;
        rh[ci] = c->h;
        order[ci] = (uint32_t)ci;
    }
    g_rect_h = rh;
    qsort(order, a->ncharts, sizeof *order, rect_cmp);
    int page = 0, x = 0, y = 0, shelf = 0;
    for (size_t k = 0; k < a->ncharts; k++) {
        rs_atlas_chart *c = &a->charts[order[k]];
        int W = c->w + 2 * g, H = c->h + 2 * g;
        if (x + W > side) { /* next shelf */
            x = 0;
            y += shelf;
            shelf = 0;
        }
        if (y + H > side) { /* next page */
            page++;
            x = y = shelf = 0;
        }
        c->page = page;
        c->x0 = x + g;
        c->y0 = y + g;
        x += W;
        if (H > shelf) shelf = H;
    }
    return page + 1;
}

static int next_pow2(double v)
{
    int s = 1;
    while (s < v && s < (1 << 30)) s <<= 1;
    return s;
}

/* The charts' rectangles with their gutters at texel size tx, texels. */
static double rect_need(const rs_atlas *a, const double *ext, double tx)
{
    double need = 0;
    int g = a->gutter;
    for (size_t ci = 0; ci < a->ncharts; ci++)
        need += (ceil((ext[4 * ci + 1] - ext[4 * ci]) / tx) + 1 + 2 * g) *
            (ceil((ext[4 * ci + 3] - ext[4 * ci + 2]) / tx) + 1 + 2 * g);
    return need;
}

/* Texel size, page side and the packing: the smallest page that holds everything on one page,
 * or max_side pages; the texel raised until the largest chart fits and the pages' texels stay
 * within max_texels. */
static int layout(rs_atlas *a, const rs_atlas_opts *o, const double *ext, int max_side, rs_err *err)
{
    uint32_t *order = malloc((a->ncharts + 1) * sizeof *order);
    double *rh = malloc((a->ncharts + 1) * sizeof *rh);
    if (!order || !rh) {
        free(order);
        free(rh);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    }
    double tx = o->texel, maxdim = 0;
    int g = a->gutter;
    for (size_t ci = 0; ci < a->ncharts; ci++)
        maxdim = fmax(maxdim, fmax(ext[4 * ci + 1] - ext[4 * ci], ext[4 * ci + 3] - ext[4 * ci + 2]));
    if (maxdim / tx + 2 + 2 * g > max_side) tx = maxdim / (max_side - 3 - 2 * g);
    int rc = -1;
    for (int iter = 0; iter < 64; iter++) {
        double need = 0;
        for (size_t ci = 0; ci < a->ncharts; ci++)
            need += (ceil((ext[4 * ci + 1] - ext[4 * ci]) / tx) + 1 + 2 * g) *
                (ceil((ext[4 * ci + 3] - ext[4 * ci + 2]) / tx) + 1 + 2 * g);
        int side = next_pow2(sqrt(need * 1.1));
        if (side > max_side) side = max_side;
        int np = 0;
        while (!(np = pack(a, ext, tx, side, order, rh)) || (np > 1 && side < max_side)) {
            if (side >= max_side) break;
            side *= 2;
        }
        if (np == 1 && side > 64) { /* a texel up to 25 % larger for a page of a quarter the texels */
            for (int k = 1; k <= 5; k++)
                if (pack(a, ext, tx * (1 + 0.05 * k), side / 2, order, rh) == 1) {
                    tx *= 1 + 0.05 * k;
                    side /= 2;
                    break;
                }
            np = pack(a, ext, tx, side, order, rh);
            need = rect_need(a, ext, tx);
        }
        double total = (double)np * side * side;
        if (np && (o->max_texels <= 0 || total <= o->max_texels || side <= 64)) {
            a->npages = np;
            a->side = side;
            a->texel = tx;
            a->rect_texels = need;
            rc = 0;
            break;
        }
        tx *= np ? fmax(1.02, sqrt(total / o->max_texels) * 0.9) : 1.05;
    }
    free(order);
    free(rh);
    if (rc != 0) rs_err_set(err, RS_ERR_INTERNAL, NULL, 0, "the atlas could not be packed");
    return rc;
}

void rs_atlas_project(const rs_atlas *a, const rs_atlas_chart *c, rs_v3 p, double *X, double *Y)
{
    double s, t;
    chart_st(c, p, &s, &t);
    *X = c->x0 + 0.5 + (s - c->smin) / a->texel;
    *Y = c->y0 + 0.5 + (c->tmax - t) / a->texel;
}

rs_atlas *rs_atlas_build(const rs_mesh *m, const rs_atlas_opts *o, rs_err *err)
{
    if (!(o->texel > 0) || !isfinite(o->texel)) {
        rs_err_set(err, RS_ERR_INPUT, NULL, 0, "atlas texel size %g: expected a positive number of metres", o->texel);
        return NULL;
    }
    if (m->nfaces == 0 || m->nfaces >= UINT32_MAX) {
        rs_err_set(err, RS_ERR_INPUT, NULL, 0, "atlas of a mesh with %zu faces: expected 1 to 2^32 - 2", m->nfaces);
        return NULL;
    }
    rs_atlas *a = calloc(1, sizeof *a);
    double *ext = NULL;
    if (!a) goto oom;
    a->nfaces = m->nfaces;
    a->gutter = o->gutter > 0 ? o->gutter : 2;
    int max_side = o->max_side > 0 ? o->max_side : 8192;
    double ang = o->max_angle_deg > 0 ? o->max_angle_deg : 10;
    a->face_chart = malloc(m->nfaces * sizeof *a->face_chart);
    a->faces = malloc(m->nfaces * sizeof *a->faces);
    a->uv = malloc(6 * m->nfaces * sizeof *a->uv);
    if (!a->face_chart || !a->faces || !a->uv) goto oom;
    if (grow_charts(m, cos(ang * M_PI / 180), a) != 0) goto oom;
    if (!(ext = malloc(4 * a->ncharts * sizeof *ext))) goto oom;
    chart_extents(m, a, ext);
    if (layout(a, o, ext, max_side, err) != 0) goto fail;
    for (size_t ci = 0; ci < a->ncharts; ci++) {
        rs_atlas_chart *c = &a->charts[ci];
        c->smin = ext[4 * ci];
        c->tmax = ext[4 * ci + 3];
        for (size_t q = c->first; q < c->first + c->count; q++)
            for (int k = 0; k < 3; k++) {
                size_t f = a->faces[q];
                double X, Y;
                rs_atlas_project(a, c, rs_mesh_vert(m, m->tris[3 * f + k]), &X, &Y);
                a->uv[6 * f + 2 * k] = (float)(X / a->side);
                a->uv[6 * f + 2 * k + 1] = (float)(Y / a->side);
            }
    }
    free(ext);
    return a;
oom:
    rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory building the texture atlas of %zu faces", m->nfaces);
fail:
    free(ext);
    rs_atlas_free(a);
    return NULL;
}

void rs_atlas_free(rs_atlas *a)
{
    if (!a) return;
    free(a->charts);
    free(a->face_chart);
    free(a->faces);
    free(a->uv);
    free(a);
}
