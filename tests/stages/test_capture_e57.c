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
#include "pipeline/capture_load.h"

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
    expect_refusal("PinholeImageWithDistortionParameters.e57", "1", "is a pinhole image: stitching");
    expect_refusal("bad-crc.e57", NULL, "checksum");
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_same_as_files), cmocka_unit_test(test_refusals))
