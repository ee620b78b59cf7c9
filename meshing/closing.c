/* closing: holes, extensions and slab tops of the mesh's planar regions (see closing.h). */
#include "meshing/closing.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "meshing/atlas.h"

enum { C_EMPTY = 0, C_REGION = 1, C_BLOCK = 2, C_HOLE = 3, C_EXT = 4 };
enum { K_OTHER = 0, K_WALL = 1, K_CEILING = 2 };

typedef struct {
    rs_v3 n, o, eu, ev; /* the plane: normal, a point, in-plane axes (eu x ev = n) */
    int kind;
    double s0, t0, cell; /* cell (i, j) covers s0 + [i, i + 1) cell, t0 + [j, j + 1) cell */
    int w, h;
    uint8_t *st;   /* C_* per cell */
    uint32_t *lab; /* the nearest region facet per cell */
    uint32_t *bfs; /* scratch: w h */
    uint8_t *mark; /* scratch: w h */
} raster;

typedef struct {
    float *verts; /* 12 per quad */
    uint32_t *proxy;
    uint8_t *source;
    size_t nq, cap;
} quads;

typedef struct {
    const rs_mesh *m;
    const rs_scene *scene;
    const rs_v3 *views;
    size_t nviews;
    const rs_closing_opts *o;
    double zmin, zmax;
    rs_closing_stats *st;
} ctx;

static int add_quad(quads *q, const rs_v3 c[4], uint32_t proxy, uint8_t source)
{
    if (q->nq == q->cap) {
        size_t cap = q->cap ? 2 * q->cap : 256;
        float *v = realloc(q->verts, cap * 12 * sizeof *v);
        if (!v) return -1;
        q->verts = v;
        uint32_t *p = realloc(q->proxy, cap * sizeof *p);
        if (!p) return -1;
        q->proxy = p;
        uint8_t *s = realloc(q->source, cap);
        if (!s) return -1;
        q->source = s;
        q->cap = cap;
    }
    for (int k = 0; k < 4; k++) {
        q->verts[12 * q->nq + 3 * k] = (float)c[k].x;
        q->verts[12 * q->nq + 3 * k + 1] = (float)c[k].y;
        q->verts[12 * q->nq + 3 * k + 2] = (float)c[k].z;
    }
    q->proxy[q->nq] = proxy;
    q->source[q->nq] = source;
    q->nq++;
    return 0;
}

static rs_v3 plane_point(const raster *r, double s, double t, double off)
{
    return rs_v3_add(rs_v3_add(r->o, rs_v3_scale(r->eu, r->s0 + s * r->cell)),
                     rs_v3_add(rs_v3_scale(r->ev, r->t0 + t * r->cell), rs_v3_scale(r->n, off)));
}

static rs_v3 cell_centre(const raster *r, int i, int j)
{
    return plane_point(r, i + 0.5, j + 0.5, 0);
}

/* The region's plane (area-weighted normal through the area-weighted centroid), its kind and the
 * RMS distance of its corners. Returns the area. */
static double fit_plane(const rs_mesh *m, const uint32_t *faces, size_t nfaces, raster *r, double *rms)
{
    rs_v3 ns = rs_v3_make(0, 0, 0), cs = ns;
    double area = 0;
    for (size_t q = 0; q < nfaces; q++) {
        rs_v3 cf, nf;
        double af;
        rs_mesh_face(m, faces[q], &cf, &nf, &af);
        ns = rs_v3_add(ns, rs_v3_scale(nf, af));
        cs = rs_v3_add(cs, rs_v3_scale(cf, af));
        area += af;
    }
    *rms = INFINITY;
    if (!(area > 0) || rs_v3_len(ns) <= 0) return 0;
    r->n = rs_v3_norm(ns);
    r->o = rs_v3_scale(cs, 1 / area);
    double ss = 0;
    for (size_t q = 0; q < nfaces; q++)
        for (int k = 0; k < 3; k++) {
            double d = rs_v3_dot(rs_v3_sub(rs_mesh_vert(m, m->tris[3 * faces[q] + k]), r->o), r->n);
            ss += d * d;
        }
    *rms = sqrt(ss / (3.0 * (double)nfaces));
    if (fabs(r->n.z) < 0.9)
        r->eu = rs_v3_norm(rs_v3_cross(rs_v3_make(0, 0, 1), r->n));
    else
        r->eu = rs_v3_norm(rs_v3_cross(r->n, rs_v3_make(0, 1, 0)));
    r->ev = rs_v3_cross(r->n, r->eu);
    r->kind = fabs(r->n.z) < 0.34 ? K_WALL : r->n.z < -0.7 ? K_CEILING : K_OTHER;
    return area;
}

static void to_st(const raster *r, rs_v3 p, double *s, double *t)
{
    rs_v3 d = rs_v3_sub(p, r->o);
    *s = (rs_v3_dot(d, r->eu) - r->s0) / r->cell;
    *t = (rs_v3_dot(d, r->ev) - r->t0) / r->cell;
}

/* The raster's extent: the region's corners, padded. 0, or -1 out of memory. */
static int raster_alloc(const ctx *x, const uint32_t *faces, size_t nfaces, raster *r)
{
    double smin = INFINITY, smax = -INFINITY, tmin = INFINITY, tmax = -INFINITY;
    r->s0 = r->t0 = 0;
    r->cell = 1;
    for (size_t q = 0; q < nfaces; q++)
        for (int k = 0; k < 3; k++) {
            double s, t;
            to_st(r, rs_mesh_vert(x->m, x->m->tris[3 * faces[q] + k]), &s, &t);
            smin = fmin(smin, s), smax = fmax(smax, s), tmin = fmin(tmin, t), tmax = fmax(tmax, t);
        }
    double cell = x->o->cell;
    double pad = r->kind != K_OTHER ? x->o->extend_max : 0;
    for (;;) {
        double p = pad + 2 * cell;
        double w = ceil((smax - smin + 2 * p) / cell), h = ceil((tmax - tmin + 2 * p) / cell);
        if (w * h <= (double)x->o->max_cells) {
            r->w = (int)w, r->h = (int)h, r->s0 = smin - p, r->t0 = tmin - p;
            break;
        }
        cell *= 1.25;
    }
    r->cell = cell;
    size_t n = (size_t)r->w * r->h;
    r->st = calloc(n, 1);
    r->mark = calloc(n, 1);
    r->lab = malloc(n * sizeof *r->lab);
    r->bfs = malloc(n * sizeof *r->bfs);
    if (!r->st || !r->mark || !r->lab || !r->bfs) return -1;
    for (size_t k = 0; k < n; k++) r->lab[k] = UINT32_MAX;
    return 0;
}

static void raster_release(raster *r)
{
    free(r->st);
    free(r->mark);
    free(r->lab);
    free(r->bfs);
    memset(r, 0, sizeof *r);
}

/* Sets cells whose centre lies in triangle (s, t)[3] (cell units) from `from` to `to`, label f. */
static void fill_tri(raster *r, const double *s, const double *t, uint8_t from, uint8_t to, uint32_t f)
{
    double area = (s[1] - s[0]) * (t[2] - t[0]) - (s[2] - s[0]) * (t[1] - t[0]);
    if (area == 0) return;
    int i0 = (int)floor(fmin(s[0], fmin(s[1], s[2]))), i1 = (int)ceil(fmax(s[0], fmax(s[1], s[2])));
    int j0 = (int)floor(fmin(t[0], fmin(t[1], t[2]))), j1 = (int)ceil(fmax(t[0], fmax(t[1], t[2])));
    if (i0 < 0) i0 = 0;
    if (j0 < 0) j0 = 0;
    if (i1 > r->w) i1 = r->w;
    if (j1 > r->h) j1 = r->h;
    double sg = area > 0 ? 1 : -1, tol = 1e-9 * fabs(area);
    for (int j = j0; j < j1; j++)
        for (int i = i0; i < i1; i++) {
            double ps = i + 0.5, pt = j + 0.5, inside = 1;
            for (int e = 0; e < 3 && inside; e++) {
                int a = e, b = (e + 1) % 3;
                double ed = (s[b] - s[a]) * (pt - t[a]) - (t[b] - t[a]) * (ps - s[a]);
                if (sg * ed < -tol) inside = 0;
            }
            size_t k = (size_t)j * r->w + i;
            if (inside && r->st[k] == from) r->st[k] = to, r->lab[k] = f;
        }
}

/* Marks the cells other facets of the mesh cross (within half a cell of the plane) C_BLOCK: the
 * plane's intersections with the other surfaces, and coplanar facets outside the region. */
static void mark_blockers(const ctx *x, const uint32_t *face_region, uint32_t region, raster *r)
{
    const rs_mesh *m = x->m;
    double half = 0.5 * r->cell;
    for (size_t f = 0; f < m->nfaces; f++) {
        if (face_region[f] == region) continue;
        rs_v3 p[3];
        double d[3], s[3], t[3];
        for (int k = 0; k < 3; k++) {
            p[k] = rs_mesh_vert(m, m->tris[3 * f + k]);
            d[k] = rs_v3_dot(rs_v3_sub(p[k], r->o), r->n);
        }
        double dmin = fmin(d[0], fmin(d[1], d[2])), dmax = fmax(d[0], fmax(d[1], d[2]));
        if (dmin > half || dmax < -half) continue;
        for (int k = 0; k < 3; k++) to_st(r, p[k], &s[k], &t[k]);
        if (fmax(s[0], fmax(s[1], s[2])) < 0 || fmin(s[0], fmin(s[1], s[2])) > r->w ||
            fmax(t[0], fmax(t[1], t[2])) < 0 || fmin(t[0], fmin(t[1], t[2])) > r->h)
            continue;
        if (dmin >= -half && dmax <= half) {
            fill_tri(r, s, t, C_EMPTY, C_BLOCK, UINT32_MAX);
            continue;
        }
        /* The segment where the facet crosses the plane, sampled every half cell. */
        double es[2], et[2];
        int ne = 0;
        for (int k = 0; k < 3 && ne < 2; k++) {
            int b = (k + 1) % 3;
            if ((d[k] < 0) == (d[b] < 0)) continue;
            double u = d[k] / (d[k] - d[b]);
            es[ne] = s[k] + u * (s[b] - s[k]), et[ne] = t[k] + u * (t[b] - t[k]), ne++;
        }
        if (ne < 2) continue;
        double len = hypot(es[1] - es[0], et[1] - et[0]);
        int steps = (int)ceil(2 * len) + 1;
        for (int q = 0; q <= steps; q++) {
            double u = (double)q / steps;
            int i = (int)floor(es[0] + u * (es[1] - es[0])), j = (int)floor(et[0] + u * (et[1] - et[0]));
            if (i < 0 || j < 0 || i >= r->w || j >= r->h) continue;
            size_t k = (size_t)j * r->w + i;
            if (r->st[k] == C_EMPTY) r->st[k] = C_BLOCK;
        }
    }
}

/* out[q] = 1 when every viewpoint in front of the plane has a surface on its line of sight to
 * cells[q]'s centre short of 0.75 cell before it, and there is one (a plane no viewpoint faces
 * was not scanned: nothing says where its shadows are). */
static void shadowed(const ctx *x, const raster *r, const uint32_t *cells, size_t n, uint8_t *out)
{
    enum { B = 1024 };
    rs_ray rays[B];
    uint8_t occ[B];
    uint32_t owner[B];
    size_t nr = 0;
    for (size_t q = 0; q < n; q++) out[q] = 0; /* 1: a viewpoint in front, 2: one of them saw it */
    for (size_t q = 0; q <= n; q++) {
        if (q == n || nr + x->nviews > B) {
            rs_scene_occluded(x->scene, rays, occ, nr);
            x->st->rays += (double)nr;
            for (size_t k = 0; k < nr; k++) out[owner[k]] |= (uint8_t)(occ[k] ? 1 : 3);
            nr = 0;
            if (q == n) {
                for (size_t k = 0; k < n; k++) out[k] = out[k] == 1;
                break;
            }
        }
        rs_v3 p = cell_centre(r, (int)(cells[q] % r->w), (int)(cells[q] / r->w));
        for (size_t v = 0; v < x->nviews; v++) {
            rs_v3 d = rs_v3_sub(p, x->views[v]);
            double len = rs_v3_len(d);
            if (rs_v3_dot(d, r->n) >= 0 || len <= r->cell) continue; /* behind the plane, or on it */
            rays[nr].org = x->views[v];
            rays[nr].dir = d;
            rays[nr].tnear = 0;
            rays[nr].tfar = 1 - 0.75 * r->cell / len;
            owner[nr++] = (uint32_t)q;
        }
    }
}

static int nbrs(const raster *r, uint32_t k, uint32_t nb[4])
{
    int i = (int)(k % r->w), j = (int)(k / r->w), c = 0;
    if (i > 0) nb[c++] = k - 1;
    if (i + 1 < r->w) nb[c++] = k + 1;
    if (j > 0) nb[c++] = k - (uint32_t)r->w;
    if (j + 1 < r->h) nb[c++] = k + (uint32_t)r->w;
    return c;
}

/* Holes: empty cells the border's empty cells do not reach, shadowed. */
static int fill_holes(const ctx *x, raster *r)
{
    size_t n = (size_t)r->w * r->h, head = 0, tail = 0;
    memset(r->mark, 0, n);
    for (int j = 0; j < r->h; j++)
        for (int i = 0; i < r->w; i++)
            if ((i == 0 || j == 0 || i == r->w - 1 || j == r->h - 1) && r->st[(size_t)j * r->w + i] == C_EMPTY) {
                r->mark[(size_t)j * r->w + i] = 1;
                r->bfs[tail++] = (uint32_t)((size_t)j * r->w + i);
            }
    while (head < tail) {
        uint32_t nb[4];
        int c = nbrs(r, r->bfs[head++], nb);
        for (int q = 0; q < c; q++)
            if (!r->mark[nb[q]] && r->st[nb[q]] == C_EMPTY) r->mark[nb[q]] = 1, r->bfs[tail++] = nb[q];
    }
    size_t nh = 0;
    for (size_t k = 0; k < n; k++)
        if (r->st[k] == C_EMPTY && !r->mark[k]) r->bfs[nh++] = (uint32_t)k;
    if (!nh) return 0;
    uint8_t *sh = malloc(nh);
    if (!sh) return -1;
    shadowed(x, r, r->bfs, nh, sh);
    for (size_t q = 0; q < nh; q++)
        if (sh[q]) r->st[r->bfs[q]] = C_HOLE;
    free(sh);
    return 0;
}

/* Extension: breadth-first from the region and its holes over empty shadowed cells, one ring at a
 * time, at most extend_max out, within the mesh's height. */
static int extend(const ctx *x, raster *r)
{
    size_t n = (size_t)r->w * r->h, nring = 0;
    uint8_t *sh = malloc(n);
    uint32_t *next = malloc(n * sizeof *next);
    if (!sh || !next) {
        free(sh);
        free(next);
        return -1;
    }
    memset(r->mark, 0, n);
    for (size_t k = 0; k < n; k++)
        if (r->st[k] == C_REGION || r->st[k] == C_HOLE) r->bfs[nring++] = (uint32_t)k, r->mark[k] = 1;
    int rings = (int)floor(x->o->extend_max / r->cell);
    for (int ring = 0; ring < rings && nring; ring++) {
        size_t nn = 0;
        for (size_t q = 0; q < nring; q++) {
            uint32_t nb[4];
            int c = nbrs(r, r->bfs[q], nb);
            for (int e = 0; e < c; e++) {
                uint32_t k = nb[e];
                if (r->mark[k] || r->st[k] != C_EMPTY) continue;
                r->mark[k] = 1;
                double z = cell_centre(r, (int)(k % r->w), (int)(k / r->w)).z;
                if (z > x->zmax || z < x->zmin) continue;
                next[nn++] = k;
            }
        }
        shadowed(x, r, next, nn, sh);
        nring = 0;
        for (size_t q = 0; q < nn; q++)
            if (sh[q]) r->st[next[q]] = C_EXT, r->bfs[nring++] = next[q];
    }
    free(sh);
    free(next);
    return 0;
}

/* Every cell's nearest region facet: breadth-first from the region's cells. */
static void spread_labels(raster *r)
{
    size_t n = (size_t)r->w * r->h, head = 0, tail = 0;
    for (size_t k = 0; k < n; k++)
        if (r->st[k] == C_REGION)
            r->bfs[tail++] = (uint32_t)k;
        else
            r->lab[k] = UINT32_MAX;
    while (head < tail) {
        uint32_t k = r->bfs[head++], nb[4];
        int c = nbrs(r, k, nb);
        for (int e = 0; e < c; e++)
            if (r->lab[nb[e]] == UINT32_MAX) r->lab[nb[e]] = r->lab[k], r->bfs[tail++] = nb[e];
    }
}

/* Greedy rectangles of the cells whose state is in `want` (a bit per C_*), at offset off along n,
 * facing n (up = 0) or -n (up = 1). Returns the area, -1 out of memory. */
static double emit_rects(raster *r, unsigned want, double off, int flip, uint8_t source, quads *out)
{
    size_t n = (size_t)r->w * r->h;
    for (size_t k = 0; k < n; k++) r->mark[k] = (want >> r->st[k]) & 1;
    double area = 0;
    for (int j = 0; j < r->h; j++)
        for (int i = 0; i < r->w; i++) {
            if (!r->mark[(size_t)j * r->w + i]) continue;
            int i1 = i + 1, j1 = j + 1;
            while (i1 < r->w && r->mark[(size_t)j * r->w + i1]) i1++;
            for (int ok = 1; ok && j1 < r->h; j1 += ok)
                for (int q = i; q < i1; q++)
                    if (!r->mark[(size_t)j1 * r->w + q]) ok = 0;
            for (int y = j; y < j1; y++) memset(r->mark + (size_t)y * r->w + i, 0, (size_t)(i1 - i));
            rs_v3 c[4] = {plane_point(r, i, j, off), plane_point(r, i1, j, off), plane_point(r, i1, j1, off),
                          plane_point(r, i, j1, off)};
            if (flip) {
                rs_v3 tmp = c[1];
                c[1] = c[3], c[3] = tmp;
            }
            uint32_t pr = r->lab[(size_t)((j + j1 - 1) / 2) * r->w + (i + i1 - 1) / 2];
            if (pr == UINT32_MAX) continue;
            if (add_quad(out, c, pr, source) != 0) return -1;
            area += (double)(i1 - i) * (j1 - j) * r->cell * r->cell;
        }
    return area;
}

/* 1 when fewer than half of the region's cells (a sample of at most 4096) have a surface within
 * slab_probe straight above them. */
static int seen_from_below_only(const ctx *x, raster *r)
{
    size_t n = (size_t)r->w * r->h, cnt = 0;
    for (size_t k = 0; k < n; k++) cnt += r->st[k] == C_REGION;
    size_t stride = cnt > 4096 ? cnt / 4096 : 1, seen = 0, hits = 0, idx = 0;
    enum { B = 512 };
    rs_ray rays[B];
    uint8_t occ[B];
    size_t nr = 0;
    for (size_t k = 0; k <= n; k++) {
        if (k == n || nr == B) {
            rs_scene_occluded(x->scene, rays, occ, nr);
            x->st->rays += (double)nr;
            for (size_t q = 0; q < nr; q++) hits += occ[q];
            seen += nr;
            nr = 0;
            if (k == n) break;
        }
        if (r->st[k] != C_REGION || idx++ % stride) continue;
        rays[nr].org = plane_point(r, (int)(k % r->w) + 0.5, (int)(k / r->w) + 0.5, -0.01);
        rays[nr].dir = rs_v3_make(0, 0, 1);
        rays[nr].tnear = 0;
        rays[nr].tfar = x->o->slab_probe;
        nr++;
    }
    return seen > 0 && 2 * hits < seen;
}

static int in_slab(const raster *r, int i, int j)
{
    if (i < 0 || j < 0 || i >= r->w || j >= r->h) return 0;
    uint8_t s = r->st[(size_t)j * r->w + i];
    return s == C_REGION || s == C_HOLE || s == C_EXT;
}

/* A facet may stand for an unseen face when its normal lies within 60 degrees of the face's, as
 * for the free-space map's proxies (meshing/freespace.h, RS_FS_PROXY_COS). */
#define RS_CLOSE_PROXY_COS 0.5

/* The facets of m facing d (normal within RS_CLOSE_PROXY_COS of it) and their centroids. */
typedef struct {
    rs_v3 d;
    size_t n;
    uint32_t *face;
    rs_v3 *c;
} facing_set;

static int facing_set_build(const rs_mesh *m, rs_v3 d, facing_set *s)
{
    s->d = d;
    s->n = 0;
    s->face = malloc((m->nfaces ? m->nfaces : 1) * sizeof *s->face);
    s->c = malloc((m->nfaces ? m->nfaces : 1) * sizeof *s->c);
    if (!s->face || !s->c) return -1;
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(m, f, &c, &n, &a);
        if (rs_v3_dot(n, d) > RS_CLOSE_PROXY_COS) s->face[s->n] = (uint32_t)f, s->c[s->n++] = c;
    }
    return 0;
}

static uint32_t facing_nearest(const facing_set *s, rs_v3 p)
{
    uint32_t best = UINT32_MAX;
    double bd = INFINITY;
    for (size_t k = 0; k < s->n; k++) {
        rs_v3 e = rs_v3_sub(s->c[k], p);
        double d = rs_v3_dot(e, e);
        if (d < bd) bd = d, best = s->face[k];
    }
    return best;
}

/* The proxies of quads first .. out->nq (a slab's top and edges): the mesh's facet nearest to each
 * among those facing its way. The region's own facets face down: as the top's proxy the
 * underside's radiance stood for the top's (the tower sample's cornice, docs/PIPELINE.md). A face
 * no facet faces the way of keeps the region's. */
static int slab_proxies(const ctx *x, quads *out, size_t first)
{
    enum { MAX_DIRS = 8 };
    facing_set set[MAX_DIRS];
    int nset = 0, rc = 0;
    for (size_t k = first; k < out->nq && rc == 0; k++) {
        const float *v = out->verts + 12 * k;
        rs_v3 c[4];
        for (int q = 0; q < 4; q++) c[q] = rs_v3_make(v[3 * q], v[3 * q + 1], v[3 * q + 2]);
        rs_v3 nrm = rs_v3_cross(rs_v3_sub(c[1], c[0]), rs_v3_sub(c[2], c[0]));
        if (!(rs_v3_len(nrm) > 0)) continue;
        nrm = rs_v3_norm(nrm);
        rs_v3 mid = rs_v3_scale(rs_v3_add(rs_v3_add(c[0], c[1]), rs_v3_add(c[2], c[3])), 0.25);
        int q = 0;
        while (q < nset && rs_v3_dot(set[q].d, nrm) < 0.999) q++;
        if (q == nset) {
            if (nset == MAX_DIRS) continue;
            if (facing_set_build(x->m, nrm, &set[nset++]) != 0) rc = -1;
        }
        uint32_t pr = rc == 0 ? facing_nearest(&set[q], mid) : UINT32_MAX;
        if (pr != UINT32_MAX) out->proxy[k] = pr;
    }
    for (int q = 0; q < nset; q++) free(set[q].face), free(set[q].c);
    return rc;
}

/* The slab's top face over its region, holes and extension, and the vertical faces around it. */
static int emit_slab(const ctx *x, raster *r, quads *out)
{
    size_t first = out->nq;
    double th = x->o->slab_thickness;
    double area = emit_rects(r, 1u << C_REGION | 1u << C_HOLE | 1u << C_EXT, -th, 1, RS_CLOSE_SLAB, out);
    if (area < 0) return -1;
    x->st->slab_area += area;
    static const int di[4] = {-1, 1, 0, 0}, dj[4] = {0, 0, -1, 1};
    for (int j = 0; j < r->h; j++)
        for (int i = 0; i < r->w; i++) {
            if (!in_slab(r, i, j)) continue;
            for (int e = 0; e < 4; e++) {
                if (in_slab(r, i + di[e], j + dj[e])) continue;
                /* the cell's side toward (di, dj): from corner a to corner b */
                double as = i + (di[e] > 0), at = j + (dj[e] > 0);
                double bs = di[e] ? as : as + 1, bt = dj[e] ? at : at + 1;
                rs_v3 c[4] = {plane_point(r, as, at, 0), plane_point(r, bs, bt, 0), plane_point(r, bs, bt, -th),
                              plane_point(r, as, at, -th)};
                rs_v3 outward = rs_v3_add(rs_v3_scale(r->eu, di[e]), rs_v3_scale(r->ev, dj[e]));
                rs_v3 nrm = rs_v3_cross(rs_v3_sub(c[1], c[0]), rs_v3_sub(c[2], c[0]));
                if (rs_v3_dot(nrm, outward) < 0) {
                    rs_v3 tmp = c[1];
                    c[1] = c[3], c[3] = tmp;
                }
                if (add_quad(out, c, r->lab[(size_t)j * r->w + i], RS_CLOSE_SLAB) != 0) return -1;
            }
        }
    x->st->slabs++;
    return slab_proxies(x, out, first);
}

/* One region: fit, rasterise, fill, extend, slab. */
static int close_region(const ctx *x, const uint32_t *faces, size_t nfaces, const uint32_t *face_region, uint32_t rid,
                        quads *out)
{
    raster r = {0};
    double rms, area = fit_plane(x->m, faces, nfaces, &r, &rms);
    if (area < x->o->min_area || !(rms <= x->o->max_rms)) return 0;
    x->st->regions++;
    x->st->walls += r.kind == K_WALL;
    x->st->ceilings += r.kind == K_CEILING;
    int rc = -1;
    if (raster_alloc(x, faces, nfaces, &r) != 0) goto done;
    for (size_t q = 0; q < nfaces; q++) {
        double s[3], t[3];
        for (int k = 0; k < 3; k++) to_st(&r, rs_mesh_vert(x->m, x->m->tris[3 * faces[q] + k]), &s[k], &t[k]);
        fill_tri(&r, s, t, C_EMPTY, C_REGION, faces[q]);
    }
    if (r.kind != K_OTHER) mark_blockers(x, face_region, rid, &r);
    if (fill_holes(x, &r) != 0) goto done;
    if (r.kind != K_OTHER && extend(x, &r) != 0) goto done;
    spread_labels(&r);
    double ha = emit_rects(&r, 1u << C_HOLE, 0, 0, RS_CLOSE_HOLE, out);
    double ea = ha < 0 ? -1 : emit_rects(&r, 1u << C_EXT, 0, 0, RS_CLOSE_EXTEND, out);
    if (ea < 0) goto done;
    x->st->hole_area += ha;
    x->st->extend_area += ea;
    if (r.kind == K_CEILING && seen_from_below_only(x, &r) && emit_slab(x, &r, out) != 0) goto done;
    rc = 0;
done:
    raster_release(&r);
    return rc;
}

typedef struct {
    rs_v3 n, c;
    double area;
    uint32_t chart;
} chart_plane;

static int by_area(const void *pa, const void *pb)
{
    const chart_plane *a = pa, *b = pb;
    if (a->area != b->area) return a->area > b->area ? -1 : 1;
    return a->chart < b->chart ? -1 : (a->chart > b->chart);
}

/* Regions: the atlas's charts, the coplanar ones together (normals within 5 degrees, the
 * chart's centroid within max_rms twice of the largest one's plane; charts under a tenth of
 * min_area left out), so that a wall the shadow of a pillar splits in two is one region.
 * face_region[f]: the region of face f (UINT32_MAX: none); returns the regions' count, -1 out of
 * memory. */
static long group_charts(const rs_mesh *m, const rs_atlas *a, double min_area, double tol, uint32_t *face_region)
{
    chart_plane *cp = malloc((a->ncharts + 1) * sizeof *cp);
    uint32_t *chart_region = malloc((2 * a->ncharts + 1) * sizeof *chart_region); /* and the seeds */
    if (!cp || !chart_region) {
        free(cp);
        free(chart_region);
        return -1;
    }
    for (size_t ci = 0; ci < a->ncharts; ci++) {
        const rs_atlas_chart *c = &a->charts[ci];
        rs_v3 ns = rs_v3_make(0, 0, 0), cs = ns;
        double area = 0;
        for (size_t q = c->first; q < c->first + c->count; q++) {
            rs_v3 cf, nf;
            double af;
            rs_mesh_face(m, a->faces[q], &cf, &nf, &af);
            ns = rs_v3_add(ns, rs_v3_scale(nf, af));
            cs = rs_v3_add(cs, rs_v3_scale(cf, af));
            area += af;
        }
        cp[ci].chart = (uint32_t)ci;
        cp[ci].area = area > 0 && rs_v3_len(ns) > 0 ? area : 0;
        cp[ci].n = cp[ci].area > 0 ? rs_v3_norm(ns) : ns;
        cp[ci].c = cp[ci].area > 0 ? rs_v3_scale(cs, 1 / area) : cs;
        chart_region[ci] = UINT32_MAX;
    }
    qsort(cp, a->ncharts, sizeof *cp, by_area);
    size_t nreg = 0; /* region r's plane is that of its first (largest) chart, cp[seed[r]] */
    uint32_t *seed = (uint32_t *)chart_region + a->ncharts; /* room: see the allocation */
    double cos5 = cos(5 * M_PI / 180);
    for (size_t k = 0; k < a->ncharts && cp[k].area >= 0.1 * min_area; k++) {
        size_t r = 0;
        for (; r < nreg; r++) {
            const chart_plane *p = &cp[seed[r]];
            if (rs_v3_dot(cp[k].n, p->n) > cos5 && fabs(rs_v3_dot(rs_v3_sub(cp[k].c, p->c), p->n)) < tol) break;
        }
        if (r == nreg) seed[nreg++] = (uint32_t)k;
        chart_region[cp[k].chart] = (uint32_t)r;
    }
    for (size_t f = 0; f < m->nfaces; f++) face_region[f] = chart_region[a->face_chart[f]];
    free(cp);
    free(chart_region);
    return (long)nreg;
}

int rs_closing_build(const rs_mesh *m, const rs_scene *scene, const rs_v3 *views, size_t nviews,
                     const rs_closing_opts *o, rs_mesh **occ, uint32_t **proxy, uint8_t **source, rs_closing_stats *st,
                     rs_err *err)
{
    *occ = NULL;
    *proxy = NULL;
    *source = NULL;
    memset(st, 0, sizeof *st);
    if (m->nfaces == 0) return 0;
    rs_atlas_opts ao = {.texel = 1.0, .max_angle_deg = 10};
    rs_atlas *a = rs_atlas_build(m, &ao, err);
    if (!a) return -1;
    ctx x = {m, scene, views, nviews < 1024 ? nviews : 1024, o, INFINITY, -INFINITY, st}; /* shadowed()'s batch */
    for (size_t v = 0; v < m->nverts; v++) {
        x.zmin = fmin(x.zmin, m->verts[3 * v + 2]);
        x.zmax = fmax(x.zmax, m->verts[3 * v + 2]);
    }
    quads q = {0};
    int rc = -1;
    uint32_t *face_region = malloc(m->nfaces * sizeof *face_region), *order = NULL;
    size_t *start = NULL;
    long nreg = face_region ? group_charts(m, a, o->min_area, 2 * o->max_rms, face_region) : -1;
    if (nreg < 0) goto oom;
    /* the faces by region (counting sort) */
    start = calloc((size_t)nreg + 2, sizeof *start);
    order = malloc(m->nfaces * sizeof *order);
    if (!start || !order) goto oom;
    for (size_t f = 0; f < m->nfaces; f++)
        if (face_region[f] != UINT32_MAX) start[face_region[f] + 2]++;
    for (long r = 0; r < nreg; r++) start[r + 2] += start[r + 1];
    for (size_t f = 0; f < m->nfaces; f++)
        if (face_region[f] != UINT32_MAX) order[start[face_region[f] + 1]++] = (uint32_t)f;
    for (long r = 0; r < nreg; r++)
        if (close_region(&x, order + start[r], start[r + 1] - start[r], face_region, (uint32_t)r, &q) != 0) goto oom;
    if (q.nq) {
        rs_mesh *out = rs_mesh_new(4 * q.nq, 2 * q.nq);
        uint32_t *pr = malloc(2 * q.nq * sizeof *pr);
        uint8_t *so = malloc(2 * q.nq);
        if (!out || !pr || !so) {
            rs_mesh_free(out);
            free(pr);
            free(so);
            goto oom;
        }
        memcpy(out->verts, q.verts, 12 * q.nq * sizeof(float));
        for (size_t k = 0; k < q.nq; k++) {
            uint32_t b = (uint32_t)(4 * k), t[6] = {b, b + 1, b + 2, b, b + 2, b + 3};
            memcpy(out->tris + 6 * k, t, sizeof t);
            pr[2 * k] = pr[2 * k + 1] = q.proxy[k];
            so[2 * k] = so[2 * k + 1] = q.source[k];
        }
        *occ = out, *proxy = pr, *source = so;
        st->faces = 2 * q.nq;
    }
    rc = 0;
    goto out;
oom:
    rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory closing the planar regions of %zu faces", m->nfaces);
out:
    free(face_region);
    free(order);
    free(start);
    free(q.verts);
    free(q.proxy);
    free(q.source);
    rs_atlas_free(a);
    return rc;
}
