/* albpool: the albedo pooled within same-material planes (stages/reflectance/albpool.h). Noise
 * on a uniform plane falls to a stated share; a step survives next to the edge; a texture that
 * the facets resolve is kept; the reported noise follows the actual error and never falls below
 * the correlated part; end to end, albedo.ply's albedo_sigma_rel keeps the floor and the sky
 * fill's share. */
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include "common/faceprop.h"
#include "common/sampling.h"
#include "stages/reflectance/albpool.h"
#include "tests/meshgen.h"

#define CELLS 40 /* a 10 m floor of 40 x 40 cells: 3200 facets */

static rs_mesh *floor_mesh(void)
{
    rs_meshgen g = rs_meshgen_new(2000, 4000);
    rs_meshgen_rect(&g, rs_v3_make(0, 0, 0), rs_v3_make(10, 0, 0), rs_v3_make(0, 10, 0), CELLS, CELLS);
    return rs_meshgen_done(&g);
}

/* A standard normal draw from two hashes (Box-Muller). */
static double gauss(uint32_t seed, uint32_t k)
{
    double u = (rs_hash_combine(seed, 2 * k) + 0.5) / 4294967296.0;
    double v = (rs_hash_combine(seed, 2 * k + 1) + 0.5) / 4294967296.0;
    return sqrt(-2 * log(u)) * cos(2 * M_PI * v);
}

typedef struct {
    size_t nf;
    double *truth, *rho, *s_rad, *s_mc;
    uint8_t *usable;
    double *o_rho, *o_rad, *o_mc, *o_bias, *o_neff;
    rs_albpool_out out;
} scene;

/* The facets' noise: noise (relative, independent) on each, but on one in bad_every (none when 0),
 * picked by a hash, bad_noise, and their reading bad_gain times the truth (a mixed pixel). */
typedef struct {
    double noise, bad_noise, bad_gain;
    uint32_t bad_every;
} noise_spec;

static int is_bad(const noise_spec *ns, uint32_t seed, size_t f)
{
    return ns->bad_every && rs_hash_combine(seed + 1000, (uint32_t)f) % ns->bad_every == 0;
}

/* truth(x, cell index) per facet; mc: the Monte Carlo relative noise reported (not drawn: wholly
 * correlated, it moves every facet alike). */
static void scene_run_spec(scene *s, const rs_mesh *m, double (*truth)(double x, size_t cell), const noise_spec *ns,
                           double mc, uint32_t seed)
{
    size_t nf = s->nf = m->nfaces;
    s->truth = malloc(nf * sizeof *s->truth), s->rho = malloc(3 * nf * sizeof *s->rho);
    s->s_rad = malloc(nf * sizeof *s->s_rad), s->s_mc = malloc(nf * sizeof *s->s_mc), s->usable = malloc(nf);
    s->o_rho = malloc(3 * nf * sizeof *s->o_rho), s->o_rad = malloc(nf * sizeof *s->o_rad);
    s->o_mc = malloc(nf * sizeof *s->o_mc), s->o_bias = malloc(nf * sizeof *s->o_bias);
    s->o_neff = malloc(nf * sizeof *s->o_neff);
    for (size_t f = 0; f < nf; f++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(m, f, &c, &n, &a);
        size_t cell = (size_t)(c.x / (10.0 / CELLS)) + CELLS * (size_t)(c.y / (10.0 / CELLS));
        s->truth[f] = truth(c.x, cell);
        int bad = is_bad(ns, seed, f);
        double sd = bad ? ns->bad_noise : ns->noise, e = sd * gauss(seed, (uint32_t)f);
        for (int ch = 0; ch < 3; ch++) s->rho[3 * f + ch] = s->truth[f] * (bad ? ns->bad_gain : 1) * (1 + e);
        s->s_rad[f] = sd, s->s_mc[f] = mc, s->usable[f] = 1;
    }
    rs_albpool_in in = {
        .nf = nf, .rho = s->rho, .usable = s->usable, .s_rad = s->s_rad, .s_mc = s->s_mc, .floor = 0.0025, .sigmas = 3};
    s->out =
        (rs_albpool_out){.rho = s->o_rho, .s_rad = s->o_rad, .s_mc = s->o_mc, .s_bias = s->o_bias, .neff = s->o_neff};
    assert_int_equal(rs_albpool_run(m, &in, &s->out), 0);
}

static void scene_run(scene *s, const rs_mesh *m, double (*truth)(double x, size_t cell), double noise, double mc,
                      uint32_t seed)
{
    noise_spec ns = {.noise = noise};
    scene_run_spec(s, m, truth, &ns, mc, seed);
}

static void scene_free(scene *s)
{
    free(s->truth), free(s->rho), free(s->s_rad), free(s->s_mc), free(s->usable);
    free(s->o_rho), free(s->o_rad), free(s->o_mc), free(s->o_bias), free(s->o_neff);
}

/* RMS relative error against the truth, before [0] and after [1] pooling, of the facets with
 * keep(x) (NULL: all). */
static void rms_error(const scene *s, const rs_mesh *m, int (*keep)(double x), double e[2])
{
    double a = 0, b = 0;
    size_t n = 0;
    for (size_t f = 0; f < s->nf; f++) {
        rs_v3 c, nn;
        double ar;
        rs_mesh_face(m, f, &c, &nn, &ar);
        if (keep && !keep(c.x)) continue;
        double d0 = s->rho[3 * f] / s->truth[f] - 1, d1 = s->o_rho[3 * f] / s->truth[f] - 1;
        a += d0 * d0, b += d1 * d1, n++;
    }
    e[0] = sqrt(a / n), e[1] = sqrt(b / n);
}

static double uniform_half(double x, size_t cell)
{
    (void)x, (void)cell;
    return 0.5;
}

static double uniform_seven(double x, size_t cell)
{
    (void)x, (void)cell;
    return 0.7;
}

static int interior(double x)
{
    return x > 1 && x < 9; /* a disk's radius (0.8 m) from the plane's ends */
}

/* A uniform plane, 5 % noise per facet: the pooled error is below a quarter of the unpooled one
 * (about 1 / sqrt(24) of it, the facets a disk holds), and the reported radiance noise follows
 * the actual error (within 30 %); the correlated Monte Carlo part (2 %) is not reduced at all. */
static void test_uniform_plane(void **state)
{
    (void)state;
    rs_mesh *m = floor_mesh();
    scene s;
    scene_run(&s, m, uniform_half, 0.05, 0.02, 5);
    double e[2];
    rms_error(&s, m, interior, e);
    double rep = 0;
    size_t n = 0;
    for (size_t f = 0; f < s.nf; f++) {
        assert_true(s.o_mc[f] >= 0.02 * (1 - 1e-12)); /* the correlated part stays */
        assert_true(s.o_rad[f] <= 0.05 * (1 + 1e-12));
        rs_v3 c, nn;
        double a;
        rs_mesh_face(m, f, &c, &nn, &a);
        if (interior(c.x)) rep += s.o_rad[f] * s.o_rad[f], n++;
    }
    rep = sqrt(rep / n);
    print_message("uniform plane: RMS error %.4f -> %.4f (ratio %.3f), reported %.4f, %.1f effective facets, "
                  "%.0f %% kept, shrinkage %.2f\n",
                  e[0], e[1], e[1] / e[0], rep, s.out.mean_neff, 100 * s.out.mean_kept_share, s.out.mean_shrink);
    assert_true(e[1] < 0.25 * e[0]);
    assert_true(rep > e[1] / 1.3 && rep < 1.3 * e[1]);
    assert_true(s.out.pooled > s.nf * 9 / 10);
    scene_free(&s);
    rs_mesh_free(m);
}

static double step(double x, size_t cell)
{
    (void)cell;
    return x < 5 ? 0.3 : 0.6;
}

static int next_to_step(double x)
{
    return fabs(x - 5) < 10.0 / CELLS; /* the cell column on each side */
}

/* An albedo step 0.3 | 0.6 with 3 % noise: the column of facets on each side of it keeps its own
 * side's albedo (RMS error below half the unpooled one, no facet off by more than 10 %: mixing
 * across would move it by tens of per cent), as far from the edge as anywhere. */
static void test_step_survives(void **state)
{
    (void)state;
    rs_mesh *m = floor_mesh();
    scene s;
    scene_run(&s, m, step, 0.03, 0, 9);
    double e[2], all[2], worst = 0;
    rms_error(&s, m, next_to_step, e);
    rms_error(&s, m, NULL, all);
    for (size_t f = 0; f < s.nf; f++) worst = fmax(worst, fabs(s.o_rho[3 * f] / s.truth[f] - 1));
    print_message("step: next to it RMS %.4f -> %.4f, everywhere %.4f -> %.4f, worst facet %.4f\n", e[0], e[1], all[0],
                  all[1], worst);
    assert_true(e[1] < 0.5 * e[0]);
    assert_true(worst < 0.1);
    scene_free(&s);
    rs_mesh_free(m);
}

/* A texture the facets resolve: every cell's albedo 0.5 (1 + 0.04 z), z normal, under 3 % noise;
 * too weak for the test to cut. Pooling all would erase it (error 4 %); the shrinkage keeps it:
 * the error falls below the unpooled one, and the pooled albedos follow the pattern (correlation
 * with it above 0.7). */
static double texture(double x, size_t cell)
{
    (void)x;
    return 0.5 * (1 + 0.04 * gauss(77, (uint32_t)cell));
}

static void test_texture_kept(void **state)
{
    (void)state;
    rs_mesh *m = floor_mesh();
    scene s;
    scene_run(&s, m, texture, 0.03, 0, 13);
    double e[2];
    rms_error(&s, m, interior, e);
    double sxy = 0, sxx = 0, syy = 0;
    for (size_t f = 0; f < s.nf; f++) {
        double x = s.truth[f] - 0.5, y = s.o_rho[3 * f] - 0.5;
        sxy += x * y, sxx += x * x, syy += y * y;
    }
    double corr = sxy / sqrt(sxx * syy);
    print_message("texture: RMS error %.4f -> %.4f, correlation with the pattern %.3f, shrinkage %.2f\n", e[0], e[1],
                  corr, s.out.mean_shrink);
    assert_true(e[1] < e[0]);
    assert_true(corr > 0.7);
    scene_free(&s);
    rs_mesh_free(m);
}

/* RMS relative error before [0] and after [1] pooling, and the mean signed error after, of the
 * interior facets that are bad (1) or not (0) under ns. */
static void error_of(const scene *s, const rs_mesh *m, const noise_spec *ns, uint32_t seed, int bad, double e[3])
{
    double a = 0, b = 0, sb = 0;
    size_t n = 0;
    for (size_t f = 0; f < s->nf; f++) {
        rs_v3 c, nn;
        double ar;
        rs_mesh_face(m, f, &c, &nn, &ar);
        if (!interior(c.x) || is_bad(ns, seed, f) != bad) continue;
        double d0 = s->rho[3 * f] / s->truth[f] - 1, d1 = s->o_rho[3 * f] / s->truth[f] - 1;
        a += d0 * d0, b += d1 * d1, sb += d1, n++;
    }
    e[0] = sqrt(a / n), e[1] = sqrt(b / n), e[2] = sb / n;
}

/* A uniform plane where one facet in eight is observed with 20 % noise (its pixels few or mixed),
 * the rest with 1 %: the noisy ones pass the lenient test (3 sigmas of 20 %), and with area
 * weights they count as much as the clean ones (measured with area weights: the well observed
 * facets' RMS error 0.98 -> 0.88 %). Weighted by inverse variance they count 1/400 as much: the
 * well observed facets fall below 0.4 of their unpooled error (measured 0.21 %), the noisy ones
 * below 0.3 of theirs (19.4 -> 5.0 %; the far low ones fail the test and keep their own). */
static void test_inverse_variance(void **state)
{
    (void)state;
    rs_mesh *m = floor_mesh();
    noise_spec ns = {.noise = 0.01, .bad_noise = 0.2, .bad_gain = 1, .bad_every = 8};
    scene s;
    scene_run_spec(&s, m, uniform_half, &ns, 0, 17);
    double good[3], bad[3];
    error_of(&s, m, &ns, 17, 0, good);
    error_of(&s, m, &ns, 17, 1, bad);
    print_message("mixed noise: well observed RMS %.4f -> %.4f, noisy %.4f -> %.4f\n", good[0], good[1], bad[0],
                  bad[1]);
    assert_true(good[1] < 0.4 * good[0]);
    assert_true(bad[1] < 0.3 * bad[0]);
    scene_free(&s);
    rs_mesh_free(m);
}

/* A plane of 0.7 under 3 % noise where one facet in ten reads twice its albedo (1.4, light the
 * model missed or pixels mixed across an edge) with a reported noise of 30 %, so that the test
 * (3 sigmas) keeps it: an albedo above 1 is no neighbour, and the rest pool as on a clean plane
 * (RMS error below 0.3 of unpooled, mean error below 0.05 %). Measured: taken at inverse-variance
 * weight they leave 2.95 -> 1.45 % (mean +0.09 %), at area weight 2.95 -> 2.78 % (+0.14 %); left
 * out, 2.95 -> 0.58 % (-0.02 %). */
static void test_above_one_left_out(void **state)
{
    (void)state;
    rs_mesh *m = floor_mesh();
    noise_spec ns = {.noise = 0.03, .bad_noise = 0.3, .bad_gain = 2, .bad_every = 10};
    scene s;
    scene_run_spec(&s, m, uniform_seven, &ns, 0, 23);
    double good[3];
    error_of(&s, m, &ns, 23, 0, good);
    print_message("above one: the others' RMS %.4f -> %.4f, mean error %+.5f\n", good[0], good[1], good[2]);
    assert_true(fabs(good[2]) < 0.0005);
    assert_true(good[1] < 0.3 * good[0]);
    scene_free(&s);
    rs_mesh_free(m);
}

/* End to end: the reflectance stage (method direct) on the floor under E = 1 with a sky fill
 * uncertainty of 1 % and a Monte Carlo one of 2 %, the radiance with 5 % noise. With the albedo
 * pooled, albedo_sigma_rel falls, but never below sqrt(floor^2 + 0.01^2 + 0.02^2): the floor, the
 * sky fill and the Monte Carlo share are correlated between neighbours. */
static void stage_on_floor(const char *dir, double sigmas, double *sig_rms, double *sig_min, double *err_rms)
{
    rs_mesh *m = floor_mesh();
    size_t nf = m->nfaces;
    rs_test_write(rs_test_path(dir, "scene.ini"), "[pipeline]\nworkdir = work\n[reflectance]\nmethod = direct\n");
    mkdir(rs_test_path(dir, "work"), 0755);
    rs_meshgen_write(m, rs_test_path(dir, "work/mesh.ply"));
    double *esky = malloc(3 * nf * sizeof *esky), *zero3 = calloc(3 * nf, sizeof *zero3),
           *L = malloc(3 * nf * sizeof *L);
    double *one = malloc(nf * sizeof *one), *lsig = malloc(nf * sizeof *lsig), *skys = malloc(nf * sizeof *skys),
           *mc = malloc(nf * sizeof *mc);
    for (size_t f = 0; f < nf; f++) {
        double e = 0.05 * gauss(21, (uint32_t)f);
        for (int ch = 0; ch < 3; ch++) esky[3 * f + ch] = 1, L[3 * f + ch] = 0.5 * (1 + e) / M_PI;
        one[f] = 1, lsig[f] = 0.05, skys[f] = 0.01, mc[f] = 0.02;
    }
    rs_err err;
    rs_ply *obs = rs_ply_new(), *irr = rs_ply_new();
    rs_ply_element *fo = rs_mesh_to_ply(m, obs), *fi = rs_mesh_to_ply(m, irr);
    assert_int_equal(rs_faceprop_add_rgb(fo, "radiance", L), 0);
    assert_non_null(rs_ply_add_scalar(fo, "observed", RS_PLY_UINT8, one));
    assert_non_null(rs_ply_add_scalar(fo, "radiance_sigma_rel", RS_PLY_FLOAT32, lsig));
    assert_int_equal(rs_faceprop_add_rgb(fi, "irradiance_sky", esky), 0);
    assert_int_equal(rs_faceprop_add_rgb(fi, "irradiance_inter_seen", zero3), 0);
    assert_non_null(rs_ply_add_scalar(fi, "sky_filled", RS_PLY_FLOAT32, one));
    assert_non_null(rs_ply_add_scalar(fi, "irradiance_sky_sigma", RS_PLY_FLOAT32, skys));
    assert_non_null(rs_ply_add_scalar(fi, "irradiance_mc_sigma", RS_PLY_FLOAT32, mc));
    assert_int_equal(rs_ply_write(obs, rs_test_path(dir, "work/observe.ply"), 1, &err), 0);
    assert_int_equal(rs_ply_write(irr, rs_test_path(dir, "work/irradiance.ply"), 1, &err), 0);
    rs_ply_free(obs);
    rs_ply_free(irr);
    char cmd[4096], *out = NULL;
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/rhoscan-reflectance' --set reflectance.albedo_pool_sigmas=%g scene.ini",
             dir, rs_test_bin_dir(), sigmas);
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) print_message("%s\n", out);
    assert_int_equal(rc, 0);
    free(out);
    rs_ply *alb = rs_ply_read(rs_test_path(dir, "work/albedo.ply"), &err);
    assert_non_null(alb);
    double *rho = malloc(3 * nf * sizeof *rho), *sig = malloc(nf * sizeof *sig);
    assert_int_equal(rs_faceprop_get_rgb(alb, "albedo.ply", "albedo", nf, rho, &err), 0);
    assert_int_equal(rs_faceprop_get(alb, "albedo.ply", "albedo_sigma_rel", nf, sig, &err), 0);
    double s2 = 0, e2 = 0;
    *sig_min = INFINITY;
    for (size_t f = 0; f < nf; f++) {
        double e = rho[3 * f] / 0.5 - 1;
        s2 += sig[f] * sig[f], e2 += e * e, *sig_min = fmin(*sig_min, sig[f]);
    }
    *sig_rms = sqrt(s2 / nf), *err_rms = sqrt(e2 / nf);
    rs_ply_free(alb);
    free(rho), free(sig), free(esky), free(zero3), free(L), free(one), free(lsig), free(skys), free(mc);
    rs_mesh_free(m);
}

static void test_stage_uncertainty(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("albpool_stage");
    double s0, min0, e0, s1, min1, e1;
    stage_on_floor(dir, 0, &s0, &min0, &e0);
    stage_on_floor(dir, 3, &s1, &min1, &e1);
    double corr = sqrt(0.0025 * 0.0025 + 0.01 * 0.01 + 0.02 * 0.02);
    print_message("albedo_sigma_rel RMS %.4f -> %.4f (least %.4f, correlated floor %.4f); RMS error %.4f -> %.4f\n", s0,
                  s1, min1, corr, e0, e1);
    assert_true(fabs(s0 - sqrt(corr * corr + 0.05 * 0.05)) < 1e-4); /* unpooled: as before */
    assert_true(s1 < 0.6 * s0);
    assert_true(min1 >= corr * (1 - 1e-5));
    assert_true(e1 < 0.3 * e0);
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_uniform_plane), cmocka_unit_test(test_step_survives),
             cmocka_unit_test(test_texture_kept), cmocka_unit_test(test_inverse_variance),
             cmocka_unit_test(test_above_one_left_out), cmocka_unit_test(test_stage_uncertainty))
