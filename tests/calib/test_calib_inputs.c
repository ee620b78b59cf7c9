/* test_calib_inputs: the calib readers' checks at the point of reading (issue 29), one value at a
 * time: rig values (rs_rig_check, what the rig fuzz harness drives), response files, pairs files,
 * a COLMAP model without points; and the fuzzing findings: a rig whose tiny focal length made
 * rs_rig_unproject return NaN as a success, and a model with no points that handed qsort NULL. */
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "calib/colmap.h"
#include "calib/register.h"
#include "calib/response.h"
#include "calib/rig.h"

static rs_cv_camera good_camera(void)
{
    rs_cv_camera c;
    memset(&c, 0, sizeof c);
    snprintf(c.name, sizeof c.name, "cam0");
    snprintf(c.model, sizeof c.model, "pinhole");
    c.width = 640;
    c.height = 512;
    c.has_width = c.has_height = 1;
    c.has_matrix = c.has_rotation = c.has_translation = 1;
    const double k[9] = {300, 0, 319.5, 0, 300, 255.5, 0, 0, 1}, r[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    memcpy(c.camera_matrix, k, sizeof k);
    memcpy(c.r_rig_cam, r, sizeof r);
    c.distortion_count = 5;
    c.t_rig_cam[2] = 0.05;
    return c;
}

static void expect_rig(const rs_cv_camera *c, int declared, const char *needle)
{
    rs_rig rig;
    rs_err err = {0};
    int rc = rs_rig_check("rig.yaml", c, 1, declared, &rig, &err);
    if (!needle) {
        if (rc != 0) fail_msg("%s", err.msg);
        rs_rig_release(&rig);
        return;
    }
    assert_int_equal(rc, -1);
    if (!strstr(err.msg, needle)) fail_msg("'%s' not in '%s'", needle, err.msg);
    assert_string_equal(err.file, "rig.yaml");
}

static void test_rig_values(void **state)
{
    (void)state;
    rs_cv_camera c = good_camera();
    expect_rig(&c, -1, NULL);
    expect_rig(&c, 2, "camera_count is 2 but 1 cameras are listed");
    c.width = 4294967297.0;
    expect_rig(&c, -1, "image_width = 4294967297: expected an integer from 1 to 65536");
    c = good_camera();
    c.has_height = 2;
    expect_rig(&c, -1, "image_height = (not a number)");
    c = good_camera();
    c.camera_matrix[2] = NAN;
    expect_rig(&c, -1, "camera_matrix entry 2 (row 1, column 3) is nan");
    c = good_camera();
    c.camera_matrix[0] = 7.6e-114; /* the fuzzing finding */
    expect_rig(&c, -1, "focal lengths from 1 to 1e+07 px");
    c = good_camera();
    c.camera_matrix[5] = -3;
    expect_rig(&c, -1, "principal point (cx, cy) = (319.5, -3)");
    c = good_camera();
    c.distortion[1] = INFINITY;
    expect_rig(&c, -1, "distortion_coefficients entry 1 is inf");
    c = good_camera();
    c.distortion[0] = -1001;
    expect_rig(&c, -1, "distortion_coefficients entry 0 is -1001: expected a finite number from -1000 to 1000");
    c = good_camera();
    c.r_rig_cam[4] = NAN;
    expect_rig(&c, -1, "R_rig_cam holds a value that is not finite");
    c = good_camera();
    c.t_rig_cam[0] = 1e3;
    expect_rig(&c, -1, "t_rig_cam entry 0 is 1000");
}

/* rs_rig_unproject on a camera beyond the checked ranges: Newton diverges to NaN, which must be
 * a failure (it was returned as a direction). */
static void test_unproject_nan_is_failure(void **state)
{
    (void)state;
    rs_rig_camera c;
    memset(&c, 0, sizeof c);
    c.model = RS_LENS_PINHOLE;
    c.width = 640;
    c.height = 512;
    c.fx = 7.6e-114;
    c.fy = 300;
    c.cx = 319.5;
    c.cy = 255.5;
    c.dist[0] = -0.08;
    c.dist[1] = 0.01;
    c.max_field = 5.67;
    rs_v3 d;
    assert_int_equal(rs_rig_unproject(&c, 0, 0, &d), 0);
}

static void test_response_and_pairs(void **state)
{
    (void)state;
    char text[8192] = "";
    float out[768];
    rs_err err = {0};
    for (int i = 0; i < 256; i++) snprintf(text + strlen(text), sizeof text - strlen(text), "%d\n", i + 1);
    assert_int_equal(rs_response_parse(text, strlen(text), "r.txt", out, &err), 0);
    text[0] = 'x';
    assert_int_equal(rs_response_parse(text, strlen(text), "r.txt", out, &err), -1);
    assert_int_equal(err.line, 1);
    rs_pair *p = NULL;
    int n = 0;
    const char *pairs = "1 2 3 4 5\n6 7 8 9 10\n11 12 13 14 15\n16,17,18,19,20\n6 7 8 9 10 # again\n";
    assert_int_equal(rs_pairs_parse(pairs, strlen(pairs), "p.txt", 100, 50, &p, &n, &err), -1);
    assert_int_equal(err.line, 5);
    assert_non_null(strstr(err.msg, "listed twice (also on line 2)"));
    assert_int_equal(rs_pairs_parse(pairs, 51, "p.txt", 100, 50, &p, &n, &err), 0); /* the first four lines */
    assert_int_equal(n, 4);
    assert_true(p[3].col == 16 && p[3].world.z == 20);
    free(p);
    const char *nul = "1 2 3 4 5\n\0";
    assert_int_equal(rs_pairs_parse(nul, 11, "p.txt", 100, 50, &p, &n, &err), -1);
    assert_non_null(strstr(err.msg, "NUL byte"));
}

/* A model whose points3D.txt is empty (qsort was handed NULL: UBSan's finding) reads or fails
 * with a message, never undefined behaviour. */
static void test_colmap_no_points(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("colmap_empty");
    rs_test_write(rs_test_path(dir, "cameras.txt"), "1 PINHOLE 512 512 256 256 256 256\n");
    rs_test_write(rs_test_path(dir, "images.txt"), "1 1 0 0 0 0 0 0 1 a.png\n\n");
    rs_test_write(rs_test_path(dir, "points3D.txt"), "# no points\n");
    rs_colmap_model m;
    rs_err err = {0};
    assert_int_equal(rs_colmap_read(dir, &m, &err), 0);
    assert_int_equal(m.npoints, 0);
    assert_null(rs_colmap_find_point(&m, 1));
    rs_colmap_release(&m);
    rs_test_write(rs_test_path(dir, "cameras.txt"), "1 PINHOLE 512 512 -256 256 256 256\n");
    assert_int_equal(rs_colmap_read(dir, &m, &err), -1);
    assert_non_null(strstr(err.msg, "expected a focal length > 0"));
    rs_test_rmtree(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_rig_values),
        cmocka_unit_test(test_unproject_nan_is_failure),
        cmocka_unit_test(test_response_and_pairs),
        cmocka_unit_test(test_colmap_no_points),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
