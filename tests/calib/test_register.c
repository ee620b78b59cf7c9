/* Tests of panorama-to-scan registration (calib/register.h) and of the absolute orientation
 * it and the COLMAP alignment rest on (calib/calib_math.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "calib/calib_math.h"
#include "calib/register.h"
#include "tests/testutil.h"

static double urand(uint64_t *s)
{
    *s = *s * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(*s >> 11) / 9007199254740992.0;
}

static double gauss(uint64_t *s)
{
    double a = urand(s), b = urand(s);
    return sqrt(-2 * log(a > 1e-300 ? a : 1e-300)) * cos(2 * M_PI * b);
}

static void random_rotation(uint64_t *s, double r[9])
{
    double w[3] = {gauss(s), gauss(s), gauss(s)};
    double len = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]), ang = M_PI * urand(s);
    for (int k = 0; k < 3; k++) w[k] *= ang / len;
    rs_calib_rot_exp(w, r);
}

/* Similarity recovered exactly from noise-free points (Horn + Umeyama's scale). */
static void test_align_similarity(void **state)
{
    (void)state;
    uint64_t s = 11;
    rs_v3 src[10], dst[10];
    double r[9], r2[9], sc;
    rs_v3 t = {4, -7, 2.5}, t2;
    random_rotation(&s, r);
    for (int i = 0; i < 10; i++) {
        src[i] = rs_v3_make(10 * urand(&s), 10 * urand(&s), 10 * urand(&s));
        dst[i] = rs_v3_add(rs_v3_scale(rs_m3_mul_v(r, src[i]), 2.5), t);
    }
    assert_int_equal(rs_calib_align(10, src, dst, 1, r2, &t2, &sc), 0);
    assert_true(rs_calib_rot_angle(r, r2) < 1e-9);
    assert_true(fabs(sc - 2.5) < 1e-9);
    assert_true(rs_v3_len(rs_v3_sub(t, t2)) < 1e-8);
    /* Collinear points: refused. */
    for (int i = 0; i < 10; i++) src[i] = rs_v3_make(i, 2 * i, 3);
    assert_int_equal(rs_calib_align(10, src, dst, 1, r2, &t2, &sc), -1);
}

/* The scene of the acceptance test: n pairs on a 2048 x 1024 panorama, points 20 m
 * away in every direction, 0.5 px Gaussian noise on both pixel coordinates, a share of pairs
 * replaced by random pixels (outliers). */
typedef struct {
    rs_pose truth;
    rs_v3 bearing[64], world[64];
    int outlier[64];
} scene;

static void make_scene(scene *sc, int n, double outlier_share, uint64_t seed)
{
    uint64_t s = seed;
    const int w = 2048, h = 1024;
    random_rotation(&s, sc->truth.rot);
    sc->truth.position = rs_v3_make(100 * urand(&s), 100 * urand(&s), 5 * urand(&s));
    int n_out = (int)lround(outlier_share * n);
    for (int i = 0; i < n; i++) {
        rs_v3 dl = rs_v3_norm(rs_v3_make(gauss(&s), gauss(&s), 0.6 * gauss(&s)));
        double dist = 20 * (0.8 + 0.4 * urand(&s));
        sc->world[i] = rs_v3_add(sc->truth.position, rs_v3_scale(rs_pose_dir_to_world(&sc->truth, dl), dist));
        double u, v;
        rs_pano_dir_to_uv(dl, &u, &v);
        double col = u * w - 0.5 + 0.5 * gauss(&s), row = v * h - 0.5 + 0.5 * gauss(&s);
        sc->outlier[i] = i < n_out;
        if (sc->outlier[i]) {
            col = urand(&s) * w - 0.5;
            row = urand(&s) * h - 0.5;
        }
        if (col < -0.5) col += w;
        if (col >= w - 0.5) col -= w;
        sc->bearing[i] = rs_pair_bearing(col, row, w, h);
    }
}

static void test_register_noise_outliers(void **state)
{
    (void)state;
    for (uint64_t seed = 1; seed <= 8; seed++) {
        scene sc;
        make_scene(&sc, 30, 0.2, seed);
        rs_register_opts opts = {500, 0.5, seed, NULL};
        rs_register_result res;
        double resid[64];
        uint8_t in[64];
        rs_err err = {0};
        assert_int_equal(rs_register_solve(sc.bearing, sc.world, 30, &opts, &res, resid, in, &err), 0);
        double rot_deg = rs_calib_rot_angle(sc.truth.rot, res.pose.rot) * 180 / M_PI;
        double pos_m = rs_v3_len(rs_v3_sub(sc.truth.position, res.pose.position));
        printf("seed %d: rotation error %.4f deg, position error %.4f m, %d inliers, rms %.4f deg\n", (int)seed,
               rot_deg, pos_m, res.inliers, res.rms_deg);
        assert_true(rot_deg < 0.05);
        assert_true(pos_m < 0.02);
        for (int i = 0; i < 30; i++) assert_int_equal(in[i], !sc.outlier[i]);
        assert_int_equal(res.inliers, 24);
    }
}

/* With no RANSAC samples the guess alone seeds the refinement, which reaches the same optimum
 * as the RANSAC path. */
static void test_register_guess(void **state)
{
    (void)state;
    scene sc;
    make_scene(&sc, 12, 0.0, 42);
    rs_pose guess = sc.truth;
    guess.position = rs_v3_add(guess.position, rs_v3_make(0.05, -0.03, 0.02));
    double w[3] = {0.002, -0.001, 0.001}, dr[9];
    rs_calib_rot_exp(w, dr);
    rs_calib_m3_mul(dr, sc.truth.rot, guess.rot);
    rs_register_opts opts = {0, 0.5, 1, &guess};
    rs_register_result res, ref;
    double resid[64];
    uint8_t in[64];
    rs_err err = {0};
    assert_int_equal(rs_register_solve(sc.bearing, sc.world, 12, &opts, &res, resid, in, &err), 0);
    opts.iterations = 300;
    opts.guess = NULL;
    assert_int_equal(rs_register_solve(sc.bearing, sc.world, 12, &opts, &ref, resid, in, &err), 0);
    assert_int_equal(res.inliers, 12);
    assert_true(rs_v3_len(rs_v3_sub(ref.pose.position, res.pose.position)) < 1e-5);
    assert_true(rs_calib_rot_angle(ref.pose.rot, res.pose.rot) < 1e-7);
}

static void test_register_errors(void **state)
{
    (void)state;
    scene sc;
    make_scene(&sc, 10, 0.0, 5);
    rs_register_opts opts = {200, 0.5, 1, NULL};
    rs_register_result res;
    double resid[64];
    uint8_t in[64];
    rs_err err = {0};
    assert_int_equal(rs_register_solve(sc.bearing, sc.world, 3, &opts, &res, resid, in, &err), -1);
    assert_non_null(strstr(err.msg, "at least 4"));
    for (int i = 0; i < 10; i++) sc.world[i] = rs_v3_make(1 + i, 2 + 0.5 * i, 3 - i);
    assert_int_equal(rs_register_solve(sc.bearing, sc.world, 10, &opts, &res, resid, in, &err), -1);
    assert_non_null(strstr(err.msg, "one line"));
}

static void test_pairs_file(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("pairs");
    const char *good = rs_test_path(dir, "good.txt");
    rs_test_write(good,
                  "# column row X Y Z\n10 20 1 2 3\n\n  -0.5 0 4 5 6 # a comment\n2047.4 1023.5 7 8 9\n"
                  "100.25 50.75 -1 -2 -3\n");
    rs_pair *p = NULL;
    int n = 0;
    rs_err err = {0};
    assert_int_equal(rs_pairs_read(good, 2048, 1024, &p, &n, &err), 0);
    assert_int_equal(n, 4);
    assert_true(p[3].col == 100.25 && p[3].row == 50.75 && p[3].world.z == -3 && p[3].line == 6);
    free(p);
    const char *few = rs_test_path(dir, "few.txt");
    rs_test_write(few, "1 2 3 4 5\n6 7 8 9 10\n11 12 13 14 15\n");
    assert_int_equal(rs_pairs_read(few, 2048, 1024, &p, &n, &err), -1);
    assert_non_null(strstr(err.msg, "3 correspondences: expected at least 4"));
    const char *bad = rs_test_path(dir, "bad.txt");
    rs_test_write(bad, "1 2 3 4 5\n6 7 8 9\n");
    assert_int_equal(rs_pairs_read(bad, 2048, 1024, &p, &n, &err), -1);
    assert_int_equal(err.line, 2);
    assert_non_null(strstr(err.msg, "column row X Y Z"));
    const char *outside = rs_test_path(dir, "outside.txt");
    rs_test_write(outside, "1 2 3 4 5\n2048 7 8 9 1\n");
    assert_int_equal(rs_pairs_read(outside, 2048, 1024, &p, &n, &err), -1);
    assert_int_equal(err.line, 2);
    assert_non_null(strstr(err.msg, "outside"));
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_align_similarity), cmocka_unit_test(test_register_noise_outliers),
             cmocka_unit_test(test_register_guess), cmocka_unit_test(test_register_errors),
             cmocka_unit_test(test_pairs_file))
