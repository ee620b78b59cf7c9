/* refine: red-green refinement of long edges (see refine.h). */
#include "meshing/refine.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define DEFAULT_MAX_FACES 50000000u
/* A target never shorter than this (m): a view point on the surface would ask for zero. */
#define MIN_EDGE_M 1e-3
/* Each pass halves the longest edge: 64 passes cover any float model. */
#define MAX_PASSES 64

typedef struct {
    uint64_t key;  /* smaller vertex << 32 | larger */
    uint32_t slot; /* 3 f + k: edge k of face f runs from corner k to corner k + 1 */
} edge_ref;

static int cmp_edge(const void *a, const void *b)
{
    const edge_ref *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return x->slot < y->slot ? -1 : x->slot > y->slot;
}

static double target_len(const rs_refine_opts *o, rs_v3 mid)
{
    double t = o->edge_m;
    if (o->edge_per_metre > 0) {
        double d = rs_v3_len(rs_v3_sub(mid, rs_v3_make(o->view_point[0], o->view_point[1], o->view_point[2])));
        if (o->edge_per_metre * d > t) t = o->edge_per_metre * d;
    }
    return t > MIN_EDGE_M ? t : MIN_EDGE_M;
}

/* The midpoint vertex of each face edge that must split (slot -> vertex index), UINT32_MAX
 * where it stays; new midpoints are numbered from *nverts on, their positions in *mids.
 * Returns the number of edges split, or -1 when out of memory. */
static long mark_edges(const rs_mesh *m, const rs_refine_opts *o, uint32_t *mid_of_slot, float **mids, size_t *nmids)
{
    size_t ns = 3 * m->nfaces;
    edge_ref *e = malloc((ns ? ns : 1) * sizeof *e);
    if (!e) return -1;
    for (size_t s = 0; s < ns; s++) {
        uint32_t a = m->tris[s], b = m->tris[s - s % 3 + (s % 3 + 1) % 3];
        e[s].key = a < b ? (uint64_t)a << 32 | b : (uint64_t)b << 32 | a;
        e[s].slot = (uint32_t)s;
    }
    qsort(e, ns, sizeof *e, cmp_edge);
    size_t cap = 0;
    *nmids = 0;
    *mids = NULL;
    long split = 0;
    for (size_t i = 0; i < ns;) {
        size_t j = i;
        while (j < ns && e[j].key == e[i].key) j++;
        uint32_t a = (uint32_t)(e[i].key >> 32), b = (uint32_t)e[i].key;
        rs_v3 pa = rs_mesh_vert(m, a), pb = rs_mesh_vert(m, b);
        rs_v3 mid = rs_v3_scale(rs_v3_add(pa, pb), 0.5);
        uint32_t v = UINT32_MAX;
        if (rs_v3_len(rs_v3_sub(pb, pa)) > target_len(o, mid)) {
            if (*nmids == cap) {
                cap = cap ? 2 * cap : 1024;
                float *grown = realloc(*mids, 3 * cap * sizeof *grown);
                if (!grown) {
                    free(e);
                    return -1;
                }
                *mids = grown;
            }
            /* The float mean of the two corners, the same from either face. */
            for (int c = 0; c < 3; c++)
                (*mids)[3 * *nmids + c] = 0.5f * (m->verts[3 * (size_t)a + c] + m->verts[3 * (size_t)b + c]);
            v = (uint32_t)(m->nverts + (*nmids)++);
            split++;
        }
        for (size_t k = i; k < j; k++) mid_of_slot[e[k].slot] = v;
        i = j;
    }
    free(e);
    return split;
}

static double dist2(const rs_mesh *m, const float *mids, uint32_t a, uint32_t b)
{
    const float *pa = a < m->nverts ? m->verts + 3 * (size_t)a : mids + 3 * (size_t)(a - m->nverts);
    const float *pb = b < m->nverts ? m->verts + 3 * (size_t)b : mids + 3 * (size_t)(b - m->nverts);
    double d = 0;
    for (int c = 0; c < 3; c++) d += ((double)pa[c] - pb[c]) * ((double)pa[c] - pb[c]);
    return d;
}

#define PUT(x, y, z) (out[0] = (x), out[1] = (y), out[2] = (z), out += 3)

/* Writes face t's pieces (corners v, midpoints mv of edges k = v[k] v[k + 1]) to out; returns the
 * advanced pointer. */
static uint32_t *split_face(const rs_mesh *m, const float *mids, const uint32_t *t, const uint32_t *mt, uint32_t *out)
{
    int n = (mt[0] != UINT32_MAX) + (mt[1] != UINT32_MAX) + (mt[2] != UINT32_MAX);
    if (n == 0) return PUT(t[0], t[1], t[2]), out;
    if (n == 3) {
        PUT(t[0], mt[0], mt[2]);
        PUT(mt[0], t[1], mt[1]);
        PUT(mt[2], mt[1], t[2]);
        return PUT(mt[0], mt[1], mt[2]), out;
    }
    /* Turn the corners so that edge 0 splits and, with two, edge 2 stays. */
    int r = 0;
    for (; r < 3; r++) {
        int s0 = mt[r] != UINT32_MAX, s2 = mt[(r + 2) % 3] != UINT32_MAX;
        if (s0 && (n == 1 || !s2)) break;
    }
    uint32_t a = t[r], b = t[(r + 1) % 3], c = t[(r + 2) % 3], m0 = mt[r], m1 = mt[(r + 1) % 3];
    if (n == 1) {
        PUT(a, m0, c);
        return PUT(m0, b, c), out;
    }
    PUT(m0, b, m1);
    /* The quad a m0 m1 c, cut along its shorter diagonal. */
    if (dist2(m, mids, a, m1) <= dist2(m, mids, m0, c)) {
        PUT(a, m0, m1);
        return PUT(a, m1, c), out;
    }
    PUT(a, m0, c);
    return PUT(m0, m1, c), out;
}

/* One pass: a new mesh with every edge that misses the target split once, or NULL (err set);
 * *split = 0 when nothing needed splitting (the result is then a copy). */
static rs_mesh *refine_pass(const rs_mesh *m, const rs_refine_opts *o, size_t max_faces, long *split, rs_err *err)
{
    size_t ns = 3 * m->nfaces, nmids = 0;
    uint32_t *mid_of_slot = malloc((ns ? ns : 1) * sizeof *mid_of_slot);
    float *mids = NULL;
    rs_mesh *out = NULL;
    *split = mid_of_slot ? mark_edges(m, o, mid_of_slot, &mids, &nmids) : -1;
    if (*split < 0) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory refining %zu faces", m->nfaces);
        goto out;
    }
    size_t nf = m->nfaces;
    for (size_t s = 0; s < ns; s++) nf += mid_of_slot[s] != UINT32_MAX;
    if (nf > max_faces || m->nverts + nmids >= UINT32_MAX) {
        rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                   "refining the mesh to edges of at most %g m (plus %g per metre of distance) would pass %zu faces; "
                   "expected a longer edge target or a finer input mesh",
                   o->edge_m, o->edge_per_metre, max_faces);
        goto out;
    }
    out = rs_mesh_new(m->nverts + nmids, nf);
    if (!out) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory refining to %zu faces", nf);
        goto out;
    }
    memcpy(out->verts, m->verts, 3 * m->nverts * sizeof *out->verts);
    if (nmids) memcpy(out->verts + 3 * m->nverts, mids, 3 * nmids * sizeof *mids);
    uint32_t *w = out->tris;
    for (size_t f = 0; f < m->nfaces; f++) w = split_face(m, mids, m->tris + 3 * f, mid_of_slot + 3 * f, w);
out:
    free(mid_of_slot);
    free(mids);
    return out;
}

rs_mesh *rs_mesh_refine(const rs_mesh *m, const rs_refine_opts *o, rs_refine_stats *stats, rs_err *err)
{
    rs_refine_stats st = {m->nfaces, m->nfaces, 0, 0};
    size_t max_faces = o->max_faces ? o->max_faces : DEFAULT_MAX_FACES;
    rs_mesh *cur = rs_mesh_new(m->nverts, m->nfaces);
    if (!cur) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        return NULL;
    }
    memcpy(cur->verts, m->verts, 3 * m->nverts * sizeof *cur->verts);
    memcpy(cur->tris, m->tris, 3 * m->nfaces * sizeof *cur->tris);
    for (int pass = 0; pass < MAX_PASSES; pass++) {
        long split = 0;
        rs_mesh *next = refine_pass(cur, o, max_faces, &split, err);
        if (!next) {
            rs_mesh_free(cur);
            return NULL;
        }
        rs_mesh_free(cur);
        cur = next;
        if (split == 0) break;
        st.passes++;
        st.edges_split += (size_t)split;
    }
    st.faces_out = cur->nfaces;
    if (stats) *stats = st;
    return cur;
}
