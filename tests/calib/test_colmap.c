/* Tests of the COLMAP import (calib/colmap.h): Umeyama on synthetic points, the model that the real
 * colmap 3.8 binary made from sample_data/colmap_courtyard's views, and errors that name the line. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "pipeline/calib_files.h"
#include "calib/calib_math.h"
#include "calib/colmap.h"
#include "tests/testutil.h"

static double urand(uint64_t *s)
{
    *s = *s * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(*s >> 11) / 9007199254740992.0;
}

/* A known similarity recovered to 1e-9; one displaced point shows up in the residuals. */
static void test_umeyama_synthetic(void **state)
{
    (void)state;
    uint64_t s = 7;
    double w[3] = {0.3, -1.1, 0.7}, r[9];
    rs_calib_rot_exp(w, r);
    const double scale = 3.7;
    const rs_v3 t = {12, -4, 0.5};
    rs_v3 model[8], world[8];
    for (int i = 0; i < 8; i++) {
        model[i] = rs_v3_make(urand(&s) * 4 - 2, urand(&s) * 4 - 2, urand(&s) * 4 - 2);
        world[i] = rs_v3_add(rs_v3_scale(rs_m3_mul_v(r, model[i]), scale), t);
    }
    rs_colmap_similarity sim;
    double resid[8];
    rs_err err = {0};
    assert_int_equal(rs_colmap_umeyama(8, model, world, &sim, resid, &err), 0);
    assert_true(fabs(sim.scale - scale) < 1e-9);
    assert_true(rs_calib_rot_angle(sim.rot, r) < 1e-9);
    assert_true(rs_v3_len(rs_v3_sub(sim.t, t)) < 1e-9);
    assert_true(sim.rms_m < 1e-9);
    for (int i = 0; i < 8; i++) assert_true(resid[i] < 1e-9);
    /* Displace one scan point by 0.3 m: it gets the largest residual, and the RMS is that of the list. */
    world[5].z += 0.3;
    assert_int_equal(rs_colmap_umeyama(8, model, world, &sim, resid, &err), 0);
    double sum = 0;
    for (int i = 0; i < 8; i++) {
        sum += resid[i] * resid[i];
        if (i != 5) assert_true(resid[i] < resid[5]);
    }
    assert_true(resid[5] > 0.1);
    assert_true(fabs(sim.rms_m - sqrt(sum / 8)) < 1e-12);
    assert_true(fabs(sim.max_m - resid[5]) < 1e-12);
    /* Too few and collinear points. */
    assert_int_equal(rs_colmap_umeyama(2, model, world, &sim, NULL, &err), -1);
    assert_non_null(strstr(err.msg, "at least 3"));
    for (int i = 0; i < 4; i++) world[i] = rs_v3_make(i, 2 * i, 1);
    assert_int_equal(rs_colmap_umeyama(4, model, world, &sim, NULL, &err), -1);
    assert_non_null(strstr(err.msg, "one line in the scan's frame"));
    for (int i = 0; i < 4; i++) model[i] = rs_v3_make(0, 0, i);
    world[3].z = 5;
    assert_int_equal(rs_colmap_umeyama(4, model, world, &sim, NULL, &err), -1);
    assert_non_null(strstr(err.msg, "one line in the COLMAP model"));
}

/* "# Number of images: 29, ..." as COLMAP writes it in the file's header. */
static long header_count(const char *path, const char *what)
{
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char line[512];
    long n = -1;
    while (fgets(line, sizeof line, f) && line[0] == '#') {
        const char *p = strstr(line, what);
        if (p) n = strtol(p + strlen(what), NULL, 10);
    }
    fclose(f);
    return n;
}

typedef struct {
    char name[64];
    rs_pose pose;
} truth_pose;

static int read_truth(const char *path, truth_pose *t, int max)
{
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char line[1024];
    int n = 0;
    while (n < max && fgets(line, sizeof line, f)) {
        double *r = t[n].pose.rot;
        if (sscanf(line, "%63s %lf %lf %lf %lf %lf %lf %lf %lf %lf %lf %lf %lf", t[n].name, &t[n].pose.position.x,
                   &t[n].pose.position.y, &t[n].pose.position.z, &r[0], &r[1], &r[2], &r[3], &r[4], &r[5], &r[6], &r[7],
                   &r[8]) == 13)
            n++;
    }
    fclose(f);
    return n;
}

/* The committed model of the real binary: its counts agree with COLMAP's own header; aligned by
 * three panorama centres, it places the fourth (held out) panorama and orients all four. */
static void test_real_model(void **state)
{
    (void)state;
    char dir[2048], model[2300], path[2400];
    snprintf(dir, sizeof dir, "%s/sample_data/colmap_courtyard", rs_test_source_dir());
    snprintf(model, sizeof model, "%s/model", dir);
    rs_colmap_model m;
    rs_err err = {0};
    assert_int_equal(rs_colmap_read(model, &m, &err), 0);
    snprintf(path, sizeof path, "%s/cameras.txt", model);
    assert_int_equal(m.ncameras, header_count(path, "Number of cameras:"));
    snprintf(path, sizeof path, "%s/images.txt", model);
    assert_int_equal(m.nimages, header_count(path, "Number of images:"));
    snprintf(path, sizeof path, "%s/points3D.txt", model);
    assert_int_equal(m.npoints, header_count(path, "Number of points:"));
    assert_string_equal(m.cameras[0].model, "PINHOLE");
    assert_true(m.nimages >= 24); /* of the 32 views cut; the mapper may leave a few out */

    rs_colmap_view *views = NULL;
    rs_colmap_control *cps = NULL;
    int nv = 0, nc = 0;
    snprintf(path, sizeof path, "%s/views.txt", dir);
    assert_int_equal(rs_colmap_views_read(path, &views, &nv, &err), 0);
    assert_int_equal(nv, 32);
    snprintf(path, sizeof path, "%s/control_points.txt", dir);
    assert_int_equal(rs_colmap_controls_read(path, &cps, &nc, &err), 0);
    assert_int_equal(nc, 3);
    rs_v3 mx[3], wx[3];
    assert_int_equal(rs_colmap_controls_locate(&m, views, nv, cps, nc, path, mx, &err), 0);
    for (int i = 0; i < 3; i++) wx[i] = cps[i].world;
    rs_colmap_similarity sim;
    double resid[3];
    assert_int_equal(rs_colmap_umeyama(3, mx, wx, &sim, resid, &err), 0);
    /* Views cut from one panorama share its centre, and SIFT on 512 px views (0.18 deg per pixel)
     * at 2-8 m places a centre to a few millimetres (measured: 2 mm at the control points, 7 mm
     * for the held-out pano3); 2 cm bounds both, and 0.3 deg (under 2 px) the rotations
     * (measured 0.07-0.21 deg; single views scatter up to 0.5 deg around their mean). */
    print_message("COLMAP courtyard: scale %.4f m/unit, control residuals %.4f %.4f %.4f m (rms %.4f)\n", sim.scale,
                  resid[0], resid[1], resid[2], sim.rms_m);
    assert_true(sim.rms_m < 0.02);

    truth_pose truth[8];
    snprintf(path, sizeof path, "%s/poses.txt", dir);
    int nt = read_truth(path, truth, 8);
    assert_int_equal(nt, 4);
    for (int i = 0; i < nt; i++) {
        rs_colmap_pano pp;
        assert_int_equal(rs_colmap_pano_pose(&m, views, nv, truth[i].name, &sim, &pp, &err), 0);
        double dpos = rs_v3_len(rs_v3_sub(pp.pose.position, truth[i].pose.position));
        double drot = rs_calib_rot_angle(pp.pose.rot, truth[i].pose.rot) * 180 / M_PI;
        print_message("  %s: %d/%d views, centre off by %.4f m, rotation by %.4f deg; views agree within %.4f deg, "
                      "%.4f m\n",
                      truth[i].name, pp.views, pp.views_listed, dpos, drot, pp.spread_deg, pp.spread_m);
        assert_true(pp.views >= 4);
        assert_true(dpos < 0.02); /* pano3 is not a control point: this is a prediction */
        assert_true(drot < 0.3);
        assert_true(pp.spread_deg < 1.0);
    }
    free(views);
    free(cps);
    rs_colmap_release(&m);
}

/* A fresh folder holding a text model of the three files. */
static const char *write_model(const char *tag, const char *cams, const char *imgs, const char *pts)
{
    const char *dir = rs_test_tmpdir(tag);
    rs_test_write(rs_test_path(dir, "cameras.txt"), cams);
    rs_test_write(rs_test_path(dir, "images.txt"), imgs);
    rs_test_write(rs_test_path(dir, "points3D.txt"), pts);
    return dir;
}

/* A bad model file: the error names the file, the line and the field. */
static void expect_model_error(const char *cams, const char *imgs, const char *pts, const char *file, long line,
                               const char *text)
{
    const char *dir = write_model("colmap_bad", cams, imgs, pts);
    rs_colmap_model m;
    rs_err err = {0};
    assert_int_equal(rs_colmap_read(dir, &m, &err), -1);
    if (!strstr(err.file, file) || err.line != line || !strstr(err.msg, text))
        fail_msg("got %s:%ld: %s; expected %s:%ld: ...%s...", err.file, err.line, err.msg, file, line, text);
    rs_test_rmtree(dir);
}

static void test_bad_files(void **state)
{
    (void)state;
    const char *cams = "# c\n1 PINHOLE 640 480 500 500 320 240\n";
    const char *imgs = "# i\n1 1 0 0 0 0 0 0 1 a.png\n10 20 7 11 30 -1\n2 1 0 0 0 1 0 0 1 b.png\n\n";
    const char *pts = "7 1 2 3 255 0 0 0.5 1 0\n";
    /* The good files read. */
    const char *dir = write_model("colmap_good", cams, imgs, pts);
    rs_colmap_model m;
    rs_err err = {0};
    assert_int_equal(rs_colmap_read(dir, &m, &err), 0);
    assert_int_equal(m.nimages, 2);
    assert_int_equal(m.images[0].points2d, 2);
    assert_int_equal(m.images[0].points2d_with_3d, 1);
    assert_int_equal(m.images[1].points2d, 0);
    assert_true(fabs(m.images[1].centre.x + 1) < 1e-12); /* C = -R^T t */
    rs_colmap_release(&m);
    rs_test_rmtree(dir);

    expect_model_error("1 PINHOL 640 480 1 2 3 4\n", imgs, pts, "cameras.txt", 1, "(MODEL) = \"PINHOL\"");
    expect_model_error("# c\n1 OPENCV 640 480 1 2 3 4\n", imgs, pts, "cameras.txt", 2, "parameter 5 of 8 of OPENCV");
    expect_model_error(cams, "1 0 0 0 0 0 0 0 1 a.png\n\n", pts, "images.txt", 1, "unit quaternion");
    expect_model_error(cams, "1 1 0 0 0 0 0 0 9 a.png\n\n", pts, "images.txt", 1, "(CAMERA_ID) = 9");
    expect_model_error(cams, "1 1 0 0 0 0 0 0 1 a.png\n", pts, "images.txt", 1, "expected a line of 2D points");
    expect_model_error(cams, "1 1 0 0 0 0 0 0 1 a.png\n10 20 8\n", pts, "images.txt", 2, "(POINT3D_ID) = 8");
    expect_model_error(cams, "1 1 0 0 0 0 0 0 1 a.png\n10 20\n", pts, "images.txt", 2, "POINT3D_ID");
    expect_model_error(cams, "1 1 0 0 0 x 0 0 1 a.png\n\n", pts, "images.txt", 1, "field 6 (TX) = \"x\"");
    expect_model_error(cams, imgs, "7 1 2 3 255 0 0 0.5 1\n", "points3D.txt", 1, "TRACK POINT2D_IDX");
    expect_model_error(cams, imgs, "7 1 2 3 255 0 0 0.5 5 0\n", "points3D.txt", 1, "(TRACK IMAGE_ID) = 5");
    expect_model_error(cams, imgs, "7 1 2 3 255 0 0 0.5 1 0\n7 1 2 3 0 0 0 1\n", "points3D.txt", 2, "listed twice");

    /* Views and control points. */
    dir = rs_test_tmpdir("colmap_files");
    rs_colmap_view *views = NULL;
    rs_colmap_control *cps = NULL;
    int n = 0;
    rs_test_write(rs_test_path(dir, "views.txt"), "# v\na.png p 1 0 0 0 1 0 0 0 1\nb.png p 1 0 0 0 1 0 0 0 2\n");
    assert_int_equal(rs_colmap_views_read(rs_test_path(dir, "views.txt"), &views, &n, &err), -1);
    assert_int_equal(err.line, 3);
    assert_non_null(strstr(err.msg, "not a rotation"));
    rs_test_write(rs_test_path(dir, "cp.txt"), "image a.png 0 0 0\npoint 7 1 0 0\n");
    assert_int_equal(rs_colmap_controls_read(rs_test_path(dir, "cp.txt"), &cps, &n, &err), -1);
    assert_non_null(strstr(err.msg, "2 control points: expected at least 3"));
    rs_test_write(rs_test_path(dir, "cp.txt"), "image a.png 0 0 0\npoint 7 1 0 0\nstar x 1 2 3\n");
    assert_int_equal(rs_colmap_controls_read(rs_test_path(dir, "cp.txt"), &cps, &n, &err), -1);
    assert_int_equal(err.line, 3);
    assert_non_null(strstr(err.msg, "expected image, point or panorama"));
    rs_test_rmtree(dir);
}

/* The pose file keeps one block per section; a file without section lines is [capture]'s. */
static void test_pose_file(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("colmap_pose");
    const char *path = rs_test_path(dir, "capture_pose.txt");
    rs_pose a = {{1, 2, 3}, {1, 0, 0, 0, 1, 0, 0, 0, 1}}, b = {{-4, 5, 6}, {0, -1, 0, 1, 0, 0, 0, 0, 1}}, got;
    rs_err err = {0};
    assert_int_equal(rs_calib_pose_write(path, "capture", &a, &err), 0);
    assert_int_equal(rs_calib_pose_write(path, "capture.north", &b, &err), 0);
    a.position.x = 7;
    assert_int_equal(rs_calib_pose_write(path, "capture", &a, &err), 0);
    assert_int_equal(rs_calib_pose_read(path, "capture", &got, &err), 0);
    assert_true(got.position.x == 7);
    assert_int_equal(rs_calib_pose_read(path, "capture.north", &got, &err), 0);
    assert_true(got.position.x == -4 && got.rot[1] == -1);
    assert_int_equal(rs_calib_pose_read(path, "capture.south", &got, &err), -1);
    assert_non_null(strstr(err.msg, "no pose for [capture.south]"));
    rs_test_write(path, "position 1 1 1\nrotation 1 0 0 0 1 0 0 0 1\n");
    assert_int_equal(rs_calib_pose_read(path, "capture", &got, &err), 0);
    assert_true(got.position.z == 1);
    rs_test_rmtree(dir);
}

/* The calib stage as a program: [colmap] poses [capture] and [capture.b] into capture_pose.txt;
 * a capture naming a panorama without [colmap] model is refused. */
static void test_stage(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("colmap_stage");
    const char *src = rs_test_source_dir();
    char text[4096], cmd[4096], *out = NULL;
    snprintf(text, sizeof text,
             "[pipeline]\nworkdir = out\n[colmap]\nmodel = %s/sample_data/colmap_courtyard/model\n"
             "views = %s/sample_data/colmap_courtyard/views.txt\n"
             "control_points = %s/sample_data/colmap_courtyard/control_points.txt\n"
             "[capture]\ncolmap_panorama = pano3\n[capture.b]\ncolmap_panorama = pano1\n",
             src, src, src);
    rs_test_write(rs_test_path(dir, "c.ini"), text);
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/rhoscan-calib' c.ini", dir, rs_test_bin_dir());
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) fail_msg("rhoscan-calib: %s", out);
    free(out);
    rs_pose p3, p1;
    rs_err err = {0};
    char path[4096];
    snprintf(path, sizeof path, "%s/out/capture_pose.txt", dir);
    assert_int_equal(rs_calib_pose_read(path, "capture", &p3, &err), 0);
    assert_int_equal(rs_calib_pose_read(path, "capture.b", &p1, &err), 0);
    assert_true(rs_v3_len(rs_v3_sub(p3.position, rs_v3_make(-1, -3.5, 1.7))) < 0.02);
    assert_true(rs_v3_len(rs_v3_sub(p1.position, rs_v3_make(-2, 0.5, 1.5))) < 0.02);
    rs_test_write(rs_test_path(dir, "c.ini"), "[pipeline]\nworkdir = out\n[capture]\ncolmap_panorama = pano3\n");
    rc = rs_test_run(cmd, &out);
    assert_int_equal(rc, 1);
    assert_non_null(strstr(out, "[capture] colmap_panorama is set but [colmap] model is not"));
    free(out);
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_umeyama_synthetic), cmocka_unit_test(test_real_model),
             cmocka_unit_test(test_bad_files), cmocka_unit_test(test_pose_file), cmocka_unit_test(test_stage))
