/* Sky harmonics (skysh.h): a smooth sky's order-2 irradiance equals the exact integral, a sharp
 * sun fails the frequency test unless it is the sun set, and in the gather only facets that see
 * only sky take it, agreeing with many rays, while a facet under an overhang still traces. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "light/gather.h"
#include "tests/fixtures.h"
#include "tests/meshgen.h"
#include "common/sampling.h"
#include "sky/skysh.h"
#include "tests/testutil.h"

static const rs_v3 SUN = {0.59, 0.35, 0.7274}; /* about 46.7 degrees up; normalised below */

/* Constant + linear + quadratic per channel (order <= 2: the projection is exact for it), plus
 * a sun disc of half-angle sun_deg and radiance sun_L when sun_L > 0, in world axes. */
typedef struct {
    double sun_L, sun_deg;
} smooth_sun;

static void smooth_radiance(rs_v3 d, size_t k, double rgb[3], void *ctx)
{
    (void)k;
    const smooth_sun *sun = ctx;
    rgb[0] = 1 + 0.5 * d.z + 0.3 * d.x + 0.2 * d.x * d.y + 0.3 * d.z * d.z;
    rgb[1] = 0.8 + 0.4 * d.z - 0.2 * d.y + 0.25 * d.z * d.z;
    rgb[2] = 0.6 + 0.45 * d.z + 0.1 * d.x * d.z;
    if (sun->sun_L > 0 && rs_v3_dot(d, rs_v3_norm(SUN)) > cos(sun->sun_deg * M_PI / 180))
        rgb[0] = rgb[1] = rgb[2] = sun->sun_L;
}

static void smooth_sky(int w, double sun_L, double sun_deg, rs_capture *cap)
{
    smooth_sun sun = {sun_L, sun_deg};
    *cap = rs_fx_capture(w, w / 2, smooth_radiance, &sun);
}

static void build_env(const rs_capture *cap, int explicit_sun, rs_skyenv *env)
{
    rs_fx_sky_env(cap, RS_FX_SUN_MAX_SR, explicit_sun, env);
}

/* The worst relative error over the test normals, by brute force (rs_skysh_exact). */
static double brute_max_error(const rs_skyenv *env, const rs_skysh *sh)
{
    double *ex = malloc(3 * (size_t)sh->normals * sizeof *ex), emax[3] = {0};
    double *shv = malloc(3 * (size_t)sh->normals * sizeof *shv);
    for (int k = 0; k < sh->normals; k++) {
        double e[RS_SKYSH_CHANNELS], s[RS_SKYSH_CHANNELS];
        rs_v3 n = rs_skysh_normal(k, sh->normals);
        rs_skysh_exact(env, n, e);
        assert_true(rs_skysh_eval(sh, n, s)); /* no sun set in these maps */
        for (int ch = 0; ch < 3; ch++)
            ex[3 * k + ch] = e[ch], shv[3 * k + ch] = s[ch], emax[ch] = fmax(emax[ch], e[ch]);
    }
    double worst = 0;
    for (int k = 0; k < sh->normals; k++)
        for (int ch = 0; ch < 3; ch++)
            worst = fmax(worst, fabs(shv[3 * k + ch] - ex[3 * k + ch]) / fmax(ex[3 * k + ch], 1e-3 * emax[ch]));
    free(ex);
    free(shv);
    return worst;
}

static void test_smooth_sky_is_exact(void **state)
{
    (void)state;
    rs_capture cap;
    rs_skyenv env;
    smooth_sky(256, 0, 0, &cap);
    build_env(&cap, 1, &env);
    rs_skysh sh;
    rs_err err;
    assert_int_equal(rs_skysh_build(&env, 0.01, 256, &sh, &err), 0);
    print_message("smooth sky: worst error %.5f %% at %d normals\n", 100 * sh.max_error, sh.normals);
    assert_false(sh.has_sun);
    assert_true(sh.usable);
    assert_true(sh.max_error < 0.005);
    /* The test's block sums are the brute-force pixel sums. */
    assert_true(fabs(brute_max_error(&env, &sh) - sh.max_error) < 1e-9 + 1e-6 * sh.max_error);
    /* Normals off the test set, against the exact sum over the pixels. */
    for (uint32_t k = 0; k < 64; k++) {
        double u = (rs_hash_u32(2 * k) >> 8) / 16777216.0, v = (rs_hash_u32(2 * k + 1) >> 8) / 16777216.0;
        rs_v3 n = rs_pano_uv_to_dir(u, v);
        double e[RS_SKYSH_CHANNELS], s[RS_SKYSH_CHANNELS];
        rs_skysh_exact(&env, n, e);
        assert_true(rs_skysh_eval(&sh, n, s));
        for (int ch = 0; ch < 3; ch++) assert_true(fabs(s[ch] - e[ch]) <= 0.005 * e[ch]);
    }
    rs_skyenv_release(&env);
    rs_capture_release(&cap);
}

/* Constant + linear only: the closed form pi a + 2 pi / 3 (b . n) checks the solid angles and
 * the frame, not only the agreement of two sums over the same pixels. */
static void test_closed_form(void **state)
{
    (void)state;
    int w = 256, h = 128;
    rs_capture cap = rs_fx_capture(w, h, NULL, NULL);
    /* a capture turned 90 degrees about z: the map's frame is not the world's */
    double rot[9] = {0, -1, 0, 1, 0, 0, 0, 0, 1};
    memcpy(cap.pose.rot, rot, sizeof rot);
    rs_v3 b = {0.3, -0.2, 0.5};
    for (int r = 0; r < h; r++)
        for (int c = 0; c < w; c++) {
            rs_v3 d = rs_pose_dir_to_world(&cap.pose, rs_pano_pixel_dir(w, h, c, r));
            float *px = rs_image_px(cap.pano, c, r);
            px[0] = px[1] = px[2] = (float)(1 + rs_v3_dot(b, d));
        }
    rs_skyenv env;
    build_env(&cap, 1, &env);
    rs_skysh sh;
    rs_err err;
    assert_int_equal(rs_skysh_build(&env, 0.01, 256, &sh, &err), 0);
    assert_true(sh.usable);
    double worst = 0;
    for (int k = 0; k < 100; k++) {
        rs_v3 n = rs_skysh_normal(k, 100);
        double e[RS_SKYSH_CHANNELS];
        assert_true(rs_skysh_eval(&sh, n, e));
        double want = M_PI + 2 * M_PI / 3 * rs_v3_dot(b, n);
        worst = fmax(worst, fabs(e[0] - want) / want);
    }
    print_message("closed form: worst error %.5f %%\n", 100 * worst);
    assert_true(worst < 0.005);
    rs_skyenv_release(&env);
    rs_capture_release(&cap);
}

/* A sharp sun in the projection fails the test; split off as the sun set, the rest passes and
 * the set is added exactly, except for normals whose plane cuts it. */
static void test_sun(void **state)
{
    (void)state;
    rs_capture cap;
    rs_skyenv whole, split;
    smooth_sky(512, 5e3, 1.0, &cap);
    build_env(&cap, 0, &whole); /* no sun set: the sun is in the map */
    build_env(&cap, 1, &split);
    rs_skysh a, b;
    rs_err err;
    assert_int_equal(rs_skysh_build(&whole, 0.01, 256, &a, &err), 0);
    assert_int_equal(rs_skysh_build(&split, 0.01, 256, &b, &err), 0);
    print_message("sun in the map: worst error %.3f %%; sun set apart: %.4f %%\n", 100 * a.max_error,
                  100 * b.max_error);
    assert_false(a.usable);
    assert_true(a.max_error > 0.01);
    assert_true(b.has_sun && b.usable);
    size_t cut = 0, used = 0;
    for (int k = 0; k < 200; k++) {
        rs_v3 n = rs_skysh_normal(k, 200);
        double e[RS_SKYSH_CHANNELS], s[RS_SKYSH_CHANNELS];
        rs_skysh_exact(&split, n, e);
        rs_facet_gather fg;
        if (!rs_skysh_eval(&b, n, s)) {
            cut++;
            assert_false(rs_skysh_facet(&b, n, &fg));
            assert_true(fabs(rs_v3_dot(n, rs_v3_norm(SUN))) < 0.1); /* the plane passes near the sun */
            continue;
        }
        used++;
        for (int ch = 0; ch < 3; ch++) assert_true(fabs(s[ch] - e[ch]) <= 0.005 * e[ch] + 1e-9);
        assert_true(rs_skysh_facet(&b, n, &fg));
        assert_true(fg.sky_sh && fg.sees_nothing && fg.rays == 0 && fg.nentries == 0);
        assert_true(fabs(fg.esky[0] - e[0]) <= 0.005 * e[0] + 1e-9);
        /* the bound of its normal (error_at is float: a relative 1e-6 of rounding) */
        assert_true(fg.sh_sigma > 0 && fg.sh_sigma <= (1 + 1e-6) * RS_SKYSH_BOUND_FACTOR * b.max_error * fg.esky_lum);
    }
    assert_true(cut > 0 && used > cut);
    /* sh_max_error = 0: never */
    rs_skysh off;
    assert_int_equal(rs_skysh_build(&split, 0, 256, &off, &err), 0);
    assert_false(off.usable);
    rs_skyenv_release(&whole);
    rs_skyenv_release(&split);
    rs_capture_release(&cap);
}

/* CIE overcast (1 + 2 cos theta) / 3 over a ground of 0.05. */
static void overcast_radiance(rs_v3 d, size_t k, double rgb[3], void *ctx)
{
    (void)k, (void)ctx;
    rgb[0] = rgb[1] = rgb[2] = d.z > 0 ? 0.8 * (1 + 2 * d.z) / 3 : 0.05;
}

/* An overcast sky over a darker ground (CIE overcast (1 + 2 cos theta) / 3, a step at the
 * horizon): order 2 is good enough for some normals and not for others. Where a facet takes
 * the harmonics, its bound holds against the exact sum; where it does not, the bound is above
 * the tolerance. */
static void test_local_bound(void **state)
{
    (void)state;
    rs_capture cap = rs_fx_capture(512, 256, overcast_radiance, NULL);
    rs_skyenv env;
    build_env(&cap, 1, &env);
    rs_skysh sh;
    rs_err err;
    assert_int_equal(rs_skysh_build(&env, 0.01, 256, &sh, &err), 0);
    print_message("overcast: worst error %.3f %%, %.0f %% of the normals within 1 %%\n", 100 * sh.max_error,
                  100 * sh.passed_share);
    assert_true(sh.usable && sh.max_error > 0.01 && sh.passed_share > 0.2 && sh.passed_share < 0.95);
    int took = 0, refused = 0;
    double worst_ratio = 0;
    for (uint32_t k = 0; k < 300; k++) {
        double u = (rs_hash_u32(3 * k + 7) >> 8) / 16777216.0, v = (rs_hash_u32(3 * k + 8) >> 8) / 16777216.0;
        rs_v3 n = rs_pano_uv_to_dir(u, v);
        rs_facet_gather fg;
        double e[RS_SKYSH_CHANNELS], bound = rs_skysh_bound(&sh, n);
        if (!rs_skysh_facet(&sh, n, &fg)) {
            assert_true(bound > 0.01);
            refused++;
            continue;
        }
        took++;
        rs_skysh_exact(&env, n, e);
        assert_true(bound <= 0.01);
        double rel = fabs(fg.esky[0] - e[0]) / e[0];
        worst_ratio = fmax(worst_ratio, rel / bound);
        assert_true(fabs(fg.esky_lum - 0.2126 * e[0] - 0.7152 * e[1] - 0.0722 * e[2]) <= (1 + 1e-6) * fg.sh_sigma);
    }
    print_message("overcast: %d normals took the harmonics, %d refused; worst error / bound %.3f\n", took, refused,
                  worst_ratio);
    assert_true(took > 0 && refused > 0 && worst_ratio <= 1);
    rs_skyenv_release(&env);
    rs_capture_release(&cap);
}

/* A floor, a slab above part of it (an overhang) and a low box: the slab's top sees only sky
 * and takes the harmonics; its E_sky matches a gather with many rays within the error bound
 * plus the rays' noise. Floor facets under the slab, and every other facet, still trace. */
static void test_gather_uses_it(void **state)
{
    (void)state;
    rs_meshgen mg = rs_meshgen_new(2000, 2000);
    rs_meshgen_rect(&mg, rs_v3_make(-5, -5, 0), rs_v3_make(10, 0, 0), rs_v3_make(0, 10, 0), 8, 8); /* floor */
    size_t slab = mg.nf;
    rs_meshgen_box(&mg, rs_v3_make(-2, -2, 2), rs_v3_make(2, 2, 2.2), 2, 0);
    size_t box = mg.nf;
    rs_meshgen_box(&mg, rs_v3_make(3, 3, 0), rs_v3_make(4, 4, 1), 1, 0);
    rs_mesh *m = rs_meshgen_done(&mg);
    rs_err err;
    rs_scene *scene = rs_fx_scene(m);
    rs_capture cap;
    rs_skyenv env;
    smooth_sky(256, 2e3, 1.5, &cap);
    build_env(&cap, 1, &env);
    assert_non_null(env.sun_cdf);
    rs_skysh sh;
    assert_int_equal(rs_skysh_build(&env, 0.01, 256, &sh, &err), 0);
    assert_true(sh.usable);
    rs_gather_ctx rays = rs_fx_gather_ctx(scene, &env, 64, 16, 11);
    rs_gather_ctx with = rays, many = rays;
    with.sky_sh = &sh;
    many.samples = many.sky_samples = 4096;
    many.sun_samples = 1024;
    rs_gather_scratch *s = rs_gather_scratch_new(4096);
    size_t nf = m->nfaces, used = 0, convex = 0, top_used = 0;
    for (uint32_t f = 0; f < nf; f++) {
        rs_facet_gather a, r;
        assert_int_equal(rs_gather_facet(&rays, f, s, &r), 0);
        convex += r.sees_nothing;
        free(r.entries);
        assert_int_equal(rs_gather_facet(&with, f, s, &a), 0);
        rs_v3 c, n;
        double area;
        rs_mesh_face(m, f, &c, &n, &area);
        int top = f >= slab && f < box && n.z > 0.5;
        int under = f < slab && fabs(c.x) < 1.5 && fabs(c.y) < 1.5;
        if (under) assert_true(!a.sky_sh && a.rays > 0 && a.nentries > 0); /* sees the slab: rays */
        if (!a.sky_sh) {
            assert_true(a.rays > 0 || a.sees_nothing);
            free(a.entries);
            continue;
        }
        /* only the slab's top, and the low box's bottom (nothing lies below z = 0) */
        assert_true(top || (f >= box && n.z < -0.5));
        top_used += top;
        assert_int_equal(a.rays, 0);
        used++;
        assert_int_equal(rs_gather_facet(&many, f, s, &r), 0);
        double mc = rs_gather_mc_sigma(&r, NULL, NULL);
        print_message("facet %u (n.z %.0f): harmonics %.5g, %d rays %.5g +- %.2g, bound %.2g\n", f, n.z, a.esky_lum,
                      r.rays, r.esky_lum, mc, a.sh_sigma);
        assert_true(fabs(a.esky_lum - r.esky_lum) <= a.sh_sigma + 4 * mc);
        for (int ch = 0; ch < 3; ch++) assert_true(fabs(a.esky[ch] - r.esky[ch]) <= 0.01 * r.esky[ch] + 4 * mc);
        free(a.entries), free(r.entries);
    }
    assert_int_equal(top_used, 8);  /* the slab's top: 2 x 2 cells of two triangles */
    assert_int_equal(used, convex); /* every facet that sees only sky: the sun set is above them all */
    assert_int_equal(rs_skysh_candidates(scene), convex); /* the count before the gather */
    /* rs_gather_run: the same facets, fewer rays */
    rs_facet_gather *fa = calloc(nf, sizeof *fa), *fb = calloc(nf, sizeof *fb);
    rs_gather_stats sa, sb;
    assert_int_equal(rs_gather_run(&rays, nf, NULL, fa, NULL, NULL, &sa, &err), 0);
    assert_int_equal(rs_gather_run(&with, nf, NULL, fb, NULL, NULL, &sb, &err), 0);
    assert_int_equal(sa.sees_nothing, sb.sees_nothing);
    size_t nsh = 0;
    for (size_t f = 0; f < nf; f++) {
        nsh += fb[f].sky_sh;
        if (!fb[f].sky_sh) { /* the rest is the gather of before */
            assert_memory_equal(fa[f].esky, fb[f].esky, sizeof fa[f].esky);
            assert_int_equal(fa[f].nentries, fb[f].nentries);
        }
        free(fa[f].entries), free(fb[f].entries);
    }
    assert_int_equal(nsh, used);
    free(fa), free(fb);
    rs_gather_scratch_free(s);
    rs_fx_release(&env, &cap, scene, m);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_smooth_sky_is_exact), cmocka_unit_test(test_closed_form),
             cmocka_unit_test(test_sun), cmocka_unit_test(test_local_bound), cmocka_unit_test(test_gather_uses_it))
