/* Adaptive per-facet gather ([irradiance] target_error): a floor under a bright sun and a
 * floating wall whose shadow edge crosses one column of facets. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "light/gather.h"
#include "tests/fixtures.h"
#include "tests/meshgen.h"
#include "tests/testutil.h"

enum { CELLS = 16 };                                                  /* floor cells per side (2 facets each), 0.5 m */
static const double WALL_BOTTOM = 0.404, WALL_TOP = 6, WALL_X = 0.05; /* wall faces x = +-0.05 */

/* A uniform sky of radiance 1 with one sun pixel (1e6) at 30 degrees elevation toward +x, in
 * world axes; *sun its direction. */
static void sun_sky(rs_capture *cap, rs_skyenv *env, rs_v3 *sun)
{
    int w = 512, h = 256;
    int sr = h / 3, sc = w / 2; /* polar angle 60 degrees, azimuth 0 */
    *cap = rs_fx_sun_pixel_capture(w, h, 1.0f, 1e6f, sc, sr);
    *sun = rs_pano_pixel_dir(w, h, sc, sr);
    rs_fx_sky_env(cap, 0.01, 1, env);
    assert_int_equal(env->bright_pixels, 1);
}

/* -1: facet f of the floor lies in the wall's shadow, 1 in the sun (each with a margin for the
 * sun pixel's size), 0: the shadow's edge crosses it. The sun passes under the wall's bottom
 * edge, so the shadow on the floor spans x from WALL_X - top cot to -WALL_X - bottom cot. */
static int sun_side(const rs_mesh *m, size_t f, rs_v3 sun)
{
    double cot = sun.x / sun.z, lo = WALL_X - WALL_TOP * cot, hi = -WALL_X - WALL_BOTTOM * cot, margin = 0.05;
    int in = 0, out = 0;
    for (int k = 0; k < 3; k++) {
        double x = m->verts[3 * (size_t)m->tris[3 * f + k]];
        in += x > lo + margin && x < hi - margin;
        out += x < lo - margin || x > hi + margin;
    }
    return in == 3 ? -1 : out == 3 ? 1 : 0;
}

static void test_adaptive_shadow_edge(void **state)
{
    (void)state;
    rs_meshgen mg = rs_meshgen_new(2000, 2000);
    rs_meshgen_rect(&mg, rs_v3_make(-4, -4, 0), rs_v3_make(8, 0, 0), rs_v3_make(0, 8, 0), CELLS, CELLS);
    size_t nfloor = mg.nf;
    rs_meshgen_box(&mg, rs_v3_make(-WALL_X, -20, WALL_BOTTOM), rs_v3_make(2 * WALL_X, 40, WALL_TOP - WALL_BOTTOM), 1,
                   0);
    rs_mesh *m = rs_meshgen_done(&mg);
    rs_scene *scene = rs_fx_scene(m);
    rs_capture cap;
    rs_skyenv env;
    rs_v3 sun;
    sun_sky(&cap, &env, &sun);
    const double target = 0.05;
    rs_gather_ctx base = rs_fx_gather_ctx(scene, &env, 32, 32, 3);
    rs_gather_ctx adapt = base, ref = base, off = base;
    adapt.target_error = target;
    off.target_error = 0;
    /* converged and independent: 64 x the rays, 256 x toward the sun (the edge's error is there) */
    ref.samples *= 64, ref.sky_samples *= 64, ref.sun_samples *= 256, ref.seed = 99;
    rs_gather_scratch *s = rs_gather_scratch_new((size_t)ref.sun_samples);
    size_t lit = 0, lit_base = 0, edge = 0, edge_refined = 0;
    double e2_base = 0, e2_adapt = 0;
    for (size_t f = 0; f < nfloor; f++) {
        int side = sun_side(m, f, sun);
        if (side < 0) continue;
        rs_facet_gather a, b;
        assert_int_equal(rs_gather_facet(&base, (uint32_t)f, s, &a), 0);
        assert_int_equal(rs_gather_facet(&adapt, (uint32_t)f, s, &b), 0);
        /* every count doubles per round, up to the cap; round 0 is the base gather itself */
        assert_true(b.rounds <= RS_GATHER_MAX_ROUNDS);
        assert_int_equal(b.rays, a.rays << b.rounds);
        assert_int_equal(a.rounds, 0);
        if (side > 0) { /* uniform light: the base counts suffice */
            lit++;
            lit_base += b.rounds == 0;
            if (b.rounds == 0) assert_memory_equal(a.esky, b.esky, sizeof a.esky);
        } else {
            rs_facet_gather r;
            assert_int_equal(rs_gather_facet(&ref, (uint32_t)f, s, &r), 0);
            edge++;
            edge_refined += b.rounds > 0;
            double ea = (a.esky_lum - r.esky_lum) / r.esky_lum, eb = (b.esky_lum - r.esky_lum) / r.esky_lum;
            e2_base += ea * ea;
            e2_adapt += eb * eb;
            free(r.entries);
        }
        free(a.entries), free(b.entries);
    }
    double rms_base = sqrt(e2_base / (double)edge), rms_adapt = sqrt(e2_adapt / (double)edge);
    print_message("target %.3f: %zu of %zu sunlit facets at the base count, %zu of %zu shadow-edge facets refined; "
                  "RMS error on the edge %.4f (base) -> %.4f (adaptive)\n",
                  target, lit_base, lit, edge_refined, edge, rms_base, rms_adapt);
    assert_true(lit >= 64 && edge >= 16);
    assert_int_equal(lit_base, lit);      /* every facet in uniform light stops at once */
    assert_int_equal(edge_refined, edge); /* every facet the edge crosses takes more rays */
    assert_true(rms_base > target);
    assert_true(rms_adapt < target);

    /* target_error 0 is the base gather, bit for bit */
    for (size_t f = 0; f < nfloor; f += 7) {
        rs_facet_gather a, b;
        assert_int_equal(rs_gather_facet(&base, (uint32_t)f, s, &a), 0);
        assert_int_equal(rs_gather_facet(&off, (uint32_t)f, s, &b), 0);
        assert_memory_equal(a.esky, b.esky, sizeof a.esky);
        assert_true(a.rays == b.rays && a.nentries == b.nentries && b.rounds == 0);
        free(a.entries), free(b.entries);
    }
    rs_gather_scratch_free(s);
    rs_fx_release(&env, &cap, scene, m);
}

/* Rays into K count the hit facet's radiance in the stopping rule: under a dark sky, floor
 * facets next to a bright wall are lit only through K (G = sum_j K_ij L_j), and the rounds bring
 * G's error against a converged row below the target where the base count leaves it above.
 * The rows stay whole rays times pi / (rays) and sum to at most pi. */
static double row_g(const rs_facet_gather *fg, const double *rad)
{
    double gsum = 0;
    for (uint32_t q = 0; q < fg->nentries; q++) gsum += fg->entries[q].k * rad[3 * (size_t)fg->entries[q].col];
    return gsum;
}

static void test_adaptive_kernel_row(void **state)
{
    (void)state;
    rs_meshgen mg = rs_meshgen_new(2000, 2000);
    rs_meshgen_rect(&mg, rs_v3_make(-2, -1, 0), rs_v3_make(4, 0, 0), rs_v3_make(0, 2, 0), 4, 2);
    size_t nfloor = mg.nf;
    rs_meshgen_rect(&mg, rs_v3_make(-2, 1, 0), rs_v3_make(4, 0, 0), rs_v3_make(0, 0, 3), 4, 4); /* wall */
    rs_mesh *m = rs_meshgen_done(&mg);
    rs_scene *scene = rs_fx_scene(m);
    rs_capture cap;
    rs_skyenv env;
    rs_v3 sun;
    sun_sky(&cap, &env, &sun);
    for (size_t k = 0; k < 3 * (size_t)env.width * env.height; k++) env.radiance[k] *= 1e-9f; /* dark */
    double *rad = calloc(3 * m->nfaces, sizeof *rad);
    for (size_t f = nfloor; f < m->nfaces; f++) rad[3 * f] = rad[3 * f + 1] = rad[3 * f + 2] = 10;
    const double target = 0.05;
    rs_gather_ctx base = {.scene = scene, .env = &env, .samples = 16, .seed = 5, .skip_convex = 1, .radiance = rad};
    rs_gather_ctx adapt = base, ref = base;
    adapt.target_error = target;
    ref.samples *= 256, ref.seed = 77;
    rs_gather_scratch *s = rs_gather_scratch_new((size_t)ref.samples);
    double e2_base = 0, e2_adapt = 0;
    size_t refined = 0;
    for (size_t f = 0; f < nfloor; f++) {
        rs_facet_gather a, b, r;
        assert_int_equal(rs_gather_facet(&base, (uint32_t)f, s, &a), 0);
        assert_int_equal(rs_gather_facet(&adapt, (uint32_t)f, s, &b), 0);
        assert_int_equal(rs_gather_facet(&ref, (uint32_t)f, s, &r), 0);
        refined += b.rounds > 0;
        double ksum = 0;
        for (uint32_t q = 0; q < b.nentries; q++) ksum += b.entries[q].k;
        assert_true(ksum > 0 && ksum <= M_PI * (1 + 1e-6));
        double hits = ksum * ((double)adapt.samples * (1 << b.rounds)) / M_PI; /* whole rays */
        assert_true(fabs(hits - floor(hits + 0.5)) < 1e-3 * hits);
        double gr = row_g(&r, rad), ea = (row_g(&a, rad) - gr) / gr, eb = (row_g(&b, rad) - gr) / gr;
        e2_base += ea * ea;
        e2_adapt += eb * eb;
        free(a.entries), free(b.entries), free(r.entries);
    }
    double rms_base = sqrt(e2_base / (double)nfloor), rms_adapt = sqrt(e2_adapt / (double)nfloor);
    print_message("dark sky, bright wall: %zu of %zu floor facets refined; RMS error of G %.4f (base) -> %.4f "
                  "(adaptive)\n",
                  refined, nfloor, rms_base, rms_adapt);
    assert_true(refined > 0);
    assert_true(rms_base > target);
    assert_true(rms_adapt < target);
    free(rad);
    rs_gather_scratch_free(s);
    rs_fx_release(&env, &cap, scene, m);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_adaptive_shadow_edge), cmocka_unit_test(test_adaptive_kernel_row))
