/* Tests of the panorama convention (docs/DESIGN.md, section Frames) and its helpers. */
#include <math.h>
#include <stdlib.h>
#include "common/pano.h"
#include "tests/testutil.h"

static void assert_dir(rs_v3 d, double x, double y, double z, double tol)
{
    assert_true(fabs(d.x - x) < tol && fabs(d.y - y) < tol && fabs(d.z - z) < tol);
}

/* The image centre looks along +X, the left quarter along +Y, the top row at the zenith. */
static void test_axes(void **state)
{
    (void)state;
    assert_dir(rs_pano_uv_to_dir(0.5, 0.5), 1, 0, 0, 1e-12);
    assert_dir(rs_pano_uv_to_dir(0.25, 0.5), 0, 1, 0, 1e-12);
    assert_dir(rs_pano_uv_to_dir(0.75, 0.5), 0, -1, 0, 1e-12);
    assert_dir(rs_pano_uv_to_dir(0.0, 0.5), -1, 0, 0, 1e-12);
    assert_dir(rs_pano_uv_to_dir(0.3, 0.0), 0, 0, 1, 1e-12);
    assert_dir(rs_pano_uv_to_dir(0.3, 1.0), 0, 0, -1, 1e-12);
    /* Pixel (0, 0) of a 8x4 image: u = 1/16, v = 1/8. */
    rs_v3 d = rs_pano_pixel_dir(8, 4, 0, 0);
    rs_v3 e = rs_pano_uv_to_dir(1.0 / 16, 1.0 / 8);
    assert_dir(d, e.x, e.y, e.z, 1e-15);
}

static void test_round_trip(void **state)
{
    (void)state;
    srand(3);
    for (int k = 0; k < 10000; k++) {
        rs_v3 d = rs_v3_norm(rs_v3_make(rand() / (double)RAND_MAX - 0.5, rand() / (double)RAND_MAX - 0.5,
                                        rand() / (double)RAND_MAX - 0.5));
        double u, v;
        rs_pano_dir_to_uv(d, &u, &v);
        assert_true(u >= 0 && u <= 1 && v >= 0 && v <= 1);
        assert_dir(rs_pano_uv_to_dir(u, v), d.x, d.y, d.z, 1e-9);
    }
}

static void test_solid_angle_sums_to_sphere(void **state)
{
    (void)state;
    int w = 512, h = 256;
    double sum = 0;
    for (int r = 0; r < h; r++) sum += w * rs_pano_pixel_solid_angle(w, h, r);
    assert_true(fabs(sum - 4 * M_PI) / (4 * M_PI) < 1e-4);
}

/* A camera turned 90 degrees about Z (local +X = world +Y) sees world +Y at the image centre. */
static void test_pose(void **state)
{
    (void)state;
    rs_pose p = {{1, 2, 3}, {0, -1, 0, 1, 0, 0, 0, 0, 1}};
    assert_dir(rs_pose_dir_to_world(&p, rs_v3_make(1, 0, 0)), 0, 1, 0, 1e-15);
    int c, r;
    rs_pano_world_to_pixel(&p, 64, 32, rs_v3_make(0, 1, 0), &c, &r);
    assert_true(c == 31 || c == 32);
    assert_true(r == 15 || r == 16);
    rs_pano_world_to_pixel(&p, 64, 32, rs_v3_make(0, 0, 1), &c, &r);
    assert_int_equal(r, 0);
    rs_pano_world_to_pixel(&p, 64, 32, rs_v3_make(0, 0, -1), &c, &r);
    assert_int_equal(r, 31);
}

static void test_bilinear(void **state)
{
    (void)state;
    rs_image *img = rs_image_new(4, 2, 1);
    for (int k = 0; k < 8; k++) img->data[k] = (float)k;
    float v;
    rs_pano_sample(img, 1.5 / 4, 0.5 / 2, &v); /* centre of pixel (1, 0) */
    assert_float_equal(v, 1, 1e-6);
    rs_pano_sample(img, 2.0 / 4, 0.5 / 2, &v); /* between pixels 1 and 2 */
    assert_float_equal(v, 1.5, 1e-6);
    rs_pano_sample(img, 0.0, 0.5 / 2, &v); /* wraps: halfway between pixels 3 and 0 */
    assert_float_equal(v, 1.5, 1e-6);
    rs_pano_sample(img, 0.5 / 4, 0.0, &v); /* clamps at the pole */
    assert_float_equal(v, 0, 1e-6);
    rs_image_free(img);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_axes), cmocka_unit_test(test_round_trip),
             cmocka_unit_test(test_solid_angle_sums_to_sphere), cmocka_unit_test(test_pose),
             cmocka_unit_test(test_bilinear))
