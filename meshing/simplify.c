/* simplify: quadric edge collapse (Garland & Heckbert 1997, "Surface simplification using
 * quadric error metrics") with a binary heap; exports rs_simplify_apply (simplify.h). */
#include "meshing/simplify.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* Placement: the new vertex minimises the quadric plus PLACE_PULL * trace(A) * |x - m|^2,
 * m the edge midpoint (a small Tikhonov term in the spirit of Lindstrom 2000). Along a plane
 * (no minimum there) the vertex stays at the midpoint, so scan noise cannot slide it; across
 * planes it falls short of the exact minimum by PLACE_PULL / (s + PLACE_PULL), s the plane's
 * share of the quadric's weight, so creases and corners are kept. */
#define PLACE_PULL 1e-3

/* An edge of the current mesh, in the heap of candidate collapses or out of it (refused
 * until its neighbourhood changes, or dead). */
typedef struct edge {
    uint32_t a, b; /* a < b */
    uint32_t pos;  /* index in the heap, or OUT / DEAD */
    double cost;
} edge;
#define OUT  UINT32_MAX
#define DEAD (UINT32_MAX - 1)

/* The heap holds each edge's sort key beside its id, so that comparisons stay in the heap. */
typedef struct heap_entry {
    double cost;
    uint64_t ab; /* a << 32 | b: ties go by vertex index */
    uint32_t id;
} heap_entry;

/* A vertex's faces or edges: ids, dead ones dropped lazily. */
typedef struct id_list {
    uint32_t *id;
    uint32_t n, cap;
} id_list;

/* One vertex's neighbours: for each, how many of the vertex's live faces hold it and one such face. */
typedef struct nbset {
    uint32_t *mark, *slot; /* per mesh vertex: stamp of the last gather, index into v */
    uint32_t stamp;
    uint32_t *v, *cnt, *face;
    size_t n, cap;
} nbset;

typedef struct simp {
    const rs_simplify_opts *o;
    rs_simplify_stats *st;
    size_t nv, nf;
    double *pos; /* 3 per vertex, recentred on the bounding box */
    double *Q;   /* 10 per vertex: A (6), b (3), c of x'Ax + 2b'x + c */
    double *w;   /* per vertex: face area gathered in its quadric (m^2) */
    uint32_t *tri;
    uint8_t *face_dead, *retry;
    id_list *vf, *ve; /* per vertex: its faces, its edges */
    edge *edges;
    size_t nedges;
    heap_entry *heap; /* a binary min-heap of edges on (cost, a, b) */
    size_t hn;
    nbset nb[2];
    double centre[3]; /* subtracted from the input coordinates */
    double edge_sum;
    size_t edge_count, faces_alive;
    double cos_turn;
} simp;

void rs_simplify_defaults(rs_simplify_opts *o)
{
    memset(o, 0, sizeof *o);
    o->max_normal_turn_rad = 60.0 * M_PI / 180.0;
    o->min_quality = 0.2;
    o->boundary_weight = 10.0;
    o->length_weight = 0.01;
}

/* ---- small geometry ---- */

static void sub3(const double *a, const double *b, double *r)
{
    r[0] = a[0] - b[0];
    r[1] = a[1] - b[1];
    r[2] = a[2] - b[2];
}
static double dot3(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static void cross3(const double *a, const double *b, double *r)
{
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}
static double dist3(const double *a, const double *b)
{
    double d[3];
    sub3(a, b, d);
    return sqrt(dot3(d, d));
}
/* Twice the area vector of triangle (p, q, r). */
static void tri_normal(const double *p, const double *q, const double *r, double *n)
{
    double u[3], v[3];
    sub3(q, p, u);
    sub3(r, p, v);
    cross3(u, v, n);
}
/* 4 sqrt(3) area / sum of squared edges: 1 for an equilateral triangle, 0 for a needle. */
static double tri_quality(const double *p, const double *q, const double *r, const double *n)
{
    double e = 0, d[3];
    sub3(q, p, d);
    e += dot3(d, d);
    sub3(r, q, d);
    e += dot3(d, d);
    sub3(p, r, d);
    e += dot3(d, d);
    return e > 0 ? 2.0 * sqrt(3.0) * sqrt(dot3(n, n)) / e : 0;
}

/* ---- quadrics ---- */

static void quadric_add_plane(double *q, const double *n, double d, double w)
{
    q[0] += w * n[0] * n[0];
    q[1] += w * n[0] * n[1];
    q[2] += w * n[0] * n[2];
    q[3] += w * n[1] * n[1];
    q[4] += w * n[1] * n[2];
    q[5] += w * n[2] * n[2];
    q[6] += w * n[0] * d;
    q[7] += w * n[1] * d;
    q[8] += w * n[2] * d;
    q[9] += w * d * d;
}

static double quadric_eval(const double *q, const double *x)
{
    return q[0] * x[0] * x[0] + 2 * q[1] * x[0] * x[1] + 2 * q[2] * x[0] * x[2] + q[3] * x[1] * x[1] +
        2 * q[4] * x[1] * x[2] + q[5] * x[2] * x[2] + 2 * (q[6] * x[0] + q[7] * x[1] + q[8] * x[2]) + q[9];
}

/* Cost of collapsing edge (a, b) and the position x of the merged vertex. */
static double evaluate(const simp *s, uint32_t a, uint32_t b, double *x)
{
    double q[10];
    const double *qa = s->Q + 10 * (size_t)a, *qb = s->Q + 10 * (size_t)b;
    const double *pa = s->pos + 3 * (size_t)a, *pb = s->pos + 3 * (size_t)b;
    for (int i = 0; i < 10; i++) q[i] = qa[i] + qb[i];
    double m[3] = {0.5 * (pa[0] + pb[0]), 0.5 * (pa[1] + pb[1]), 0.5 * (pa[2] + pb[2])};
    /* Minimise Q(x) + mu |x - m|^2: (A + mu I) x = mu m - b, by Cramer's rule. */
    double mu = PLACE_PULL * (q[0] + q[3] + q[5]);
    double a00 = q[0] + mu, a01 = q[1], a02 = q[2], a11 = q[3] + mu, a12 = q[4], a22 = q[5] + mu;
    double r0 = mu * m[0] - q[6], r1 = mu * m[1] - q[7], r2 = mu * m[2] - q[8];
    double c00 = a11 * a22 - a12 * a12, c01 = a02 * a12 - a01 * a22, c02 = a01 * a12 - a02 * a11;
    double det = a00 * c00 + a01 * c01 + a02 * c02;
    if (det > 0) {
        double c11 = a00 * a22 - a02 * a02, c12 = a01 * a02 - a00 * a12, c22 = a00 * a11 - a01 * a01;
        x[0] = (c00 * r0 + c01 * r1 + c02 * r2) / det;
        x[1] = (c01 * r0 + c11 * r1 + c12 * r2) / det;
        x[2] = (c02 * r0 + c12 * r1 + c22 * r2) / det;
    } else {
        memcpy(x, m, sizeof m); /* no area around the edge: nothing to fit */
    }
    double cost = quadric_eval(q, x);
    if (!(cost > 0)) cost = 0; /* rounding */
    double e[3];
    sub3(pa, pb, e);
    return cost + s->o->length_weight * (s->w[a] + s->w[b]) * dot3(e, e);
}

/* ---- heap of edges: min on (cost, a, b), so that ties go by vertex index ---- */

static int entry_less(const heap_entry *x, const heap_entry *y)
{
    return x->cost < y->cost || (x->cost == y->cost && x->ab < y->ab);
}

static void heap_place(simp *s, size_t i, heap_entry h)
{
    s->heap[i] = h;
    s->edges[h.id].pos = (uint32_t)i;
}

static void sift_up(simp *s, size_t i)
{
    heap_entry h = s->heap[i];
    while (i > 0 && entry_less(&h, &s->heap[(i - 1) / 2])) {
        heap_place(s, i, s->heap[(i - 1) / 2]);
        i = (i - 1) / 2;
    }
    heap_place(s, i, h);
}

static void sift_down(simp *s, size_t i)
{
    heap_entry h = s->heap[i];
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= s->hn) break;
        if (c + 1 < s->hn && entry_less(&s->heap[c + 1], &s->heap[c])) c++;
        if (!entry_less(&s->heap[c], &h)) break;
        heap_place(s, i, s->heap[c]);
        i = c;
    }
    heap_place(s, i, h);
}

static heap_entry entry_of(const simp *s, uint32_t id)
{
    const edge *e = &s->edges[id];
    heap_entry h = {e->cost, (uint64_t)e->a << 32 | e->b, id};
    return h;
}

/* Takes edge e out of the heap (state becomes `state`: OUT or DEAD). */
static void heap_remove(simp *s, uint32_t e, uint32_t state)
{
    uint32_t i = s->edges[e].pos;
    if (i < s->hn) {
        heap_entry last = s->heap[--s->hn];
        if (last.id != e) {
            heap_place(s, i, last);
            sift_up(s, i);
            sift_down(s, s->edges[last.id].pos);
        }
    }
    s->edges[e].pos = state;
}

/* Recomputes e's cost and puts it in the heap (or moves it there). */
static void heap_update(simp *s, uint32_t e)
{
    double x[3];
    edge *ed = &s->edges[e];
    ed->cost = evaluate(s, ed->a, ed->b, x);
    if (ed->pos == OUT) {
        heap_place(s, s->hn++, entry_of(s, e));
        sift_up(s, s->hn - 1);
    } else {
        uint32_t i = ed->pos;
        s->heap[i] = entry_of(s, e);
        sift_up(s, i);
        sift_down(s, ed->pos);
    }
}

/* ---- adjacency ---- */

static int nbset_grow(nbset *nb)
{
    size_t cap = nb->cap ? 2 * nb->cap : 64;
    uint32_t **arr[3] = {&nb->v, &nb->cnt, &nb->face};
    for (int i = 0; i < 3; i++) {
        uint32_t *p = realloc(*arr[i], cap * sizeof *p);
        if (!p) return -1;
        *arr[i] = p;
    }
    nb->cap = cap;
    return 0;
}

/* Collects v's neighbours with their face counts into nb, and drops dead faces from v's list. */
static int gather(simp *s, uint32_t v, nbset *nb)
{
    if (++nb->stamp == 0) {
        memset(nb->mark, 0, s->nv * sizeof *nb->mark);
        nb->stamp = 1;
    }
    nb->n = 0;
    id_list *fl = &s->vf[v];
    uint32_t kept = 0;
    for (uint32_t k = 0; k < fl->n; k++) {
        uint32_t f = fl->id[k];
        if (s->face_dead[f]) continue;
        fl->id[kept++] = f;
        for (int j = 0; j < 3; j++) {
            uint32_t u = s->tri[3 * (size_t)f + j];
            if (u == v) continue;
            if (nb->mark[u] != nb->stamp) {
                if (nb->n == nb->cap && nbset_grow(nb) != 0) return -1;
                nb->mark[u] = nb->stamp;
                nb->slot[u] = (uint32_t)nb->n;
                nb->v[nb->n] = u;
                nb->cnt[nb->n++] = 0;
            }
            nb->cnt[nb->slot[u]]++;
            nb->face[nb->slot[u]] = f;
        }
    }
    fl->n = kept;
    return 0;
}

static int in_set(const nbset *nb, uint32_t u)
{
    return nb->mark[u] == nb->stamp;
}

static int face_has(const simp *s, uint32_t f, uint32_t v)
{
    const uint32_t *t = s->tri + 3 * (size_t)f;
    return t[0] == v || t[1] == v || t[2] == v;
}

static int list_append(id_list *l, uint32_t id)
{
    if (l->n == l->cap) {
        uint32_t cap = l->cap ? 2 * l->cap : 8;
        uint32_t *a = realloc(l->id, cap * sizeof *a);
        if (!a) return -1;
        l->id = a;
        l->cap = cap;
    }
    l->id[l->n++] = id;
    return 0;
}

/* Checks the faces of `from` that survive the collapse of (from, other) into x: returns 1
 * when a normal would turn too far. Lowers *q_new to the worst new quality and *q_old to
 * the worst present quality over all of from's faces, the dying ones included. */
static int check_faces(const simp *s, uint32_t from, uint32_t other, const double *x, double *q_new, double *q_old)
{
    const id_list *fl = &s->vf[from];
    for (uint32_t k = 0; k < fl->n; k++) {
        uint32_t f = fl->id[k];
        const uint32_t *t = s->tri + 3 * (size_t)f;
        const double *p[3], *q[3];
        for (int j = 0; j < 3; j++) p[j] = q[j] = s->pos + 3 * (size_t)t[j];
        double n_old[3], n_new[3];
        tri_normal(p[0], p[1], p[2], n_old);
        *q_old = fmin(*q_old, tri_quality(p[0], p[1], p[2], n_old));
        if (face_has(s, f, other)) continue;
        for (int j = 0; j < 3; j++)
            if (t[j] == from) q[j] = x;
        tri_normal(q[0], q[1], q[2], n_new);
        double len_old = sqrt(dot3(n_old, n_old)), len_new = sqrt(dot3(n_new, n_new));
        if (len_old > 0 && !(dot3(n_old, n_new) > s->cos_turn * len_old * len_new)) return 1;
        *q_new = fmin(*q_new, tri_quality(q[0], q[1], q[2], n_new));
    }
    return 0;
}

/* 1 when an edge from x to a neighbour in set N (other than a and b) would be longer than
 * edge_per_metre times the distance from x to the view point. */
static int too_long(const simp *s, const double *x, const nbset *N, uint32_t a, uint32_t b)
{
    double dv[3];
    for (int j = 0; j < 3; j++) dv[j] = x[j] - (s->o->view_point[j] - s->centre[j]);
    double limit = s->o->edge_per_metre * sqrt(dot3(dv, dv));
    for (size_t k = 0; k < N->n; k++) {
        uint32_t v = N->v[k];
        if (v == a || v == b) continue;
        double e[3];
        for (int j = 0; j < 3; j++) e[j] = s->pos[3 * (size_t)v + j] - x[j];
        if (dot3(e, e) > limit * limit) return 1;
    }
    return 0;
}

/* The topology of collapsing edge e = (a, b), with a's and b's neighbours gathered into
 * s->nb[0] and s->nb[1]: returns 1 allowed (*merged: the merged vertex's neighbour count),
 * 0 refused, -1 no memory. */
static int topology_allows(simp *s, uint32_t e, uint32_t a, uint32_t b, size_t *merged)
{
    nbset *A = &s->nb[0], *B = &s->nb[1];
    if (gather(s, a, A) != 0 || gather(s, b, B) != 0) return -1;
    if (!in_set(A, b)) { /* cannot happen while edges and faces agree; never retry it */
        s->edges[e].pos = DEAD;
        return 0;
    }
    uint32_t shared = A->cnt[A->slot[b]];
    if (shared > 2) { /* a non-manifold edge stays as it is */
        s->st->rejected_topology++;
        return 0;
    }
    int bnd_a = 0, bnd_b = 0;
    for (size_t k = 0; k < A->n; k++) bnd_a |= A->cnt[k] == 1;
    for (size_t k = 0; k < B->n; k++) bnd_b |= B->cnt[k] == 1;
    size_t common = 0;
    for (size_t k = 0; k < B->n; k++) common += B->v[k] != a && in_set(A, B->v[k]);
    *merged = (A->n - 1) + (B->n - 1) - common;
    size_t faces_left = (size_t)s->vf[a].n + s->vf[b].n - 2 * (size_t)shared;
    /* Link condition (the common neighbours are exactly the tips of the shared faces), no
     * pinching of two boundaries through an interior edge, no tetrahedron or lone triangle. */
    if (common != shared || (shared == 2 && bnd_a && bnd_b) || *merged < 3 || faces_left == 0) {
        s->st->rejected_topology++;
        s->retry[a] = s->retry[b] = 1;
        return 0;
    }
    return 1;
}

/* The geometry of collapsing (a, b) into x (its placement, set here): no normal turns too far,
 * and the worst triangle around the edge does not get worse unless it stays above min_quality
 * (slivers from grazing scan cells may improve through collapses that do not make things
 * worse), and no edge grows past the size limit. Returns 1 allowed, 0 refused. */
static int geometry_allows(simp *s, uint32_t a, uint32_t b, double *x)
{
    const nbset *A = &s->nb[0], *B = &s->nb[1];
    double q_new = 1, q_old = 1;
    evaluate(s, a, b, x);
    if (check_faces(s, a, b, x, &q_new, &q_old) || check_faces(s, b, a, x, &q_new, &q_old)) {
        s->st->rejected_flip++;
        s->retry[a] = s->retry[b] = 1;
        return 0;
    }
    if (q_new < s->o->min_quality && q_new < q_old) {
        s->st->rejected_quality++;
        s->retry[a] = s->retry[b] = 1;
        return 0;
    }
    if (s->o->edge_per_metre > 0 && too_long(s, x, A, a, b) + too_long(s, x, B, a, b)) {
        s->st->rejected_size++;
        s->retry[a] = s->retry[b] = 1;
        return 0;
    }
    return 1;
}

/* Mean edge length bookkeeping: the edges around a and b become the edges around x. */
static void account_edges(simp *s, uint32_t a, uint32_t b, const double *x, size_t merged)
{
    const nbset *A = &s->nb[0], *B = &s->nb[1];
    const double *pa = s->pos + 3 * (size_t)a, *pb = s->pos + 3 * (size_t)b;
    double before = 0, after = 0;
    for (size_t k = 0; k < A->n; k++) {
        const double *pw = s->pos + 3 * (size_t)A->v[k];
        before += dist3(pa, pw);
        if (A->v[k] != b) after += dist3(x, pw);
    }
    for (size_t k = 0; k < B->n; k++) {
        if (B->v[k] == a) continue;
        const double *pw = s->pos + 3 * (size_t)B->v[k];
        before += dist3(pb, pw);
        if (!in_set(A, B->v[k])) after += dist3(x, pw);
    }
    s->edge_sum += after - before;
    s->edge_count = s->edge_count - (A->n + B->n - 1) + merged;
}

/* Faces on the edge (a, b) die, b's other faces move to a. 0, or -1 no memory. */
static int move_faces(simp *s, uint32_t a, uint32_t b)
{
    id_list *fa = &s->vf[a], *fb = &s->vf[b];
    uint32_t kept = 0;
    for (uint32_t k = 0; k < fa->n; k++) {
        uint32_t f = fa->id[k];
        if (face_has(s, f, b)) {
            s->face_dead[f] = 1;
            s->faces_alive--;
        } else {
            fa->id[kept++] = f;
        }
    }
    fa->n = kept;
    for (uint32_t k = 0; k < fb->n; k++) {
        uint32_t f = fb->id[k];
        if (s->face_dead[f]) continue;
        uint32_t *t = s->tri + 3 * (size_t)f;
        for (int j = 0; j < 3; j++)
            if (t[j] == b) t[j] = a;
        if (list_append(fa, f) != 0) return -1;
    }
    return 0;
}

/* Edges: e = a-b dies, b-w dies where a-w exists (w a tip of a shared face), the others move
 * to a. 0, or -1 no memory. */
static int move_edges(simp *s, uint32_t e, uint32_t a, uint32_t b)
{
    const nbset *A = &s->nb[0];
    s->edges[e].pos = DEAD;
    id_list *ea = &s->ve[a], *eb = &s->ve[b];
    for (uint32_t k = 0; k < eb->n; k++) {
        uint32_t id = eb->id[k];
        edge *ed = &s->edges[id];
        if (ed->pos == DEAD) continue;
        uint32_t w = ed->a == b ? ed->b : ed->a;
        if (in_set(A, w)) {
            heap_remove(s, id, DEAD);
        } else {
            ed->a = w < a ? w : a;
            ed->b = w < a ? a : w;
            if (list_append(ea, id) != 0) return -1;
        }
    }
    return 0;
}

/* b is gone: its lists are freed, and a takes the place x and b's quadric and area. */
static void merge_vertex(simp *s, uint32_t a, uint32_t b, const double *x)
{
    id_list *fb = &s->vf[b], *eb = &s->ve[b];
    free(fb->id);
    free(eb->id);
    memset(fb, 0, sizeof *fb);
    memset(eb, 0, sizeof *eb);
    memcpy(s->pos + 3 * (size_t)a, x, 3 * sizeof *x);
    for (int i = 0; i < 10; i++) s->Q[10 * (size_t)a + i] += s->Q[10 * (size_t)b + i];
    s->w[a] += s->w[b];
    s->retry[a] = 0;
    s->st->collapses++;
}

/* New costs around a; edges refused earlier next to a get another chance, as their
 * neighbourhood just changed. Drops a's dead edges from its list. */
static void refresh_around(simp *s, uint32_t a)
{
    id_list *ea = &s->ve[a];
    uint32_t kept = 0;
    for (uint32_t k = 0; k < ea->n; k++) {
        uint32_t id = ea->id[k];
        if (s->edges[id].pos == DEAD) continue;
        ea->id[kept++] = id;
        heap_update(s, id);
        uint32_t u = s->edges[id].a == a ? s->edges[id].b : s->edges[id].a;
        if (!s->retry[u]) continue;
        s->retry[u] = 0;
        for (uint32_t j = 0; j < s->ve[u].n; j++) {
            uint32_t id2 = s->ve[u].id[j];
            if (s->edges[id2].pos == OUT) heap_update(s, id2);
        }
    }
    ea->n = kept;
}

/* Collapses edge e = (a, b) into a if the checks allow. Returns 1 done, 0 refused, -1 no memory. */
static int try_collapse(simp *s, uint32_t e)
{
    uint32_t a = s->edges[e].a, b = s->edges[e].b;
    size_t merged;
    double x[3];
    int ok = topology_allows(s, e, a, b, &merged);
    if (ok <= 0) return ok;
    if (!geometry_allows(s, a, b, x)) return 0;
    account_edges(s, a, b, x, merged);
    if (move_faces(s, a, b) != 0 || move_edges(s, e, a, b) != 0) return -1;
    merge_vertex(s, a, b, x);
    refresh_around(s, a);
    return 1;
}

/* ---- set-up and result ---- */

static int setup(simp *s, const rs_mesh *in)
{
    s->nv = in->nverts;
    s->nf = in->nfaces;
    size_t nv = s->nv ? s->nv : 1, nf = s->nf ? s->nf : 1;
    s->pos = malloc(3 * nv * sizeof *s->pos);
    s->Q = calloc(10 * nv, sizeof *s->Q);
    s->w = calloc(nv, sizeof *s->w);
    s->tri = malloc(3 * nf * sizeof *s->tri);
    s->face_dead = calloc(nf, 1);
    s->retry = calloc(nv, 1);
    s->vf = calloc(nv, sizeof *s->vf);
    s->ve = calloc(nv, sizeof *s->ve);
    for (int i = 0; i < 2; i++) {
        s->nb[i].mark = calloc(nv, sizeof(uint32_t));
        s->nb[i].slot = calloc(nv, sizeof(uint32_t));
        if (!s->nb[i].mark || !s->nb[i].slot) return -1;
    }
    if (!s->pos || !s->Q || !s->w || !s->tri || !s->face_dead || !s->retry || !s->vf || !s->ve) return -1;

    /* Recentre: quadrics of georeferenced coordinates would lose every digit to d^2. */
    double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    for (size_t v = 0; v < s->nv; v++)
        for (int j = 0; j < 3; j++) {
            double c = in->verts[3 * v + j];
            if (v == 0 || c < lo[j]) lo[j] = c;
            if (v == 0 || c > hi[j]) hi[j] = c;
        }
    for (int j = 0; j < 3; j++) s->centre[j] = 0.5 * (lo[j] + hi[j]);
    for (size_t v = 0; v < s->nv; v++)
        for (int j = 0; j < 3; j++) s->pos[3 * v + j] = (double)in->verts[3 * v + j] - s->centre[j];

    memcpy(s->tri, in->tris, 3 * s->nf * sizeof *s->tri);
    for (size_t f = 0; f < s->nf; f++) {
        const uint32_t *t = s->tri + 3 * f;
        if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || t[0] >= s->nv || t[1] >= s->nv || t[2] >= s->nv) {
            s->face_dead[f] = 1;
            continue;
        }
        s->faces_alive++;
        for (int j = 0; j < 3; j++) s->vf[t[j]].cap++;
    }
    for (size_t v = 0; v < s->nv; v++)
        if (s->vf[v].cap && !(s->vf[v].id = malloc(s->vf[v].cap * sizeof(uint32_t)))) return -1;
    for (size_t f = 0; f < s->nf; f++) {
        if (s->face_dead[f]) continue;
        const uint32_t *t = s->tri + 3 * f;
        double n[3];
        tri_normal(s->pos + 3 * (size_t)t[0], s->pos + 3 * (size_t)t[1], s->pos + 3 * (size_t)t[2], n);
        double len = sqrt(dot3(n, n));
        for (int j = 0; j < 3; j++) s->vf[t[j]].id[s->vf[t[j]].n++] = (uint32_t)f;
        if (!(len > 0)) continue;
        /* The face's plane, weighted by its area (GH section 6.2). */
        for (int j = 0; j < 3; j++) n[j] /= len;
        double d = -dot3(n, s->pos + 3 * (size_t)t[0]), area = 0.5 * len;
        for (int j = 0; j < 3; j++) {
            quadric_add_plane(s->Q + 10 * (size_t)t[j], n, d, area);
            s->w[t[j]] += area;
        }
    }
    /* Edges, and for boundary edges (one face) a plane through the edge, perpendicular to
     * its face, that keeps the boundary where it is (GH section 6.1). */
    size_t cap = 0;
    for (size_t a = 0; a < s->nv; a++) {
        if (gather(s, (uint32_t)a, &s->nb[0]) != 0) return -1;
        const nbset *A = &s->nb[0];
        for (size_t k = 0; k < A->n; k++) {
            uint32_t b = A->v[k];
            if (b < a) continue;
            if (s->nedges == cap) {
                cap = cap ? 2 * cap : 1024;
                edge *ne = realloc(s->edges, cap * sizeof *ne);
                if (!ne) return -1;
                s->edges = ne;
            }
            if (s->nedges >= UINT32_MAX - 2) return -1;
            uint32_t id = (uint32_t)s->nedges++;
            s->edges[id] = (edge){(uint32_t)a, b, OUT, 0};
            if (list_append(&s->ve[a], id) != 0 || list_append(&s->ve[b], id) != 0) return -1;
            const double *pa = s->pos + 3 * a, *pb = s->pos + 3 * (size_t)b;
            s->edge_sum += dist3(pa, pb);
            if (A->cnt[k] != 1) continue;
            const uint32_t *t = s->tri + 3 * (size_t)A->face[k];
            double n[3], e[3], p[3];
            tri_normal(s->pos + 3 * (size_t)t[0], s->pos + 3 * (size_t)t[1], s->pos + 3 * (size_t)t[2], n);
            sub3(pb, pa, e);
            cross3(e, n, p);
            double len = sqrt(dot3(p, p));
            if (!(len > 0)) continue;
            for (int j = 0; j < 3; j++) p[j] /= len;
            double d = -dot3(p, pa), w = s->o->boundary_weight * dot3(e, e);
            quadric_add_plane(s->Q + 10 * a, p, d, w);
            quadric_add_plane(s->Q + 10 * (size_t)b, p, d, w);
        }
    }
    s->edge_count = s->nedges;
    s->heap = malloc((s->nedges ? s->nedges : 1) * sizeof *s->heap);
    if (!s->heap) return -1;
    for (size_t id = 0; id < s->nedges; id++) {
        double x[3];
        s->edges[id].cost = evaluate(s, s->edges[id].a, s->edges[id].b, x);
        heap_place(s, s->hn++, entry_of(s, (uint32_t)id));
    }
    for (size_t i = s->hn / 2; i-- > 0;) sift_down(s, i);
    return 0;
}

static int target_reached(const simp *s)
{
    const rs_simplify_opts *o = s->o;
    if (o->target_faces && s->faces_alive <= o->target_faces) return 1;
    if (o->target_edge_m > 0 && s->edge_count && s->edge_sum / (double)s->edge_count >= o->target_edge_m) return 1;
    return 0;
}

static void simp_free(simp *s)
{
    free(s->pos);
    free(s->Q);
    free(s->w);
    free(s->tri);
    free(s->face_dead);
    free(s->retry);
    for (size_t v = 0; v < s->nv; v++) {
        if (s->vf) free(s->vf[v].id);
        if (s->ve) free(s->ve[v].id);
    }
    free(s->vf);
    free(s->ve);
    free(s->edges);
    free(s->heap);
    for (int i = 0; i < 2; i++) {
        free(s->nb[i].mark);
        free(s->nb[i].slot);
        free(s->nb[i].v);
        free(s->nb[i].cnt);
        free(s->nb[i].face);
    }
}

/* The surviving faces and the vertices they use, both in their original order. */
static rs_mesh *result(const simp *s)
{
    uint32_t *remap = malloc((s->nv ? s->nv : 1) * sizeof *remap);
    if (!remap) return NULL;
    for (size_t v = 0; v < s->nv; v++) remap[v] = UINT32_MAX;
    for (size_t f = 0; f < s->nf; f++)
        if (!s->face_dead[f])
            for (int j = 0; j < 3; j++) remap[s->tri[3 * f + j]] = 0;
    size_t nv = 0;
    for (size_t v = 0; v < s->nv; v++)
        if (remap[v] == 0) remap[v] = (uint32_t)nv++;
    rs_mesh *m = rs_mesh_new(nv, s->faces_alive);
    if (!m) {
        free(remap);
        return NULL;
    }
    for (size_t v = 0; v < s->nv; v++)
        if (remap[v] != UINT32_MAX)
            for (int j = 0; j < 3; j++) m->verts[3 * (size_t)remap[v] + j] = (float)(s->pos[3 * v + j] + s->centre[j]);
    size_t k = 0;
    for (size_t f = 0; f < s->nf; f++)
        if (!s->face_dead[f]) {
            for (int j = 0; j < 3; j++) m->tris[3 * k + j] = remap[s->tri[3 * f + j]];
            k++;
        }
    free(remap);
    return m;
}

rs_mesh *rs_simplify_apply(const rs_mesh *in, const rs_simplify_opts *o, rs_simplify_stats *st, rs_err *err)
{
    rs_simplify_stats local;
    if (!st) st = &local;
    memset(st, 0, sizeof *st);
    if (in->nverts >= UINT32_MAX || in->nfaces >= UINT32_MAX / 2) {
        rs_err_set(err, RS_ERR_INPUT, NULL, 0, "mesh of %zu vertices and %zu faces; at most %u of each are supported",
                   in->nverts, in->nfaces, UINT32_MAX / 2 - 1);
        return NULL;
    }
    simp s;
    memset(&s, 0, sizeof s);
    s.o = o;
    s.st = st;
    s.cos_turn = cos(o->max_normal_turn_rad);
    rs_mesh *out = NULL;
    if (setup(&s, in) != 0) goto nomem;
    st->faces_in = in->nfaces;
    st->verts_in = in->nverts;
    st->mean_edge_in = s.edge_count ? s.edge_sum / (double)s.edge_count : 0;
    while (s.hn > 0 && !target_reached(&s)) {
        uint32_t e = s.heap[0].id;
        heap_remove(&s, e, OUT);
        if (try_collapse(&s, e) < 0) goto nomem;
    }
    out = result(&s);
    if (!out) goto nomem;
    st->faces_out = out->nfaces;
    st->verts_out = out->nverts;
    st->mean_edge_out = s.edge_count ? s.edge_sum / (double)s.edge_count : 0;
    simp_free(&s);
    return out;
nomem:
    rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory simplifying a mesh of %zu faces", in->nfaces);
    simp_free(&s);
    return NULL;
}
