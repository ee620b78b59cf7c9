/* test_refine: red-green refinement of a closed box with one long thin side (a slab 20 m x
 * 0.3 m x 4 m, 12 triangles): every edge meets its target, the surface stays closed and
 * consistently wound (no T-junction), and its area and shape do not change; a target that grows
 * with the distance gives longer edges far away; a target past the face cap is refused. */
#include "tests/testutil.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/mesh.h"
#include "meshing/refine.h"

static const float slab_hi[3] = {20.0f, 0.3f, 4.0f};

/* The slab [0, hi], 8 shared corners, wound counter-clockwise from outside. */
static rs_mesh *make_slab(void)
{
    rs_mesh *m = rs_mesh_new(8, 12);
    for (int v = 0; v < 8; v++)
        for (int c = 0; c < 3; c++) m->verts[3 * v + c] = (v >> c & 1) ? slab_hi[c] : 0.0f;
    /* Per side: the quad's corners, counter-clockwise from outside. */
    static const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                         {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (int q = 0; q < 6; q++) {
        const uint32_t *c = quads[q];
        uint32_t t[6] = {c[0], c[1], c[2], c[0], c[2], c[3]};
        memcpy(m->tris + 6 * q, t, sizeof t);
    }
    return m;
}

static double mesh_area(const rs_mesh *m)
{
    double a = 0;
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 c, n;
        double af;
        rs_mesh_face(m, f, &c, &n, &af);
        a += af;
    }
    return a;
}

typedef struct {
    uint32_t a, b;
} dir_edge;

static int cmp_dir_edge(const void *x, const void *y)
{
    const dir_edge *p = x, *q = y;
    uint32_t pa = p->a < p->b ? p->a : p->b, pb = p->a < p->b ? p->b : p->a;
    uint32_t qa = q->a < q->b ? q->a : q->b, qb = q->a < q->b ? q->b : q->a;
    if (pa != qa) return pa < qa ? -1 : 1;
    if (pb != qb) return pb < qb ? -1 : 1;
    return p->a < q->a ? -1 : p->a > q->a;
}

/* Closed and consistently wound: every undirected edge is used exactly twice, once each way. */
static void assert_closed(const rs_mesh *m)
{
    size_t ne = 3 * m->nfaces;
    dir_edge *e = malloc(ne * sizeof *e);
    for (size_t s = 0; s < ne; s++) e[s] = (dir_edge){m->tris[s], m->tris[s - s % 3 + (s % 3 + 1) % 3]};
    qsort(e, ne, sizeof *e, cmp_dir_edge);
    for (size_t s = 0; s < ne; s += 2) {
        /* The two uses of an edge sort next to each other; a third use would start the next pair
         * with the same edge. */
        assert_true(s + 1 < ne);
        assert_true(e[s].a == e[s + 1].b && e[s].b == e[s + 1].a);
        if (s + 2 < ne) {
            uint32_t lo = e[s].a < e[s].b ? e[s].a : e[s].b, hi = e[s].a ^ e[s].b ^ lo;
            uint32_t lo2 = e[s + 2].a < e[s + 2].b ? e[s + 2].a : e[s + 2].b, hi2 = e[s + 2].a ^ e[s + 2].b ^ lo2;
            assert_false(lo == lo2 && hi == hi2);
        }
    }
    free(e);
}

/* Each face lies in the side of the slab it came from, facing out. */
static void assert_on_sides(const rs_mesh *m)
{
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(m, f, &c, &n, &a);
        assert_true(a > 0);
        double cc[3] = {c.x, c.y, c.z}, nn[3] = {n.x, n.y, n.z};
        int axis = -1;
        for (int k = 0; k < 3; k++)
            if (fabs(nn[k]) > 0.999999) axis = k;
        assert_true(axis >= 0);
        double plane = nn[axis] > 0 ? slab_hi[axis] : 0.0;
        assert_true(fabs(cc[axis] - plane) < 1e-5);
    }
}

static double longest_edge(const rs_mesh *m, size_t f)
{
    double l = 0;
    for (int k = 0; k < 3; k++) {
        rs_v3 a = rs_mesh_vert(m, m->tris[3 * f + k]), b = rs_mesh_vert(m, m->tris[3 * f + (k + 1) % 3]);
        double d = rs_v3_len(rs_v3_sub(a, b));
        if (d > l) l = d;
    }
    return l;
}

static void test_constant_target(void **state)
{
    (void)state;
    rs_mesh *m = make_slab();
    double area0 = mesh_area(m);
    rs_refine_opts o = {.edge_m = 0.5};
    rs_refine_stats st;
    rs_err err = {0};
    rs_mesh *r = rs_mesh_refine(m, &o, &st, &err);
    assert_non_null(r);
    assert_int_equal(st.faces_in, 12);
    assert_int_equal(st.faces_out, r->nfaces);
    /* The 20 m x 4 m sides alone need at least 2 x 40 x 8 triangles each of 0.5 m edges. */
    assert_true(r->nfaces >= 2 * 2 * 40 * 8);
    for (size_t f = 0; f < r->nfaces; f++) assert_true(longest_edge(r, f) <= 0.5 + 1e-6);
    assert_closed(r);
    assert_on_sides(r);
    assert_true(fabs(mesh_area(r) - area0) < 1e-5 * area0);
    /* The original corners keep their indices and positions. */
    assert_memory_equal(r->verts, m->verts, 3 * m->nverts * sizeof *m->verts);
    rs_mesh_free(r);
    rs_mesh_free(m);
}

static void test_growing_target(void **state)
{
    (void)state;
    rs_mesh *m = make_slab();
    rs_refine_opts o = {.edge_per_metre = 0.05, .view_point = {0, -2, 1}};
    rs_err err = {0};
    rs_mesh *r = rs_mesh_refine(m, &o, NULL, &err);
    assert_non_null(r);
    assert_closed(r);
    assert_on_sides(r);
    double near = 0, far = 0;
    for (size_t f = 0; f < r->nfaces; f++) {
        for (int k = 0; k < 3; k++) {
            rs_v3 a = rs_mesh_vert(r, r->tris[3 * f + k]), b = rs_mesh_vert(r, r->tris[3 * f + (k + 1) % 3]);
            rs_v3 mid = rs_v3_scale(rs_v3_add(a, b), 0.5);
            double d = rs_v3_len(rs_v3_sub(mid, rs_v3_make(0, -2, 1)));
            double len = rs_v3_len(rs_v3_sub(a, b));
            assert_true(len <= fmax(0.05 * d, 1e-3) + 1e-6);
        }
        rs_v3 c, n;
        double a;
        rs_mesh_face(r, f, &c, &n, &a);
        if (c.x < 2 && longest_edge(r, f) > near) near = longest_edge(r, f);
        if (c.x > 18 && longest_edge(r, f) > far) far = longest_edge(r, f);
    }
    /* 2-4 m away the edges stay under 0.2 m; 18-20 m away they reach past 0.45 m. */
    assert_true(near < 0.2);
    assert_true(far > 0.45);
    rs_mesh_free(r);
    rs_mesh_free(m);
}

static void test_face_cap(void **state)
{
    (void)state;
    rs_mesh *m = make_slab();
    rs_refine_opts o = {.edge_m = 0.01, .max_faces = 100000};
    rs_err err = {0};
    assert_null(rs_mesh_refine(m, &o, NULL, &err));
    assert_int_equal(err.kind, RS_ERR_INPUT);
    assert_non_null(strstr(err.msg, "100000 faces"));
    rs_mesh_free(m);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_constant_target), cmocka_unit_test(test_growing_target),
             cmocka_unit_test(test_face_cap))
