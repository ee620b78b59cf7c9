/* Tests of the rig gains (calib/gains.h, through calib/stitch.h): a six-camera rig at one centre
 * looks at an environment with a sky, a sun halo and brick walls with sharp mortar lines; its
 * frames carry known gains. The gains must come back within 1 % when 10 to 30 % of the pixels
 * near the frame edges (where the overlaps are) are corrupted by flare or darkening; known gains
 * and vignetting given in the rig file are honoured; a valid-pixel mask keeps a camera's masked
 * pixels out of the panorama; bad photometric fields are refused by name. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/image.h"
#include "common/pano.h"
#include "calib/gains.h"
#include "calib/rig.h"
#include "calib/stitch.h"
#include "tests/testutil.h"

#define NCAM    6
#define PANO_W  720
#define EDGE_PX 32 /* "near the frame edge": within this many pixels of the border */

static const double true_gain[NCAM] = {1.00, 1.08, 0.93, 1.12, 0.90, 1.04};

/* The geometric mean of the true gains, which the estimate is normalised to without a known gain. */
static double true_mean(void)
{
    double s = 0;
    for (int i = 0; i < NCAM; i++) s += log(true_gain[i]);
    return exp(s / NCAM);
}

/* Radiance along world direction d: brick walls below 20 degrees of elevation (bricks 0.25 x
 * 0.08 rad with dark mortar lines), a sky brightening upward, a sun halo. */
static void environment(rs_v3 d, float rgb[3])
{
    double el = asin(fmax(-1, fmin(1, d.z))), az = atan2(d.y, d.x);
    double v;
    if (el < 0.35) {
        double row = floor((el + 2) / 0.08), u = (az + 4 + 0.125 * fmod(row, 2)) / 0.25;
        int mortar = fmod((el + 2) / 0.08, 1) < 0.12 || fmod(u, 1) < 0.05;
        v = mortar ? 0.08 : 0.25 + 0.15 * fmod(row * 7.3 + floor(u) * 3.1, 1);
    } else {
        rs_v3 sun = rs_v3_norm(rs_v3_make(0.5, 0.3, 0.8));
        double c = fmin(1, rs_v3_dot(d, sun));
        v = 0.6 + 0.8 * d.z + 40 * exp(-(1 - c) / 0.002);
    }
    rgb[0] = (float)(0.9 * v), rgb[1] = (float)v, rgb[2] = (float)(1.1 * v);
}

/* Five cameras every 72 degrees around the horizon and one up, 256 x 320, f = 130 px. */
static void write_rig(const char *path, const char *extra_cam0)
{
    char text[16384];
    int len = snprintf(text, sizeof text, "%%YAML:1.0\n---\ncamera_count: %d\ncameras:\n", NCAM);
    for (int i = 0; i < NCAM; i++) {
        double a = 2 * M_PI * i / 5, ca = cos(a), sa = sin(a);
        double side[9] = {sa, 0, ca, -ca, 0, sa, 0, -1, 0}, up[9] = {0, 1, 0, -1, 0, 0, 0, 0, 1};
        const double *r = i < 5 ? side : up;
        len +=
            snprintf(text + len, sizeof text - (size_t)len,
                     "   - name: cam%d\n     image_width: 256\n     image_height: 320\n     model: pinhole\n"
                     "     camera_matrix: !!opencv-matrix\n        rows: 3\n        cols: 3\n        dt: d\n"
                     "        data: [ 130., 0., 127.5, 0., 130., 159.5, 0., 0., 1. ]\n"
                     "     distortion_coefficients: !!opencv-matrix\n        rows: 1\n        cols: 5\n"
                     "        dt: d\n        data: [ 0., 0., 0., 0., 0. ]\n"
                     "     R_rig_cam: !!opencv-matrix\n        rows: 3\n        cols: 3\n        dt: d\n"
                     "        data: [ %.17g, %.17g, %.17g, %.17g, %.17g, %.17g, %.17g, %.17g, %.17g ]\n"
                     "     t_rig_cam: !!opencv-matrix\n        rows: 3\n        cols: 1\n        dt: d\n"
                     "        data: [ 0., 0., 0. ]\n%s",
                     i, r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], i == 0 && extra_cam0 ? extra_cam0 : "");
    }
    rs_test_write(path, text);
}

/* Camera k's frame: the environment through its lens, times its gain and vignetting. */
static rs_image *render_frame(const rs_rig_camera *c, double gain, const double vignetting[3])
{
    rs_image *img = rs_image_new(c->width, c->height, 3);
    assert_non_null(img);
    rs_rig_camera v = *c;
    memcpy(v.vignetting, vignetting, sizeof v.vignetting);
    for (int y = 0; y < c->height; y++)
        for (int x = 0; x < c->width; x++) {
            rs_v3 dc;
            assert_true(rs_rig_unproject(c, x, y, &dc));
            rs_v3 dw = rs_m3_mul_v(c->r_rig_cam, dc);
            float rgb[3];
            environment(dw, rgb);
            double f = gain * rs_rig_vignetting(&v, x, y);
            float *px = rs_image_px(img, x, y);
            for (int ch = 0; ch < 3; ch++) px[ch] = (float)(rgb[ch] * f);
        }
    return img;
}

/* Corrupts share of the pixels within EDGE_PX of the border: flare (x 1.5 to 4) or darkening
 * (x 0.2 to 0.7), chosen at random with a fixed seed. */
static void corrupt_edges(rs_image *img, double share, unsigned seed)
{
    srand(seed);
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            int d = x < y ? x : y;
            d = d < img->width - 1 - x ? d : img->width - 1 - x;
            d = d < img->height - 1 - y ? d : img->height - 1 - y;
            if (d >= EDGE_PX || rand() / (RAND_MAX + 1.0) >= share) continue;
            double u = rand() / (RAND_MAX + 1.0);
            double f = u < 0.5 ? 1.5 + 5 * u : 0.2 + (u - 0.5);
            float *px = rs_image_px(img, x, y);
            for (int ch = 0; ch < 3; ch++) px[ch] = (float)(px[ch] * f);
        }
}

/* The largest relative error of the gains against the truth divided by norm. */
static double worst_gain_error(const double *g, double norm)
{
    double e = 0;
    for (int i = 0; i < NCAM; i++) e = fmax(e, fabs(g[i] / (true_gain[i] / norm) - 1));
    return e;
}

static double stitch_gains(const rs_rig *rig, rs_image **frames, int min_pairs, double *g, rs_image **pano_out)
{
    rs_err err;
    rs_image *pano = NULL;
    rs_stitch_stats st;
    rs_stitch_opts o = {PANO_W, 32, 1, NULL, {{0, 0, 0}, {1, 0, 0, 0, 1, 0, 0, 0, 1}}};
    if (rs_stitch(rig, frames, &o, &pano, g, &st, &err) != 0) fail_msg("%s", err.msg);
    assert_true(st.gain.npairs >= min_pairs);
    double rms = st.gain.residual_rms;
    rs_gain_report_free(&st.gain);
    if (pano_out)
        *pano_out = pano;
    else
        rs_image_free(pano);
    return rms;
}

static void load_rig(const char *dir, const char *extra_cam0, rs_rig *rig)
{
    rs_err err;
    const char *path = rs_test_path(dir, "rig.yaml");
    write_rig(path, extra_cam0);
    if (rs_rig_load(path, rig, &err) != 0) fail_msg("%s", err.msg);
}

static void test_corrupted_edges(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("gains");
    rs_rig rig;
    load_rig(dir, NULL, &rig);
    static const double none[3] = {0, 0, 0};
    const double shares[] = {0, 0.1, 0.2, 0.3};
    for (size_t s = 0; s < sizeof shares / sizeof shares[0]; s++) {
        rs_image *frames[NCAM];
        for (int i = 0; i < NCAM; i++) {
            frames[i] = render_frame(&rig.cams[i], true_gain[i], none);
            if (shares[s] > 0) corrupt_edges(frames[i], shares[s], 17u + (unsigned)i);
        }
        double g[NCAM];
        double rms = stitch_gains(&rig, frames, 10, g, NULL); /* 5 around the horizon, 5 with the up camera */
        double e = worst_gain_error(g, true_mean());
        printf("# %2.0f %% of the edge pixels corrupted: worst gain error %.3f %%, pair residual RMS %.3f %%\n",
               100 * shares[s], 100 * e, 100 * rms);
        assert_true(e < (shares[s] > 0 ? 0.01 : 0.002));
        for (int i = 0; i < NCAM; i++) rs_image_free(frames[i]);
    }
    rs_rig_release(&rig);
    rs_test_rmtree(dir);
}

/* A gain given for cam0 fixes the scale: the others come out absolute, not normalised. Given
 * vignetting is divided out before anything else. */
static void test_known_gain_and_vignetting(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("gains");
    rs_rig rig;
    load_rig(dir, "     gain: 1.0\n     vignetting: [ -0.25, 0.05, 0. ]\n", &rig);
    assert_true(rig.cams[0].gain == 1.0 && rig.cams[1].gain == 0);
    assert_true(fabs(rig.cams[0].vignetting[0] + 0.25) < 1e-12);
    rs_image *frames[NCAM];
    static const double none[3] = {0, 0, 0};
    for (int i = 0; i < NCAM; i++)
        frames[i] = render_frame(&rig.cams[i], true_gain[i], i == 0 ? rig.cams[0].vignetting : none);
    double g[NCAM];
    rs_image *pano = NULL;
    stitch_gains(&rig, frames, 10, g, &pano);
    double e = worst_gain_error(g, 1.0);
    printf("# cam0's gain known, its vignetting given: worst gain error %.3f %%\n", 100 * e);
    assert_true(g[0] == 1.0);
    assert_true(e < 0.002);
    /* On cam0's axis, where it alone sees, the panorama is the truth: its vignetting divided out. */
    rs_v3 axis = rs_m3_mul_v(rig.cams[0].r_rig_cam, rs_v3_make(0, 0, 1));
    int col, row;
    rs_pose identity = {{0, 0, 0}, {1, 0, 0, 0, 1, 0, 0, 0, 1}};
    rs_pano_world_to_pixel(&identity, PANO_W, PANO_W / 2, axis, &col, &row);
    float truth[3];
    environment(rs_pano_pixel_dir(PANO_W, PANO_W / 2, col, row), truth);
    const float *px = rs_image_px(pano, col, row);
    printf("# on cam0's axis: stitched / truth %.5f\n", px[1] / truth[1]);
    assert_true(fabs(px[1] / truth[1] - 1) < 0.002);
    rs_image_free(pano);
    for (int i = 0; i < NCAM; i++) rs_image_free(frames[i]);
    rs_rig_release(&rig);
    rs_test_rmtree(dir);
}

/* cam1's left half masked, and filled with rubbish (the rig's housing): none of it reaches the
 * panorama, and the other cameras fill what cam1 no longer gives. */
static void test_mask(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("gains");
    rs_image *mask = rs_image_new(256, 320, 1);
    for (int y = 0; y < 320; y++)
        for (int x = 0; x < 256; x++) rs_image_px(mask, x, y)[0] = x >= 128;
    rs_err err;
    if (rs_image_write_png(mask, rs_test_path(dir, "mask1.png"), 1, &err) != 0) fail_msg("%s", err.msg);
    rs_image_free(mask);
    /* The mask is cam1's: write the rig with the field on that camera. */
    const char *path = rs_test_path(dir, "rig.yaml");
    write_rig(path, NULL);
    char *text = strdup(rs_test_read_text(path)), *at = strstr(text, "   - name: cam2");
    assert_non_null(at);
    char out[20000];
    snprintf(out, sizeof out, "%.*s     valid_mask: mask1.png\n%s", (int)(at - text), text, at);
    rs_test_write(path, out);
    free(text);
    rs_rig rig;
    if (rs_rig_load(path, &rig, &err) != 0) fail_msg("%s", err.msg);
    assert_non_null(rig.cams[1].mask);
    rs_image *frames[NCAM];
    static const double none[3] = {0, 0, 0};
    for (int i = 0; i < NCAM; i++) frames[i] = render_frame(&rig.cams[i], 1.0, none);
    for (int y = 0; y < 320; y++)
        for (int x = 0; x < 128; x++)
            for (int ch = 0; ch < 3; ch++) rs_image_px(frames[1], x, y)[ch] = -1e6;
    double g[NCAM];
    rs_image *pano = NULL;
    stitch_gains(&rig, frames, 9, g, &pano); /* cam1's half masked: it may lose a pair */
    /* Any weight on the housing, even the blend's floor of 1e-6, would pull a pixel below 0. */
    double lowest = INFINITY;
    size_t seen = 0;
    for (int row = 0; row < PANO_W / 2; row++)
        for (int col = 0; col < PANO_W; col++) {
            const float *px = rs_image_px(pano, col, row);
            if (isfinite(px[1])) lowest = fmin(lowest, px[1]), seen++;
        }
    printf("# masked housing (-1e6): lowest stitched value %g over %zu pixels\n", lowest, seen);
    assert_true(lowest > 0);
    assert_true(seen > (size_t)PANO_W * PANO_W / 2 * 0.6); /* no camera looks below -51 degrees */
    rs_image_free(pano);
    for (int i = 0; i < NCAM; i++) rs_image_free(frames[i]);
    rs_rig_release(&rig);
    rs_test_rmtree(dir);
}

static void test_pair_estimate(void **state)
{
    (void)state;
    rs_gain_samples s = {0};
    srand(5);
    /* 70 % of the samples at ln 1.1 with 2 % noise, 30 % outliers on one side (flare). */
    for (int k = 0; k < 10000; k++) {
        double u = rand() / (RAND_MAX + 1.0), v = rand() / (RAND_MAX + 1.0);
        double lr = k % 10 < 7 ? log(1.1) + 0.02 * (u + v - 1) * 2.45 : log(1.1) + 0.4 + 1.5 * u;
        assert_int_equal(rs_gain_samples_add(&s, (float)lr, 1), 0);
    }
    double r, spread, inlier;
    assert_int_equal(rs_gain_pair_estimate(&s, &r, &spread, &inlier), 0);
    printf("# pair: estimate %.5f for %.5f, spread %.4f, inliers %.2f\n", r, log(1.1), spread, inlier);
    assert_true(fabs(r - log(1.1)) < 1e-3);
    assert_true(inlier > 0.65 && inlier < 0.75);
    rs_gain_samples_free(&s);
    assert_int_equal(rs_gain_pair_estimate(&s, &r, NULL, NULL), -1);
}

static void expect_refused(const char *extra, const char *needle)
{
    const char *dir = rs_test_tmpdir("gains");
    const char *path = rs_test_path(dir, "rig.yaml");
    write_rig(path, extra);
    rs_rig rig;
    rs_err err;
    int rc = rs_rig_load(path, &rig, &err);
    if (rc == 0) rs_rig_release(&rig);
    print_message("%s -> %s\n", extra, rc ? err.msg : "(accepted)");
    assert_int_not_equal(rc, 0);
    assert_non_null(strstr(err.msg, needle));
    assert_non_null(strstr(err.file, "rig.yaml"));
    rs_test_rmtree(dir);
}

static void test_bad_fields(void **state)
{
    (void)state;
    expect_refused("     gain: -2\n", "gain = -2");
    expect_refused("     gain: nope\n", "gain is not a number");
    expect_refused("     gain: .nan\n", "gain = -nan: expected a number from 0.001");
    expect_refused("     vignetting: [ -0.3, 0.1 ]\n", "vignetting has 2 entries");
    expect_refused("     vignetting: [ -2., 0., 0. ]\n", "falloff");
    expect_refused("     vignetting: [ .inf, 0., 0. ]\n", "vignetting entry 0");
    expect_refused("     valid_mask: nowhere.png\n", "nowhere.png");
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_pair_estimate), cmocka_unit_test(test_corrupted_edges),
             cmocka_unit_test(test_known_gain_and_vignetting), cmocka_unit_test(test_mask),
             cmocka_unit_test(test_bad_fields))
