/* The gather's speed-ups must not change what it computes: the guided sky pick equals the
 * binary search, rs_gather_run equals facet-by-facet gathers whatever the thread count, the
 * closure of skip_unseen keeps every row it needs, skip_convex changes no number, and adaptive
 * sun rays spend rays where a shadow edge is and nowhere else. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#include "light/gather.h"
#include "tests/fixtures.h"
#include "tests/meshgen.h"
#include "common/sampling.h"
#include "tests/testutil.h"

/* A sky of random luminance with a few bright pixels (the sun set), in world axes. */
static void random_sky(int w, rs_capture *cap, rs_skyenv *env)
{
    rs_fx_random_sky(w, 1e4f, 97, cap, env);
    assert_non_null(env->cdf);
    assert_non_null(env->sun_cdf);
}

static void test_pick_matches_binary_search(void **state)
{
    (void)state;
    rs_capture cap;
    rs_skyenv env;
    random_sky(512, &cap, &env);
    assert_non_null(env.cdf_guide);
    assert_non_null(env.sun_cdf_guide);
    /* The map's own guides, then (a map made without them) guides built in the scratch. */
    rs_skyenv bare = env;
    bare.cdf_guide = bare.sun_cdf_guide = NULL;
    for (int own = 0; own < 2; own++) {
        const rs_skyenv *e = own ? &bare : &env;
        rs_gather_scratch *s = rs_gather_scratch_new(16);
        size_t mismatches = 0;
        for (int sun = 0; sun < 2; sun++)
            for (uint32_t k = 0; k < 200000; k++) {
                double x = (rs_hash_u32(k * 2 + (uint32_t)sun) >> 8) / 16777216.0;
                if (k < 1000) x = k / 1000.0;           /* bucket edges and 0 */
                if (k == 1000) x = nextafter(1.0, 0.0); /* the last representable x */
                size_t a = rs_gather_pick(s, e, sun, x), b = sun ? rs_skyenv_pick_sun(e, x) : rs_skyenv_pick(e, x);
                mismatches += a != b;
            }
        assert_int_equal(mismatches, 0);
        rs_gather_scratch_free(s);
    }
    rs_skyenv_release(&env);
    rs_capture_release(&cap);
}

/* An L of floor and wall, plus a box below the floor that nothing above it can see. */
static rs_mesh *scene_mesh(size_t *first_hidden)
{
    rs_meshgen g = rs_meshgen_new(4000, 4000);
    rs_meshgen_rect(&g, rs_v3_make(0, 0, 0), rs_v3_make(4, 0, 0), rs_v3_make(0, 4, 0), 6, 6); /* floor */
    rs_meshgen_rect(&g, rs_v3_make(0, 4, 0), rs_v3_make(4, 0, 0), rs_v3_make(0, 0, 3), 6, 6); /* wall, facing -y */
    *first_hidden = g.nf;
    rs_meshgen_box(&g, rs_v3_make(1, 1, -5), rs_v3_make(2, 2, -4), 2, 0);
    return rs_meshgen_done(&g);
}

static void same_rows(const rs_facet_gather *a, const rs_facet_gather *b)
{
    assert_memory_equal(a->esky, b->esky, sizeof a->esky);
    assert_int_equal(a->nentries, b->nentries);
    if (a->nentries) assert_memory_equal(a->entries, b->entries, a->nentries * sizeof *a->entries);
}

static void test_run_threads_and_closure(void **state)
{
    (void)state;
    size_t hidden;
    rs_mesh *m = scene_mesh(&hidden);
    rs_scene *scene = rs_fx_scene(m);
    rs_capture cap;
    rs_skyenv env;
    random_sky(256, &cap, &env);
    size_t nf = m->nfaces;
    rs_gather_ctx g = rs_fx_gather_ctx(scene, &env, 64, 16, 7);
    rs_facet_gather *one = calloc(nf, sizeof *one), *two = calloc(nf, sizeof *two), *part = calloc(nf, sizeof *part);
    rs_gather_stats st;
    rs_err err;
#ifdef _OPENMP
    omp_set_num_threads(1);
#endif
    assert_int_equal(rs_gather_run(&g, nf, NULL, one, NULL, NULL, &st, &err), 0);
    assert_int_equal(st.gathered, nf);
#ifdef _OPENMP
    omp_set_num_threads(2);
#endif
    assert_int_equal(rs_gather_run(&g, nf, NULL, two, NULL, NULL, &st, &err), 0);
    rs_gather_scratch *s = rs_gather_scratch_new(64);
    for (size_t f = 0; f < nf; f++) {
        rs_facet_gather ref;
        assert_int_equal(rs_gather_facet(&g, (uint32_t)f, s, &ref), 0);
        same_rows(&one[f], &ref);    /* the order of facets changes nothing */
        same_rows(&one[f], &two[f]); /* nor the thread count */
        free(ref.entries);
    }
    rs_gather_scratch_free(s);

    /* Needed: one floor facet. The wall it sees is gathered, the box below the floor is not,
     * and every gathered row equals the full gather's and points only at gathered facets. */
    uint8_t *needed = calloc(nf, 1), *gathered = calloc(nf, 1);
    needed[0] = 1;
    assert_int_equal(rs_gather_run(&g, nf, needed, part, gathered, NULL, &st, &err), 0);
    print_message("closure: %zu of %zu facets in %d waves\n", st.gathered, nf, st.waves);
    assert_true(st.waves >= 2);
    assert_true(gathered[0]);
    size_t wall_gathered = 0;
    for (size_t f = 72; f < hidden; f++) wall_gathered += gathered[f];
    assert_true(wall_gathered > 0);
    for (size_t f = hidden; f < nf; f++) assert_false(gathered[f]);
    for (size_t f = 0; f < nf; f++) {
        if (!gathered[f]) {
            assert_int_equal(part[f].nentries, 0);
            assert_true(part[f].esky[0] == 0);
            continue;
        }
        same_rows(&part[f], &one[f]);
        for (uint32_t q = 0; q < part[f].nentries; q++) assert_true(gathered[part[f].entries[q].col]);
    }

    /* Relays at a quarter of the rays (relay_share): the needed facet keeps the full gather's row,
     * every relay traces 16 / 16 / 4 rays and its row points only at gathered facets, and on
     * average a relay's row sums to what the full rows do (a weight left at the needed facets'
     * count would make it a quarter). The noise calibration regathers the needed facet alone. */
    rs_gather_ctx rg = g;
    rg.relay_share = 0.25;
    rs_facet_gather *relay = calloc(nf, sizeof *relay);
    uint8_t *rgathered = calloc(nf, 1);
    assert_int_equal(rs_gather_run(&rg, nf, needed, relay, rgathered, NULL, &st, &err), 0);
    same_rows(&relay[0], &one[0]);
    assert_int_equal(relay[0].samples, 64);
    assert_false(relay[0].relay);
    double sum_relay = 0, sum_full = 0;
    size_t relays = 0;
    for (size_t f = 1; f < nf; f++) {
        if (!rgathered[f]) continue;
        assert_int_equal(relay[f].samples, 16);
        assert_true(relay[f].relay);
        assert_int_equal(relay[f].rays, 16 + 16 + 4);
        for (uint32_t q = 0; q < relay[f].nentries; q++) {
            assert_true(rgathered[relay[f].entries[q].col]);
            sum_relay += relay[f].entries[q].k;
        }
        for (uint32_t q = 0; q < one[f].nentries; q++) sum_full += one[f].entries[q].k;
        relays++;
    }
    assert_int_equal(st.relays, relays);
    print_message("relays: %zu, mean K row sum %.4f at a quarter of the rays, %.4f at all\n", relays,
                  sum_relay / relays, sum_full / relays);
    assert_true(relays > 20);
    assert_true(fabs(sum_relay / sum_full - 1) < 0.1);
    double factor;
    size_t used;
    assert_int_equal(rs_gather_mc_calibration(&rg, nf, relay, NULL, NULL, 512, &factor, &used, &err), 0);
    assert_int_equal(used, 1);
    for (size_t f = 0; f < nf; f++) free(relay[f].entries);
    free(relay), free(rgathered);
    for (size_t f = 0; f < nf; f++) {
        free(one[f].entries);
        free(two[f].entries);
        free(part[f].entries);
    }
    free(one), free(two), free(part), free(needed), free(gathered);
    rs_fx_release(&env, &cap, scene, m);
}

/* sun_samples = 0 with a sun set in the map: the cosine rays must count the sun (they used to
 * skip it, leaving it to sun rays that were not cast). */
static void test_sun_without_sun_rays(void **state)
{
    (void)state;
    rs_mesh *m = rs_fx_unit_square();
    rs_scene *scene = rs_fx_scene(m);
    rs_capture cap;
    rs_skyenv env;
    random_sky(128, &cap, &env);
    rs_gather_scratch *s = rs_gather_scratch_new(1 << 18);
    rs_gather_ctx with = rs_fx_gather_ctx(scene, &env, 256, 256, 3), without = with;
    without.sun_samples = 0;
    without.samples = 1 << 18; /* enough cosine rays to find the sun */
    rs_facet_gather a, b;
    assert_int_equal(rs_gather_facet(&with, 0, s, &a), 0);
    assert_int_equal(rs_gather_facet(&without, 0, s, &b), 0);
    print_message("E with sun rays %.5g, cosine rays only %.5g\n", a.esky[0], b.esky[0]);
    assert_true(fabs(b.esky[0] - a.esky[0]) / a.esky[0] < 0.03);
    rs_gather_scratch_free(s);
    rs_fx_release(&env, &cap, scene, m);
}

/* A floor half in the shadow of a thin blade: adaptive sun rays add rays on the facets that
 * the shadow edge crosses and none on the facets fully in the sun, and get closer to a
 * 16-times-sampled reference there. */
static void test_adaptive_sun(void **state)
{
    (void)state;
    rs_meshgen mg = rs_meshgen_new(400, 400);
    rs_meshgen_rect(&mg, rs_v3_make(-4, -4, 0), rs_v3_make(8, 0, 0), rs_v3_make(0, 8, 0), 8, 8);
    rs_meshgen_box(&mg, rs_v3_make(-0.05, -10, 0.5), rs_v3_make(0.05, 10, 6), 1, 0);
    rs_mesh *m = rs_meshgen_done(&mg);
    rs_scene *scene = rs_fx_scene(m);
    rs_capture cap;
    rs_skyenv env;
    random_sky(256, &cap, &env);
    rs_gather_scratch *s = rs_gather_scratch_new(1024);
    rs_gather_ctx base = rs_fx_gather_ctx(scene, &env, 64, 16, 5), adapt = base, ref = base;
    adapt.sun_target_error = 0.01;
    ref.sun_samples = 256;
    int lit_only = 0, extra = 0;
    double err_base = 0, err_adapt = 0;
    for (uint32_t f = 0; f < 128; f++) {
        rs_facet_gather a, b, r;
        assert_int_equal(rs_gather_facet(&base, f, s, &a), 0);
        assert_int_equal(rs_gather_facet(&adapt, f, s, &b), 0);
        assert_int_equal(rs_gather_facet(&ref, f, s, &r), 0);
        assert_true(b.rays >= a.rays && b.rays <= a.rays + 15 * 16);
        if (b.rays > a.rays)
            extra++;
        else
            lit_only++;
        err_base += fabs(a.esky_lum - r.esky_lum) / r.esky_lum;
        err_adapt += fabs(b.esky_lum - r.esky_lum) / r.esky_lum;
        free(a.entries), free(b.entries), free(r.entries);
    }
    print_message("adaptive: %d facets with extra sun rays, %d without; error %.4f -> %.4f\n", extra, lit_only,
                  err_base / 128, err_adapt / 128);
    assert_true(extra > 0 && lit_only > extra);
    assert_true(err_adapt < err_base);
    rs_gather_scratch_free(s);
    rs_fx_release(&env, &cap, scene, m);
}

/* skip_convex: a box on a wide floor. The box's top sees nothing (the model lies below its
 * plane), nor does its bottom; its sides see the floor; skipping the tracing changes no number. */
static void test_convex_skip(void **state)
{
    (void)state;
    rs_meshgen mg = rs_meshgen_new(400, 400);
    rs_meshgen_rect(&mg, rs_v3_make(-5, -5, 0), rs_v3_make(10, 0, 0), rs_v3_make(0, 10, 0), 4, 4);
    size_t box = mg.nf;
    rs_meshgen_box(&mg, rs_v3_make(-1, -1, 0), rs_v3_make(1, 1, 2), 2, 0);
    rs_mesh *m = rs_meshgen_done(&mg);
    rs_scene *scene = rs_fx_scene(m);
    rs_capture cap;
    rs_skyenv env;
    random_sky(128, &cap, &env);
    rs_gather_scratch *s = rs_gather_scratch_new(64);
    rs_gather_ctx on = rs_fx_gather_ctx(scene, &env, 64, 16, 9), off = on;
    off.skip_convex = 0;
    size_t skipped = 0;
    for (uint32_t f = 0; f < m->nfaces; f++) {
        rs_facet_gather a, b;
        assert_int_equal(rs_gather_facet(&on, f, s, &a), 0);
        assert_int_equal(rs_gather_facet(&off, f, s, &b), 0);
        same_rows(&a, &b);
        assert_false(b.sees_nothing);
        rs_v3 c, n;
        double area;
        rs_mesh_face(m, f, &c, &n, &area);
        /* the box's top (z = 2, facing up) and bottom (z = 0, facing down) see nothing; floor
         * and box sides see each other */
        int none = f >= box && ((n.z > 0.5 && c.z > 1.9) || n.z < -0.5);
        assert_int_equal(a.sees_nothing, none);
        skipped += a.sees_nothing;
        free(a.entries), free(b.entries);
    }
    assert_int_equal(skipped, 16); /* top and bottom: 2 x 2 cells of two triangles each */
    rs_gather_scratch_free(s);
    rs_fx_release(&env, &cap, scene, m);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_pick_matches_binary_search),
             cmocka_unit_test(test_run_threads_and_closure), cmocka_unit_test(test_sun_without_sun_rays),
             cmocka_unit_test(test_adaptive_sun), cmocka_unit_test(test_convex_skip))
