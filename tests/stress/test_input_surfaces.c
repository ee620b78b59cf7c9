/* test_input_surfaces: the input surfaces added since the first robustness round (issue 29), tried
 * through the real programs as a careless or hostile user would: rig files, exposure brackets and
 * response files, pairs files, COLMAP models, datetime and sun keys, the grey card, captures and
 * sky panoramas, input meshes, PCD and XYZ clouds, long paths and a read-only work folder. Each
 * case asserts the exit code (1 bad input, 2 an output that cannot be written, never 0 or a
 * signal) and that the message names the file or key and what was found; nothing may hang. */
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "common/fileio.h"
#include "common/image.h"

/* Every program run here must end within this (s): a hang is a failure, not a slow test. */
#define RUN_LIMIT_S 60

static const char *src(void)
{
    return rs_test_source_dir();
}

/* Runs cmd in dir under `timeout`, prints what it said, and checks its exit status and that
 * every needle (NULL-terminated) is in its output. */
static void expect_in(const char *dir, const char *cmd, int rc_want, const char *const *needles)
{
    char full[8192], *out = NULL;
    snprintf(full, sizeof full, "cd '%s' && timeout %d %s", dir, RUN_LIMIT_S, cmd);
    int rc = rs_test_run(full, &out);
    size_t n = out ? strlen(out) : 0;
    print_message("exit %d: ...%s\n", rc, out ? out + (n > 700 ? n - 700 : 0) : "");
    if (rc == 124) fail_msg("did not finish within %d s: %s", RUN_LIMIT_S, cmd);
    assert_int_equal(rc, rc_want);
    for (; *needles; needles++)
        if (!strstr(out, *needles)) fail_msg("missing in the output: '%s'", *needles);
    free(out);
}

#define EXPECT(dir, rc, cmd, ...)                           \
    do {                                                    \
        const char *const needles_[] = {__VA_ARGS__, NULL}; \
        expect_in(dir, cmd, rc, needles_);                  \
    } while (0)

static void write_bytes(const char *path, const void *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
}

/* ---- rig files, brackets, response files, pairs (rhoscan-calib) ---- */

/* A one-camera rig (64 x 32 pinhole) with fields replaceable by text: any argument NULL keeps
 * the good value. */
static void write_rig(const char *path, const char *count, const char *width, const char *k, const char *dist,
                      const char *t)
{
    char text[4096];
    snprintf(text, sizeof text,
             "%%YAML:1.0\n---\ncamera_count: %s\ncameras:\n   - name: cam0\n     image_width: %s\n"
             "     image_height: 32\n     model: pinhole\n"
             "     camera_matrix: !!opencv-matrix\n        rows: 3\n        cols: 3\n        dt: d\n        data: %s\n"
             "     distortion_coefficients: !!opencv-matrix\n        rows: 1\n        cols: 5\n        dt: d\n"
             "        data: %s\n"
             "     R_rig_cam: !!opencv-matrix\n        rows: 3\n        cols: 3\n        dt: d\n"
             "        data: [ 0., 0., 1., -1., 0., 0., 0., -1., 0. ]\n"
             "     t_rig_cam: !!opencv-matrix\n        rows: 3\n        cols: 1\n        dt: d\n        data: %s\n",
             count ? count : "1", width ? width : "64", k ? k : "[ 40., 0., 31.5, 0., 40., 15.5, 0., 0., 1. ]",
             dist ? dist : "[ 0., 0., 0., 0., 0. ]", t ? t : "[ 0., 0., 0. ]");
    rs_test_write(path, text);
}

/* calib.ini in dir: the rig file rig.yaml, its frames, and extra INI text. */
static void write_calib_config(const char *dir, const char *frames, const char *extra)
{
    char text[4096];
    snprintf(text, sizeof text, "[pipeline]\nworkdir = out\n[rig]\nfile = rig.yaml\nframes = %s\nwidth = 128\n%s\n",
             frames, extra ? extra : "");
    rs_test_write(rs_test_path(dir, "calib.ini"), text);
}

static const char *calib_cmd(void)
{
    static char cmd[2048];
    snprintf(cmd, sizeof cmd, "'%s/rhoscan-calib' calib.ini", rs_test_bin_dir());
    return cmd;
}

static void write_frames(const char *dir)
{
    rs_image *img = rs_image_new(64, 32, 3);
    for (size_t k = 0; k < 3 * 64 * 32; k++) img->data[k] = (float)(k % 97) / 97.0f;
    rs_err err;
    static const char *const names[] = {"cam0.png", "cam0_e0.png", "cam0_e1.png"};
    for (int i = 0; i < 3; i++)
        if (rs_image_write_png(img, rs_test_path(dir, names[i]), 1.0f, &err) != 0) fail_msg("%s", err.msg);
    rs_image_free(img);
}

static void test_rig_values(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("surf_rig");
    const char *rig = rs_test_path(dir, "rig.yaml");
    write_frames(dir);
    write_calib_config(dir, "cam0.png", NULL);
    write_rig(rig, NULL, NULL, NULL, NULL, NULL);
    EXPECT(dir, 0, calib_cmd(), "calib: done");
    /* A NaN principal point crashed calib (SIGSEGV in the stitcher). */
    write_rig(rig, NULL, NULL, "[ 40., 0., .nan, 0., 40., 15.5, 0., 0., 1. ]", NULL, NULL);
    EXPECT(dir, 1, calib_cmd(), "rig.yaml", "camera_matrix entry 2", "nan", "expected finite numbers");
    write_rig(rig, NULL, NULL, "[ .nan, 0., 31.5, 0., 40., 15.5, 0., 0., 1. ]", NULL, NULL);
    EXPECT(dir, 1, calib_cmd(), "rig.yaml", "camera_matrix entry 0", "expected finite numbers");
    write_rig(rig, NULL, NULL, "[ 40., 0., 31.5, 0., 40., .inf, 0., 0., 1. ]", NULL, NULL);
    EXPECT(dir, 1, calib_cmd(), "rig.yaml", "camera_matrix entry 5", "inf");
    write_rig(rig, NULL, NULL, "[ 40., 0., 300., 0., 40., 15.5, 0., 0., 1. ]", NULL, NULL);
    EXPECT(dir, 1, calib_cmd(), "rig.yaml", "principal point", "300", "inside the");
    write_rig(rig, NULL, NULL, NULL, "[ .nan, 0., 0., 0., 0. ]", NULL);
    EXPECT(dir, 1, calib_cmd(), "rig.yaml", "distortion_coefficients entry 0", "expected a finite number");
    write_rig(rig, NULL, NULL, NULL, NULL, "[ 0., .inf, 0. ]");
    EXPECT(dir, 1, calib_cmd(), "rig.yaml", "t_rig_cam entry 1 is inf");
    write_rig(rig, NULL, NULL, NULL, NULL, "[ 0., .nan, 0. ]");
    EXPECT(dir, 1, calib_cmd(), "rig.yaml", "t_rig_cam entry 1", "finite");
    write_rig(rig, "-1", NULL, NULL, NULL, NULL);
    EXPECT(dir, 1, calib_cmd(), "rig.yaml", "camera_count = -1", "expected an integer from 0");
    /* OpenCV wraps integers to 32 bits: 4294967297 would have been read as 1. */
    write_rig(rig, NULL, "4294967297", NULL, NULL, NULL);
    EXPECT(dir, 1, calib_cmd(), "rig.yaml:6:", "image_width = 4294967297", "32 bits", "1 to 65536");
    write_rig(rig, NULL, "1e10", NULL, NULL, NULL);
    EXPECT(dir, 1, calib_cmd(), "rig.yaml", "image_width = 10000000000", "expected an integer from 1 to 65536");
    write_rig(rig, NULL, "0", NULL, NULL, NULL);
    EXPECT(dir, 1, calib_cmd(), "rig.yaml", "image_width = 0");
    rs_test_rmtree(dir);
}

static void test_brackets_and_response(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("surf_hdr");
    write_frames(dir);
    write_rig(rs_test_path(dir, "rig.yaml"), NULL, NULL, NULL, NULL, NULL);
    char resp[256 * 16] = "";
    for (int i = 0; i < 256; i++) snprintf(resp + strlen(resp), sizeof resp - strlen(resp), "%g\n", (i + 1) / 256.0);
    rs_test_write(rs_test_path(dir, "resp.txt"), resp);
    /* A response file alone used to be ignored without a word. */
    write_calib_config(dir, "cam0.png", "response_file = resp.txt\n");
    EXPECT(dir, 1, calib_cmd(), "calib.ini", "[rig] response_file is set without [rig] exposure_times_s");
    write_calib_config(dir, "cam0_e0.png cam0_e1.png", "exposure_times_s = 0.01 inf\n");
    EXPECT(dir, 1, calib_cmd(), "calib.ini", "[rig] exposure_times_s", "time 2 is inf", "at most 3600 s");
    write_calib_config(dir, "cam0_e0.png cam0_e1.png", "exposure_times_s = 0.01 nan\n");
    EXPECT(dir, 1, calib_cmd(), "calib.ini", "[rig] exposure_times_s", "time 2 is nan");
    write_calib_config(dir, "cam0_e0.png cam0_e1.png", "exposure_times_s = 0.01 0.02\nresponse_file = resp.txt\n");
    EXPECT(dir, 0, calib_cmd(), "calib: done");
    /* Response values: not finite, beyond float, trailing garbage, a NUL byte. */
    char bad[256 * 16];
    const char *line3 = strchr(strchr(resp, '\n') + 1, '\n') + 1;
    snprintf(bad, sizeof bad, "0.001\ninf\n%s", line3);
    rs_test_write(rs_test_path(dir, "resp.txt"), bad);
    EXPECT(dir, 1, calib_cmd(), "resp.txt:2:", "expected 1 or 3 finite numbers");
    snprintf(bad, sizeof bad, "1e-45\n%s", strchr(resp, '\n') + 1);
    rs_test_write(rs_test_path(dir, "resp.txt"), bad);
    EXPECT(dir, 1, calib_cmd(), "resp.txt:1:", "code 0", "expected a linear exposure from 1e-30 to 1e+30");
    snprintf(bad, sizeof bad, "0.5x\n%s", strchr(resp, '\n') + 1);
    rs_test_write(rs_test_path(dir, "resp.txt"), bad);
    EXPECT(dir, 1, calib_cmd(), "resp.txt:1:", "\"0.5x\"");
    size_t n = strlen(resp);
    resp[10] = 0;
    write_bytes(rs_test_path(dir, "resp.txt"), resp, n);
    EXPECT(dir, 1, calib_cmd(), "resp.txt", "NUL byte");
    rs_test_rmtree(dir);
}

static void test_pairs(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("surf_pairs");
    write_frames(dir);
    write_rig(rs_test_path(dir, "rig.yaml"), NULL, NULL, NULL, NULL, NULL);
    write_calib_config(dir, "cam0.png", "[capture]\ncorrespondences = pairs.txt\nposition = 0 0 0\n");
    char pairs[4096] = "# column row X Y Z\n";
    for (int i = 0; i < 6; i++)
        snprintf(pairs + strlen(pairs), sizeof pairs - strlen(pairs), "%d %d %d %d 3\n", 10 + 17 * i, 10 + 7 * i, i,
                 2 * i + 1);
    char text[8192];
    snprintf(text, sizeof text, "%s10 10 0 1 3  # line 2 again\n", pairs);
    rs_test_write(rs_test_path(dir, "pairs.txt"), text);
    EXPECT(dir, 1, calib_cmd(), "pairs.txt:8:", "listed twice (also on line 2)");
    snprintf(text, sizeof text, "%s1 2 nan 4 5\n", pairs);
    rs_test_write(rs_test_path(dir, "pairs.txt"), text);
    EXPECT(dir, 1, calib_cmd(), "pairs.txt:8:", "X is nan", "expected finite numbers");
    snprintf(text, sizeof text, "%s1 2 3 4 5 6\n", pairs);
    rs_test_write(rs_test_path(dir, "pairs.txt"), text);
    EXPECT(dir, 1, calib_cmd(), "pairs.txt:8:", "five numbers");
    /* A line longer than the old 1024-byte buffer was read as two lines: read whole, it is the
     * pair of line 2 again. */
    char longline[3000];
    memset(longline, ' ', sizeof longline);
    memcpy(longline, "10 10 0", 7);
    memcpy(longline + 2000, "1 3\n", 5);
    snprintf(text, sizeof text, "%s%s", pairs, longline);
    rs_test_write(rs_test_path(dir, "pairs.txt"), text);
    EXPECT(dir, 1, calib_cmd(), "pairs.txt:8:", "listed twice (also on line 2)");
    rs_test_rmtree(dir);
}

/* ---- COLMAP text models (rhoscan-calib) ---- */

/* dir/model: the committed model with one line of one file replaced (line 0: none). */
static void write_colmap_model(const char *dir, const char *file, int line, const char *text)
{
    static const char *const files[] = {"cameras.txt", "images.txt", "points3D.txt"};
    char path[4096];
    snprintf(path, sizeof path, "%s/model", dir);
    mkdir(path, 0777);
    for (int k = 0; k < 3; k++) {
        char from[4096], *data;
        size_t size;
        rs_err err;
        snprintf(from, sizeof from, "%s/sample_data/colmap_courtyard/model/%s", src(), files[k]);
        if (rs_read_file(from, &data, &size, &err) != 0) fail_msg("%s", err.msg);
        snprintf(path, sizeof path, "%s/model/%s", dir, files[k]);
        FILE *f = fopen(path, "wb");
        assert_non_null(f);
        long n = 0;
        for (char *p = data; *p;) {
            char *nl = strchr(p, '\n');
            size_t len = nl ? (size_t)(nl - p + 1) : strlen(p);
            if (++n == line && strcmp(files[k], file) == 0)
                fprintf(f, "%s\n", text);
            else
                fwrite(p, 1, len, f);
            p += len;
        }
        fclose(f);
        free(data);
    }
}

static void test_colmap_text(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("surf_colmap");
    char text[4096], cmd[2048];
    snprintf(
        text, sizeof text,
        "[pipeline]\nworkdir = out\n[colmap]\nmodel = model\nviews = %s/sample_data/colmap_courtyard/views.txt\n"
        "control_points = %s/sample_data/colmap_courtyard/control_points.txt\n[capture]\ncolmap_panorama = pano3\n",
        src(), src());
    rs_test_write(rs_test_path(dir, "c.ini"), text);
    snprintf(cmd, sizeof cmd, "'%s/rhoscan-calib' c.ini", rs_test_bin_dir());
    write_colmap_model(dir, "", 0, "");
    EXPECT(dir, 0, cmd, "calib: done");
    write_colmap_model(dir, "cameras.txt", 4, "1 PINHOLE 512 512 0 256 256 256");
    EXPECT(dir, 1, cmd, "cameras.txt:4:", "a focal length) = 0", "expected a focal length > 0");
    write_colmap_model(dir, "cameras.txt", 4, "1 PINHOLE 512 512 nan 256 256 256");
    EXPECT(dir, 1, cmd, "cameras.txt:4:", "\"nan\": expected a finite number");
    write_colmap_model(dir, "cameras.txt", 4, "1 PINHOLE 4294967296 512 256 256 256 256");
    EXPECT(dir, 1, cmd, "cameras.txt:4:", "WIDTH HEIGHT = 4294967296 512");
    /* 200 digits used to be cut to 127 and read as a smaller number. */
    char big[400] = "1 PINHOLE 512 512 256.";
    for (int i = 0; i < 200; i++) strcat(big, "0");
    strcat(big, "1 256 256 256");
    write_colmap_model(dir, "cameras.txt", 4, big);
    EXPECT(dir, 1, cmd, "cameras.txt:4:", "characters: expected a number of at most 127");
    write_colmap_model(dir, "cameras.txt", 4, "-1 PINHOLE 512 512 256 256 256 256");
    EXPECT(dir, 1, cmd, "cameras.txt:4:", "CAMERA_ID) = -1");
    rs_test_rmtree(dir);
}

/* ---- keys of a whole run: datetime and sun, grey card, captures, sky panoramas (rhoscan) ---- */

static char base_dir[512];

/* `rhoscan run` on the sample in dir/work with few rays, plus args; with_mesh: the true mesh as
 * [mesh] input_mesh (else the sample's scan). Static buffer. */
static const char *rhoscan_cmd(const char *dir, int with_mesh, const char *args)
{
    static char cmd[6144];
    char mesh[2048] = "";
    if (with_mesh) snprintf(mesh, sizeof mesh, "--set mesh.input_mesh='%s/sample_data/two_planes/truth.ply'", src());
    int n = snprintf(cmd, sizeof cmd,
                     "'%s/rhoscan' run '%s/configs/two_planes.ini' --set pipeline.workdir='%s/work' %s "
                     "--set irradiance.samples=32 --set irradiance.sky_samples=32 --set irradiance.sun_samples=8 %s",
                     rs_test_bin_dir(), src(), dir, mesh, args);
    if (n >= (int)sizeof cmd) fail_msg("command too long: %s", cmd);
    return cmd;
}

#define run_cmd(args) rhoscan_cmd(dir, 1, args)

/* The work folder of one good run, made once for the tests that rerun a single stage on it. */
static int setup_base(void **state)
{
    (void)state;
    if (base_dir[0]) return 0;
    snprintf(base_dir, sizeof base_dir, "%s", rs_test_tmpdir("surf_run"));
    char full[8192];
    snprintf(full, sizeof full, "cd '%s' && %s", base_dir, rhoscan_cmd(base_dir, 1, ""));
    return rs_test_run(full, NULL) == 0 ? 0 : -1;
}

static void test_datetime_and_sun(void **state)
{
    (void)state;
    const char *d = base_dir, *dir = base_dir;
    const char *site = "--set sky.latitude_deg=40 --set sky.longitude_deg=-3 --only irradiance";
    char args[1024];
#define DT(text) (snprintf(args, sizeof args, "--set 'sky.datetime=%s' %s", text, site), run_cmd(args))
    EXPECT(d, 1, DT("2021-02-30T12:00:00Z"), "two_planes.ini", "[sky] datetime", "day 30: February 2021 has 28 days");
    EXPECT(d, 1, DT("2100-02-29T12:00:00Z"), "day 29: February 2100 has 28 days");
    EXPECT(d, 1, DT("2021-06-01T12:00:00+99:00"), "two_planes.ini", "time zone +99:00", "at most 14 hours");
    EXPECT(d, 1, DT("2021-06-01T12:00:00-14:30"), "time zone -14:30");
    /* Seconds of NaN hung the run (an infinite sky map made every sample walk the map). */
    EXPECT(d, 1, DT("2021-06-01T12:00:nan"), "two_planes.ini", "the seconds are not two digits");
    EXPECT(d, 1, DT("2021-06-01T12:00:infZ"), "the seconds are not two digits");
    EXPECT(d, 1, DT("2021-06-01T25:00:00Z"), "time 25:00");
    EXPECT(d, 1, DT("2021-13-01T12:00Z"), "month 13");
    EXPECT(d, 1, DT("2021-06-01T12:00:00Zjunk"), "\"junk\" after the time");
    EXPECT(d, 0, DT("2020-02-29T12:00:30.5+05:30"), "NOAA solar position for 2020-02-29T12:00:30.5+05:30");
#undef DT
    EXPECT(d, 1, run_cmd("--set sky.sun_azimuth_deg=nan --set sky.sun_elevation_deg=30 --only irradiance"),
           "sun_azimuth_deg", "nan");
    EXPECT(d, 1, run_cmd("--set sky.sun_irradiance=1e400 --only irradiance"), "sun_irradiance", "1e400");
}

static void test_grey_card(void **state)
{
    (void)state;
    const char *d = base_dir, *dir = base_dir;
    /* sscanf's %d wrapped 4294967396 to 100, a region on the card: accepted. */
    EXPECT(d, 1, run_cmd("--set 'calib.grey_card_region=4294967396 0 4294967496 10' --only reflectance"),
           "two_planes.ini", "[calib] grey_card_region", "value 1 is not an integer from 0 to 1048576");
    EXPECT(d, 1, run_cmd("--set 'calib.grey_card_region=0 0 99999999999 10' --only reflectance"), "value 3");
    EXPECT(d, 1, run_cmd("--set 'calib.grey_card_region=10 10 5 20' --only reflectance"), "the region is empty");
    EXPECT(d, 1, run_cmd("--set 'calib.grey_card_region=1 2 3' --only reflectance"), "value 4");
    EXPECT(d, 1,
           run_cmd("--set 'calib.grey_card_region=0 0 10 10' --set calib.grey_card_albedo=1e999 --only reflectance"),
           "grey_card_albedo");
}

static void test_captures_and_sky(void **state)
{
    (void)state;
    const char *d = base_dir, *dir = base_dir;
    EXPECT(d, 1, run_cmd("--set 'capture.b.position=0 nan 4' --set capture.b.panorama=pano.exr --only observe"),
           "[capture.b] position", "nan");
    EXPECT(d, 1, run_cmd("--set capture.b.panorama=none.exr --set 'capture.b.position=0 -9 4' --only irradiance"),
           "none.exr");
    EXPECT(d, 1, run_cmd("--set sky.panorama=nowhere.exr --set 'sky.position=0 -9 4' --only irradiance"),
           "nowhere.exr");
    EXPECT(d, 1, run_cmd("--set sky.panorama=pano.exr --set 'sky.position=0 -9 inf' --only irradiance"),
           "[sky] position", "inf");
}

/* ---- input meshes and clouds ---- */

static void write_ascii_mesh(const char *path, const float (*v)[3], int nv, const int (*f)[3], int nf)
{
    FILE *fp = fopen(path, "w");
    assert_non_null(fp);
    fprintf(fp,
            "ply\nformat ascii 1.0\nelement vertex %d\nproperty float x\nproperty float y\nproperty float z\n"
            "element face %d\nproperty list uchar int vertex_indices\nend_header\n",
            nv, nf);
    for (int i = 0; i < nv; i++) fprintf(fp, "%.9g %.9g %.9g\n", v[i][0], v[i][1], v[i][2]);
    for (int i = 0; i < nf; i++) fprintf(fp, "3 %d %d %d\n", f[i][0], f[i][1], f[i][2]);
    fclose(fp);
}

static void test_meshes(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("surf_mesh");
    char args[2048];
    /* Corners on one line, written in decimal: in float they keep a tiny area. */
    static const float line[][3] = {{0, 0, 0}, {0.1f, 0.2f, 0.3f}, {0.3f, 0.6f, 0.9f}, {0.7f, 1.4f, 2.1f}};
    static const int tris[][3] = {{0, 1, 2}, {1, 2, 3}, {0, 1, 3}};
    write_ascii_mesh(rs_test_path(dir, "collinear.ply"), line, 4, tris, 3);
    snprintf(args, sizeof args, "--only mesh --set mesh.input_mesh='%s/collinear.ply'", dir);
    EXPECT(dir, 1, run_cmd(args), "collinear.ply", "[mesh] input_mesh", "none of its 3 faces is a usable triangle",
           "3 with collinear corners");
    static const float same[][3] = {{1, 1, 1}, {1, 1, 1}, {1, 1, 1}};
    write_ascii_mesh(rs_test_path(dir, "point.ply"), same, 3, tris, 1);
    snprintf(args, sizeof args, "--only mesh --set mesh.input_mesh='%s/point.ply'", dir);
    EXPECT(dir, 1, run_cmd(args), "point.ply", "1 of zero area");

    /* Two million copies of one triangle: every ray met all of them (observe 34 s, irradiance past
     * 400 s). Now found while reading, with progress, and the run ends well within the limit. */
    const uint32_t n = 2000000;
    char head[512];
    int hl = snprintf(head, sizeof head,
                      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                      "property float z\nelement face %u\nproperty list uchar int vertex_indices\nend_header\n",
                      n);
    size_t size = (size_t)hl + 36 + 13 * (size_t)n;
    unsigned char *data = malloc(size), *p = data + hl;
    memcpy(data, head, (size_t)hl);
    const float v[9] = {-1, -1, 0.01f, 1, -1, 0.01f, 0, 1, 0.01f};
    memcpy(p, v, 36);
    p += 36;
    for (uint32_t k = 0; k < n; k++, p += 13) {
        static const unsigned char face[13] = {3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0};
        memcpy(p, face, 13);
    }
    write_bytes(rs_test_path(dir, "coincident.ply"), data, size);
    free(data);
    double t0 = (double)time(NULL);
    snprintf(args, sizeof args, "--set mesh.input_mesh='%s/coincident.ply'", dir);
    EXPECT(dir, 0, run_cmd(args), "checking the input mesh's faces: 50%",
           "dropped 1999999 faces of 2000000 that repeat the corners of another face");
    print_message("2 million coincident triangles: the whole run in %.0f s\n", (double)time(NULL) - t0);
    rs_test_rmtree(dir);
}

static void write_pcd(const char *path, const char *fields, const char *size, const char *type, int npts,
                      const char *points)
{
    char text[65536];
    int count = 1;
    for (const char *c = fields; *c; c++) count += *c == ' ';
    char counts[64] = "";
    for (int i = 0; i < count; i++) strcat(counts, i ? " 1" : "1");
    snprintf(text, sizeof text,
             "# .PCD v0.7\nVERSION 0.7\nFIELDS %s\nSIZE %s\nTYPE %s\nCOUNT %s\nWIDTH %d\nHEIGHT 1\n"
             "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA ascii\n%s",
             fields, size, type, counts, npts, npts, points);
    rs_test_write(path, text);
}

static void test_clouds(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("surf_cloud");
    char args[2048], pts[32768] = "";
    for (int i = 0; i < 400; i++)
        snprintf(pts + strlen(pts), sizeof pts - strlen(pts), "%g %g %g\n", (i % 20) * 0.5, (i / 20) * 0.5,
                 0.01 * (i % 7));
    char text[40000];
    const char *scan = "--only ingest --force --set 'ingest.scanner_position=0 -9 4' --set ingest.scan=";
    /* PCD: infinite and far coordinates, an intensity beyond float, a field outside the record. */
    snprintf(text, sizeof text, "inf 0 0\n%s", pts);
    write_pcd(rs_test_path(dir, "inf.pcd"), "x y z", "4 4 4", "F F F", 401, text);
    snprintf(args, sizeof args, "%s'%s/inf.pcd'", scan, dir);
    EXPECT(dir, 1, rhoscan_cmd(dir, 0, args), "inf.pcd", "point 0: coordinates (inf, 0, 0)",
           "expected -1e+09 to 1e+09 (m)");
    snprintf(text, sizeof text, "3e9 0 0\n%s", pts);
    write_pcd(rs_test_path(dir, "far.pcd"), "x y z", "8 8 8", "F F F", 401, text);
    snprintf(args, sizeof args, "%s'%s/far.pcd'", scan, dir);
    EXPECT(dir, 1, rhoscan_cmd(dir, 0, args), "far.pcd", "coordinates (3e+09, 0, 0)");
    write_pcd(rs_test_path(dir, "bigi.pcd"), "x y z intensity", "4 4 4 8", "F F F F", 1, "1 2 3 1e300\n");
    snprintf(args, sizeof args, "%s'%s/bigi.pcd'", scan, dir);
    EXPECT(dir, 1, rhoscan_cmd(dir, 0, args), "bigi.pcd", "intensity 1e+300", "float range");
    write_pcd(rs_test_path(dir, "nan.pcd"), "x y z", "4 4 4", "F F F", 2, "nan 0 0\nnan 1 1\n");
    snprintf(args, sizeof args, "%s'%s/nan.pcd'", scan, dir);
    EXPECT(dir, 1, rhoscan_cmd(dir, 0, args), "nan.pcd", "no point with finite coordinates among 2");
    /* XYZ: intensity beyond float, colour above 255, a coordinate of 1e300. */
    snprintf(text, sizeof text, "1 2 3 1e300\n");
    rs_test_write(rs_test_path(dir, "bigi.xyz"), text);
    snprintf(args, sizeof args, "%s'%s/bigi.xyz' --set 'ingest.columns=x y z intensity'", scan, dir);
    EXPECT(dir, 1, rhoscan_cmd(dir, 0, args), "bigi.xyz:1:", "column 4: intensity 1e+300");
    rs_test_write(rs_test_path(dir, "rgb.xyz"), "1 2 3 300 0 0\n");
    snprintf(args, sizeof args, "%s'%s/rgb.xyz' --set 'ingest.columns=x y z r g b'", scan, dir);
    EXPECT(dir, 1, rhoscan_cmd(dir, 0, args), "rgb.xyz:1:", "column 4: colour 300", "expected 0 to 255");
    snprintf(text, sizeof text, "%s1e300 0 0\n", pts);
    rs_test_write(rs_test_path(dir, "far.xyz"), text);
    snprintf(args, sizeof args, "%s'%s/far.xyz'", scan, dir);
    EXPECT(dir, 1, rhoscan_cmd(dir, 0, args), "far.xyz:401:", "column 1: coordinate 1e+300");
    /* Degenerate clouds: every point the same (PCL's kd-tree took 214 s on 200000), all on a line. */
    size_t big = 200000, len = strlen("1 2 3\n");
    char *same = malloc(big * len + 1);
    for (size_t k = 0; k < big; k++) memcpy(same + k * len, "1 2 3\n", len);
    write_bytes(rs_test_path(dir, "same.xyz"), same, big * len);
    free(same);
    snprintf(args, sizeof args, "%s'%s/same.xyz'", scan, dir);
    EXPECT(dir, 1, rhoscan_cmd(dir, 0, args), "same.xyz", "[ingest] scan",
           "200000 unorganized points are at 1 distinct position");
    FILE *f = fopen(rs_test_path(dir, "line.xyz"), "w");
    for (int k = 0; k < 5000; k++) fprintf(f, "%g %g %g\n", k * 0.01, 2 * k * 0.01, 3 * k * 0.01);
    fclose(f);
    snprintf(args, sizeof args, "%s'%s/line.xyz'", scan, dir);
    EXPECT(dir, 1, rhoscan_cmd(dir, 0, args), "line.xyz", "lie on one line");
    rs_test_write(rs_test_path(dir, "empty.xyz"), "# nothing\n");
    snprintf(args, sizeof args, "%s'%s/empty.xyz'", scan, dir);
    EXPECT(dir, 1, rhoscan_cmd(dir, 0, args), "empty.xyz", "no point lines");
    rs_test_rmtree(dir);
}

/* ---- paths and outputs ---- */

static void test_long_path(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("surf_long");
    char path[2048];
    snprintf(path, sizeof path, "%s", dir);
    for (int i = 0; i < 14; i++) {
        snprintf(path + strlen(path), sizeof path - strlen(path), "/d%02d_%s", i,
                 "a_folder_name_of_forty_characters_xxxxxx");
        mkdir(path, 0777);
    }
    assert_true(strlen(path) > 600);
    snprintf(path + strlen(path), sizeof path - strlen(path), "/the_bad_mesh.ply");
    rs_test_write(path, "ply\nformat ascii 1.0\nelement vertex 1\n");
    char args[4096];
    snprintf(args, sizeof args, "--only mesh --set mesh.input_mesh='%s'", path);
    EXPECT(dir, 1, run_cmd(args), "/the_bad_mesh.ply:3: the header has no 'end_header' line", dir);
    rs_test_rmtree(dir);
}

/* Bytes of every PLY and EXR of work, concatenated with their names. */
static char *outputs(const char *work, size_t *n)
{
    static const char *const names[] = {"mesh.ply",     "observe.ply", "irradiance.ply", "transport.ply", "albedo.ply",
                                        "facet_id.exr", "albedo.exr",  "irradiance.exr", "synth.exr"};
    char *all = NULL;
    *n = 0;
    for (size_t k = 0; k < sizeof names / sizeof *names; k++) {
        char path[4096], *data;
        size_t size;
        rs_err err;
        snprintf(path, sizeof path, "%s/%s", work, names[k]);
        if (rs_read_file(path, &data, &size, &err) != 0) fail_msg("%s", err.msg);
        all = realloc(all, *n + size + 64);
        *n += (size_t)snprintf(all + *n, 64, "%s:", names[k]);
        memcpy(all + *n, data, size);
        *n += size;
        free(data);
    }
    return all;
}

/* A read-only work folder: the rerun cannot write albedo.ply, says so (exit 2), and every earlier
 * output stays byte-identical. Root ignores permissions: the rerun then drops to nobody. */
static void test_read_only_workdir(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("surf_ro");
    char work[1024], cmd[8192];
    snprintf(work, sizeof work, "%s/work", dir);
    EXPECT(dir, 0, run_cmd(""), "stages run");
    size_t n0, n1;
    char *before = outputs(work, &n0);
    const char *as = "";
    if (geteuid() == 0) {
        if (rs_test_run("command -v setpriv", NULL) != 0) {
            print_message("skipped: running as root without setpriv, permissions cannot fail\n");
            free(before);
            rs_test_rmtree(dir);
            return;
        }
        as = "setpriv --reuid=65534 --regid=65534 --clear-groups ";
    }
    snprintf(cmd, sizeof cmd, "chmod -R a+rX '%s' && chmod 555 '%s' '%s/.rhoscan'", dir, work, work);
    assert_int_equal(rs_test_run(cmd, NULL), 0);
    snprintf(cmd, sizeof cmd, "%s%s", as, run_cmd("--set reflectance.method=direct"));
    EXPECT(dir, 2, cmd, "work/albedo.ply: cannot create a temporary file beside the output: Permission denied");
    char *after = outputs(work, &n1);
    assert_true(n0 == n1 && memcmp(before, after, n0) == 0);
    free(before);
    free(after);
    snprintf(cmd, sizeof cmd, "chmod 755 '%s' '%s/.rhoscan'", work, work);
    assert_int_equal(rs_test_run(cmd, NULL), 0);
    rs_test_rmtree(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_rig_values),
        cmocka_unit_test(test_brackets_and_response),
        cmocka_unit_test(test_pairs),
        cmocka_unit_test(test_colmap_text),
        cmocka_unit_test_setup(test_datetime_and_sun, setup_base),
        cmocka_unit_test_setup(test_grey_card, setup_base),
        cmocka_unit_test_setup(test_captures_and_sky, setup_base),
        cmocka_unit_test(test_meshes),
        cmocka_unit_test(test_clouds),
        cmocka_unit_test(test_long_path),
        cmocka_unit_test(test_read_only_workdir),
    };
    int failed = cmocka_run_group_tests(tests, NULL, NULL);
    if (base_dir[0]) rs_test_rmtree(base_dir);
    return failed;
}
