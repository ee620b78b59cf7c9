/* The per-facet uncertainty's sources, each against a known truth: observe's radiance_sigma_rel
 * against noise injected into the panorama, the gather's Monte Carlo sigma against the spread of
 * its estimates over seeds (its 1/sqrt(rays) fall, and the calibration by a second seed), and
 * albedo.ply's 80 % bound against its sigma. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "light/gather.h"
#include "tests/fixtures.h"
#include "common/image.h"
#include "tests/meshgen.h"
#include "common/ply.h"
#include "common/sampling.h"
#include "tests/testutil.h"

/* A standard normal number from two hashes (Box-Muller). */
static double normal(uint32_t k)
{
    double u = ((rs_hash_u32(2 * k) >> 8) + 0.5) / 16777216.0, v = (rs_hash_u32(2 * k + 1) >> 8) / 16777216.0;
    return sqrt(-2 * log(u)) * cos(2 * M_PI * v);
}

/* The panorama's radiance: 0.5 times (1 + noise_rel N(0, 1)) per pixel and channel. */
typedef struct {
    int w, h;
    double noise_rel;
} noisy_sky;

static void noisy_radiance(rs_v3 d, size_t k, double rgb[3], void *ctx)
{
    (void)d;
    const noisy_sky *n = ctx;
    size_t row = k / (size_t)n->w;
    for (int ch = 0; ch < 3; ch++) {
        /* sky above the horizon (camera at 1.5 m: the upper half sees sky or the wall's top) */
        rgb[ch] = 0.5 * (1 + n->noise_rel * normal((uint32_t)(3 * k + ch)));
        if (row < (size_t)n->h / 8) rgb[ch] = 1.0; /* zenith sky: no model there */
    }
}

/* Floor and wall (the wall's normal toward the camera at y = -4), and a panorama whose model
 * pixels are 0.5 times (1 + noise_rel N(0, 1)), independently per pixel and channel. */
static void write_noisy_scene(const char *dir, int pano_w, double noise_rel, int cells)
{
    rs_fx_write_floor_wall(dir, cells, cells, cells);
    noisy_sky n = {pano_w, pano_w / 2, noise_rel};
    rs_image *img = rs_fx_pano(pano_w, pano_w / 2, noisy_radiance, &n);
    rs_fx_write_pano(img, dir);
    rs_image_free(img);
    rs_fx_write_scene_ini(dir, "0 -4 1.5", 64, 16, NULL);
}

static double prop(const rs_ply_element *e, const char *name, size_t i)
{
    const rs_ply_prop *p = rs_ply_find_prop(e, name);
    assert_non_null(p);
    return p->data[i];
}

/* radiance_sigma_rel against the injected noise: the facets' actual relative errors of L (the
 * truth is 0.5 in every channel), divided by their reported sigma, must have an RMS of 1 within
 * 20 % (the estimate from same-surface neighbours is unbiased for independent pixel noise; the
 * tolerance covers the sampling spread of a few hundred facets), both for facets averaged over
 * their pure pixels and for small facets read at points. */
static void check_radiance_sigma(int pano_w, int cells, double noise_rel)
{
    const char *dir = rs_test_tmpdir("unc-observe");
    write_noisy_scene(dir, pano_w, noise_rel, cells);
    char cmd[4096], *out = NULL;
    /* the albedo's own pooling (tests/stages/test_albpool.c) off: the facet's own radiance term */
    snprintf(cmd, sizeof cmd, "'%s/rhoscan' run --set reflectance.albedo_pool_sigmas=0 '%s'", rs_test_bin_dir(),
             rs_test_path(dir, "scene.ini"));
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) print_message("%s", out);
    assert_int_equal(rc, 0);
    free(out);
    rs_err err;
    rs_ply *obs = rs_ply_read(rs_test_path(dir, "work/observe.ply"), &err);
    assert_non_null(obs);
    const rs_ply_element *f = rs_ply_find_element(obs, "face");
    double z2[2] = {0, 0};
    size_t n[2] = {0, 0};
    for (size_t i = 0; i < f->count; i++) {
        if (prop(f, "observed", i) == 0) continue;
        double s = prop(f, "radiance_sigma_rel", i);
        assert_true(s > 0 && isfinite(s));
        int by_pixels = prop(f, "observe_pixels", i) >= 3;
        static const char *const ch[3] = {"radiance_r", "radiance_g", "radiance_b"};
        for (int c = 0; c < 3; c++) {
            double e = prop(f, ch[c], i) / 0.5 - 1;
            z2[by_pixels] += e * e / (s * s);
            n[by_pixels]++;
        }
    }
    for (int b = 0; b < 2; b++) {
        if (!n[b]) continue;
        double zrms = sqrt(z2[b] / n[b]);
        print_message("pano %d, %d cells, noise %.2f: facets by %s: %zu channel errors, RMS error / sigma %.3f\n",
                      pano_w, cells, noise_rel, b ? "pixels" : "points", n[b], zrms);
        assert_true(n[b] >= 300);
        assert_true(zrms > 0.8 && zrms < 1.2);
    }
    /* albedo.ply: the 80 % bound is 1.2816 sigma, and sigma holds at least the radiance part */
    rs_ply *alb = rs_ply_read(rs_test_path(dir, "work/albedo.ply"), &err);
    assert_non_null(alb);
    const rs_ply_element *a = rs_ply_find_element(alb, "face");
    size_t est = 0;
    for (size_t i = 0; i < a->count; i++) {
        double s = prop(a, "albedo_sigma_rel", i), b = prop(a, "albedo_bound80_rel", i);
        assert_true(fabs(b - 1.2816 * s) <= 1e-5 * (1 + b));
        if (prop(a, "estimable", i) == 0) continue;
        est++;
        assert_true(s >= prop(f, "radiance_sigma_rel", i) * (1 - 1e-5));
    }
    assert_true(est > 0);
    rs_ply_free(alb);
    rs_ply_free(obs);
    rs_test_rmtree(dir);
}

/* 40 x 40 cells per plane seen in a 256 x 128 panorama: the near facets span many pixels (the
 * pixel path), the far ones a pixel or two (the point path, with pixels read more than once). */
static void test_radiance_sigma(void **state)
{
    (void)state;
    check_radiance_sigma(256, 40, 0.2);
}

/* Floor and wall (cells x cells each) and a thin blade that shadows them, under a sky of random
 * luminance with a sun of a few pixels, in world axes. */
static rs_mesh *blade_scene(int cells, rs_scene **scene, rs_capture *cap, rs_skyenv *env)
{
    rs_meshgen mg = rs_meshgen_new(400, 400);
    rs_meshgen_rect(&mg, rs_v3_make(-2, -2, 0), rs_v3_make(4, 0, 0), rs_v3_make(0, 4, 0), cells, cells);
    rs_meshgen_rect(&mg, rs_v3_make(-2, 2, 0), rs_v3_make(4, 0, 0), rs_v3_make(0, 0, 3), cells, cells);
    rs_meshgen_box(&mg, rs_v3_make(-0.05, -10, 0.5), rs_v3_make(0.05, 10, 6), 1, 0);
    rs_mesh *m = rs_meshgen_done(&mg);
    *scene = rs_fx_scene(m);
    rs_fx_random_sky(256, 1e3f, 0, cap, env);
    return m;
}

/* Over 128 seeds, per ray count N: the spread (standard deviation) of a floor facet's E_sky + G
 * next to a wall that a thin blade shadows, and the mean reported rs_gather_mc_sigma. The
 * reported sigma must fall like 1 / sqrt(N) (ratio 2 between N and 4N, within 25 %), and must
 * not be below the actual spread: the independent-sample formula can only overstate the error
 * of the stratified sequences, by at most 3 times here. */
static void test_mc_sigma(void **state)
{
    (void)state;
    rs_scene *scene;
    rs_capture cap;
    rs_skyenv env;
    rs_mesh *m = blade_scene(2, &scene, &cap, &env);
    size_t nf = m->nfaces;
    double *radiance = malloc(3 * nf * sizeof *radiance);
    for (size_t k = 0; k < 3 * nf; k++) radiance[k] = 0.3;
    rs_gather_scratch *s = rs_gather_scratch_new(1024);
    const int counts[2] = {64, 256};
    double sigma[2], spread[2];
    for (int c = 0; c < 2; c++) {
        double sum = 0, sum_sq = 0, rep = 0;
        const int seeds = 128;
        for (int seed = 0; seed < seeds; seed++) {
            rs_gather_ctx g = rs_fx_gather_ctx(scene, &env, counts[c], counts[c] / 4, (uint32_t)seed);
            rs_facet_gather r;
            assert_int_equal(rs_gather_facet(&g, 2, s, &r), 0);
            double e = r.esky_lum;
            for (uint32_t q = 0; q < r.nentries; q++) e += r.entries[q].k_unseen * 0.3;
            sum += e;
            sum_sq += e * e;
            rep += rs_gather_mc_sigma(&r, radiance, NULL);
            free(r.entries);
        }
        double mean = sum / seeds;
        spread[c] = sqrt(fmax(0, sum_sq / seeds - mean * mean) * seeds / (seeds - 1));
        sigma[c] = rep / seeds;
        print_message("N = %d: E %.4g, spread over seeds %.4g, reported sigma %.4g\n", counts[c], mean, spread[c],
                      sigma[c]);
        assert_true(sigma[c] >= 0.9 * spread[c]);
        assert_true(sigma[c] <= 3 * spread[c]);
    }
    double ratio = sigma[0] / sigma[1];
    print_message("sigma(64) / sigma(256) = %.3f (1/sqrt(N): 2)\n", ratio);
    assert_true(ratio > 1.5 && ratio < 2.5);
    rs_gather_scratch_free(s);
    free(radiance);
    rs_fx_release(&env, &cap, scene, m);
}

/* rs_gather_mc_calibration: every facet of the same scene gathered with 32 seeds; the
 * calibrated sigma (factor x formula) against each facet's deviation from its mean over the
 * seeds must have an RMS ratio of 1 within 25 % (the formula alone is off by the factor, which
 * must be below 1 here: the stratified sequences beat independent samples). */
static void test_mc_calibration(void **state)
{
    (void)state;
    rs_scene *scene;
    rs_capture cap;
    rs_skyenv env;
    rs_mesh *m = blade_scene(4, &scene, &cap, &env);
    size_t nf = m->nfaces;
    double *radiance = malloc(3 * nf * sizeof *radiance);
    for (size_t k = 0; k < 3 * nf; k++) radiance[k] = 0.3;
    enum { SEEDS = 32 };
    double *E = calloc(nf * SEEDS, sizeof *E), *sig = calloc(nf * SEEDS, sizeof *sig), factor = 0;
    rs_facet_gather *fg = calloc(nf, sizeof *fg);
    rs_gather_stats st;
    rs_err err;
    for (int seed = 0; seed < SEEDS; seed++) {
        rs_gather_ctx g = rs_fx_gather_ctx(scene, &env, 64, 16, (uint32_t)(100 + seed));
        assert_int_equal(rs_gather_run(&g, nf, NULL, fg, NULL, NULL, &st, &err), 0);
        double fac;
        size_t used;
        assert_int_equal(rs_gather_mc_calibration(&g, nf, fg, radiance, NULL, 1000, &fac, &used, &err), 0);
        assert_int_equal(used, nf);
        factor += fac / SEEDS;
        for (size_t f = 0; f < nf; f++) {
            E[f * SEEDS + seed] = fg[f].esky_lum;
            for (uint32_t q = 0; q < fg[f].nentries; q++) E[f * SEEDS + seed] += fg[f].entries[q].k_unseen * 0.3;
            sig[f * SEEDS + seed] = fac * rs_gather_mc_sigma(&fg[f], radiance, NULL);
            free(fg[f].entries);
        }
    }
    double z2 = 0;
    size_t n = 0;
    for (size_t f = 0; f < nf; f++) {
        double mean = 0;
        for (int k = 0; k < SEEDS; k++) mean += E[f * SEEDS + k] / SEEDS;
        for (int k = 0; k < SEEDS; k++) {
            if (!(sig[f * SEEDS + k] > 0)) continue;
            double d = (E[f * SEEDS + k] - mean) / sig[f * SEEDS + k];
            z2 += d * d * SEEDS / (SEEDS - 1);
            n++;
        }
    }
    double zrms = sqrt(z2 / n);
    print_message("calibration factor %.3f; RMS deviation over seeds / calibrated sigma %.3f (%zu)\n", factor, zrms, n);
    assert_true(factor < 1);
    assert_true(zrms > 0.75 && zrms < 1.25);
    free(E), free(sig), free(fg), free(radiance);
    rs_fx_release(&env, &cap, scene, m);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_radiance_sigma), cmocka_unit_test(test_mc_sigma),
             cmocka_unit_test(test_mc_calibration))
