/* test_capture_e57: a capture's panorama taken from an E57 file ([capture] panorama = FILE.e57,
 * e57_image): an 8-bit equirectangular PNG embedded by tools/e57write as a spherical image with a
 * pose gives the same capture (pixels and pose) as the same PNG, position and rotation given as
 * ordinary files; the response file linearises it; clipped pixels are flagged; the shared
 * reference set's files give the refusals (cylindrical, a blob of zeros, not a full sphere, no
 * spherical image). */
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/capture.h"
#include "common/config.h"
#include "common/image.h"
#include "common/pano.h"
#include "pipeline/capture_load.h"
#include "pipeline/panorama.h"

#define W 64
#define H 32

/* A smooth colour panorama below code 255 except, when clip, one pixel. */
static void write_png(const char *path, int clip)
{
    rs_image *img = rs_image_new(W, H, 3);
    for (int r = 0; r < H; r++)
        for (int c = 0; c < W; c++)
            for (int k = 0; k < 3; k++)
                img->data[3 * (r * W + c) + k] = 0.05f + 0.8f * (float)((c * (k + 1) + 3 * r) % 97) / 97.0f;
    if (clip) img->data[3 * (5 * W + 7)] = 1.0f;
    rs_err err = {0};
    assert_int_equal(rs_image_write_png(img, path, 1.0f, &err), 0);
    rs_image_free(img);
}

static void make_e57(const char *dir, const char *png, const char *e57)
{
    const char *ptx = rs_test_path(dir, "s.ptx");
    rs_test_write(ptx, "1\n2\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n1 0 0 0.5\n0 1 0 0.5\n");
    char cmd[8192], *out = NULL;
    /* (w x y z) = (0 0 0 1): half a turn about z, exactly R = diag(-1, -1, 1). */
    snprintf(cmd, sizeof cmd, "%s/e57write --image '%s' --image-pose '0 0 0 1 1.5 -2 3.25' --image-name pano '%s' '%s'",
             rs_test_bin_dir(), png, ptx, e57);
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) fail_msg("%s: %s", cmd, out ? out : "");
    free(out);
}

static int load(const char *dir, const char *capture, rs_capture *cap, rs_err *err)
{
    char text[20000];
    snprintf(text, sizeof text, "[pipeline]\nworkdir = work\n[capture]\n%s", capture);
    rs_config *cfg = rs_config_load_string(text, rs_test_path(dir, "c.ini"), dir, NULL, err);
    if (!cfg) fail_msg("config: %s", err->msg);
    int rc = rs_capture_load(cfg, "capture", cap, err);
    rs_config_free(cfg);
    return rc;
}

static void test_same_as_files(void **state)
{
    const char *dir = rs_test_tmpdir("cape57");
    char png[4096], e57[4096], resp[4096]; /* rs_test_path's buffers rotate */
    snprintf(png, sizeof png, "%s", rs_test_path(dir, "pano.png"));
    snprintf(e57, sizeof e57, "%s", rs_test_path(dir, "pano.e57"));
    snprintf(resp, sizeof resp, "%s", rs_test_path(dir, "resp.txt"));
    write_png(png, 0);
    make_e57(dir, png, e57);
    rs_capture a, b;
    rs_err err = {0};
    char text[16384];
    snprintf(text, sizeof text, "panorama = %s\nposition = 1.5 -2 3.25\nrotation = -1 0 0 0 -1 0 0 0 1\n", png);
    if (load(dir, text, &a, &err) != 0) fail_msg("%s", err.msg);
    const char *sel[] = {"pano", "0", NULL};
    for (int k = 0; k < 3; k++) {
        snprintf(text, sizeof text, "panorama = %s\n%s%s\n", e57, sel[k] ? "e57_image = " : "", sel[k] ? sel[k] : "");
        if (load(dir, text, &b, &err) != 0) fail_msg("%s", err.msg);
        assert_int_equal(b.pano->width, W);
        assert_int_equal(b.pano->height, H);
        assert_memory_equal(a.pano->data, b.pano->data, sizeof(float) * 3 * W * H);
        assert_memory_equal(&a.pose.position, &b.pose.position, sizeof a.pose.position);
        assert_memory_equal(a.pose.rot, b.pose.rot, sizeof a.pose.rot);
        assert_int_equal(b.nonfinite, 0);
        rs_capture_release(&b);
    }
    rs_capture_release(&a);

    /* A response file: each code's value is its line's. */
    FILE *fp = fopen(resp, "w");
    for (int i = 0; i < 256; i++) fprintf(fp, "%d %d %d\n", i + 1, 2 * i + 1, 3 * i + 1);
    fclose(fp);
    snprintf(text, sizeof text, "panorama = %s\nresponse_file = %s\n", e57, resp);
    if (load(dir, text, &b, &err) != 0) fail_msg("%s", err.msg);
    snprintf(text, sizeof text, "panorama = %s\nposition = 0 0 0\n", png);
    if (load(dir, text, &a, &err) != 0) fail_msg("%s", err.msg);
    for (int p = 0; p < W * H; p++)
        for (int k = 0; k < 3; k++) {
            int code = (int)lround(rs_linear_to_srgb(a.pano->data[3 * p + k]) * 255.0f);
            assert_true(b.pano->data[3 * p + k] == (float)((k + 1) * code + 1));
        }
    rs_capture_release(&a);
    rs_capture_release(&b);

    /* A clipped pixel is flagged (NaN, counted), not trusted. */
    write_png(png, 1);
    make_e57(dir, png, e57);
    snprintf(text, sizeof text, "panorama = %s\n", e57);
    if (load(dir, text, &b, &err) != 0) fail_msg("%s", err.msg);
    assert_int_equal(b.nonfinite, 1);
    assert_true(isnan(b.pano->data[3 * (5 * W + 7) + 1]));
    assert_false(rs_capture_pixel_ok(b.pano->data + 3 * (5 * W + 7)));
    rs_capture_release(&b);
    snprintf(text, sizeof text, "panorama = %s\ne57_image = other\n", e57);
    assert_int_equal(load(dir, text, &b, &err), -1);
    assert_non_null(strstr(err.msg, "e57_image = other: no images2D entry"));
    rs_test_rmtree(dir);
}

/* The synthetic sky every camera sees: smooth in the direction, below code 255. */
static void sky(const double d[3], float out[3])
{
    out[0] = (float)(0.1 + 0.3 * (d[0] + 1)), out[1] = (float)(0.15 + 0.25 * (d[1] + 1)),
    out[2] = (float)(0.2 + 0.2 * (d[2] + 1));
}

/* The unit quaternion (w x y z) of a rotation matrix (row-major) with a positive trace or not. */
static void quat(const double *R, double q[4])
{
    double tr = R[0] + R[4] + R[8];
    if (tr > 0) {
        double s = sqrt(tr + 1) * 2;
        q[0] = s / 4, q[1] = (R[7] - R[5]) / s, q[2] = (R[2] - R[6]) / s, q[3] = (R[3] - R[1]) / s;
    } else if (R[0] > R[4] && R[0] > R[8]) {
        double s = sqrt(1 + R[0] - R[4] - R[8]) * 2;
        q[0] = (R[7] - R[5]) / s, q[1] = s / 4, q[2] = (R[1] + R[3]) / s, q[3] = (R[2] + R[6]) / s;
    } else if (R[4] > R[8]) {
        double s = sqrt(1 + R[4] - R[0] - R[8]) * 2;
        q[0] = (R[2] - R[6]) / s, q[1] = (R[1] + R[3]) / s, q[2] = s / 4, q[3] = (R[5] + R[7]) / s;
    } else {
        double s = sqrt(1 + R[8] - R[0] - R[4]) * 2;
        q[0] = (R[3] - R[1]) / s, q[1] = (R[2] + R[6]) / s, q[2] = (R[5] + R[7]) / s, q[3] = s / 4;
    }
}

/* Six pinhole cameras on the cube's faces (100 degree field), each
 * an 8-bit PNG of the synthetic sky, embedded with their poses: stitched into a panorama that
 * shows that sky. */
static void test_pinholes_stitched(void **state)
{
    const char *dir = rs_test_tmpdir("cape57p");
    /* columns: right, down, forward (camera axes in the world) */
    const double axes[6][9] = {{0, -1, 0, 0, 0, -1, 1, 0, 0}, {1, 0, 0, 0, 0, -1, 0, 1, 0},
                               {0, 1, 0, 0, 0, -1, -1, 0, 0}, {-1, 0, 0, 0, 0, -1, 0, -1, 0},
                               {1, 0, 0, 0, 1, 0, 0, 0, 1},   {1, 0, 0, 0, -1, 0, 0, 0, -1}};
    const int n = 64;
    const double fx = (n / 2.0) / tan(50 * M_PI / 180), cx = (n - 1) / 2.0, pw = 1e-5;
    char args[16384] = "", path[4096], e57[4096];
    size_t at = 0;
    for (int c = 0; c < 6; c++) {
        double R[9]; /* camera -> world, row-major: its columns are the axes */
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) R[3 * i + j] = axes[c][3 * j + i];
        rs_image *img = rs_image_new(n, n, 3);
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++) {
                double dc[3] = {(x - cx) / fx, (y - cx) / fx, 1}, len = sqrt(dc[0] * dc[0] + dc[1] * dc[1] + 1), d[3];
                for (int i = 0; i < 3; i++) d[i] = (R[3 * i] * dc[0] + R[3 * i + 1] * dc[1] + R[3 * i + 2]) / len;
                sky(d, img->data + 3 * (y * n + x));
            }
        snprintf(path, sizeof path, "%s/cam%d.png", dir, c);
        rs_err err = {0};
        assert_int_equal(rs_image_write_png(img, path, 1.0f, &err), 0);
        rs_image_free(img);
        /* Written as the standard has them (ASTM E2807 8.4.13): the camera looks along -z with y
         * up (the OpenCV frame's y and z negated), image coordinate 0 at the first pixel's corner. */
        double Re[9], q[4];
        for (int i = 0; i < 3; i++) Re[3 * i] = R[3 * i], Re[3 * i + 1] = -R[3 * i + 1], Re[3 * i + 2] = -R[3 * i + 2];
        quat(Re, q);
        at += (size_t)snprintf(args + at, sizeof args - at,
                               "--image '%s' --image-name cam%d --image-pose '%.17g %.17g %.17g %.17g 2 3 %g' "
                               "--pinhole '%.17g %.17g %.17g %.17g %.17g' ",
                               path, c, q[0], q[1], q[2], q[3], 1.5 + 0.01 * c, fx * pw, pw, pw, cx + 0.5, cx + 0.5);
    }
    snprintf(e57, sizeof e57, "%s/rig.e57", dir);
    const char *ptx = rs_test_path(dir, "s.ptx");
    rs_test_write(ptx, "1\n1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n1 0 0 0.5\n");
    char cmd[20000], *out = NULL;
    snprintf(cmd, sizeof cmd, "%s/e57write %s '%s' '%s'", rs_test_bin_dir(), args, ptx, e57);
    if (rs_test_run(cmd, &out) != 0) fail_msg("%s", out ? out : "");
    free(out);
    char text[8192];
    snprintf(text, sizeof text, "panorama = %s\ne57_image = cam2\n", e57);
    rs_capture cap;
    rs_err err = {0};
    if (load(dir, text, &cap, &err) != 0) fail_msg("%s", err.msg);
    /* The capture: at the cameras' mean centre, world axes. */
    assert_true(fabs(cap.pose.position.x - 2) < 1e-12 && fabs(cap.pose.position.z - 1.525) < 1e-12);
    assert_true(cap.pose.rot[0] == 1 && cap.pose.rot[4] == 1 && cap.pose.rot[8] == 1);
    int w = cap.pano->width, h = cap.pano->height;
    assert_true(w > 100 && w == 2 * h);
    /* The width the mesh stage derives its facet size from, before anything is stitched. */
    char cfgtext[9000];
    snprintf(cfgtext, sizeof cfgtext, "[pipeline]\nworkdir = work\n[capture]\n%s", text);
    rs_config *cfg = rs_config_load_string(cfgtext, rs_test_path(dir, "w.ini"), dir, NULL, &err);
    assert_non_null(cfg);
    int width = 0;
    char from[4096];
    assert_int_equal(rs_capture_panorama_width(cfg, &width, from, sizeof from, &err), 1);
    assert_int_equal(width, w);
    double pos[3];
    assert_int_equal(rs_capture_position(cfg, pos), 0);
    assert_true(pos[0] == cap.pose.position.x && pos[1] == cap.pose.position.y && pos[2] == cap.pose.position.z);
    rs_config_free(cfg);
    double sum = 0, worst = 0;
    long seen = 0;
    for (int r = 0; r < h; r++)
        for (int c = 0; c < w; c++) {
            const float *px = cap.pano->data + 3 * ((size_t)r * w + c);
            if (!rs_capture_pixel_ok(px)) continue;
            rs_v3 d = rs_pano_pixel_dir(w, h, c, r);
            float want[3];
            sky((double[]){d.x, d.y, d.z}, want);
            for (int k = 0; k < 3; k++) {
                double e = fabs(px[k] - want[k]);
                sum += e, worst = fmax(worst, e);
            }
            seen++;
        }
    print_message("stitched %d x %d: %ld of %d pixels seen, mean |error| %.5f, max %.5f\n", w, h, seen, w * h,
                  sum / (3.0 * seen), worst);
    assert_true(seen == (long)w * h);
    assert_true(sum / (3.0 * seen) < 0.003);
    assert_true(worst < 0.03);
    rs_capture_release(&cap);
    rs_test_rmtree(dir);
}

static void expect_refusal(const char *file, const char *image, const char *words)
{
    char rel[256], text[4096];
    snprintf(rel, sizeof rel, "formats/e57/%s", file);
    const char *p = rs_test_shared_file(rel);
    if (!p) {
        if (getenv("CI") && strcmp(getenv("CI"), "true") == 0) fail_msg("%s is missing", rel);
        skip();
    }
    snprintf(text, sizeof text, "panorama = %s\nposition = 0 0 0\n%s%s\n", p, image ? "e57_image = " : "",
             image ? image : "");
    rs_capture cap;
    rs_err err = {0};
    assert_int_equal(load("/tmp", text, &cap, &err), -1);
    assert_int_equal(err.kind, RS_ERR_INPUT);
    if (!strstr(err.msg, words)) fail_msg("%s %s: \"%s\" lacks \"%s\"", file, image, err.msg, words);
    assert_non_null(strstr(err.file, file));
}

static void test_refusals(void **state)
{
    expect_refusal("tiny_pc_and_images.e57", "cylindrical",
                   "is a cylindrical image: it cannot be a capture's panorama");
    expect_refusal("tiny_pc_and_images.e57", "3", "is a cylindrical image");
    expect_refusal("tiny_pc_and_images.e57", "0", "is a visual reference image");
    expect_refusal("tiny_pc_and_images.e57", "pinhole",
                   "image 2 \"pinhole\": its PNG blob (1073 bytes) does not decode");
    expect_refusal("tiny_pc_and_images.e57", "spherical", "expected a full sphere");
    expect_refusal("tiny_pc_and_images.e57", NULL, "expected a full sphere"); /* the only spherical one */
    expect_refusal("PinholeImageWithDistortionParameters.e57", NULL, "has 0 spherical images (of 3)");
    expect_refusal("PinholeImageWithDistortionParameters.e57", "1",
                   "pinhole image 0 \"JPEG Image Test 1\" has no pose");
    expect_refusal("bad-crc.e57", NULL, "checksum");
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_same_as_files), cmocka_unit_test(test_pinholes_stitched),
             cmocka_unit_test(test_refusals))
