/* The hidden sky's brightness from same-plane facets (sky/skyscale.h) on a synthetic wall whose
 * upper facets see more of a hidden sky that the fill made too dark; and the Perez fit
 * (sky/skymodel.h) recovering a known sky's parameters with trees in front of part of it. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/sampling.h"
#include "sky/skymodel.h"
#include "sky/skyscale.h"
#include "tests/testutil.h"

enum { NX = 60, NZ = 40, MAXP = 16 };
#define CELL  0.25 /* m: facet spacing on the wall (x along it, z up, 10 m high) */
#define SIGMA 0.25 /* the fill's relative uncertainty of its light */
#define RHO   0.6

static double noise(uint32_t k, uint32_t salt)
{
    return (rs_hash_u32(rs_hash_combine(salt, k)) >> 8) / 16777216.0 - 0.5; /* uniform [-0.5, 0.5) */
}

typedef struct {
    double E[3 * NX * NZ], S[3 * NX * NZ], L[3 * NX * NZ];
    uint32_t a[NX * NZ * MAXP], b[NX * NZ * MAXP], block[NX * NZ * MAXP];
    size_t np;
} wall;

/* Facet k at (x, z): measured light 1 (sky the camera saw, and the light of other facets), filled
 * light F = 0.2 + 0.6 z / 10 as the fill has it, whose truth is F (1 + t_true SIGMA); the observed
 * radiance rho (1 + F (1 + t_true SIGMA)) / pi with 2 % noise, and a patch of another material
 * (albedo 0.9, an eighth of the wall) that the pairs across its edge must not follow. flat: every
 * facet sees the same share (no pair informs). */
static void make_wall(wall *w, double t_true, int flat)
{
    memset(w, 0, sizeof *w);
    for (int iz = 0; iz < NZ; iz++)
        for (int ix = 0; ix < NX; ix++) {
            size_t k = (size_t)iz * NX + ix;
            double z = (iz + 0.5) * CELL, F = flat ? 0.5 : 0.2 + 0.6 * z / 10;
            double rho = (ix >= 40 && iz >= 20 && iz < 35) ? 0.9 : RHO;
            for (int ch = 0; ch < 3; ch++) {
                w->E[3 * k + ch] = 1 + F;
                w->S[3 * k + ch] = SIGMA * F;
                w->L[3 * k + ch] =
                    rho * (1 + F * (1 + t_true * SIGMA)) / M_PI * (1 + 0.04 * noise((uint32_t)(3 * k + ch), 7));
            }
        }
    /* Pairs: each facet with partners up to 3 m away on the wall, at most MAXP per facet; the
     * block is the 2 m cell of the first. */
    uint32_t cnt[NX * NZ] = {0};
    for (int iz = 0; iz < NZ; iz++)
        for (int ix = 0; ix < NX; ix++) {
            uint32_t i = (uint32_t)(iz * NX + ix);
            for (int q = 1; q <= 64 && cnt[i] < MAXP; q++) {
                int dz = (int)(noise(i, (uint32_t)q) * 24), dx = (int)(noise(i, (uint32_t)q + 100) * 24);
                int jz = iz + dz, jx = ix + dx;
                if (jz < 0 || jz >= NZ || jx < 0 || jx >= NX || (dz == 0 && dx == 0)) continue;
                uint32_t j = (uint32_t)(jz * NX + jx);
                if (cnt[j] >= MAXP) continue;
                w->a[w->np] = i;
                w->b[w->np] = j;
                w->block[w->np++] = (uint32_t)((int)(iz * CELL / 2) * 100 + (int)(ix * CELL / 2));
                cnt[i]++;
                cnt[j]++;
            }
        }
}

static rs_skyscale run(const wall *w, int *rc)
{
    rs_skyscale_input in = {.nf = NX * NZ,
                            .E = w->E,
                            .S = w->S,
                            .L = w->L,
                            .a = w->a,
                            .b = w->b,
                            .npairs = w->np,
                            .block = w->block,
                            .max_per_facet = MAXP};
    rs_skyscale sc;
    rs_err err;
    *rc = rs_skyscale_estimate(&in, &sc, &err);
    return sc;
}

/* Mean |relative albedo error| of the wall's main material with E corrected by t. */
static double albedo_error(const wall *w, double t)
{
    double s = 0;
    int n = 0;
    for (int iz = 0; iz < NZ; iz++)
        for (int ix = 0; ix < NX; ix++) {
            if (ix >= 40 && iz >= 20 && iz < 35) continue;
            size_t k = (size_t)iz * NX + ix;
            double rho = M_PI * w->L[3 * k + 1] / (w->E[3 * k + 1] + t * w->S[3 * k + 1]);
            s += fabs(rho / RHO - 1);
            n++;
        }
    return s / n;
}

/* The fill made the hidden sky 2 sigma too dark (its light x 1.5): the pairs find t near 2 in
 * every channel, well beyond 2 of its sigmas, and the wall's albedo error falls to a fifth. */
static void test_wrong_hidden_sky_moves_to_truth(void **state)
{
    (void)state;
    static wall w;
    make_wall(&w, 2.0, 0);
    int rc;
    rs_skyscale sc = run(&w, &rc);
    double before = albedo_error(&w, 0), after = albedo_error(&w, sc.t[1]);
    print_message("t %.3f %.3f %.3f (+- %.3f), luminance %.3f +- %.3f from %zu pairs of %zu facets; albedo error "
                  "%.2f %% -> %.2f %%\n",
                  sc.t[0], sc.t[1], sc.t[2], sc.sigma[1], sc.t_lum, sc.sigma_lum, sc.pairs, sc.facets, 100 * before,
                  100 * after);
    assert_int_equal(rc, 0);
    for (int ch = 0; ch < 3; ch++) assert_true(fabs(sc.t[ch] - 2.0) < 0.25);
    assert_true(fabs(sc.t_lum) > 2 * sc.sigma_lum);
    assert_false(sc.at_bound);
    assert_true(sc.sigma_lum > 0 && sc.sigma_lum < 0.5);
    assert_true(after < 0.2 * before);
}

/* A fill that was right: t stays within 2 sigma of 0 (auto leaves E as it was). */
static void test_right_hidden_sky_left_alone(void **state)
{
    (void)state;
    static wall w;
    make_wall(&w, 0.0, 0);
    int rc;
    rs_skyscale sc = run(&w, &rc);
    print_message("t %.3f +- %.3f from %zu pairs\n", sc.t_lum, sc.sigma_lum, sc.pairs);
    assert_int_equal(rc, 0);
    assert_true(fabs(sc.t_lum) < 2 * sc.sigma_lum);
}

/* Every facet sees the same share of the hidden sky: no pair says anything, no estimate. */
static void test_no_contrast_no_estimate(void **state)
{
    (void)state;
    static wall w;
    make_wall(&w, 2.0, 1);
    int rc;
    rs_skyscale sc = run(&w, &rc);
    assert_int_equal(rc, 1);
    assert_int_equal(sc.pairs, 0);
    for (int ch = 0; ch < 3; ch++) assert_true(sc.t[ch] == 0);
}

/* A Perez sky of known parameters (sun 25 degrees up) sampled over the visible hemisphere, a low
 * sector by the sun hidden; with trees or not (10 % of the visible patches darkened to a tenth).
 * Fills the hidden sector's light relative error into *hidden and returns the fit. */
static rs_skymodel fit_known_sky(const double truth[5], int trees, double *hidden)
{
    const double el = 25 * M_PI / 180;
    rs_v3 sun = rs_v3_make(cos(el), 0, sin(el));
    static rs_skysample s[4050];
    size_t n = 0;
    double hid_t = 0, hid_f = 0;
    rs_skymodel m;
    memset(&m, 0, sizeof m);
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1) assert_int_equal(rs_skymodel_fit(s, n, sun, -1, 1e-3, &m), 0);
        for (int r = 0; r < 45; r++)
            for (int c = 0; c < 90; c++) {
                double e = (r + 0.5) * M_PI / 90, a = (c + 0.5) * 2 * M_PI / 90 - M_PI;
                rs_v3 d = rs_v3_make(cos(e) * cos(a), cos(e) * sin(a), sin(e));
                double g = atan2(rs_v3_len(rs_v3_cross(d, sun)), rs_v3_dot(d, sun));
                double y = 2.0 * rs_skymodel_perez(truth, d.z, g), om = cos(e) * (M_PI / 90) * (2 * M_PI / 90);
                int hidden = fabs(a) < M_PI / 3 && e < M_PI / 6 && g > 5 * M_PI / 180;
                if (pass == 1) {
                    double rgb[3];
                    rs_skymodel_eval(&m, d, rgb);
                    hid_t += hidden ? om * y : 0;
                    hid_f += hidden ? om * rgb[1] : 0;
                    continue;
                }
                if (hidden || g < 4 * M_PI / 180) continue;
                if (trees && rs_hash_u32((uint32_t)(r * 90 + c)) % 10 == 0) y *= 0.1;
                s[n].dir = d;
                s[n].rgb[0] = s[n].rgb[1] = s[n].rgb[2] = y;
                s[n++].weight = om;
            }
    }
    *hidden = (hid_f - hid_t) / hid_t;
    return m;
}

/* The robust Perez fit (skymodel.c, unchanged by the facets' check) on a known sky: the
 * gradation (a, b), the horizon-to-sun term e and the circumsolar glow where the visible sky has
 * it (c exp(d gamma) at 30 degrees) are recovered; c and d alone only along their ridge (the
 * prior toward the CIE clear sky holds c near 11.6 for 14). Trees cost accuracy in the hidden
 * sector (-4 % without, -7.5 % with them, measured): bounded here at 5 % and 10 %. */
static void test_perez_fit_recovers_parameters(void **state)
{
    (void)state;
    static const double truth[5] = {-1.1, -0.40, 14, -3.4, 0.5};
    double hid_clean, hid_trees;
    rs_skymodel clean = fit_known_sky(truth, 0, &hid_clean), m = fit_known_sky(truth, 1, &hid_trees);
    const double *p = m.perez[1], g30 = 30 * M_PI / 180;
    double glow_t = truth[2] * exp(truth[3] * g30), glow_f = p[2] * exp(p[3] * g30);
    print_message("with trees: a %.3f b %.3f c %.3f d %.3f e %.3f (truth -1.1 -0.40 14 -3.4 0.5), glow at 30 deg "
                  "%.3f (truth %.3f); hidden sector light %+.2f %% (without trees %+.2f %%, c %.3f)\n",
                  p[0], p[1], p[2], p[3], p[4], glow_f, glow_t, 100 * hid_trees, 100 * hid_clean, clean.perez[1][2]);
    assert_true(fabs(p[0] - truth[0]) < 0.15);
    assert_true(fabs(p[1] - truth[1]) < 0.08);
    assert_true(fabs(p[4] - truth[4]) < 0.1);
    assert_true(fabs(glow_f / glow_t - 1) < 0.1);
    assert_true(fabs(hid_clean) < 0.05);
    assert_true(fabs(hid_trees) < 0.10);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_wrong_hidden_sky_moves_to_truth),
             cmocka_unit_test(test_right_hidden_sky_left_alone), cmocka_unit_test(test_no_contrast_no_estimate),
             cmocka_unit_test(test_perez_fit_recovers_parameters))
