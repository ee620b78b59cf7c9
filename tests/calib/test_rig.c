/* Tests of the rig file reader and the lens models (calib/rig.h): the C projection agrees with
 * OpenCV's projectPoints, inverts, stops where the radial model folds back, and bad rig files
 * give messages that name the camera and the field. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "calib/cv_adapter.h"
#include "calib/rig.h"
#include "tests/testutil.h"

static rs_rig_camera camera(rs_lens_model model, const double *dist)
{
    rs_rig_camera c;
    memset(&c, 0, sizeof c);
    c.width = 640;
    c.height = 512;
    c.model = model;
    c.fx = 300;
    c.fy = 310;
    c.cx = 319.5;
    c.cy = 255.5;
    memcpy(c.dist, dist, 5 * sizeof *dist);
    rs_m3_identity(c.r_rig_cam);
    c.max_field = model == RS_LENS_PINHOLE ? 3 : 2.5; /* both models are one-to-one that far */
    return c;
}

/* Writes a one-camera YAML rig; the fields are passed in as text so each test can spoil one. */
static void write_rig(const char *path, const char *count, const char *model, const char *dist, const char *rot)
{
    int cols = 1;
    for (const char *p = dist; *p; p++) cols += *p == ',';
    char text[4096];
    snprintf(text, sizeof text,
             "%%YAML:1.0\n---\ncamera_count: %s\ncameras:\n"
             "   - name: front\n     image_width: 640\n     image_height: 512\n     model: %s\n"
             "     camera_matrix: !!opencv-matrix\n        rows: 3\n        cols: 3\n        dt: d\n"
             "        data: [ 300., 0., 319.5, 0., 310., 255.5, 0., 0., 1. ]\n"
             "     distortion_coefficients: !!opencv-matrix\n        rows: 1\n        cols: %d\n        dt: d\n"
             "        data: [ %s ]\n"
             "     R_rig_cam: !!opencv-matrix\n        rows: 3\n        cols: 3\n        dt: d\n        data: [ %s ]\n"
             "     t_rig_cam: !!opencv-matrix\n        rows: 3\n        cols: 1\n        dt: d\n"
             "        data: [ 0.01, 0., 0.02 ]\n",
             count, model, cols, dist, rot);
    rs_test_write(path, text);
}

static void test_projection_matches_opencv(void **state)
{
    (void)state;
    const double pin[5] = {-0.12, 0.03, 0.0008, -0.0005, -0.002}, fish[5] = {0.05, -0.01, 0.002, -0.0005, 0};
    for (int m = 0; m < 2; m++) {
        rs_rig_camera c = camera(m ? RS_LENS_FISHEYE : RS_LENS_PINHOLE, m ? fish : pin);
        double k[9] = {c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1};
        enum { N = 200 };
        double pts[3 * N], ref[2 * N];
        srand(7 + m);
        for (int i = 0; i < N; i++) {
            /* Directions up to 40 degrees (pinhole) or 80 (fisheye) off the axis. */
            double th = (m ? 80 : 40) * M_PI / 180 * rand() / RAND_MAX, ph = 2 * M_PI * rand() / RAND_MAX;
            pts[3 * i] = sin(th) * cos(ph);
            pts[3 * i + 1] = sin(th) * sin(ph);
            pts[3 * i + 2] = cos(th);
        }
        char msg[256];
        assert_int_equal(rs_cv_project(m, k, m ? fish : pin, N, pts, ref, msg, sizeof msg), 0);
        for (int i = 0; i < N; i++) {
            double x, y;
            rs_v3 d = rs_v3_make(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]);
            rs_rig_project(&c, d, &x, &y, NULL);
            assert_true(fabs(x - ref[2 * i]) < 1e-6 && fabs(y - ref[2 * i + 1]) < 1e-6);
            rs_v3 back;
            if (x >= 0 && x <= c.width - 1 && y >= 0 && y <= c.height - 1) {
                assert_int_equal(rs_rig_unproject(&c, x, y, &back), 1);
                assert_true(rs_v3_len(rs_v3_sub(back, rs_v3_norm(d))) < 1e-8);
            }
        }
    }
}

/* k1 = -0.4 folds back at r = 1 / sqrt(1.2): directions beyond are refused, and the projection
 * is one-to-one below. */
static void test_fold_back(void **state)
{
    (void)state;
    /* rs_rig_load computes max_field: go through the YAML reader. */
    const char *dir = rs_test_tmpdir("rigfold");
    const char *path = rs_test_path(dir, "rig.yaml");
    write_rig(path, "1", "pinhole", "-0.4, 0., 0., 0., 0.", "1., 0., 0., 0., 1., 0., 0., 0., 1.");
    rs_rig rig;
    rs_err err = {0};
    assert_int_equal(rs_rig_load(path, &rig, &err), 0);
    double fold = 1 / sqrt(1.2);
    assert_true(rig.cams[0].max_field < fold && rig.cams[0].max_field > 0.95 * fold);
    rig.cams[0].width = rig.cams[0].height = 4000;
    rig.cams[0].cx = rig.cams[0].cy = 1999.5;
    double x, y, prev = -1;
    for (double t = 0; t < 1.5; t += 0.01) {
        int ok = rs_rig_project(&rig.cams[0], rs_v3_make(t, 0, 1), &x, &y, NULL);
        assert_int_equal(ok, t < rig.cams[0].max_field);
        if (ok) {
            assert_true(x > prev);
            prev = x;
        }
    }
    rs_rig_release(&rig);
    rs_test_rmtree(dir);
}

static void expect_rig_error(const char *path, const char *needle)
{
    rs_rig rig;
    rs_err err = {0};
    assert_int_equal(rs_rig_load(path, &rig, &err), -1);
    print_message("%s\n", err.msg);
    assert_non_null(strstr(err.msg, needle));
    assert_null(rig.cams);
}

static void test_bad_rig_files(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("rigbad");
    const char *path = rs_test_path(dir, "rig.yaml");
    const char *id = "1., 0., 0., 0., 1., 0., 0., 0., 1.";
    rs_rig rig;
    rs_err err = {0};
    write_rig(path, "1", "fisheye", "0.01, 0., 0., 0.", id);
    assert_int_equal(rs_rig_load(path, &rig, &err), 0);
    assert_int_equal(rig.count, 1);
    assert_string_equal(rig.cams[0].name, "front");
    assert_true(rig.cams[0].model == RS_LENS_FISHEYE && rig.cams[0].fy == 310 && rig.cams[0].t_rig_cam.z == 0.02);
    rs_rig_release(&rig);
    write_rig(path, "2", "pinhole", "0., 0., 0., 0., 0.", id);
    expect_rig_error(path, "camera_count is 2 but 1 cameras are listed");
    write_rig(path, "1", "equidistant", "0., 0., 0., 0., 0.", id);
    expect_rig_error(path, "model \"equidistant\": expected pinhole or fisheye");
    write_rig(path, "1", "pinhole", "0., 0., 0.", id);
    expect_rig_error(path, "distortion_coefficients has 3 entries");
    write_rig(path, "1", "pinhole", "0., 0., 0., 0., 0.", "1., 0., 0., 0., 1., 0., 0., 0., -1.");
    expect_rig_error(path, "R_rig_cam is not a rotation");
    rs_test_write(path, "%YAML:1.0\n---\ncamera_count: 1\n");
    expect_rig_error(path, "no `cameras` sequence");
    rs_test_write(path, "this is: [not, a rig\n");
    expect_rig_error(path, "");
    expect_rig_error(rs_test_path(dir, "missing.yaml"), "cannot open the rig file");
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_projection_matches_opencv), cmocka_unit_test(test_fold_back),
             cmocka_unit_test(test_bad_rig_files))
