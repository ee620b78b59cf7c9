/* test_unobserved_fill: an unobserved facet takes the albedo of the estimable facets facing the
 * same way ([reflectance] unobserved_albedo_by = orientation), so a dark ground the camera does not
 * see lights a bright wall with the ground's albedo, not the wall-dominated mean of all.
 *
 * Three facets, each under E_sky = 1: an observed ground (up, albedo 0.2, 1 m^2), an observed wall
 * (sideways, albedo 0.8, 10 m^2) and an unobserved ground (up, albedo 0.2) that the wall sees
 * through K = 0.5 sr. Its true light on the wall is 0.5 x 0.2 / pi. */
#include "tests/stress/stress.h"

#define RHO_GROUND    0.2
#define RHO_WALL      0.8
#define K_WALL_GROUND 0.5

static void put_tri(rs_mesh *m, size_t f, const double v[9])
{
    for (int k = 0; k < 9; k++) m->verts[9 * f + k] = (float)v[k];
    for (int j = 0; j < 3; j++) m->tris[3 * f + j] = (uint32_t)(3 * f + j);
}

/* Runs reflectance with the given extra config; returns the wall's albedo (green) and the
 * unobserved ground's written albedo (green), and the stage's fills from reflectance.json. */
static void run_case(const char *extra, double *wall, double *hidden, double fill_up[3], double fill_all[3])
{
    rs_mesh *m = rs_mesh_new(9, 3);
    assert_non_null(m);
    double s2 = sqrt(2.0), s20 = sqrt(20.0);
    const double ground[9] = {0, 0, 0, s2, 0, 0, 0, s2, 0};         /* +z, 1 m^2 */
    const double wallv[9] = {5, 0, 0, 5, s20, 0, 5, 0, s20};        /* +x, toward the hidden ground, 10 m^2 */
    const double hiddenv[9] = {10, 0, 0, 10 + s2, 0, 0, 10, s2, 0}; /* +z, 1 m^2 */
    put_tri(m, 0, ground);
    put_tri(m, 1, wallv);
    put_tri(m, 2, hiddenv);
    double esky[9], L[9], observed[3] = {1, 1, 0};
    double L_hidden = RHO_GROUND / M_PI, G_wall = K_WALL_GROUND * L_hidden;
    for (int ch = 0; ch < 3; ch++) {
        for (int f = 0; f < 3; f++) esky[3 * f + ch] = 1;
        L[ch] = RHO_GROUND / M_PI;
        L[3 + ch] = RHO_WALL * (1 + G_wall) / M_PI;
        L[6 + ch] = 0; /* not observed: the stage must not read it */
    }
    size_t row_start[4] = {0, 0, 1, 1};
    uint32_t col[1] = {2};
    float k[1] = {K_WALL_GROUND}, ku[1] = {K_WALL_GROUND}; /* the camera sees no hit point */
    rs_transport K = {3, 1, row_start, col, k, ku};
    const char *dir = rs_test_tmpdir("unobserved_fill");
    stress_write_reflectance_inputs(dir, m, L, esky, observed, &K);
    rs_err err;
    if (stress_run_stage("reflectance", dir, extra, &err) != 0) fail_msg("reflectance: %s", err.msg);
    double *alb, *est;
    stress_read_albedo(dir, 3, &alb, &est);
    assert_true(est[0] == 1 && est[1] == 1 && est[2] == 0);
    *wall = alb[3 + 1];
    *hidden = alb[6 + 1];
    const char *json = rs_test_path(dir, "reflectance.json");
    rs_test_json_rgb(json, "fill_albedo", fill_all);
    rs_test_json_rgb(json, "fill_albedo_by_orientation/up", fill_up);
    free(alb);
    free(est);
    rs_mesh_free(m);
    rs_test_rmtree(dir);
}

static void test_fill_by_orientation(void **state)
{
    (void)state;
    double wall, hidden, up[3], all[3];
    run_case("", &wall, &hidden, up, all);
    /* The up class: the observed ground's albedo shrunk toward the mean of all by 1 % of the
     * estimable area (11 m^2), with the estimates the stage itself made. */
    double rho_wall_est = wall, mean_all = (1 * RHO_GROUND + 10 * rho_wall_est) / 11;
    double want_up = (1 * RHO_GROUND + 0.11 * mean_all) / (1 + 0.11);
    print_message("orientation: wall %.5f (true %.2f), hidden ground %.5f, up fill %.5f (want %.5f), "
                  "mean of all %.5f\n",
                  wall, RHO_WALL, hidden, up[1], want_up, all[1]);
    assert_true(fabs(all[1] - mean_all) < 1e-5);
    assert_true(fabs(up[1] - want_up) < 1e-5);
    assert_true(fabs(hidden - up[1]) < 1e-5); /* albedo.ply carries the class's fill */
    assert_true(fabs(wall - RHO_WALL) < 0.01 * RHO_WALL);

    /* One mean for all: the hidden ground lights the wall as if it were mostly wall. */
    double wall_all, hidden_all;
    run_case("[reflectance]\nunobserved_albedo_by = all\n", &wall_all, &hidden_all, up, all);
    print_message("all: wall %.5f, hidden ground %.5f, mean of all %.5f\n", wall_all, hidden_all, all[1]);
    assert_true(fabs(hidden_all - all[1]) < 1e-5);
    assert_true(fabs(up[1] - all[1]) < 1e-9);
    assert_true(fabs(wall_all - RHO_WALL) > 0.05 * RHO_WALL);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_fill_by_orientation))
