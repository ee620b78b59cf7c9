/* Sums over a million facets: the reflectance stage's area-weighted mean albedo (the fill for
 * unobserved facets) must match a compensated long-double sum to 1e-6 relative, with facet
 * areas spanning six orders of magnitude and irradiance eight (a sun of 1e5 over 1e-3 shade),
 * so that no float accumulation or cancellation can hide in the stage's loops. */
#include "common/sampling.h"
#include "tests/stress/stress.h"

#define NFACETS 1000000

static void test_million_facet_sums(void **state)
{
    (void)state;
    rs_mesh *m = rs_mesh_new(3 * (size_t)NFACETS, NFACETS);
    double *L = malloc(3 * (size_t)NFACETS * sizeof *L), *E = malloc(3 * (size_t)NFACETS * sizeof *E);
    assert_non_null(m);
    uint32_t seed = 12345;
    for (size_t k = 0; k < NFACETS; k++) {
        /* Triangle k in cell (k % 1000, k / 1000) of a 12 m grid, side 1e-2 .. 10 m. */
        seed = rs_hash_u32(seed + (uint32_t)k);
        double side = pow(10.0, -2.0 + 3.0 * (seed & 0xffff) / 65535.0);
        double x = 12.0 * (double)(k % 1000), y = 12.0 * (double)(k / 1000);
        float *v = m->verts + 9 * k;
        v[0] = (float)x, v[1] = (float)y, v[2] = 0;
        v[3] = (float)(x + side), v[4] = (float)y, v[5] = 0;
        v[6] = (float)x, v[7] = (float)(y + side), v[8] = 0;
        for (int j = 0; j < 3; j++) m->tris[3 * k + j] = (uint32_t)(3 * k + j);
        double e = pow(10.0, -3.0 + 8.0 * ((seed >> 16) & 0xffff) / 65535.0); /* 1e-3 .. 1e5 */
        for (int ch = 0; ch < 3; ch++) {
            double rho = 0.1 + 0.8 * ((rs_hash_u32(seed + (uint32_t)ch) & 0xffff) / 65535.0);
            E[3 * k + ch] = e;
            L[3 * k + ch] = rho * e / M_PI;
        }
    }
    const char *dir = rs_test_tmpdir("sums");
    stress_write_reflectance_inputs(dir, m, L, E, NULL, NULL);
    rs_err err;
    /* Every facet estimable: no minimum share of the median irradiance. */
    if (stress_run_stage("reflectance", dir, "[reflectance]\nmin_irradiance = 0\n", &err) != 0)
        fail_msg("reflectance: %s", err.msg);

    /* Reference from the values the stage read (float in the PLY files), compensated sums. */
    rs_ply *obs = rs_ply_read(rs_test_path(dir, "observe.ply"), &err),
           *irr = rs_ply_read(rs_test_path(dir, "irradiance.ply"), &err);
    assert_non_null(obs);
    assert_non_null(irr);
    double *Lf = malloc(3 * (size_t)NFACETS * sizeof *Lf), *Ef = malloc(3 * (size_t)NFACETS * sizeof *Ef);
    assert_int_equal(rs_faceprop_get_rgb(obs, "observe.ply", "radiance", NFACETS, Lf, &err), 0);
    assert_int_equal(rs_faceprop_get_rgb(irr, "irradiance.ply", "irradiance_sky", NFACETS, Ef, &err), 0);
    long double num[3] = {0, 0, 0}, comp[3] = {0, 0, 0}, den = 0, dcomp = 0;
    for (size_t k = 0; k < NFACETS; k++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(m, k, &c, &n, &a);
        long double y = (long double)a - dcomp, t = den + y; /* Kahan */
        dcomp = (t - den) - y;
        den = t;
        for (int ch = 0; ch < 3; ch++) {
            long double v = (long double)a * (long double)M_PI * Lf[3 * k + ch] / Ef[3 * k + ch] - comp[ch];
            long double s = num[ch] + v;
            comp[ch] = (s - num[ch]) - v;
            num[ch] = s;
        }
    }
    double fill[3];
    rs_test_json_rgb(rs_test_path(dir, "reflectance.json"), "fill_albedo", fill);
    for (int ch = 0; ch < 3; ch++) {
        double want = (double)(num[ch] / den);
        print_message("channel %d: fill albedo %.10g, compensated reference %.10g\n", ch, fill[ch], want);
        assert_true(fabs(fill[ch] - want) <= 1e-6 * want);
    }
    free(Lf);
    free(Ef);
    rs_ply_free(obs);
    rs_ply_free(irr);
    free(L);
    free(E);
    rs_mesh_free(m);
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_million_facet_sums))
