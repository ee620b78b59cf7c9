/* test_mesh_stride: the grid mesher's stride (every k-th row and column when the facet budget
 * is far below a large grid's cells) and the coarse nadir cap that welds to that lattice. */
#include "tests/testutil.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "common/cloud.h"
#include "meshing/grid.h"
#include "common/mesh.h"
#include "meshing/nadir.h"

/* A full turn of cols azimuths by rows elevations from -80 to -40 degrees, every ray hitting
 * the floor z = 0 from a scanner at height h above the origin. */
static rs_cloud *floor_scan(double h, int cols, int rows)
{
    rs_cloud *c = calloc(1, sizeof *c);
    assert_non_null(c);
    c->npoints = (size_t)cols * rows;
    c->xyz = malloc(3 * c->npoints * sizeof *c->xyz);
    c->valid = malloc(c->npoints);
    c->nscans = 1;
    c->scans = calloc(1, sizeof *c->scans);
    assert_true(c->xyz && c->valid && c->scans);
    c->scans[0].cols = cols;
    c->scans[0].rows = rows;
    c->scans[0].position[2] = h;
    for (int col = 0; col < cols; col++)
        for (int row = 0; row < rows; row++) {
            double az = 2 * M_PI * col / cols, el = (-80 + 40.0 * row / (rows - 1)) * M_PI / 180;
            double d[3] = {cos(el) * cos(az), cos(el) * sin(az), sin(el)}, t = -h / d[2];
            size_t i = (size_t)col * rows + row;
            c->xyz[3 * i] = t * d[0];
            c->xyz[3 * i + 1] = t * d[1];
            c->xyz[3 * i + 2] = h + t * d[2];
            c->valid[i] = 1;
        }
    return c;
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

/* Edges used by exactly one face. */
static size_t boundary_edges(const rs_mesh *m)
{
    uint64_t *e = malloc(3 * m->nfaces * sizeof *e);
    assert_non_null(e);
    for (size_t f = 0; f < m->nfaces; f++)
        for (int j = 0; j < 3; j++) {
            uint64_t a = m->tris[3 * f + j], b = m->tris[3 * f + (j + 1) % 3];
            e[3 * f + j] = a < b ? a << 32 | b : b << 32 | a;
        }
    qsort(e, 3 * m->nfaces, sizeof *e, cmp_u64);
    size_t n = 0;
    for (size_t i = 0; i < 3 * m->nfaces;) {
        size_t j = i;
        while (j < 3 * m->nfaces && e[j] == e[i]) j++;
        n += j - i == 1;
        i = j;
    }
    free(e);
    return n;
}

static double area(const rs_mesh *m)
{
    double a = 0;
    for (size_t f = 0; f < m->nfaces; f++) {
        double fa;
        rs_mesh_face(m, f, NULL, NULL, &fa);
        a += fa;
    }
    return a;
}

/* Small grids stay at stride 1 whatever the budget; a 2000 x 1000 grid (4e6 triangles) at a
 * 10000-facet budget goes to stride 2 (RS_GRID_MIN_TRIANGLES keeps 1e6 of them), uses only
 * the lattice's points and covers the same floor; the coarse cap welds to its rim. */
static void test_stride_and_coarse_cap(void **state)
{
    (void)state;
    rs_grid_opts go = {0.05, 85 * M_PI / 180, 2.5, 10000, 0};
    rs_grid_stats st;
    rs_err err = {0};
    rs_cloud *small = floor_scan(2, 720, 360);
    rs_mesh *m = rs_grid_triangulate(small, &go, &st, &err);
    assert_non_null(m);
    assert_int_equal(st.stride, 1);
    assert_int_equal(m->nfaces, 2 * 720 * 359);
    rs_mesh_free(m);
    rs_cloud_free(small);

    enum { COLS = 2000, ROWS = 1000 };
    rs_cloud *c = floor_scan(2, COLS, ROWS);
    m = rs_grid_triangulate(c, &go, &st, &err);
    if (!m) fail_msg("%s", err.msg);
    assert_int_equal(st.stride, 2);
    /* Columns 0, 2, ..., 1998 and 1999 (then the wrap to 0); rows 0, 2, ..., 998 and 999. */
    int ncl = COLS / 2 + 1, nrl = ROWS / 2 + 1;
    assert_int_equal(st.cells, (size_t)ncl * (nrl - 1));
    assert_int_equal(m->nfaces, 2 * st.cells);
    assert_int_equal(m->nverts, (size_t)ncl * nrl);
    assert_int_equal(boundary_edges(m), 2 * (size_t)ncl); /* the top and bottom rings */
    /* The annulus between the rays at -80 and -40 degrees, minus what its chords cut off. */
    double r0 = 2 / tan(80 * M_PI / 180), r1 = 2 / tan(40 * M_PI / 180);
    double annulus = M_PI * (r1 * r1 - r0 * r0), a = area(m);
    print_message("stride 2: %zu faces, area %.5f m2 of %.5f\n", m->nfaces, a, annulus);
    assert_true(a < annulus && a > annulus * (1 - 1e-4));

    rs_nadir_stats ns;
    rs_mesh *cap = rs_nadir_cap_coarse(c, 0, 0.01, st.stride, 0.05, &ns, &err);
    if (!cap) fail_msg("no cap: %s %s", ns.why_not, err.msg);
    /* Rings 5 cm apart inside a 35 cm rim, 22 rim gaps (2.2 mm each) per inner column: a few
     * thousand triangles where the grid's own spacing (stride 1) gives about a million. */
    print_message("coarse cap: %zu triangles, %zu vertices, rim %zu points\n", cap->nfaces, cap->nverts,
                  ns.ring_points);
    assert_int_equal(ns.ring_points, (size_t)ncl);
    assert_true(cap->nfaces < 3000);
    for (size_t v = 0; v < cap->nverts; v++) assert_true(fabs(cap->verts[3 * v + 2]) < 1e-5);
    rs_mesh *both = rs_mesh_merge_welded(m, cap);
    assert_non_null(both);
    assert_int_equal(both->nverts, m->nverts + cap->nverts - (size_t)ncl); /* every rim point welded */
    assert_int_equal(boundary_edges(both), (size_t)ncl);                   /* only the top ring left */
    double disc = M_PI * r1 * r1, ab = area(both);
    print_message("grid + cap: area %.5f m2 of the disc's %.5f\n", ab, disc);
    assert_true(ab < disc && ab > disc * (1 - 1e-4));
    rs_mesh_free(both);
    rs_mesh_free(cap);
    rs_mesh_free(m);
    rs_cloud_free(c);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_stride_and_coarse_cap))
