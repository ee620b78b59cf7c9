/* Analytic checks of the hemisphere gather and the forward model: a facet under a uniform sky,
 * a sun as a single bright pixel, the view factor between a floor and a wall at 90 degrees,
 * and a closed cavity whose radiance must reach L_s / (1 - rho). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "light/gather.h"
#include "tests/fixtures.h"
#include "tests/meshgen.h"
#include "tests/testutil.h"
#include "light/transport.h"

/* A sky map in world axes with a uniform radiance (no camera, nothing filled). */
static rs_skyenv uniform_env(int w, float L)
{
    rs_skyenv env;
    memset(&env, 0, sizeof env);
    env.width = w;
    env.height = w / 2;
    rs_m3_identity(env.pose.rot);
    env.radiance = malloc(3 * (size_t)w * (w / 2) * sizeof(float));
    env.filled = calloc((size_t)w * (w / 2), 1);
    env.sun = calloc((size_t)w * (w / 2), 1);
    for (size_t k = 0; k < 3 * (size_t)w * (w / 2); k++) env.radiance[k] = L;
    return env;
}

static rs_facet_gather gather_one(const rs_scene *scene, const rs_skyenv *env, uint32_t f, int samples, int sun_samples)
{
    rs_gather_ctx g = {
        .scene = scene, .env = env, .samples = samples, .sky_samples = 64, .sun_samples = sun_samples, .seed = 1};
    rs_gather_scratch *s = rs_gather_scratch_new((size_t)(samples > sun_samples ? samples : sun_samples));
    rs_facet_gather out;
    assert_int_equal(rs_gather_facet(&g, f, s, &out), 0);
    rs_gather_scratch_free(s);
    return out;
}

/* An unoccluded upward facet under a uniform sky of radiance L gets E = pi L. */
static void test_uniform_sky(void **state)
{
    (void)state;
    rs_mesh *m = rs_fx_unit_square();
    rs_scene *scene = rs_fx_scene(m);
    rs_skyenv env = uniform_env(256, 2.0f);
    rs_facet_gather out = gather_one(scene, &env, 0, 256, 0);
    for (int ch = 0; ch < 3; ch++) assert_true(fabs(out.esky[ch] - 2 * M_PI) / (2 * M_PI) < 0.005);
    assert_int_equal(out.nentries, 0);
    free(out.entries);
    rs_fx_release(&env, NULL, scene, m);
}

/* A dark sky with one bright pixel (a sun at 30 degrees elevation): explicit sampling must give
 * L Omega cos(theta) of that pixel, which cosine-weighted rays alone would almost never find. */
static void test_sun_pixel(void **state)
{
    (void)state;
    rs_mesh *m = rs_fx_unit_square();
    rs_scene *scene = rs_fx_scene(m);
    int w = 512, h = 256;
    int sr = h / 3, sc = w / 2 + 10; /* polar angle ~60 degrees */
    rs_capture cap = rs_fx_sun_pixel_capture(w, h, 0.01f, 1e5f, sc, sr);
    rs_skyenv env;
    rs_fx_sky_env(&cap, 0.01, 1, &env);
    assert_int_equal(env.bright_pixels, 1);
    assert_non_null(env.cdf);
    /* Exact value for the piecewise-constant map: sum over the upper hemisphere's pixels. */
    double expect = 0;
    for (int r = 0; r < h; r++)
        for (int c = 0; c < w; c++) {
            rs_v3 d = rs_pano_pixel_dir(w, h, c, r);
            if (d.z > 0) expect += rs_image_px(cap.pano, c, r)[0] * rs_pano_pixel_solid_angle(w, h, r) * d.z;
        }
    rs_facet_gather out = gather_one(scene, &env, 0, 256, 64);
    print_message("sun pixel: E = %.5g, expected %.5g\n", out.esky[0], expect);
    assert_true(fabs(out.esky[0] - expect) / expect < 0.005);
    /* Its sun part (never pooled between facets) is that pixel's light alone. */
    double sun = 1e5 * rs_pano_pixel_solid_angle(w, h, sr) * rs_pano_pixel_dir(w, h, sc, sr).z;
    print_message("sun part: %.5g, expected %.5g\n", out.esun[0], sun);
    assert_true(fabs(out.esun[0] - sun) / sun < 0.005);
    free(out.entries);
    rs_fx_release(&env, &cap, scene, m);
}

/* Floor and a wall meeting at 90 degrees, long and high enough to be infinite-ish: a floor
 * facet at distance x from the wall sees it with view factor F = (1 - x / sqrt(x^2 + H^2)) / 2
 * (infinitely long strip of height H), so K's row sum over the wall is pi F and E_sky = pi (1 - F). */
static void test_floor_wall_view_factor(void **state)
{
    (void)state;
    const double H = 20, len = 400, x = 1.0;
    rs_meshgen g = rs_meshgen_new(1000, 1000);
    /* the floor facet: a small square at distance x from the wall (wall at y = 0, floor y < 0) */
    rs_meshgen_rect(&g, rs_v3_make(-0.05, -x - 0.05, 0), rs_v3_make(0.1, 0, 0), rs_v3_make(0, 0.1, 0), 1, 1);
    size_t wall = rs_meshgen_rect(&g, rs_v3_make(-len / 2, 0, 0), rs_v3_make(0, 0, H), rs_v3_make(len, 0, 0), 4, 4);
    rs_mesh *m = rs_meshgen_done(&g);
    rs_scene *scene = rs_fx_scene(m);
    rs_skyenv env = uniform_env(512, 1.0f);
    rs_facet_gather out = gather_one(scene, &env, 0, 4096, 0);
    double F = 0.5 * (1 - x / sqrt(x * x + H * H)), kwall = 0;
    for (uint32_t e = 0; e < out.nentries; e++) {
        assert_true(out.entries[e].col >= wall);
        kwall += out.entries[e].k;
    }
    print_message("view factor to the wall: %.5f (expected %.5f); E_sky/pi %.5f (expected %.5f)\n", kwall / M_PI, F,
                  out.esky[0] / M_PI, 1 - F);
    assert_true(fabs(kwall / M_PI - F) / F < 0.005);
    assert_true(fabs(out.esky[0] / M_PI - (1 - F)) / (1 - F) < 0.005);
    free(out.entries);
    rs_fx_release(&env, NULL, scene, m);
}

/* A closed box seen from inside: every ray hits, so K's rows sum to pi; the forward solve with
 * uniform albedo rho and source L_s converges to L_s / (1 - rho). */
static void test_closed_cavity(void **state)
{
    (void)state;
    rs_meshgen g = rs_meshgen_new(6 * 25, 6 * 32);
    rs_meshgen_box(&g, rs_v3_make(0, 0, 0), rs_v3_make(2, 3, 1.5), 4, 1);
    rs_mesh *m = rs_meshgen_done(&g);
    rs_scene *scene = rs_fx_scene(m);
    size_t nf = m->nfaces, ne = 0;
    rs_facet_gather *rows = calloc(nf, sizeof *rows);
    for (uint32_t f = 0; f < nf; f++) {
        rows[f] = gather_one(scene, NULL, f, 256, 0);
        double sum = 0;
        for (uint32_t e = 0; e < rows[f].nentries; e++) {
            assert_int_not_equal(rows[f].entries[e].col, f);
            sum += rows[f].entries[e].k;
        }
        assert_true(fabs(sum - M_PI) < 1e-5);
        ne += rows[f].nentries;
    }
    rs_transport K = {nf,
                      ne,
                      calloc(nf + 1, sizeof(size_t)),
                      malloc(ne * sizeof(uint32_t)),
                      malloc(ne * sizeof(float)),
                      malloc(ne * sizeof(float))};
    size_t e = 0;
    for (size_t f = 0; f < nf; f++) {
        for (uint32_t q = 0; q < rows[f].nentries; q++, e++) {
            K.col[e] = rows[f].entries[q].col;
            K.k[e] = rows[f].entries[q].k;
            K.k_unseen[e] = rows[f].entries[q].k_unseen;
        }
        K.row_start[f + 1] = e;
        free(rows[f].entries);
    }
    free(rows);
    const double rhos[3] = {0.5, 0.9, 0.99};
    double *rho = malloc(3 * nf * sizeof *rho), *esky = malloc(3 * nf * sizeof *esky), *L = malloc(3 * nf * sizeof *L),
           *G = malloc(3 * nf * sizeof *G);
    for (int t = 0; t < 3; t++) {
        const double Ls = 1.0;
        for (size_t i = 0; i < 3 * nf; i++) {
            rho[i] = rhos[t];
            esky[i] = M_PI * Ls / rhos[t]; /* so that L_s = rho E_sky / pi = Ls */
        }
        double residual;
        int it = rs_transport_solve(&K, rho, esky, L, G, 1e-9, 100000, &residual);
        double worst = 0;
        for (size_t i = 0; i < 3 * nf; i++) worst = fmax(worst, fabs(L[i] * (1 - rhos[t]) / Ls - 1));
        print_message("cavity rho %.2f: %d iterations, residual %.2g, worst relative error %.2g\n", rhos[t], it,
                      residual, worst);
        assert_true(residual < 1e-9);
        assert_true(worst < 0.005);
    }
    free(rho);
    free(esky);
    free(L);
    free(G);
    free(K.row_start);
    free(K.col);
    free(K.k);
    free(K.k_unseen);
    rs_scene_free(scene);
    rs_mesh_free(m);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_uniform_sky), cmocka_unit_test(test_sun_pixel),
             cmocka_unit_test(test_floor_wall_view_factor), cmocka_unit_test(test_closed_cavity))
