/* Tests of the stitcher's parallax correction (calib/stitch.h with a scene): a six-camera rig
 * whose centres sit 6 cm off the rig centre looks at a room 2 to 5 m away; frames ray-cast from
 * each camera's true centre, stitched with and without the model, against the panorama cast from
 * the rig centre, and the per-camera gains recovered from the overlaps. */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/fileio.h"
#include "common/pano.h"
#include "common/ply.h"
#include "calib/rig.h"
#include "common/scene.h"
#include "calib/stitch.h"
#include "tests/testutil.h"

#define NCAM      6
#define OFFSET_M  0.06
#define PANO_W    800
#define BORDER_PX 8

static const double true_gain[NCAM] = {1.00, 1.06, 0.95, 1.10, 0.92, 1.03};

/* An open room (floor, four walls, no ceiling: the sky shows above) and a column 1.3 m from the
 * rig that hides parts of the walls from some cameras. */
static rs_mesh *room(void)
{
    static const double boxes[][6] = {{-2.6, -3.6, -1.6, 4.6, 2.6, -1.5}, {-2.6, -3.6, -1.5, -2.5, 2.6, 2.5},
                                      {4.5, -3.6, -1.5, 4.6, 2.6, 2.5},   {-2.5, -3.6, -1.5, 4.5, -3.5, 2.5},
                                      {-2.5, 2.5, -1.5, 4.5, 2.6, 2.5},   {1.2, 0.8, -1.5, 1.5, 1.1, 1.0}};
    static const int quad[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    int nb = (int)(sizeof boxes / sizeof boxes[0]);
    rs_mesh *m = rs_mesh_new((size_t)nb * 8, (size_t)nb * 12);
    assert_non_null(m);
    for (int b = 0; b < nb; b++) {
        for (int v = 0; v < 8; v++) {
            float *p = m->verts + 3 * (size_t)(8 * b + v);
            p[0] = (float)boxes[b][v & 1 ? 3 : 0];
            p[1] = (float)boxes[b][v & 2 ? 4 : 1];
            p[2] = (float)boxes[b][v & 4 ? 5 : 2];
        }
        for (int q = 0; q < 6; q++) {
            uint32_t *t = m->tris + 3 * (size_t)(12 * b + 2 * q), o = 8 * (uint32_t)b;
            t[0] = o + quad[q][0], t[1] = o + quad[q][1], t[2] = o + quad[q][2];
            t[3] = o + quad[q][0], t[4] = o + quad[q][2], t[5] = o + quad[q][3];
        }
    }
    return m;
}

/* Radiance of a surface point: smooth patterns a few decimetres across (the frames resolve them). */
static void surface(rs_v3 p, float rgb[3])
{
    double v = 0.45 + 0.25 * sin(2 * M_PI * (p.x + 0.7 * p.y) / 0.6) * cos(2 * M_PI * (p.z - 0.3 * p.y) / 0.8) +
        0.1 * sin(2 * M_PI * (0.5 * p.x + p.z) / 1.7);
    rgb[0] = (float)v, rgb[1] = (float)(0.9 * v), rgb[2] = (float)(0.8 * v + 0.05);
}

static void sky(rs_v3 d, float rgb[3])
{
    double v = 0.3 + 0.4 * fmax(d.z, 0) + 0.05 * d.x;
    rgb[0] = (float)(0.8 * v), rgb[1] = (float)(0.9 * v), rgb[2] = (float)v;
}

/* What a ray from org along the world direction d sees. */
static void trace(const rs_scene *s, rs_v3 org, rs_v3 d, float rgb[3], double *depth)
{
    rs_ray ray = {org, d, 0, INFINITY};
    rs_hit hit;
    rs_scene_intersect(s, &ray, &hit, 1);
    *depth = hit.face == RS_NO_HIT ? INFINITY : hit.t;
    if (hit.face == RS_NO_HIT)
        sky(rs_v3_norm(d), rgb);
    else
        surface(rs_v3_add(org, rs_v3_scale(d, hit.t)), rgb);
}

/* ladybug5-like: five cameras around every 72 degrees and one up, 256 x 320, f = 130 px, OpenCV
 * distortion, each centre OFFSET_M from the rig centre along its optical axis. */
static void write_rig(const char *path)
{
    char text[16384];
    int len = snprintf(text, sizeof text, "%%YAML:1.0\n---\ncamera_count: %d\ncameras:\n", NCAM);
    for (int i = 0; i < NCAM; i++) {
        double r[9], t[3];
        if (i < 5) {
            double a = 2 * M_PI * i / 5, ca = cos(a), sa = sin(a);
            double rr[9] = {sa, 0, ca, -ca, 0, sa, 0, -1, 0}; /* columns: right, down, forward */
            memcpy(r, rr, sizeof r);
            t[0] = OFFSET_M * ca, t[1] = OFFSET_M * sa, t[2] = 0;
        } else {
            double rr[9] = {0, 1, 0, -1, 0, 0, 0, 0, 1};
            memcpy(r, rr, sizeof r);
            t[0] = 0, t[1] = 0, t[2] = OFFSET_M;
        }
        len += snprintf(text + len, sizeof text - (size_t)len,
                        "   - name: cam%d\n     image_width: 256\n     image_height: 320\n     model: pinhole\n"
                        "     camera_matrix: !!opencv-matrix\n        rows: 3\n        cols: 3\n        dt: d\n"
                        "        data: [ 130., 0., %.1f, 0., 131., %.1f, 0., 0., 1. ]\n"
                        "     distortion_coefficients: !!opencv-matrix\n        rows: 1\n        cols: 5\n"
                        "        dt: d\n        data: [ -0.12, 0.02, 0.0005, -0.0003, 0. ]\n"
                        "     R_rig_cam: !!opencv-matrix\n        rows: 3\n        cols: 3\n        dt: d\n"
                        "        data: [ %.17g, %.17g, %.17g, %.17g, %.17g, %.17g, %.17g, %.17g, %.17g ]\n"
                        "     t_rig_cam: !!opencv-matrix\n        rows: 3\n        cols: 1\n        dt: d\n"
                        "        data: [ %.17g, %.17g, %.17g ]\n",
                        i, 127.5 + i - 2, 159.5 - i + 3, r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], t[0],
                        t[1], t[2]);
    }
    rs_test_write(path, text);
}

typedef struct {
    rs_rig rig;
    rs_mesh *mesh;
    rs_scene *scene;
    rs_pose pose;
    rs_image *frames[NCAM];
    rs_image *truth; /* cast from the rig centre */
    double *depth;   /* the truth's depth per pixel (INFINITY: sky) */
} fixture;

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    rs_err err;
    const char *dir = rs_test_tmpdir("stitch_parallax");
    write_rig(rs_test_path(dir, "rig.yaml"));
    if (rs_rig_load(rs_test_path(dir, "rig.yaml"), &f->rig, &err) != 0) fail_msg("%s", err.msg);
    rs_test_rmtree(dir);
    f->mesh = room();
    f->scene = rs_scene_new(f->mesh, &err);
    assert_non_null(f->scene);
    /* A rig placed off the origin and turned, so that the pose is used the right way round. */
    double yaw = 30 * M_PI / 180;
    double rot[9] = {cos(yaw), -sin(yaw), 0, sin(yaw), cos(yaw), 0, 0, 0, 1};
    f->pose.position = rs_v3_make(0.3, -0.2, 0.1);
    memcpy(f->pose.rot, rot, sizeof rot);
    for (int i = 0; i < NCAM; i++) {
        const rs_rig_camera *c = &f->rig.cams[i];
        rs_v3 org = rs_v3_add(f->pose.position, rs_pose_dir_to_world(&f->pose, c->t_rig_cam));
        f->frames[i] = rs_image_new(c->width, c->height, 3);
        for (int y = 0; y < c->height; y++)
            for (int x = 0; x < c->width; x++) {
                float *px = rs_image_px(f->frames[i], x, y);
                rs_v3 d;
                double t;
                if (!rs_rig_unproject(c, x, y, &d)) {
                    px[0] = px[1] = px[2] = 0;
                    continue;
                }
                trace(f->scene, org, rs_pose_dir_to_world(&f->pose, rs_m3_mul_v(c->r_rig_cam, d)), px, &t);
                for (int ch = 0; ch < 3; ch++) px[ch] *= (float)true_gain[i];
            }
    }
    f->truth = rs_image_new(PANO_W, PANO_W / 2, 3);
    f->depth = malloc((size_t)PANO_W * PANO_W / 2 * sizeof *f->depth);
    for (int r = 0; r < PANO_W / 2; r++)
        for (int col = 0; col < PANO_W; col++)
            trace(f->scene, f->pose.position,
                  rs_pose_dir_to_world(&f->pose, rs_pano_pixel_dir(PANO_W, PANO_W / 2, col, r)),
                  rs_image_px(f->truth, col, r), &f->depth[(size_t)r * PANO_W + col]);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    for (int i = 0; i < NCAM; i++) rs_image_free(f->frames[i]);
    rs_image_free(f->truth);
    free(f->depth);
    rs_scene_free(f->scene);
    rs_mesh_free(f->mesh);
    rs_rig_release(&f->rig);
    free(f);
    return 0;
}

/* The pixels that count: seen by some camera at least BORDER_PX inside its usable region and by
 * none closer to its border (the point at its true depth, from each camera's own centre). */
static int counted(const fixture *f, int col, int r)
{
    rs_v3 d = rs_pano_pixel_dir(PANO_W, PANO_W / 2, col, r);
    double t = f->depth[(size_t)r * PANO_W + col];
    int inside = 0;
    for (int i = 0; i < NCAM; i++) {
        const rs_rig_camera *c = &f->rig.cams[i];
        rs_v3 p = isfinite(t) ? rs_v3_sub(rs_v3_scale(d, t), c->t_rig_cam) : d;
        double x, y, margin;
        if (!rs_rig_project(c, rs_m3_mul_vt(c->r_rig_cam, p), &x, &y, &margin)) continue;
        if (margin < BORDER_PX) return 0;
        inside = 1;
    }
    return inside;
}

/* PSNR (peak 1) of a against the truth over the counted pixels finite in both a and b. */
static double psnr(const fixture *f, const rs_image *a, const rs_image *b, double *share)
{
    double se = 0, n = 0, all = 0;
    for (int r = 0; r < PANO_W / 2; r++)
        for (int col = 0; col < PANO_W; col++) {
            const float *pa = rs_image_px(a, col, r), *pb = rs_image_px(b, col, r), *pt = rs_image_px(f->truth, col, r);
            all += 1;
            if (!isfinite(pa[0]) || !isfinite(pb[0]) || !counted(f, col, r)) continue;
            for (int ch = 0; ch < 3; ch++) se += (pa[ch] - pt[ch]) * (pa[ch] - pt[ch]);
            n += 3;
        }
    *share = n / 3 / all;
    return -10 * log10(se / n);
}

static double gain_error(const double *gains)
{
    double lg = 0, worst = 0;
    for (int i = 0; i < NCAM; i++) lg += log(true_gain[i]) / NCAM;
    for (int i = 0; i < NCAM; i++) worst = fmax(worst, fabs(gains[i] / (true_gain[i] / exp(lg)) - 1));
    return worst;
}

static void test_parallax_corrected(void **state)
{
    fixture *f = *state;
    rs_err err;
    rs_image *flat = NULL, *model = NULL;
    double g_flat[NCAM], g_model[NCAM];
    rs_stitch_stats st_flat, st_model;
    rs_stitch_opts o = {PANO_W, 16, 1, NULL, f->pose};
    if (rs_stitch(&f->rig, f->frames, &o, &flat, g_flat, &st_flat, &err) != 0) fail_msg("%s", err.msg);
    o.scene = f->scene;
    if (rs_stitch(&f->rig, f->frames, &o, &model, g_model, &st_model, &err) != 0) fail_msg("%s", err.msg);
    double share, p_flat = psnr(f, flat, model, &share), p_model = psnr(f, model, flat, &share);
    double e_flat = gain_error(g_flat), e_model = gain_error(g_model);
    printf("# parallax: PSNR %.2f dB infinite depth, %.2f dB model depth over %.1f %% of the panorama; "
           "worst gain error %.3f %% and %.3f %%; model depth on %.1f %% of the sphere, %.2f %% of the camera "
           "samples hidden\n",
           p_flat, p_model, 100 * share, 100 * e_flat, 100 * e_model, 100 * st_model.model_coverage,
           100 * st_model.hidden_share);
    assert_true(share > 0.5);
    assert_true(st_flat.model_coverage == 0 && st_flat.hidden_share == 0);
    /* The room and its floor fill most of what the rig sees; the column hides some samples. */
    assert_true(st_model.model_coverage > 0.5 && st_model.model_coverage < st_model.coverage);
    assert_true(st_model.hidden_share > 0 && st_model.hidden_share < 0.1);
    assert_true(p_model >= 35);
    assert_true(p_model > p_flat + 6);
    /* The robust gains (calib/gains.h) leave out the pixels where parallax moves content (high
     * gradients) and outvote the rest: both stitches recover the gains. */
    assert_true(e_model < 0.005);
    assert_true(e_flat < 0.005);
    rs_gain_report_free(&st_flat.gain);
    rs_gain_report_free(&st_model.gain);
    rs_image_free(flat);
    rs_image_free(model);
}

/* The sky is at infinite depth either way: pixels that see no model come out the same, except
 * next to the model's silhouette, where a camera off the rig centre sees the model instead of
 * the sky; there the corrected stitch leaves that camera out and comes closer to the truth. */
static void test_sky(void **state)
{
    fixture *f = *state;
    rs_err err;
    rs_image *flat = NULL, *model = NULL;
    double g[NCAM];
    rs_stitch_stats st;
    rs_stitch_opts o = {PANO_W, 16, 0, NULL, f->pose};
    if (rs_stitch(&f->rig, f->frames, &o, &flat, g, &st, &err) != 0) fail_msg("%s", err.msg);
    o.scene = f->scene;
    if (rs_stitch(&f->rig, f->frames, &o, &model, g, &st, &err) != 0) fail_msg("%s", err.msg);
    size_t sky = 0, same = 0;
    double e_flat = 0, e_model = 0;
    for (int r = 0; r < PANO_W / 2; r++)
        for (int col = 0; col < PANO_W; col++) {
            if (isfinite(f->depth[(size_t)r * PANO_W + col])) continue;
            const float *a = rs_image_px(flat, col, r), *b = rs_image_px(model, col, r);
            const float *t = rs_image_px(f->truth, col, r);
            if (!isfinite(a[0]) || !isfinite(b[0])) continue;
            sky++;
            same += a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
            for (int ch = 0; ch < 3; ch++) {
                e_flat += fabs(a[ch] - t[ch]);
                e_model += fabs(b[ch] - t[ch]);
            }
        }
    printf("# sky: %zu pixels, %.2f %% unchanged; mean error %.5f infinite depth, %.5f model\n", sky,
           100.0 * same / sky, e_flat / sky / 3, e_model / sky / 3);
    assert_true(sky > (size_t)PANO_W * PANO_W / 20);
    assert_true(same < sky && same > 0.9 * sky);
    assert_true(e_model < e_flat);
    rs_gain_report_free(&st.gain);
    rs_image_free(flat);
    rs_image_free(model);
}

/* The calib stage: with mesh.ply in the work folder and [capture] position and rotation, the
 * stitched panorama is corrected (the default), and [rig] parallax = false turns it off. With
 * [capture] correspondences (pairs: NULL for the true pose as position and rotation) the pose is
 * solved from the first stitch and the frames stitched again with the model's depth. */
static double stage_psnr(const fixture *f, const char *dir, const char *extra, const char *pairs, int *corrected)
{
    char text[4096], frames[1024] = "", capture[1024], *out = NULL;
    for (int i = 0; i < NCAM; i++) snprintf(frames + strlen(frames), sizeof frames - strlen(frames), "cam%d.exr ", i);
    if (pairs)
        snprintf(capture, sizeof capture, "correspondences = %s\n", pairs);
    else
        snprintf(capture, sizeof capture,
                 "position = %.17g %.17g %.17g\nrotation = %.17g %.17g %.17g %.17g %.17g "
                 "%.17g %.17g %.17g %.17g\n",
                 f->pose.position.x, f->pose.position.y, f->pose.position.z, f->pose.rot[0], f->pose.rot[1],
                 f->pose.rot[2], f->pose.rot[3], f->pose.rot[4], f->pose.rot[5], f->pose.rot[6], f->pose.rot[7],
                 f->pose.rot[8]);
    snprintf(text, sizeof text,
             "[pipeline]\nworkdir = out\n[rig]\nfile = rig.yaml\nframes = %s\nwidth = %d\nfeather_px = 16\n%s\n"
             "[capture]\n%s",
             frames, PANO_W, extra, capture);
    rs_test_write(rs_test_path(dir, "calib.ini"), text);
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "'%s/rhoscan-calib' '%s'", rs_test_bin_dir(), rs_test_path(dir, "calib.ini"));
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) fail_msg("rhoscan-calib exit %d: %s", rc, out);
    free(out);
    rs_err err;
    rs_image *pano = rs_image_read(rs_test_path(dir, "out/pano_stitched.exr"), &err);
    assert_non_null(pano);
    char *rep = NULL;
    size_t size;
    assert_int_equal(rs_read_file(rs_test_path(dir, "out/calib.json"), &rep, &size, &err), 0);
    const struct cJSON *flag = rs_test_json_find(rs_test_json_text(rep), "parallax_corrected");
    free(rep);
    assert_true(cJSON_IsBool(flag));
    *corrected = cJSON_IsTrue(flag);
    double share, p = psnr(f, pano, pano, &share);
    rs_image_free(pano);
    return p;
}

static void test_calib_stage(void **state)
{
    fixture *f = *state;
    rs_err err;
    const char *dir = rs_test_tmpdir("stitch_parallax_stage");
    write_rig(rs_test_path(dir, "rig.yaml"));
    static const char *const names[] = {"R", "G", "B"};
    for (int i = 0; i < NCAM; i++) {
        char name[32];
        snprintf(name, sizeof name, "cam%d.exr", i);
        /* Float EXR: the frames as cast, no half-float rounding. */
        assert_int_equal(rs_image_write_exr(f->frames[i], rs_test_path(dir, name), names, 0, NULL, &err), 0);
    }
    int corrected = 0;
    double p_none = stage_psnr(f, dir, "", NULL, &corrected); /* no mesh.ply yet: infinite depth */
    assert_false(corrected);
    rs_ply *ply = rs_ply_new();
    rs_mesh_to_ply(f->mesh, ply);
    assert_int_equal(rs_ply_write(ply, rs_test_path(dir, "out/mesh.ply"), 1, &err), 0);
    rs_ply_free(ply);
    double p_model = stage_psnr(f, dir, "", NULL, &corrected);
    assert_true(corrected);
    double p_off = stage_psnr(f, dir, "parallax = false", NULL, &corrected);
    assert_false(corrected);
    /* Pairs: the room's inner corners and the column's top, exact pixels on the stitched panorama. */
    static const double corners[][3] = {{-2.5, -3.5, -1.5}, {4.5, -3.5, -1.5}, {4.5, 2.5, -1.5}, {-2.5, 2.5, -1.5},
                                        {-2.5, -3.5, 2.5},  {4.5, -3.5, 2.5},  {4.5, 2.5, 2.5},  {-2.5, 2.5, 2.5},
                                        {1.2, 0.8, 1.0},    {1.5, 0.8, 1.0},   {1.2, 1.1, 1.0},  {1.5, 1.1, 1.0}};
    char text[4096] = "";
    for (size_t k = 0; k < sizeof corners / sizeof corners[0]; k++) {
        rs_v3 p = rs_v3_make(corners[k][0], corners[k][1], corners[k][2]);
        double u, v;
        rs_pano_dir_to_uv(rs_pose_dir_to_local(&f->pose, rs_v3_sub(p, f->pose.position)), &u, &v);
        snprintf(text + strlen(text), sizeof text - strlen(text), "%.9f %.9f %g %g %g\n", u * PANO_W - 0.5,
                 v * PANO_W / 2 - 0.5, p.x, p.y, p.z);
    }
    rs_test_write(rs_test_path(dir, "pairs.txt"), text);
    double p_solved = stage_psnr(f, dir, "", "pairs.txt", &corrected);
    assert_true(corrected);
    printf("# calib stage: PSNR %.2f dB without mesh.ply, %.2f dB with it, %.2f dB with parallax = false, %.2f dB "
           "with the pose solved from pairs\n",
           p_none, p_model, p_off, p_solved);
    assert_true(p_model >= 35 && p_model > p_none + 6);
    assert_true(fabs(p_off - p_none) < 1e-9);
    assert_true(p_solved >= 35 && fabs(p_solved - p_model) < 1);
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(setup, teardown, cmocka_unit_test(test_parallax_corrected), cmocka_unit_test(test_sky),
             cmocka_unit_test(test_calib_stage))
