/* test_mesh: rs_mesh life cycle, PLY conversion both ways (polygons split into fans, bad
 * indices and coordinates refused with the element named), face geometry and edge lengths. */
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/mesh.h"

/* A unit square as one quad plus a triangle above it, in ascii PLY. */
static const char *quad_ply =
    "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
    "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n"
    "4 0 1 2 3\n3 0 4 1\n";

static rs_mesh *mesh_from_text(const char *dir, const char *text, rs_err *err)
{
    const char *path = rs_test_path(dir, "m.ply");
    rs_test_write(path, text);
    return rs_mesh_read(path, NULL, err);
}

static void test_read_polygons(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("mesh");
    rs_err err = {0};
    rs_mesh *m = mesh_from_text(dir, quad_ply, &err);
    if (!m) fail_msg("%s", err.msg);
    assert_int_equal(m->nverts, 5);
    assert_int_equal(m->nfaces, 3); /* the quad becomes a fan of two */
    const uint32_t want[9] = {0, 1, 2, 0, 2, 3, 0, 4, 1};
    assert_memory_equal(m->tris, want, sizeof want);

    rs_v3 c, n;
    double area;
    rs_mesh_face(m, 0, &c, &n, &area);
    assert_float_equal(area, 0.5, 1e-12);
    assert_float_equal(n.z, 1.0, 1e-12); /* counter-clockwise seen from +z */
    assert_float_equal(c.x, 2.0 / 3.0, 1e-7);
    rs_mesh_face(m, 2, NULL, &n, &area);
    assert_float_equal(n.y, 1.0, 1e-12); /* (0,0,0) (0,0,1) (1,0,0): normal +y */
    assert_float_equal(rs_mesh_extent(m), sqrt(3.0), 1e-7);

    /* Distinct edges: 0-1 1-2 2-3 3-0 0-2 0-4 4-1 = 7, lengths 1 1 1 1 sqrt2 1 sqrt2. */
    size_t ne;
    double *len = rs_mesh_edge_lengths(m, &ne), sum = 0;
    assert_int_equal(ne, 7);
    for (size_t i = 0; i < ne; i++) sum += len[i];
    assert_float_equal(sum, 5 + 2 * sqrt(2.0), 1e-6);
    free(len);
    rs_mesh_free(m);
    rs_test_rmtree(dir);
}

static void test_round_trip(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("mesh");
    rs_mesh *m = rs_mesh_new(4, 2);
    const float v[12] = {0, 0, 0, 1.5f, 0, 0, 1.5f, 2.25f, -1, 1e-3f, 3, 7};
    const uint32_t t[6] = {0, 1, 2, 0, 2, 3};
    memcpy(m->verts, v, sizeof v);
    memcpy(m->tris, t, sizeof t);
    rs_ply *ply = rs_ply_new();
    rs_ply_element *fe = rs_mesh_to_ply(m, ply);
    assert_non_null(fe);
    assert_string_equal(fe->name, "face");
    assert_non_null(rs_ply_add_scalar(fe, "albedo_r", RS_PLY_FLOAT32, NULL)); /* callers add face properties */
    rs_err err = {0};
    const char *path = rs_test_path(dir, "rt.ply");
    assert_int_equal(rs_ply_write(ply, path, 1, &err), 0);
    rs_ply_free(ply);
    rs_ply *back_ply = NULL;
    rs_mesh *back = rs_mesh_read(path, &back_ply, &err);
    if (!back) fail_msg("%s", err.msg);
    assert_non_null(back_ply);
    assert_non_null(rs_ply_find_prop(rs_ply_find_element(back_ply, "face"), "albedo_r"));
    assert_int_equal(back->nverts, 4);
    assert_int_equal(back->nfaces, 2);
    assert_memory_equal(back->verts, v, sizeof v);
    assert_memory_equal(back->tris, t, sizeof t);
    rs_ply_free(back_ply);
    rs_mesh_free(back);
    rs_mesh_free(m);
    rs_mesh_free(NULL);
    rs_test_rmtree(dir);
}

static void expect_bad(const char *dir, const char *text, const char *phrase)
{
    rs_err err = {0};
    rs_mesh *m = mesh_from_text(dir, text, &err);
    if (m) fail_msg("accepted: expected an error with \"%s\"", phrase);
    assert_non_null(strstr(err.file, "m.ply"));
    if (!strstr(err.msg, phrase)) fail_msg("message \"%s\" lacks \"%s\"", err.msg, phrase);
    assert_int_equal(err.kind, RS_ERR_INPUT);
}

#define HEAD(nv, nf)                                                                                        \
    "ply\nformat ascii 1.0\nelement vertex " #nv "\nproperty float x\nproperty float y\nproperty float z\n" \
    "element face " #nf "\nproperty list uchar int vertex_indices\nend_header\n"

static void test_errors(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("mesh");
    expect_bad(dir, HEAD(3, 1) "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
               "face 0: vertex index 3; expected an integer from 0 to 2");
    expect_bad(dir, HEAD(3, 2) "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 -1 2\n", "face 1: vertex index -1");
    expect_bad(dir, HEAD(3, 1) "0 0 0\n1 0 0\n0 1 0\n2 0 1\n", "face 0 has 2 vertices; expected 3 or more");
    expect_bad(dir, HEAD(3, 1) "0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n", "vertex 1: coordinates");
    expect_bad(dir,
               "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\n"
               "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1e300 0\n3 0 1 2\n",
               "within the float range");
    expect_bad(dir,
               "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
               "end_header\n0 0 0\n",
               "no face element");
    expect_bad(dir, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n",
               "no vertex element with scalar x, y and z");
    rs_test_rmtree(dir);
}

/* vertex_index (the other common spelling) is accepted. */
static void test_vertex_index(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("mesh");
    rs_err err = {0};
    rs_mesh *m = mesh_from_text(dir,
                                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                "property float z\nelement face 1\nproperty list uchar uint vertex_index\nend_header\n"
                                "0 0 0\n1 0 0\n0 1 0\n3 2 1 0\n",
                                &err);
    if (!m) fail_msg("%s", err.msg);
    assert_int_equal(m->tris[0], 2);
    rs_v3 n;
    rs_mesh_face(m, 0, NULL, &n, NULL);
    assert_float_equal(n.z, -1.0, 1e-12);
    rs_mesh_free(m);
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_read_polygons), cmocka_unit_test(test_round_trip),
             cmocka_unit_test(test_errors), cmocka_unit_test(test_vertex_index))
