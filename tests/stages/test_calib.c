/* The calib stage as a program: frames rendered from a known panorama through a known rig stitch
 * back to it (PSNR >= 35 dB away from the cameras' borders) with the sensors' gains recovered; the
 * pose is solved from a pairs file and rs_capture_load hands both to the later stages; bad rig
 * files, mismatched frame counts and conflicting keys end in clear messages. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "pipeline/calib_files.h"
#include "calib/calib_math.h"
#include "common/capture.h"
#include "pipeline/capture_load.h"
#include "common/image.h"
#include "calib/register.h"
#include "calib/rig.h"
#include "calib/stitch.h"
#include "tests/fixtures.h"
#include "tests/testutil.h"

#define NCAM   6
#define PANO_W 1024

static const double true_gain[NCAM] = {1.03, 0.97, 1.02, 0.99, 1.01, 0.0}; /* last: geometric mean 1 */

/* The known panorama: smooth colour patterns with detail down to about 20 pixels. */
static float truth_value(rs_v3 d, int ch)
{
    double v = 0.45 + 0.2 * sin(5 * d.x + 3 * d.y + ch) * cos(4 * d.z + 1) + 0.12 * sin(13 * d.x - 11 * d.y + 7 * d.z) +
        0.06 * sin(40 * d.y + 25 * d.z - 2 * ch);
    return (float)v;
}

/* Camera k's rotation: five around the horizon every 72 degrees (pinhole), one looking up
 * (fisheye). Columns: the camera's x (right), y (down), z (forward) in the rig frame. */
static void camera_rotation(int k, double r[9])
{
    rs_v3 x, y, z;
    if (k < 5) {
        double yaw = k * 72 * M_PI / 180;
        z = rs_v3_make(cos(yaw), sin(yaw), 0);
        x = rs_v3_make(sin(yaw), -cos(yaw), 0);
        y = rs_v3_make(0, 0, -1);
    } else {
        z = rs_v3_make(0, 0, 1);
        x = rs_v3_make(0, -1, 0);
        y = rs_v3_make(1, 0, 0);
    }
    double m[9] = {x.x, y.x, z.x, x.y, y.y, z.y, x.z, y.z, z.z};
    memcpy(r, m, sizeof m);
}

static void write_rig_file(const char *path, int count_declared)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f, "%%YAML:1.0\n---\ncamera_count: %d\ncameras:\n", count_declared);
    for (int k = 0; k < NCAM; k++) {
        double r[9];
        camera_rotation(k, r);
        int fish = k == 5;
        fprintf(f, "   - name: cam%d\n     image_width: %d\n     image_height: %d\n     model: %s\n", k, 640,
                fish ? 640 : 512, fish ? "fisheye" : "pinhole");
        fprintf(f,
                "     camera_matrix: !!opencv-matrix\n        rows: 3\n        cols: 3\n        dt: d\n"
                "        data: [ %.1f, 0., 319.5, 0., %.1f, %.1f, 0., 0., 1. ]\n",
                fish ? 200.0 : 300.0, fish ? 200.0 : 300.0, fish ? 319.5 : 255.5);
        if (fish)
            fprintf(f,
                    "     distortion_coefficients: !!opencv-matrix\n        rows: 1\n        cols: 4\n        dt: d\n"
                    "        data: [ 0.02, -0.004, 0.0005, 0. ]\n");
        else
            fprintf(f,
                    "     distortion_coefficients: !!opencv-matrix\n        rows: 1\n        cols: 5\n        dt: d\n"
                    "        data: [ -0.08, 0.01, 0.0005, -0.0003, 0. ]\n");
        fprintf(f,
                "     R_rig_cam: !!opencv-matrix\n        rows: 3\n        cols: 3\n        dt: d\n        data: [ ");
        for (int i = 0; i < 9; i++) fprintf(f, "%.17g%s", r[i], i < 8 ? ", " : " ]\n");
        fprintf(f,
                "     t_rig_cam: !!opencv-matrix\n        rows: 3\n        cols: 1\n        dt: d\n"
                "        data: [ %g, %g, 0.05 ]\n",
                0.04 * cos(k * 1.2566), 0.04 * sin(k * 1.2566));
    }
    fclose(f);
}

/* Renders camera k's frame from the known panorama (bilinear), times its gain. */
static void write_frames(const char *dir, const rs_rig *rig, const rs_image *truth, double *gains)
{
    double prod = 1;
    for (int k = 0; k < NCAM - 1; k++) prod *= true_gain[k];
    for (int k = 0; k < NCAM; k++) gains[k] = k < NCAM - 1 ? true_gain[k] : 1 / prod;
    for (int k = 0; k < NCAM; k++) {
        const rs_rig_camera *c = &rig->cams[k];
        rs_image *img = rs_image_new(c->width, c->height, 3);
        for (int y = 0; y < c->height; y++)
            for (int x = 0; x < c->width; x++) {
                rs_v3 d;
                float *px = rs_image_px(img, x, y);
                if (!rs_rig_unproject(c, x, y, &d)) continue; /* outside the lens's usable field: black */
                double u, v;
                rs_pano_dir_to_uv(rs_m3_mul_v(c->r_rig_cam, d), &u, &v);
                rs_pano_sample(truth, u, v, px);
                for (int ch = 0; ch < 3; ch++) px[ch] = (float)(px[ch] * gains[k]);
            }
        char name[32];
        snprintf(name, sizeof name, "cam%d.exr", k);
        rs_err err;
        static const char *const names[] = {"R", "G", "B"};
        assert_int_equal(rs_image_write_exr(img, rs_test_path(dir, name), names, 0, NULL, &err), 0);
        rs_image_free(img);
    }
}

/* The known panorama (returned; caller frees), dir/rig.yaml (loaded into rig) and the frames
 * rendered from the panorama through it, with the sensors' gains. */
static rs_image *write_rig_and_frames(const char *dir, rs_rig *rig, double *gains)
{
    rs_image *truth = rs_image_new(PANO_W, PANO_W / 2, 3);
    for (int r = 0; r < PANO_W / 2; r++)
        for (int c = 0; c < PANO_W; c++)
            for (int ch = 0; ch < 3; ch++)
                rs_image_px(truth, c, r)[ch] = truth_value(rs_pano_pixel_dir(PANO_W, PANO_W / 2, c, r), ch);
    write_rig_file(rs_test_path(dir, "rig.yaml"), NCAM);
    rs_err err = {0};
    assert_int_equal(rs_rig_load(rs_test_path(dir, "rig.yaml"), rig, &err), 0);
    write_frames(dir, rig, truth, gains);
    return truth;
}

static int run_calib(const char *config, char **out)
{
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "'%s/rhoscan-calib' '%s'", rs_test_bin_dir(), config);
    return rs_test_run(cmd, out);
}

static void write_config(const char *dir, const char *frames, const char *extra)
{
    char text[4096];
    snprintf(text, sizeof text, "[pipeline]\nworkdir = out\n[rig]\nfile = rig.yaml\nframes = %s\nwidth = %d\n%s\n",
             frames, PANO_W, extra ? extra : "");
    rs_test_write(rs_test_path(dir, "calib.ini"), text);
}

/* rhoscan-calib on dir/calib.ini succeeds; prints what it said. */
static void expect_success(const char *dir)
{
    char *out = NULL;
    int rc = run_calib(rs_test_path(dir, "calib.ini"), &out);
    print_message("%s", out);
    assert_int_equal(rc, 0);
    free(out);
}

static void expect_failure(const char *dir, const char *needle)
{
    char *out = NULL;
    int rc = run_calib(rs_test_path(dir, "calib.ini"), &out);
    print_message("exit %d: %s", rc, out);
    assert_int_equal(rc, 1);
    assert_non_null(strstr(out, needle));
    free(out);
}

static void test_stitch_and_register(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("calib");
    rs_rig rig;
    double gains[NCAM];
    rs_image *truth = write_rig_and_frames(dir, &rig, gains);
    rs_err err = {0};
    const char *frames = "cam0.exr cam1.exr cam2.exr cam3.exr cam4.exr cam5.exr";

    /* Pairs: 20 points 15-25 m away seen from a known pose, plus 4 wrong pairs. */
    rs_pose pose;
    double w[3] = {0.1, -0.05, 0.7};
    rs_calib_rot_exp(w, pose.rot);
    pose.position = rs_v3_make(12, -4, 1.6);
    FILE *f = fopen(rs_test_path(dir, "pairs.txt"), "w");
    fprintf(f, "# column row X Y Z\n");
    srand(3);
    for (int i = 0; i < 24; i++) {
        rs_v3 dl = rs_v3_norm(rs_v3_make(rand() / (double)RAND_MAX - 0.5, rand() / (double)RAND_MAX - 0.5,
                                         0.5 * (rand() / (double)RAND_MAX - 0.5)));
        rs_v3 x = rs_v3_add(pose.position, rs_v3_scale(rs_pose_dir_to_world(&pose, dl), 15 + 10.0 * rand() / RAND_MAX));
        double u, v;
        rs_pano_dir_to_uv(dl, &u, &v);
        if (i >= 20) u = fmod(u + 0.3, 1.0); /* outliers */
        fprintf(f, "%.4f %.4f %.6f %.6f %.6f\n", u * PANO_W - 0.5, v * PANO_W / 2 - 0.5, x.x, x.y, x.z);
    }
    fclose(f);
    write_config(dir, frames, "[capture]\ncorrespondences = pairs.txt\nposition = 11 -3 1\n");
    expect_success(dir);

    /* The stitched panorama against the known one, leaving out pixels that any camera sees
     * within 8 px of its image border, and those no camera sees. */
    rs_image *pano = rs_image_read(rs_test_path(dir, "out/" RS_CALIB_PANO_FILE), &err);
    assert_non_null(pano);
    assert_int_equal(pano->width, PANO_W);
    double se = 0, only_sum[NCAM][2] = {{0}};
    long used = 0, uncovered = 0;
    for (int r = 0; r < pano->height; r++)
        for (int c = 0; c < pano->width; c++) {
            rs_v3 d = rs_pano_pixel_dir(PANO_W, PANO_W / 2, c, r);
            int near_border = 0, seen = 0, only = -1;
            for (int k = 0; k < NCAM; k++) {
                double x, y;
                if (!rs_rig_project(&rig.cams[k], rs_m3_mul_vt(rig.cams[k].r_rig_cam, d), &x, &y, NULL)) continue;
                only = seen ? -2 : k;
                seen = 1;
                if (x < 8 || y < 8 || x > rig.cams[k].width - 9 || y > rig.cams[k].height - 9) near_border = 1;
            }
            const float *p = rs_image_px(pano, c, r);
            if (!seen) {
                assert_true(isnan(p[0]));
                uncovered++;
                continue;
            }
            if (near_border) continue;
            if (only >= 0)
                for (int ch = 0; ch < 3; ch++) {
                    only_sum[only][0] += p[ch];
                    only_sum[only][1] += rs_image_px(truth, c, r)[ch];
                }
            for (int ch = 0; ch < 3; ch++) {
                double e = p[ch] - rs_image_px(truth, c, r)[ch];
                se += e * e;
            }
            used++;
        }
    double psnr = 10 * log10(1.0 / (se / (3.0 * used)));
    print_message("stitch: PSNR %.2f dB over %ld pixels (%.1f %% of the panorama); %ld pixels unseen\n", psnr, used,
                  100.0 * used / (PANO_W * PANO_W / 2), uncovered);
    assert_true(psnr >= 35);
    /* Where one camera alone sees, the stitched radiance is the truth: its gain was divided out
     * (without the correction the ratio would be the gain, 0.97 to 1.03). */
    for (int k = 0; k < NCAM; k++) {
        double ratio = only_sum[k][0] / only_sum[k][1];
        print_message("cam%d: gain %.4f, stitched / truth where it sees alone %.5f\n", k, gains[k], ratio);
        assert_true(fabs(ratio - 1) < 0.002);
    }
    assert_true(used > PANO_W * PANO_W / 2 / 2);

    /* The pose, and what rs_capture_load gives the later stages. */
    rs_config *cfg = rs_config_load(rs_test_path(dir, "calib.ini"), NULL, &err);
    assert_non_null(cfg);
    rs_capture cap;
    assert_int_equal(rs_capture_load(cfg, "capture", &cap, &err), 0);
    assert_int_equal(cap.pano->width, PANO_W);
    print_message("pose: %.6f m, %.6f deg from the truth\n", rs_v3_len(rs_v3_sub(cap.pose.position, pose.position)),
                  rs_calib_rot_angle(cap.pose.rot, pose.rot) * 180 / M_PI);
    assert_true(rs_v3_len(rs_v3_sub(cap.pose.position, pose.position)) < 0.005);
    assert_true(rs_calib_rot_angle(cap.pose.rot, pose.rot) * 180 / M_PI < 0.01);
    rs_capture_release(&cap);
    rs_config_free(cfg);

    /* Failures. */
    write_config(dir, "cam0.exr cam1.exr cam2.exr cam3.exr cam4.exr", NULL);
    expect_failure(dir, "[rig] frames lists 5 images but");
    write_config(dir, "cam0.exr cam1.exr cam2.exr cam3.exr cam5.exr cam4.exr", NULL);
    expect_failure(dir, "frame is 640 x 640 but camera 4 (cam4)");
    write_config(dir, frames, "[capture]\npanorama = cam0.exr\n");
    expect_failure(dir, "both [rig] file and [capture] panorama are set");
    write_rig_file(rs_test_path(dir, "rig.yaml"), 5);
    write_config(dir, frames, NULL);
    expect_failure(dir, "camera_count is 5 but 6 cameras are listed");
    rs_test_write(rs_test_path(dir, "few.txt"), "1 2 3 4 5\n6 7 8 9 10\n");
    write_rig_file(rs_test_path(dir, "rig.yaml"), NCAM);
    write_config(dir, frames, "[capture]\ncorrespondences = few.txt\n");
    expect_failure(dir, "2 correspondences: expected at least 4");

    rs_rig_release(&rig);
    rs_image_free(pano);
    rs_image_free(truth);
    rs_test_rmtree(dir);
}

/* Brackets: each camera's frame (linear, times its gain) photographed at three exposure times
 * through a gamma 2.2 response into 8-bit PNG codes. */
static void write_brackets(const char *dir, const rs_rig *rig, const double *times, char *list, size_t n)
{
    list[0] = 0;
    for (int k = 0; k < NCAM; k++) {
        char name[64];
        snprintf(name, sizeof name, "cam%d.exr", k);
        rs_err err;
        rs_image *lin = rs_image_read(rs_test_path(dir, name), &err);
        assert_non_null(lin);
        assert_int_equal(lin->width, rig->cams[k].width);
        for (int e = 0; e < 3; e++) {
            rs_image *shot = rs_image_new(lin->width, lin->height, 3);
            for (size_t i = 0; i < (size_t)lin->width * lin->height * 3; i++) {
                double code = floor(255 * pow(fmin(lin->data[i] * times[e] * 60, 1), 1 / 2.2) + 0.5);
                shot->data[i] = rs_srgb_to_linear((float)(code / 255)); /* the PNG writer sRGB-encodes */
            }
            snprintf(name, sizeof name, "cam%d_e%d.png", k, e);
            assert_int_equal(rs_image_write_png(shot, rs_test_path(dir, name), 1, &err), 0);
            rs_image_free(shot);
            snprintf(list + strlen(list), n - strlen(list), "%s ", name);
        }
        rs_image_free(lin);
    }
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static void test_brackets(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("calibhdr");
    rs_rig rig;
    double gains[NCAM];
    rs_image *truth = write_rig_and_frames(dir, &rig, gains);
    rs_err err = {0};
    const double times[3] = {1.0 / 200, 1.0 / 50, 1.0 / 12.5};
    char list[2048];
    write_brackets(dir, &rig, times, list, sizeof list);
    write_config(dir, list, "exposure_times_s = 0.005 0.02 0.08\n");
    expect_success(dir);
    /* Debevec's radiance has one free scale: fix it by the median ratio, then compare. */
    rs_image *pano = rs_image_read(rs_test_path(dir, "out/" RS_CALIB_PANO_FILE), &err);
    assert_non_null(pano);
    size_t n = (size_t)PANO_W * PANO_W / 2 * 3, m = 0;
    double *ratio = malloc(n * sizeof *ratio), sum_rel = 0;
    for (size_t k = 0; k < n; k++)
        if (isfinite(pano->data[k])) ratio[m++] = pano->data[k] / truth->data[k];
    qsort(ratio, m, sizeof *ratio, cmp_double);
    double scale = ratio[m / 2];
    for (size_t k = 0; k < n; k++)
        if (isfinite(pano->data[k])) sum_rel += fabs(pano->data[k] / truth->data[k] / scale - 1);
    print_message("brackets: scale %g, mean relative error %.4f over %zu values\n", scale, sum_rel / m, m);
    assert_true(sum_rel / m < 0.03);

    /* [rig] response_file: the known gamma curve (code i <- exposure (i / 255)^2.2 / 60, the
     * brackets' own scale) inverts the brackets to the true radiance, scale included. */
    char resp[256 * 24 + 64] = "# gamma 2.2, sensor full scale at radiance x time = 1 / 60\n";
    for (int i = 0; i < 256; i++)
        snprintf(resp + strlen(resp), sizeof resp - strlen(resp), "%.9g\n", pow(fmax(i, 0.25) / 255, 2.2) / 60);
    rs_test_write(rs_test_path(dir, "gamma.txt"), resp);
    char extra[256];
    snprintf(extra, sizeof extra, "exposure_times_s = 0.005 0.02 0.08\nresponse_file = gamma.txt\n");
    write_config(dir, list, extra);
    char *out = NULL;
    int rc = run_calib(rs_test_path(dir, "calib.ini"), &out);
    if (rc != 0) print_message("%s", out);
    assert_int_equal(rc, 0);
    free(out);
    rs_image_free(pano);
    pano = rs_image_read(rs_test_path(dir, "out/" RS_CALIB_PANO_FILE), &err);
    assert_non_null(pano);
    m = 0;
    sum_rel = 0;
    for (size_t k = 0; k < n; k++)
        if (isfinite(pano->data[k])) {
            ratio[m++] = pano->data[k] / truth->data[k];
            sum_rel += fabs(pano->data[k] / truth->data[k] - 1);
        }
    qsort(ratio, m, sizeof *ratio, cmp_double);
    print_message("response file: scale %g, mean relative error %.4f (no scale fitted)\n", ratio[m / 2], sum_rel / m);
    assert_true(fabs(ratio[m / 2] - 1) < 0.01);
    assert_true(sum_rel / m < 0.02);
    /* A linear curve in its place does not invert the gamma: the test can tell. */
    resp[0] = 0;
    for (int i = 0; i < 256; i++)
        snprintf(resp + strlen(resp), sizeof resp - strlen(resp), "%.9g\n", (i + 0.25) / 255 / 60);
    rs_test_write(rs_test_path(dir, "linear.txt"), resp);
    snprintf(extra, sizeof extra, "exposure_times_s = 0.005 0.02 0.08\nresponse_file = linear.txt\n");
    write_config(dir, list, extra);
    assert_int_equal(run_calib(rs_test_path(dir, "calib.ini"), &out), 0);
    free(out);
    rs_image_free(pano);
    pano = rs_image_read(rs_test_path(dir, "out/" RS_CALIB_PANO_FILE), &err);
    sum_rel = 0;
    for (size_t k = 0; k < n; k++)
        if (isfinite(pano->data[k])) sum_rel += fabs(pano->data[k] / truth->data[k] - 1);
    print_message("linear response file: mean relative error %.4f\n", sum_rel / m);
    assert_true(sum_rel / m > 0.1);
    /* A curve that falls, and one short of 256 codes. */
    rs_test_write(rs_test_path(dir, "bad.txt"), "# R G B\n1 1 1\n2 2 2\n3 1.5 3\n");
    snprintf(extra, sizeof extra, "exposure_times_s = 0.005 0.02 0.08\nresponse_file = bad.txt\n");
    write_config(dir, list, extra);
    expect_failure(dir, "bad.txt:4: code 2, channel 1: 1.5 is below code 1's 2");
    rs_test_write(rs_test_path(dir, "bad.txt"), "1\n2\n3\n");
    expect_failure(dir, "3 values: expected 256");
    /* Brackets that do not add up. */
    write_config(dir, "cam0_e0.png cam0_e1.png", "exposure_times_s = 0.005 0.02 0.08\n");
    expect_failure(dir, "exposure_times_s gives 3 exposures: expected 18 frames");
    free(ratio);
    rs_image_free(pano);
    rs_image_free(truth);
    rs_rig_release(&rig);
    rs_test_rmtree(dir);
}

/* The facet size of the mesh in rhoscan_facet_size of mesh.ply (0 when missing). */
static double mesh_facet_size(const char *dir)
{
    FILE *f = fopen(rs_test_path(dir, "out/mesh.ply"), "rb");
    assert_non_null(f);
    char line[512];
    double size = 0;
    while (fgets(line, sizeof line, f) && strncmp(line, "end_header", 10) != 0)
        if (sscanf(line, "comment rhoscan_facet_size %lf", &size) == 1) break;
    fclose(f);
    return size;
}

/* Runs ingest and mesh on scan.ptx with the [capture] or [rig] lines given; the facet size. */
static double facet_size_with(const char *dir, const char *lines)
{
    char text[1024], cmd[4096], *out = NULL;
    snprintf(text, sizeof text, "[pipeline]\nworkdir = out\n[ingest]\nscan = scan.ptx\n%s", lines);
    rs_test_write(rs_test_path(dir, "mesh.ini"), text);
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/rhoscan-ingest' mesh.ini && '%s/rhoscan-mesh' mesh.ini", dir,
             rs_test_bin_dir(), rs_test_bin_dir());
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) print_message("%s\n", out);
    assert_int_equal(rc, 0);
    free(out);
    return mesh_facet_size(dir);
}

/* With [rig] and no [capture] panorama, the mesh's facet size follows the panorama the rig will
 * stitch: [rig] width, else the width from the rig's finest camera. */
static void test_facet_size_from_rig(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("calibmesh");
    /* A scan of a wall 5 m away (x = 5), 360 x 180 directions. */
    FILE *f = fopen(rs_test_path(dir, "scan.ptx"), "w");
    assert_non_null(f);
    fprintf(f, "360\n180\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
    for (int c = 0; c < 360; c++)
        for (int r = 0; r < 180; r++) {
            double az = 2 * M_PI * c / 360, el = (-80 + 160.0 * r / 179) * M_PI / 180;
            rs_v3 d = rs_v3_make(cos(az) * cos(el), sin(az) * cos(el), sin(el));
            if (d.x > 0.5)
                fprintf(f, "%.5f %.5f %.5f 0.5\n", 5.0, 5 * d.y / d.x, 5 * d.z / d.x);
            else
                fprintf(f, "0 0 0 0.5\n");
        }
    fclose(f);
    write_rig_file(rs_test_path(dir, "rig.yaml"), NCAM);
    rs_image *img = rs_image_new(1024, 512, 3);
    rs_err err = {0};
    rs_fx_write_pano(img, dir);
    rs_image_free(img);
    double from_pano = facet_size_with(dir, "[capture]\npanorama = pano.exr\nposition = 0 0 0\n");
    double from_rig = facet_size_with(dir, "[capture]\nposition = 0 0 0\n[rig]\nfile = rig.yaml\nwidth = 1024\n");
    double from_rig_half = facet_size_with(dir, "[capture]\nposition = 0 0 0\n[rig]\nfile = rig.yaml\nwidth = 512\n");
    double from_focal = facet_size_with(dir, "[capture]\nposition = 0 0 0\n[rig]\nfile = rig.yaml\n");
    rs_rig rig;
    assert_int_equal(rs_rig_load(rs_test_path(dir, "rig.yaml"), &rig, &err), 0);
    int w = rs_stitch_default_width(&rig);
    rs_rig_release(&rig);
    print_message("facet size: panorama 1024 px %.5f m, rig width 1024 %.5f, 512 %.5f, from the focal (%d px) %.5f\n",
                  from_pano, from_rig, from_rig_half, w, from_focal);
    assert_true(from_pano > 0);
    assert_true(fabs(from_rig - from_pano) < 1e-9 * from_pano);
    assert_true(fabs(from_rig_half - 2 * from_pano) < 1e-6 * from_pano);
    assert_true(fabs(from_focal - from_pano * 1024.0 / w) < 1e-6 * from_pano);
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_stitch_and_register), cmocka_unit_test(test_brackets),
             cmocka_unit_test(test_facet_size_from_rig))
