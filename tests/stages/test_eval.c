/* rhoscan-eval on a tiny synthetic truth (a floor and a wall, known albedo and irradiance) and a
 * result with known errors: every figure it reports is checked against its definition. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "tools/eval/eval.h"
#include "common/fileio.h"
#include "common/image.h"
#include "tests/meshgen.h"
#include "common/ply.h"
#include "tests/testutil.h"

#define W 64
#define H 32
static const double FLOOR_RHO[3] = {0.5, 0.4, 0.3}, WALL_RHO[3] = {0.2, 0.6, 0.4};
static const double E_SKY = 300, E_G = 40; /* true irradiance on every model pixel */

typedef struct scene {
    const char *truth, *work;
    size_t nfloor, nwall, nf; /* result facets: floor, wall, 1 straddling */
    int id[W * H];            /* facet per pixel, -1 none */
} scene;

static void rects(rs_meshgen *g, int n)
{
    rs_meshgen_rect(g, rs_v3_make(-5, -5, 0), rs_v3_make(10, 0, 0), rs_v3_make(0, 10, 0), n, n);
    rs_meshgen_rect(g, rs_v3_make(-5, 5, 0), rs_v3_make(10, 0, 0), rs_v3_make(0, 0, 6), n, n);
}

static void write_img(const char *dir, const char *name, const float *px, int channels)
{
    rs_image *img = rs_image_new(W, H, channels);
    memcpy(img->data, px, sizeof(float) * W * H * channels);
    const char *rgb[3] = {"R", "G", "B"}, *y[1] = {"Y"};
    rs_err err;
    assert_int_equal(rs_image_write_exr(img, rs_test_path(dir, name), channels == 3 ? rgb : y, 0, NULL, &err), 0);
    rs_image_free(img);
}

/* Truth: 4 triangles. Result: 4 x 4 cells per plane, floor albedo 2 % high, wall 10 % low, one
 * small facet across the corner; E_sky 3 % high, G 10 % low. Facet `unobserved` is flagged
 * unobserved; facet `nan_facet` gets a NaN albedo (observed or not as nan_observed says). */
static scene make_scene(long unobserved, long nan_facet, int nan_observed)
{
    scene s;
    s.truth = rs_test_tmpdir("evaltruth");
    s.work = rs_test_tmpdir("evalwork");
    rs_err err;
    rs_meshgen g = rs_meshgen_new(16, 8);
    rects(&g, 1);
    rs_mesh *t = rs_meshgen_done(&g);
    rs_ply *ply = rs_ply_new();
    rs_ply_element *fe = rs_mesh_to_ply(t, ply);
    double rgb[3][4], part[4];
    for (int f = 0; f < 4; f++) {
        for (int c = 0; c < 3; c++) rgb[c][f] = f < 2 ? FLOOR_RHO[c] : WALL_RHO[c];
        part[f] = f < 2 ? 0 : 1;
    }
    rs_ply_add_scalar(fe, "red", RS_PLY_FLOAT32, rgb[0]);
    rs_ply_add_scalar(fe, "green", RS_PLY_FLOAT32, rgb[1]);
    rs_ply_add_scalar(fe, "blue", RS_PLY_FLOAT32, rgb[2]);
    rs_ply_add_scalar(fe, "part", RS_PLY_INT32, part);
    assert_int_equal(rs_ply_write(ply, rs_test_path(s.truth, "truth.ply"), 0, &err), 0);
    rs_ply_free(ply);
    rs_mesh_free(t);

    g = rs_meshgen_new(128, 128);
    rects(&g, 4);
    rs_mesh *r = g.m;
    /* the straddling facet: two corners on the floor, one on the wall, 0.1 m from the corner */
    size_t v0 = g.nv;
    float extra[9] = {-0.2f, 4.9f, 0, 0.2f, 4.9f, 0, 0, 5, 0.3f};
    memcpy(r->verts + 3 * v0, extra, sizeof extra);
    g.nv += 3;
    uint32_t tri[3] = {(uint32_t)v0, (uint32_t)v0 + 1, (uint32_t)v0 + 2};
    memcpy(r->tris + 3 * g.nf, tri, sizeof tri);
    g.nf++;
    r = rs_meshgen_done(&g);
    s.nfloor = s.nwall = 32;
    s.nf = r->nfaces;
    assert_int_equal(s.nf, 65);
    double *buf = calloc(11 * s.nf, sizeof *buf);
    double *alb = buf, *esky = buf + 3 * s.nf, *gi = buf + 6 * s.nf, *obs = buf + 9 * s.nf, *est = buf + 10 * s.nf;
    for (size_t f = 0; f < s.nf; f++) {
        int wall = f >= s.nfloor && f < s.nfloor + s.nwall;
        for (int c = 0; c < 3; c++) {
            alb[3 * f + c] = wall ? 0.9 * WALL_RHO[c] : 1.02 * FLOOR_RHO[c];
            esky[3 * f + c] = 1.03 * E_SKY;
            gi[3 * f + c] = 0.9 * E_G;
        }
        obs[f] = est[f] = (long)f != unobserved;
    }
    if (nan_facet >= 0) {
        alb[3 * nan_facet + 1] = NAN;
        obs[nan_facet] = est[nan_facet] = nan_observed;
    }
    ply = rs_ply_new();
    fe = rs_mesh_to_ply(r, ply);
    const char *pre[3] = {"albedo", "irradiance_sky", "irradiance_inter"};
    const char *ch[3] = {"r", "g", "b"};
    double col[65];
    for (int k = 0; k < 3; k++)
        for (int c = 0; c < 3; c++) {
            char name[64];
            snprintf(name, sizeof name, "%s_%s", pre[k], ch[c]);
            for (size_t f = 0; f < s.nf; f++) col[f] = buf[3 * s.nf * k + 3 * f + c];
            rs_ply_add_scalar(fe, name, RS_PLY_FLOAT32, col);
        }
    rs_ply_add_scalar(fe, "observed", RS_PLY_UINT8, obs);
    rs_ply_add_scalar(fe, "estimable", RS_PLY_UINT8, est);
    assert_int_equal(rs_ply_write(ply, rs_test_path(s.work, "albedo.ply"), 1, &err), 0);
    rs_ply_free(ply);
    rs_mesh_free(r);
    free(buf);

    /* Camera view: rows 0-7 sky, 8-15 wall, 16-31 floor; facet ids cycle over each plane's
     * facets; one floor pixel shows no facet (a hole in the mesh). */
    float *pano = calloc(3 * W * H, sizeof(float)), *syn = calloc(3 * W * H, sizeof(float));
    float *dc = calloc(3 * W * H, sizeof(float)), *dd = calloc(3 * W * H, sizeof(float));
    float *di = calloc(3 * W * H, sizeof(float)), *ids = calloc(W * H, sizeof(float));
    for (int k = 0; k < W * H; k++) {
        int row = k / W;
        const double *rho = row < 8 ? NULL : row < 16 ? WALL_RHO : FLOOR_RHO;
        s.id[k] = row < 8 ? -1 : row < 16 ? (int)(s.nfloor + k % s.nwall) : (int)(k % s.nfloor);
        if (k == 20 * W + 3) s.id[k] = -1;
        ids[k] = (float)s.id[k];
        for (int c = 0; c < 3; c++) {
            dc[3 * k + c] = rho ? (float)rho[c] : 0;
            dd[3 * k + c] = rho ? (float)(E_SKY / M_PI) : 0;
            di[3 * k + c] = rho ? (float)(E_G / M_PI) : 0;
            pano[3 * k + c] = rho ? (float)(rho[c] * (E_SKY + E_G) / M_PI) : 2.0f;
            syn[3 * k + c] = rho ? 1.05f * pano[3 * k + c] : pano[3 * k + c];
        }
    }
    write_img(s.truth, "pano.exr", pano, 3);
    write_img(s.truth, "pano_diffcol.exr", dc, 3);
    write_img(s.truth, "pano_diffdir.exr", dd, 3);
    write_img(s.truth, "pano_diffind.exr", di, 3);
    write_img(s.work, "synth.exr", syn, 3);
    write_img(s.work, "facet_id.exr", ids, 1);
    free(pano), free(syn), free(dc), free(dd), free(di), free(ids);
    return s;
}

static rs_json *evaluate(const scene *s, double concave_threshold, int *passed)
{
    rs_eval_opts o;
    rs_eval_opts_default(&o);
    o.truth_dir = s->truth;
    o.work_dir = s->work;
    o.concave_threshold = concave_threshold;
    rs_json *doc = NULL;
    rs_err err;
    int rc = rs_eval_run(&o, &doc, passed, &err);
    if (rc != 0) print_message("%s: %s\n", err.file, err.msg);
    assert_int_equal(rc, 0);
    return doc;
}

static void cleanup(const scene *s)
{
    rs_test_rmtree(s->truth);
    rs_test_rmtree(s->work);
}

static void test_albedo_statistics(void **state)
{
    scene s = make_scene(-1, -1, 0);
    int passed;
    rs_json *d = evaluate(&s, 0.2, &passed);
    assert_true(passed);
    /* every facet is matched; the corner facet is the only one off the interior */
    assert_int_equal((int)rs_eval_get(d, "matched"), 65);
    assert_int_equal((int)rs_eval_get(d, "albedo.all.facets"), 65);
    assert_int_equal((int)rs_eval_get(d, "albedo.interior.facets"), 64);
    /* area-weighted: floor 100 m2 at 2 %, wall 60 m2 at 10 % */
    assert_float_equal(rs_eval_get(d, "albedo.interior.mean_rel"), (100 * 0.02 + 60 * 0.1) / 160, 1e-6);
    assert_float_equal(rs_eval_get(d, "albedo.interior.bias_rel"), (100 * 0.02 - 60 * 0.1) / 160, 1e-6);
    assert_float_equal(rs_eval_get(d, "albedo.interior.median_rel"), 0.02, 1e-6); /* 100 of 160 m2 */
    assert_float_equal(rs_eval_get(d, "albedo.interior.p95_rel"), 0.1, 1e-6);
    assert_float_equal(rs_eval_get(d, "parts.0.interior.mean_rel"), 0.02, 1e-6);
    assert_float_equal(rs_eval_get(d, "parts.1.interior.mean_rel"), 0.1, 1e-6);
    assert_float_equal(rs_eval_get(d, "parts.1.interior.bias_rel"), -0.1, 1e-6);
    assert_float_equal(rs_eval_get(d, "parts.0.interior.area_m2"), 100, 1e-3);
    /* the truth's interreflection share per part, from the passes */
    assert_float_equal(rs_eval_get(d, "parts.0.truth_interreflection_share"), E_G / (E_SKY + E_G), 1e-4);
    /* camera view: one hole pixel among the model pixels, rows 9-31 (row 8 borders the sky) */
    assert_int_equal((int)rs_eval_get(d, "coverage.model_pixels"), 23 * W);
    assert_float_equal(rs_eval_get(d, "coverage.share"), (23.0 * W - 1) / (23 * W), 1e-9);
    assert_float_equal(rs_eval_get(d, "irradiance.esky_rel"), 0.03, 1e-4);
    assert_float_equal(rs_eval_get(d, "irradiance.esky_bias"), 0.03, 1e-4);
    assert_float_equal(rs_eval_get(d, "irradiance.g_rel"), 0.1, 1e-4);
    assert_float_equal(rs_eval_get(d, "irradiance.g_bias"), -0.1, 1e-4);
    assert_float_equal(rs_eval_get(d, "irradiance.total_bias"), (1.03 * E_SKY + 0.9 * E_G) / (E_SKY + E_G) - 1, 1e-4);
    assert_float_equal(rs_eval_get(d, "synth.rel_diff"), 0.05, 1e-3);
    /* the error image holds the facet's error against the per-pixel truth albedo */
    rs_err err;
    rs_image *e = rs_image_read(rs_test_path(s.work, "eval_error.exr"), &err);
    assert_non_null(e);
    assert_float_equal(e->data[25 * W + 7], 0.02, 1e-5);
    assert_float_equal(e->data[10 * W + 7], 0.1, 1e-5);
    assert_float_equal(e->data[20 * W + 3], -1, 0); /* the hole */
    assert_float_equal(e->data[2 * W + 7], 0, 0);   /* sky */
    rs_image_free(e);
    assert_true(rs_file_exists(rs_test_path(s.work, "eval_error.png")));
    assert_true(rs_file_exists(rs_test_path(s.work, "eval.json")));
    /* the concave/convex split follows the threshold */
    double encl = rs_eval_get(d, "parts.0.enclosure");
    assert_true(encl > 0 && encl < 1);
    rs_json_free(d);
    d = evaluate(&s, 0, &passed);
    assert_int_equal((int)rs_eval_get(d, "albedo.concave_parts.all.facets"), 65);
    assert_true(isnan(rs_eval_get(d, "albedo.convex_parts.all.facets")));
    rs_json_free(d);
    d = evaluate(&s, 1.01, &passed);
    assert_int_equal((int)rs_eval_get(d, "albedo.convex_parts.all.facets"), 65);
    rs_json_free(d);
    cleanup(&s);
}

/* Flagging a facet unobserved takes it out of the error but lowers the coverage by its pixels. */
static void test_unobserved_lowers_coverage(void **state)
{
    scene s = make_scene(33, -1, 0); /* a wall facet */
    int passed, lost = 0;
    for (int k = 9 * W; k < W * H; k++) lost += s.id[k] == 33;
    rs_json *d = evaluate(&s, 0.2, &passed);
    assert_int_equal((int)rs_eval_get(d, "albedo.all.facets"), 64);
    assert_true(lost > 0);
    assert_float_equal(rs_eval_get(d, "coverage.share"), (23.0 * W - 1 - lost) / (23 * W), 1e-9);
    rs_json_free(d);
    cleanup(&s);
}

static int run_eval(const scene *s, const char *args, char **out)
{
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "'%s/rhoscan-eval' '%s' '%s' %s", rs_test_bin_dir(), s->truth, s->work, args);
    return rs_test_run(cmd, out);
}

/* The program: thresholds decide the exit code; a non-finite albedo on an observed, estimable
 * facet fails; on an unobserved one it does not. */
static void test_program_exit_codes(void **state)
{
    scene s = make_scene(-1, -1, 0);
    char *out = NULL;
    assert_int_equal(run_eval(&s, "--max-error 0.06 --min-coverage 0.99", &out), 0);
    free(out);
    assert_int_equal(run_eval(&s, "--max-error 0.04", &out), 1);
    assert_non_null(strstr(out, "--max-error"));
    free(out);
    assert_int_equal(run_eval(&s, "--min-coverage 1", &out), 1);
    free(out);
    assert_int_equal(run_eval(&s, "--max-error nope", &out), 1);
    assert_non_null(strstr(out, "nope"));
    free(out);
    cleanup(&s);

    s = make_scene(-1, 5, 1);
    assert_int_equal(run_eval(&s, "", &out), 1);
    assert_non_null(strstr(out, "non-finite"));
    free(out);
    cleanup(&s);
    s = make_scene(-1, 5, 0);
    assert_int_equal(run_eval(&s, "", &out), 0);
    free(out);
    /* a missing input names the file */
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "rm '%s'", rs_test_path(s.work, "synth.exr"));
    assert_int_equal(system(cmd), 0);
    assert_int_equal(run_eval(&s, "", &out), 1);
    assert_non_null(strstr(out, "synth.exr"));
    free(out);
    cleanup(&s);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_albedo_statistics), cmocka_unit_test(test_unobserved_lowers_coverage),
             cmocka_unit_test(test_program_exit_codes))
