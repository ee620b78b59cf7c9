/* pool: irradiance shared within a plane (stages/reflectance/pool.h). The noise of independent
 * per-facet values falls, their mean does not move, and nothing is shared across planes, across
 * a parallel step, beyond Ward's radius, or with a facet that was not gathered. */
#include "tests/testutil.h"

#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include "common/faceprop.h"
#include "tests/meshgen.h"
#include "stages/reflectance/pool.h"
#include "common/sampling.h"

/* A 10 m floor of 40 x 40 cells (3200 facets) and, at x = 10, a wall 5 m high of 40 x 20. */
static rs_mesh *floor_and_wall(size_t *nfloor)
{
    rs_meshgen g = rs_meshgen_new(4000, 5000);
    *nfloor = 2 * 40 * 40;
    rs_meshgen_rect(&g, rs_v3_make(0, 0, 0), rs_v3_make(10, 0, 0), rs_v3_make(0, 10, 0), 40, 40);
    rs_meshgen_rect(&g, rs_v3_make(10, 0, 0), rs_v3_make(0, 10, 0), rs_v3_make(0, 0, 5), 40, 20);
    return rs_meshgen_done(&g);
}

/* Independent noisy values around 1 (sigma 0.1) on every facet: the pooled ones keep the mean
 * and have less than half the spread; every weight list sums to 1 and starts with the facet. */
static void test_noise_falls_mean_stays(void **state)
{
    (void)state;
    size_t nfloor;
    rs_mesh *m = floor_and_wall(&nfloor);
    size_t nf = m->nfaces;
    double *inv = calloc(nf, sizeof *inv), *v = malloc(3 * nf * sizeof *v), *p = malloc(3 * nf * sizeof *p);
    assert_non_null(inv);
    rs_pool pool;
    assert_int_equal(rs_pool_build(m, inv, NULL, NULL, 0.1, &pool), 0);
    for (size_t f = 0; f < nf; f++) {
        double u = rs_hash_combine(7, (uint32_t)f) / 4294967296.0;
        double noise = 0.1 * sqrt(12) * (u - 0.5);
        for (int ch = 0; ch < 3; ch++) v[3 * f + ch] = 1 + noise;
        double s = 0;
        assert_int_equal(pool.nbr[pool.start[f]], f);
        for (size_t q = pool.start[f]; q < pool.start[f + 1]; q++) s += pool.w[q];
        assert_true(fabs(s - 1) < 1e-5);
    }
    rs_pool_apply3(&pool, v, p);
    double m0 = 0, m1 = 0, s0 = 0, s1 = 0;
    for (size_t f = 0; f < nfloor; f++) m0 += v[3 * f], m1 += p[3 * f];
    m0 /= nfloor, m1 /= nfloor;
    for (size_t f = 0; f < nfloor; f++)
        s0 += (v[3 * f] - m0) * (v[3 * f] - m0), s1 += (p[3 * f] - m1) * (p[3 * f] - m1);
    s0 = sqrt(s0 / nfloor), s1 = sqrt(s1 / nfloor);
    print_message("floor: spread %.4f -> %.4f, mean %.4f -> %.4f\n", s0, s1, m0, m1);
    assert_true(s1 < 0.5 * s0);
    assert_true(fabs(m1 - m0) < 0.005);
    /* The reported noise of the mean follows the same fall. */
    double *sig = malloc(nf * sizeof *sig), *sp = malloc(nf * sizeof *sp);
    for (size_t f = 0; f < nf; f++) sig[f] = 0.1;
    rs_pool_sigma(&pool, sig, sp);
    double ms = 0;
    for (size_t f = 0; f < nfloor; f++) ms += sp[f] * sp[f];
    ms = sqrt(ms / nfloor);
    print_message("reported sigma 0.1 -> %.4f (actual spread %.4f)\n", ms, s1);
    assert_true(ms < 0.5 * 0.1 && ms > 0.5 * s1 && ms < 2 * s1);
    rs_pool_free(&pool);
    free(inv), free(v), free(p), free(sig), free(sp);
    rs_mesh_free(m);
}

/* Near the wall the floor sees it close by: the radius shrinks with Ward's R, no floor facet
 * takes a wall facet (or the reverse), and a facet that was not gathered is nobody's neighbour. */
static void test_planes_radius_and_unusable(void **state)
{
    (void)state;
    size_t nfloor;
    rs_mesh *m = floor_and_wall(&nfloor);
    size_t nf = m->nfaces;
    double *inv = calloc(nf, sizeof *inv);
    uint8_t *usable = malloc(nf);
    memset(usable, 1, nf);
    usable[100] = 0;
    for (size_t f = 0; f < nf; f++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(m, f, &c, &n, &a);
        inv[f] = f < nfloor ? 1 / fmax(0.05, 10 - c.x) : 1 / fmax(0.05, c.z); /* the other plane's distance */
    }
    rs_pool pool;
    assert_int_equal(rs_pool_build(m, inv, usable, NULL, 0.2, &pool), 0);
    assert_int_equal(pool.start[101] - pool.start[100], 1);
    size_t with_others = 0;
    for (size_t f = 0; f < nf; f++) {
        rs_v3 ci, n;
        double a;
        rs_mesh_face(m, f, &ci, &n, &a);
        with_others += pool.start[f + 1] - pool.start[f] > 1;
        for (size_t q = pool.start[f] + 1; q < pool.start[f + 1]; q++) {
            uint32_t j = pool.nbr[q];
            assert_int_not_equal(j, 100);
            assert_int_equal(j < nfloor, f < nfloor);
            rs_v3 cj;
            rs_mesh_face(m, j, &cj, &n, &a);
            double R = fmin(1 / inv[f], 1 / inv[j]);
            assert_true(rs_v3_len(rs_v3_sub(cj, ci)) < 0.2 * R + 1e-9);
        }
    }
    print_message("%zu of %zu facets pooled, %.1f facets per mean\n", with_others, nf, (double)pool.start[nf] / nf);
    assert_true(with_others > nf / 2);
    rs_pool_free(&pool);
    free(inv);
    free(usable);
    rs_mesh_free(m);
}

/* Two parallel floors 5 cm apart (a step seen from far away): neither takes the other's facets. */
static void test_parallel_step(void **state)
{
    (void)state;
    rs_meshgen g = rs_meshgen_new(400, 400);
    rs_meshgen_rect(&g, rs_v3_make(0, 0, 0), rs_v3_make(1, 0, 0), rs_v3_make(0, 2, 0), 5, 10);
    rs_meshgen_rect(&g, rs_v3_make(1, 0, 0.05), rs_v3_make(1, 0, 0), rs_v3_make(0, 2, 0), 5, 10);
    rs_mesh *m = rs_meshgen_done(&g);
    double *inv = calloc(m->nfaces, sizeof *inv);
    rs_pool pool;
    assert_int_equal(rs_pool_build(m, inv, NULL, NULL, 0.1, &pool), 0);
    for (size_t f = 0; f < m->nfaces; f++)
        for (size_t q = pool.start[f]; q < pool.start[f + 1]; q++) assert_int_equal(pool.nbr[q] < 100, f < 100);
    rs_pool_free(&pool);
    free(inv);
    rs_mesh_free(m);
}

/* The reflectance stage on a floor half in the sun: E = sun (3 where x < 5, else 0) + a diffuse
 * 1 drawn with noise 0.2 per facet, albedo 0.5 everywhere, the radiance exact. Pooled, the
 * albedo's spread falls on both sides and the shadow edge stays sharp (the facets next to it are
 * as right as the rest: pooling the sun too would miss them by a third); albedo.ply's E_sky + G
 * is what the albedo divided by. Returns the RMS relative albedo error: [0] all, [1] the two
 * cell columns along the edge. */
static void reflectance_on_floor(const char *dir, double accuracy, double rms[2])
{
    rs_meshgen g = rs_meshgen_new(2000, 4000);
    rs_meshgen_rect(&g, rs_v3_make(0, 0, 0), rs_v3_make(10, 0, 0), rs_v3_make(0, 10, 0), 40, 40);
    rs_mesh *m = rs_meshgen_done(&g);
    size_t nf = m->nfaces;
    rs_test_write(rs_test_path(dir, "scene.ini"), "[pipeline]\nworkdir = work\n[reflectance]\nmethod = direct\n");
    mkdir(rs_test_path(dir, "work"), 0755);
    rs_meshgen_write(m, rs_test_path(dir, "work/mesh.ply"));
    double *esky = calloc(3 * nf, sizeof *esky), *esun = calloc(3 * nf, sizeof *esun), *L = calloc(3 * nf, sizeof *L),
           *zero3 = calloc(3 * nf, sizeof *zero3), *zero = calloc(nf, sizeof *zero), *one = malloc(nf * sizeof *one),
           *mc = malloc(nf * sizeof *mc);
    for (size_t f = 0; f < nf; f++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(m, f, &c, &n, &a);
        double sun = c.x < 5 ? 3 : 0, u = rs_hash_combine(11, (uint32_t)f) / 4294967296.0;
        double diffuse = 1 + 0.2 * sqrt(12) * (u - 0.5);
        for (int ch = 0; ch < 3; ch++) {
            esun[3 * f + ch] = sun;
            esky[3 * f + ch] = sun + diffuse;
            L[3 * f + ch] = 0.5 * (sun + 1) / M_PI;
        }
        one[f] = 1;
        mc[f] = 0.2;
    }
    rs_err err;
    rs_ply *obs = rs_ply_new(), *irr = rs_ply_new();
    rs_ply_element *fo = rs_mesh_to_ply(m, obs), *fi = rs_mesh_to_ply(m, irr);
    assert_int_equal(rs_faceprop_add_rgb(fo, "radiance", L), 0);
    assert_non_null(rs_ply_add_scalar(fo, "observed", RS_PLY_UINT8, one));
    assert_int_equal(rs_faceprop_add_rgb(fi, "irradiance_sky", esky), 0);
    assert_int_equal(rs_faceprop_add_rgb(fi, "irradiance_inter", zero3), 0);
    assert_int_equal(rs_faceprop_add_rgb(fi, "irradiance_inter_seen", zero3), 0);
    assert_int_equal(rs_faceprop_add_rgb(fi, "irradiance_sun", esun), 0);
    assert_non_null(rs_ply_add_scalar(fi, "sky_filled", RS_PLY_FLOAT32, zero));
    assert_non_null(rs_ply_add_scalar(fi, "irradiance_sky_sigma", RS_PLY_FLOAT32, zero));
    assert_non_null(rs_ply_add_scalar(fi, "irradiance_mc_sigma", RS_PLY_FLOAT32, mc));
    assert_non_null(rs_ply_add_scalar(fi, "hit_distance_inv", RS_PLY_FLOAT32, zero));
    assert_non_null(rs_ply_add_scalar(fi, "gathered", RS_PLY_UINT8, one));
    assert_int_equal(rs_ply_write(obs, rs_test_path(dir, "work/observe.ply"), 1, &err), 0);
    assert_int_equal(rs_ply_write(irr, rs_test_path(dir, "work/irradiance.ply"), 1, &err), 0);
    rs_ply_free(obs);
    rs_ply_free(irr);

    char cmd[4096], *out = NULL;
    /* the irradiance's pooling alone: the albedo's (tests/stages/test_albpool.c) off */
    snprintf(cmd, sizeof cmd,
             "cd '%s' && '%s/rhoscan-reflectance' --set reflectance.pool_accuracy=%g --set "
             "reflectance.albedo_pool_sigmas=0 scene.ini",
             dir, rs_test_bin_dir(), accuracy);
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) print_message("%s\n", out);
    assert_int_equal(rc, 0);
    free(out);
    rs_ply *alb = rs_ply_read(rs_test_path(dir, "work/albedo.ply"), &err);
    assert_non_null(alb);
    double *rho = malloc(3 * nf * sizeof *rho), *ws = malloc(3 * nf * sizeof *ws), *wg = malloc(3 * nf * sizeof *wg);
    assert_int_equal(rs_faceprop_get_rgb(alb, "albedo.ply", "albedo", nf, rho, &err), 0);
    assert_int_equal(rs_faceprop_get_rgb(alb, "albedo.ply", "irradiance_sky", nf, ws, &err), 0);
    assert_int_equal(rs_faceprop_get_rgb(alb, "albedo.ply", "irradiance_inter", nf, wg, &err), 0);
    double s[2] = {0, 0};
    size_t n[2] = {0, 0};
    for (size_t f = 0; f < nf; f++) {
        rs_v3 c, nn;
        double a;
        rs_mesh_face(m, f, &c, &nn, &a);
        double e = rho[3 * f] / 0.5 - 1;
        s[0] += e * e, n[0]++;
        if (fabs(c.x - 5) < 0.5) s[1] += e * e, n[1]++;
        assert_true(fabs(rho[3 * f] * (ws[3 * f] + wg[3 * f]) / (M_PI * L[3 * f]) - 1) < 1e-5);
    }
    rms[0] = sqrt(s[0] / n[0]), rms[1] = sqrt(s[1] / n[1]);
    rs_ply_free(alb);
    free(rho), free(ws), free(wg);
    free(esky), free(esun), free(L), free(zero3), free(zero), free(one), free(mc);
    rs_mesh_free(m);
}

static void test_reflectance_keeps_the_shadow_edge(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("pool_stage");
    double own[2], pooled[2];
    reflectance_on_floor(dir, 0, own);
    reflectance_on_floor(dir, 0.1, pooled);
    print_message("RMS relative albedo error: own gather %.4f (edge %.4f), pooled %.4f (edge %.4f)\n", own[0], own[1],
                  pooled[0], pooled[1]);
    assert_true(pooled[0] < 0.5 * own[0]);
    assert_true(pooled[1] < 0.5 * own[1]);
    assert_true(pooled[1] < 2 * pooled[0]);
    rs_test_rmtree(dir);
}

/* The lists do not depend on the thread count, nor a facet's on which others asked for one. */
static void test_threads(void **state)
{
    (void)state;
    size_t nfloor;
    rs_mesh *m = floor_and_wall(&nfloor);
    double *inv = calloc(m->nfaces, sizeof *inv);
    for (size_t f = 0; f < m->nfaces; f++) inv[f] = 0.1 + 0.01 * (double)(f % 7);
    rs_pool a, b;
    omp_set_num_threads(1);
    assert_int_equal(rs_pool_build(m, inv, NULL, NULL, 0.1, &a), 0);
    omp_set_num_threads(2);
    assert_int_equal(rs_pool_build(m, inv, NULL, NULL, 0.1, &b), 0);
    assert_memory_equal(a.start, b.start, (m->nfaces + 1) * sizeof *a.start);
    assert_memory_equal(a.nbr, b.nbr, a.start[m->nfaces] * sizeof *a.nbr);
    assert_memory_equal(a.w, b.w, a.start[m->nfaces] * sizeof *a.w);
    /* Lists for every other facet only: those are the full ones, the rest are alone. */
    uint8_t *wanted = malloc(m->nfaces);
    for (size_t f = 0; f < m->nfaces; f++) wanted[f] = f % 2 == 0;
    rs_pool_free(&b);
    assert_int_equal(rs_pool_build(m, inv, NULL, wanted, 0.1, &b), 0);
    size_t entries = 0, nwanted = 0, pooled, asked;
    for (size_t f = 0; f < m->nfaces; f++) {
        size_t na = a.start[f + 1] - a.start[f], nb = b.start[f + 1] - b.start[f];
        assert_int_equal(nb, wanted[f] ? na : 1);
        if (wanted[f]) assert_memory_equal(a.nbr + a.start[f], b.nbr + b.start[f], na * sizeof *a.nbr);
        if (wanted[f]) entries += na, nwanted++;
    }
    /* The summary counts the facets that asked, not those left alone. */
    double mean;
    rs_pool_stats(&b, wanted, &mean, &pooled, &asked);
    assert_int_equal(asked, nwanted);
    assert_true(fabs(mean - (double)entries / nwanted) < 1e-12);
    free(wanted);
    rs_pool_free(&a);
    rs_pool_free(&b);
    free(inv);
    rs_mesh_free(m);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_noise_falls_mean_stays),
             cmocka_unit_test(test_planes_radius_and_unusable), cmocka_unit_test(test_parallel_step),
             cmocka_unit_test(test_threads), cmocka_unit_test(test_reflectance_keeps_the_shadow_edge))
