/* test_atlas: the UV atlas's invariants (issue 22, part 1) on a box of planes, a sphere (many
 * small charts) and a building-like L of walls: every face in exactly one chart, no two charts'
 * gutters overlap in a page, no two triangles cover the same texel, every corner inside its
 * chart's rectangle, texel density uniform within 10 %, power-of-two pages within the limits. */
#include "tests/testutil.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "meshing/atlas.h"
#include "tests/meshgen.h"

static rs_mesh *make_sphere(int nlat, int nlon, double r)
{
    rs_mesh *m = rs_mesh_new((size_t)(nlat + 1) * nlon, (size_t)2 * nlat * nlon);
    for (int i = 0; i <= nlat; i++)
        for (int j = 0; j < nlon; j++) {
            double th = M_PI * i / nlat, ph = 2 * M_PI * j / nlon;
            float *v = m->verts + 3 * ((size_t)i * nlon + j);
            v[0] = (float)(r * sin(th) * cos(ph));
            v[1] = (float)(r * sin(th) * sin(ph));
            v[2] = (float)(r * cos(th));
        }
    size_t f = 0;
    for (int i = 0; i < nlat; i++)
        for (int j = 0; j < nlon; j++) {
            uint32_t a = (uint32_t)(i * nlon + j), b = (uint32_t)(i * nlon + (j + 1) % nlon);
            uint32_t c = a + (uint32_t)nlon, d = b + (uint32_t)nlon;
            uint32_t t[6] = {a, c, d, a, d, b}; /* outward */
            memcpy(m->tris + 3 * f, t, sizeof t);
            f += 2;
        }
    return m;
}

static rs_mesh *make_l_walls(void)
{
    rs_meshgen g = rs_meshgen_new(4000, 4000);
    rs_meshgen_rect(&g, rs_v3_make(-5, -5, 0), rs_v3_make(10, 0, 0), rs_v3_make(0, 10, 0), 12, 12);
    rs_meshgen_rect(&g, rs_v3_make(-5, 5, 0), rs_v3_make(10, 0, 0), rs_v3_make(0, 0, 6), 10, 6);
    rs_meshgen_rect(&g, rs_v3_make(5, 5, 0), rs_v3_make(0, -10, 0), rs_v3_make(0, 0, 6), 10, 6);
    rs_meshgen_rect(&g, rs_v3_make(1, 1, 0), rs_v3_make(0, 0, 3), rs_v3_make(1, 0, 0), 2, 3); /* pillar side */
    return rs_meshgen_done(&g);
}

/* 1 when (px, py) lies strictly inside the triangle (page pixel coordinates). */
static int inside(const double *x, const double *y, double px, double py)
{
    double d0 = (x[1] - x[0]) * (py - y[0]) - (y[1] - y[0]) * (px - x[0]);
    double d1 = (x[2] - x[1]) * (py - y[1]) - (y[2] - y[1]) * (px - x[1]);
    double d2 = (x[0] - x[2]) * (py - y[2]) - (y[0] - y[2]) * (px - x[2]);
    const double e = 1e-9;
    return (d0 > e && d1 > e && d2 > e) || (d0 < -e && d1 < -e && d2 < -e);
}

static void check_atlas(const rs_mesh *m, const rs_atlas *a, const rs_atlas_opts *o)
{
    int max_side = o->max_side ? o->max_side : 8192;
    assert_true(a->side >= 1 && a->side <= max_side && (a->side & (a->side - 1)) == 0);
    if (o->max_texels > 0) assert_true((double)a->npages * a->side * a->side <= o->max_texels);
    assert_true(a->texel >= o->texel);
    /* every face in exactly one chart */
    uint8_t *seen = calloc(m->nfaces, 1);
    for (size_t ci = 0; ci < a->ncharts; ci++) {
        const rs_atlas_chart *c = &a->charts[ci];
        for (size_t q = c->first; q < c->first + c->count; q++) {
            uint32_t f = a->faces[q];
            assert_true(f < m->nfaces);
            assert_int_equal(seen[f], 0);
            seen[f] = 1;
            assert_int_equal(a->face_chart[f], ci);
        }
        /* gutter rectangles inside the page and disjoint from every other chart's */
        int g = a->gutter;
        assert_true(c->page >= 0 && c->page < a->npages);
        assert_true(c->x0 - g >= 0 && c->y0 - g >= 0 && c->x0 + c->w + g <= a->side && c->y0 + c->h + g <= a->side);
        for (size_t cj = ci + 1; cj < a->ncharts; cj++) {
            const rs_atlas_chart *d = &a->charts[cj];
            if (d->page != c->page) continue;
            int apart = c->x0 + c->w + g <= d->x0 - g || d->x0 + d->w + g <= c->x0 - g ||
                c->y0 + c->h + g <= d->y0 - g || d->y0 + d->h + g <= c->y0 - g;
            assert_true(apart);
        }
    }
    for (size_t f = 0; f < m->nfaces; f++) assert_int_equal(seen[f], 1);
    free(seen);
    /* corners inside their chart's content; density; no texel covered twice */
    double dmin = INFINITY, dmax = 0;
    size_t npx = (size_t)a->npages * a->side * a->side;
    uint8_t *cover = calloc(npx, 1);
    for (size_t f = 0; f < m->nfaces; f++) {
        const rs_atlas_chart *c = &a->charts[a->face_chart[f]];
        double x[3], y[3];
        for (int k = 0; k < 3; k++) {
            x[k] = a->uv[6 * f + 2 * k] * (double)a->side;
            y[k] = a->uv[6 * f + 2 * k + 1] * (double)a->side;
            assert_true(x[k] >= c->x0 && x[k] <= c->x0 + c->w && y[k] >= c->y0 && y[k] <= c->y0 + c->h);
        }
        rs_v3 cen, n;
        double area;
        rs_mesh_face(m, f, &cen, &n, &area);
        double uva = 0.5 * fabs((x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]));
        if (area > 1e-8) {
            double d = uva / (area / (a->texel * a->texel)); /* texels per texel-area of surface */
            dmin = fmin(dmin, d);
            dmax = fmax(dmax, d);
        }
        int xa = (int)floor(fmin(x[0], fmin(x[1], x[2]))), xb = (int)ceil(fmax(x[0], fmax(x[1], x[2])));
        int ya = (int)floor(fmin(y[0], fmin(y[1], y[2]))), yb = (int)ceil(fmax(y[0], fmax(y[1], y[2])));
        for (int py = ya; py < yb; py++)
            for (int px = xa; px < xb; px++)
                if (inside(x, y, px + 0.5, py + 0.5)) {
                    size_t k = ((size_t)c->page * a->side + (size_t)py) * a->side + (size_t)px;
                    assert_int_equal(cover[k], 0);
                    cover[k] = 1;
                }
    }
    free(cover);
    assert_true(dmax <= 1.0 + 1e-4);
    assert_true(dmax / dmin <= 1.10);
}

static void run_case(rs_mesh *m, rs_atlas_opts o, size_t min_charts, size_t max_charts)
{
    rs_err err = {0};
    rs_atlas *a = rs_atlas_build(m, &o, &err);
    assert_non_null(a);
    assert_true(a->ncharts >= min_charts && a->ncharts <= max_charts);
    check_atlas(m, a, &o);
    rs_atlas_free(a);
}

static void test_box(void **state)
{
    rs_meshgen g = rs_meshgen_new(2000, 2000);
    rs_meshgen_box(&g, rs_v3_make(0, 0, 0), rs_v3_make(3, 2, 1), 5, 0);
    rs_mesh *m = rs_meshgen_done(&g);
    run_case(m, (rs_atlas_opts){.texel = 0.01}, 6, 6); /* one chart per side */
    rs_mesh_free(m);
}

static void test_sphere(void **state)
{
    rs_mesh *m = make_sphere(24, 48, 2.0);
    run_case(m, (rs_atlas_opts){.texel = 0.02}, 30, m->nfaces);
    rs_mesh_free(m);
}

static void test_walls_pages(void **state)
{
    rs_mesh *m = make_l_walls();
    run_case(m, (rs_atlas_opts){.texel = 0.01}, 4, 4);
    /* small pages: several of them, the same invariants */
    rs_err err = {0};
    rs_atlas_opts o = {.texel = 0.01, .max_side = 1024};
    rs_atlas *a = rs_atlas_build(m, &o, &err);
    assert_non_null(a);
    assert_true(a->npages > 1);
    check_atlas(m, a, &o);
    rs_atlas_free(a);
    /* a texel budget: the texel grows, the pages stay within it */
    run_case(m, (rs_atlas_opts){.texel = 0.001, .max_texels = 4e6}, 4, 4);
    rs_mesh_free(m);
}

static void test_bad_texel(void **state)
{
    rs_mesh *m = make_l_walls();
    rs_err err = {0};
    assert_null(rs_atlas_build(m, &(rs_atlas_opts){.texel = 0}, &err));
    assert_int_equal(err.kind, RS_ERR_INPUT);
    assert_null(rs_atlas_build(m, &(rs_atlas_opts){.texel = NAN}, &err));
    rs_mesh_free(m);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_box), cmocka_unit_test(test_sphere), cmocka_unit_test(test_walls_pages),
             cmocka_unit_test(test_bad_texel))
