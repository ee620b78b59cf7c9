/* test_closing: the planar closing (meshing/closing.h). A wall with the scan shadow a box casts
 * on it gets that hole filled (every point of it covered, the area within half a cell along its
 * perimeter, nothing outside the wall's plane or the hole), while an opening the scanner saw
 * through stays open; a slab seen from below gets a top face (whose proxy faces up) and edges, one
 * whose top was scanned does not; in an open courtyard a pillar's shadow on the tall wall is closed and nothing is added
 * above the low walls' tops. */
#include "tests/testutil.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/scene.h"
#include "meshing/closing.h"
#include "tests/meshgen.h"

typedef struct {
    double lo[3], hi[3];
} box3;

static int in_box(const box3 *b, rs_v3 p)
{
    return p.x > b->lo[0] && p.x < b->hi[0] && p.y > b->lo[1] && p.y < b->hi[1] && p.z > b->lo[2] && p.z < b->hi[2];
}

/* Drops the faces whose centroid lies in one of the boxes (the scan's holes). */
static void cut(rs_mesh *m, const box3 *cuts, int ncuts)
{
    size_t keep = 0;
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(m, f, &c, &n, &a);
        int drop = 0;
        for (int k = 0; k < ncuts; k++) drop |= in_box(&cuts[k], c);
        if (drop) continue;
        memmove(m->tris + 3 * keep, m->tris + 3 * f, 3 * sizeof *m->tris);
        keep++;
    }
    m->nfaces = keep;
}

typedef struct {
    rs_mesh *occ;
    uint32_t *proxy;
    uint8_t *source;
    rs_closing_stats st;
} closed;

static closed run_closing(const rs_mesh *m, const rs_v3 *views, size_t nviews)
{
    rs_err err;
    rs_scene *sc = rs_scene_new(m, &err);
    assert_non_null(sc);
    rs_closing_opts o = RS_CLOSING_OPTS_DEFAULT;
    closed c;
    assert_int_equal(rs_closing_build(m, sc, views, nviews, &o, &c.occ, &c.proxy, &c.source, &c.st, &err), 0);
    if (c.occ)
        for (size_t f = 0; f < c.occ->nfaces; f++) assert_true(c.proxy[f] < m->nfaces);
    rs_scene_free(sc);
    return c;
}

static void closed_free(closed *c)
{
    rs_mesh_free(c->occ);
    free(c->proxy);
    free(c->source);
}

static double area_of(const closed *c, int source)
{
    double sum = 0;
    for (size_t f = 0; c->occ && f < c->occ->nfaces; f++) {
        rs_v3 cen, n;
        double a;
        rs_mesh_face(c->occ, f, &cen, &n, &a);
        if (c->source[f] == source) sum += a;
    }
    return sum;
}

/* 1 when the ray from o along d hits an occluder face. */
static int covered(const rs_scene *occ, rs_v3 o, rs_v3 d)
{
    rs_ray r = {o, d, 0, 100};
    rs_hit h;
    rs_scene_intersect(occ, &r, &h, 1);
    return h.face != RS_NO_HIT;
}

/* A 10 x 4 m wall in y = 5 facing the scanner at y = 0; a box between them casts its shadow over
 * the hole x 4..5, z 1..2.5 (1.5 m^2); the hole x 7..8 is an opening the scanner sees through. */
static void test_wall_shadow_filled(void **state)
{
    (void)state;
    rs_meshgen g = rs_meshgen_new(20000, 20000);
    rs_meshgen_rect(&g, rs_v3_make(0, 5, 0), rs_v3_make(10, 0, 0), rs_v3_make(0, 0, 4), 40, 16); /* faces -y */
    rs_meshgen_box(&g, rs_v3_make(4.2, 2, 1.3), rs_v3_make(4.8, 2.6, 2.2), 2, 0);
    rs_mesh *m = rs_meshgen_done(&g);
    box3 holes[2] = {{{4, 4.9, 1}, {5, 5.1, 2.5}}, {{7, 4.9, 1}, {8, 5.1, 2.5}}};
    cut(m, holes, 2);
    rs_v3 view = rs_v3_make(4.5, 0, 1.75);
    closed c = run_closing(m, &view, 1);
    assert_non_null(c.occ);
    double cell = 0.1, tol = 0.5 * cell * 5.0; /* half a cell along the hole's 5 m perimeter */
    double ha = area_of(&c, RS_CLOSE_HOLE);
    print_message("hole: %.3f m^2 filled (1.5 expected, +-%.2f), %zu faces, %zu regions\n", ha, tol, c.occ->nfaces,
                  c.st.regions);
    assert_true(fabs(ha - 1.5) <= tol);
    for (size_t v = 0; v < c.occ->nverts; v++) {
        rs_v3 p = rs_mesh_vert(c.occ, (uint32_t)v);
        assert_true(fabs(p.y - 5) < 1e-4);
        assert_true(p.x >= 4 - cell - 1e-4 && p.x <= 5 + cell + 1e-4);
        assert_true(p.z >= 1 - cell - 1e-4 && p.z <= 2.5 + cell + 1e-4);
    }
    for (size_t f = 0; f < c.occ->nfaces; f++) {
        assert_int_equal(c.source[f], RS_CLOSE_HOLE);
        rs_v3 cen, n;
        double a;
        rs_mesh_face(c.occ, f, &cen, &n, &a);
        assert_true(n.y < -0.999); /* facing the side the scanner saw */
    }
    rs_err err;
    rs_scene *os = rs_scene_new(c.occ, &err);
    assert_non_null(os);
    for (double x = 4 + cell; x <= 5 - cell + 1e-9; x += 0.05)
        for (double z = 1 + cell; z <= 2.5 - cell + 1e-9; z += 0.05)
            assert_true(covered(os, rs_v3_make(x, 4, z), rs_v3_make(0, 1, 0)));
    assert_false(covered(os, rs_v3_make(7.5, 4, 1.75), rs_v3_make(0, 1, 0))); /* the opening */
    rs_scene_free(os);
    closed_free(&c);
    rs_mesh_free(m);
}

/* A 4 x 3 m slab, underside at z = 3 facing down, over a ground, scanned from below; then the
 * same with its top scanned. */
static void test_slab_top(void **state)
{
    (void)state;
    for (int with_top = 0; with_top < 2; with_top++) {
        rs_meshgen g = rs_meshgen_new(20000, 20000);
        rs_meshgen_rect(&g, rs_v3_make(-5, -5, 0), rs_v3_make(10, 0, 0), rs_v3_make(0, 10, 0), 20, 20);
        rs_meshgen_rect(&g, rs_v3_make(-2, -1.5, 3), rs_v3_make(0, 3, 0), rs_v3_make(4, 0, 0), 12, 16);
        if (with_top) rs_meshgen_rect(&g, rs_v3_make(-2, -1.5, 3.2), rs_v3_make(4, 0, 0), rs_v3_make(0, 3, 0), 16, 12);
        rs_mesh *m = rs_meshgen_done(&g);
        rs_v3 views[2] = {rs_v3_make(3, -4, 1.5), rs_v3_make(0, 0, 1.5)};
        closed c = run_closing(m, views, 2);
        double top = 0, edge = 0;
        for (size_t f = 0; c.occ && f < c.occ->nfaces; f++) {
            rs_v3 cen, n;
            double a;
            rs_mesh_face(c.occ, f, &cen, &n, &a);
            if (c.source[f] != RS_CLOSE_SLAB) continue;
            if (n.z > 0.999) {
                assert_true(fabs(cen.z - 3.2) < 1e-4);
                /* its proxy faces up (the ground), not the underside's dark radiance */
                rs_v3 pc, pn;
                double pa;
                rs_mesh_face(m, c.proxy[f], &pc, &pn, &pa);
                assert_true(pn.z > 0.9 && fabs(pc.z) < 1e-6);
                top += a;
            } else {
                assert_true(fabs(n.z) < 1e-6);
                assert_true(cen.z > 3 && cen.z < 3.2);
                /* facing out of the slab */
                assert_true(fabs(cen.x) > 1.9 || fabs(cen.y) > 1.4);
                assert_true(n.x * cen.x + n.y * cen.y > 0);
                edge += a;
            }
        }
        print_message("slab (top scanned %d): top %.3f m^2, edges %.3f m^2, %zu slabs\n", with_top, top, edge,
                      c.st.slabs);
        if (with_top) {
            assert_int_equal(c.st.slabs, 0);
            assert_true(top == 0 && edge == 0);
        } else {
            assert_int_equal(c.st.slabs, 1);
            assert_true(fabs(top - 12) <= 0.5 * 0.1 * 14);
            assert_true(fabs(edge - 14 * 0.2) <= 0.1 * 0.2 * 8);
        }
        closed_free(&c);
        rs_mesh_free(m);
    }
}

/* A 20 x 20 m courtyard: the north wall 8 m high, the others 4 m, a 1 x 0.5 m pillar 8 m high
 * 2 m in front of the north wall, whose shadow splits that wall's scan (x 9.5..10.5). */
static void test_courtyard_sky_open(void **state)
{
    (void)state;
    rs_meshgen g = rs_meshgen_new(60000, 60000);
    rs_meshgen_rect(&g, rs_v3_make(0, 0, 0), rs_v3_make(20, 0, 0), rs_v3_make(0, 20, 0), 40, 40);
    rs_meshgen_rect(&g, rs_v3_make(0, 20, 0), rs_v3_make(20, 0, 0), rs_v3_make(0, 0, 8), 80, 32); /* north */
    rs_meshgen_rect(&g, rs_v3_make(0, 0, 0), rs_v3_make(0, 0, 4), rs_v3_make(20, 0, 0), 16, 40);  /* south */
    rs_meshgen_rect(&g, rs_v3_make(0, 0, 0), rs_v3_make(0, 20, 0), rs_v3_make(0, 0, 4), 40, 16);  /* west */
    rs_meshgen_rect(&g, rs_v3_make(20, 0, 0), rs_v3_make(0, 0, 4), rs_v3_make(0, 20, 0), 16, 40); /* east */
    rs_meshgen_box(&g, rs_v3_make(9.5, 17.5, 0), rs_v3_make(10.5, 18, 8), 4, 0);
    rs_mesh *m = rs_meshgen_done(&g);
    box3 shadow = {{9.5, 19.9, -1}, {10.5, 20.1, 9}};
    cut(m, &shadow, 1);
    rs_v3 view = rs_v3_make(10, 10, 1.5);
    closed c = run_closing(m, &view, 1);
    assert_non_null(c.occ);
    double in_shadow = 0;
    for (size_t f = 0; f < c.occ->nfaces; f++) {
        rs_v3 cen, n;
        double a;
        rs_mesh_face(c.occ, f, &cen, &n, &a);
        for (int k = 0; k < 3; k++) {
            rs_v3 p = rs_mesh_vert(c.occ, c.occ->tris[3 * f + k]);
            assert_true(p.z <= 8 + 1e-4);
            if (p.z > 4 + 1e-4) assert_true(fabs(p.y - 20) < 1e-4 && p.x > 9.4 - 1e-4 && p.x < 10.6 + 1e-4);
        }
        if (fabs(cen.y - 20) < 1e-4) in_shadow += a;
    }
    print_message("courtyard: %.2f m^2 closed in the pillar's shadow (8 expected), %zu faces\n", in_shadow,
                  c.occ->nfaces);
    assert_true(fabs(in_shadow - 8) <= 0.5 * 0.1 * 18 + 0.1 * 8);
    closed_free(&c);
    rs_mesh_free(m);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_wall_shadow_filled), cmocka_unit_test(test_slab_top),
             cmocka_unit_test(test_courtyard_sky_open))
