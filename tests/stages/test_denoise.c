/* test_denoise: the mesh stage's bilateral normal denoising on a noisy profile strip (a floor,
 * a wall at a 90 degree crease, a roof at a 135 degree edge): flat parts smoothed, creases kept. */
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/config.h"
#include "meshing/denoise.h"
#include "common/mesh.h"

#define H     0.05   /* grid spacing (m) */
#define NOISE 0.0015 /* per-axis vertex noise (m), like a scan's millimetres */
#define NY    20

/* The profile in x-z: floor (0,0)-(1,0), wall (1,0)-(1,1), roof (1,1)-(2,2). */
static const double corner[4][2] = {{0, 0}, {1, 0}, {1, 1}, {2, 2}};
static int seg_steps[3], crease_at[2], nsteps;

static rs_v3 seg_normal(int s)
{
    rs_v3 d = rs_v3_norm(rs_v3_make(corner[s + 1][0] - corner[s][0], 0, corner[s + 1][1] - corner[s][1]));
    return rs_v3_cross(d, rs_v3_make(0, 1, 0)); /* the winding's normal: floor +z, wall -x */
}

static uint64_t rng = 88172645463325252ull;
static double uniform(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return ((rng >> 11) + 0.5) / 9007199254740992.0;
}
static double gauss(void)
{
    return sqrt(-2 * log(uniform())) * cos(2 * M_PI * uniform());
}

/* The strip extruded along y, exact (noise = 0) or noisy; face f lies on segment *seg[f]. */
static rs_mesh *make_strip(double noise, int **seg)
{
    nsteps = 0;
    for (int s = 0; s < 3; s++) {
        double len = hypot(corner[s + 1][0] - corner[s][0], corner[s + 1][1] - corner[s][1]);
        seg_steps[s] = (int)lround(len / H);
        nsteps += seg_steps[s];
        if (s < 2) crease_at[s] = nsteps;
    }
    rs_mesh *m = rs_mesh_new((size_t)(nsteps + 1) * (NY + 1), (size_t)2 * nsteps * NY);
    int i = 0;
    for (int s = 0; s < 3; s++)
        for (int k = (s == 0 ? 0 : 1); k <= seg_steps[s]; k++, i++) {
            double t = (double)k / seg_steps[s];
            double px = corner[s][0] + t * (corner[s + 1][0] - corner[s][0]);
            double pz = corner[s][1] + t * (corner[s + 1][1] - corner[s][1]);
            for (int j = 0; j <= NY; j++) {
                float *v = m->verts + 3 * ((size_t)i * (NY + 1) + j);
                v[0] = (float)(px + noise * gauss());
                v[1] = (float)(j * H + noise * gauss());
                v[2] = (float)(pz + noise * gauss());
            }
        }
    *seg = malloc(m->nfaces * sizeof **seg);
    size_t f = 0;
    for (i = 0; i < nsteps; i++) {
        int s = i < crease_at[0] ? 0 : i < crease_at[1] ? 1 : 2;
        for (int j = 0; j < NY; j++) {
            uint32_t a = (uint32_t)(i * (NY + 1) + j), b = a + NY + 1, c = b + 1, d = a + 1;
            uint32_t t[6] = {a, b, c, a, c, d};
            memcpy(m->tris + 3 * f, t, sizeof t);
            (*seg)[f] = (*seg)[f + 1] = s;
            f += 2;
        }
    }
    return m;
}

/* Profile step of face f (two faces per step and NY steps along y). */
static int face_step(size_t f)
{
    return (int)(f / (2 * NY));
}

/* A face with a corner on a crease line. */
static int on_crease(size_t f)
{
    int i = face_step(f);
    return i + 1 == crease_at[0] || i == crease_at[0] || i + 1 == crease_at[1] || i == crease_at[1];
}

/* Three or more steps from either crease. */
static int flat(size_t f)
{
    int i = face_step(f);
    for (int c = 0; c < 2; c++)
        if (i >= crease_at[c] - 3 && i < crease_at[c] + 3) return 0;
    return 1;
}

/* RMS and max angle (degrees) between the faces' normals and their segment's, over the faces
 * where pick(f) holds. */
static void normal_error(const rs_mesh *m, const int *seg, int (*pick)(size_t), double *rms, double *max)
{
    double sum = 0;
    size_t n = 0;
    *max = 0;
    for (size_t f = 0; f < m->nfaces; f++) {
        if (!pick(f)) continue;
        rs_v3 nrm;
        rs_mesh_face(m, f, NULL, &nrm, NULL);
        double c = rs_v3_dot(nrm, seg_normal(seg[f]));
        double a = acos(c > 1 ? 1 : c < -1 ? -1 : c) * 180 / M_PI;
        sum += a * a;
        n++;
        if (a > *max) *max = a;
    }
    *rms = sqrt(sum / (double)n);
}

static void test_denoise_strip(void **state)
{
    (void)state;
    int *seg;
    rs_mesh *m = make_strip(NOISE, &seg);
    float *before = malloc(3 * m->nverts * sizeof *before);
    memcpy(before, m->verts, 3 * m->nverts * sizeof *before);
    double flat0, flatmax0, cr0, crmax0;
    normal_error(m, seg, flat, &flat0, &flatmax0);
    normal_error(m, seg, on_crease, &cr0, &crmax0);

    rs_denoise_opts o;
    rs_denoise_defaults(&o);
    rs_denoise_stats st;
    rs_err err = {0};
    assert_int_equal(rs_denoise_apply(m, &o, &st, &err), 0);
    double flat1, flatmax1, cr1, crmax1;
    normal_error(m, seg, flat, &flat1, &flatmax1);
    normal_error(m, seg, on_crease, &cr1, &crmax1);
    print_message("flat RMS %.2f -> %.2f deg (max %.2f -> %.2f); crease RMS %.2f -> %.2f deg (max %.2f -> %.2f); "
                  "moved %zu, RMS %.2f mm, max %.2f mm\n",
                  flat0, flat1, flatmax0, flatmax1, cr0, cr1, crmax0, crmax1, st.moved, 1e3 * st.rms_move_m,
                  1e3 * st.max_move_m);
    assert_true(flat0 > 1.0); /* the noise is there to remove */
    assert_true(flat1 < flat0 / 3);
    assert_true(cr1 < 3.0); /* crease facets within a few degrees of truth */
    assert_true(crmax1 < 8.0);
    assert_true(st.moved > m->nverts / 2);
    double maxmove = 0;
    for (size_t k = 0; k < m->nverts; k++) {
        double d2 = 0;
        for (int j = 0; j < 3; j++) d2 += pow((double)m->verts[3 * k + j] - before[3 * k + j], 2);
        if (sqrt(d2) > maxmove) maxmove = sqrt(d2);
    }
    assert_true(maxmove <= o.max_move_m + 1e-6);
    assert_true(fabs(maxmove - st.max_move_m) < 1e-9);

    /* Without the range weight (sigma_r 90 degrees) the creases round off: the same check fails,
     * so the kept creases are the range weight's doing. */
    memcpy(m->verts, before, 3 * m->nverts * sizeof *before);
    o.sigma_r_deg = 90;
    o.max_move_m = 0.05;
    assert_int_equal(rs_denoise_apply(m, &o, &st, &err), 0);
    double crw, crmaxw;
    normal_error(m, seg, on_crease, &crw, &crmaxw);
    print_message("sigma_r 90 deg: crease RMS %.2f deg (max %.2f)\n", crw, crmaxw);
    assert_true(crw > 3 * cr1);

    /* A tight bound holds every vertex within it. */
    memcpy(m->verts, before, 3 * m->nverts * sizeof *before);
    rs_denoise_defaults(&o);
    o.max_move_m = 0.0005;
    assert_int_equal(rs_denoise_apply(m, &o, &st, &err), 0);
    assert_true(st.max_move_m <= 0.0005 + 1e-6);
    assert_true(st.clamped > 0);
    free(before);
    free(seg);
    rs_mesh_free(m);
}

/* A noiseless strip stays where it is: the filter has nothing to correct. */
static void test_denoise_exact(void **state)
{
    (void)state;
    int *seg;
    rs_mesh *m = make_strip(0, &seg);
    rs_denoise_opts o;
    rs_denoise_defaults(&o);
    rs_denoise_stats st;
    rs_err err = {0};
    assert_int_equal(rs_denoise_apply(m, &o, &st, &err), 0);
    print_message("exact strip: max move %.3g m\n", st.max_move_m);
    assert_true(st.max_move_m < 1e-5); /* the 45 degree turn leaks exp(-9.6) of weight: microns */
    free(seg);
    rs_mesh_free(m);
}

static void expect_config_error(const char *text, const char *key)
{
    rs_err err = {0};
    rs_config *cfg = rs_config_load_string(text, "test.ini", ".", NULL, &err);
    if (cfg) rs_config_free(cfg);
    assert_null(cfg);
    if (!strstr(err.msg, key)) fail_msg("error does not name %s: %s", key, err.msg);
}

static void test_denoise_bad_values(void **state)
{
    (void)state;
    expect_config_error("[mesh]\ndenoise = perhaps\n", "denoise");
    expect_config_error("[mesh]\ndenoise_sigma_r_deg = 0\n", "denoise_sigma_r_deg");
    expect_config_error("[mesh]\ndenoise_sigma_r_deg = 120\n", "denoise_sigma_r_deg");
    expect_config_error("[mesh]\ndenoise_iterations = 0\n", "denoise_iterations");
    expect_config_error("[mesh]\ndenoise_max_move = -0.01\n", "denoise_max_move");
    expect_config_error("[mesh]\ndenoise_sigma_s = abc\n", "denoise_sigma_s");

    /* The library checks its options too, naming the key. */
    int *seg;
    rs_mesh *m = make_strip(0, &seg);
    rs_denoise_opts o;
    rs_denoise_stats st;
    rs_err err = {0};
    rs_denoise_defaults(&o);
    o.max_move_m = NAN;
    assert_int_equal(rs_denoise_apply(m, &o, &st, &err), -1);
    assert_non_null(strstr(err.msg, "denoise_max_move"));
    rs_denoise_defaults(&o);
    o.sigma_r_deg = 0;
    assert_int_equal(rs_denoise_apply(m, &o, &st, &err), -1);
    assert_non_null(strstr(err.msg, "denoise_sigma_r_deg"));
    free(seg);
    rs_mesh_free(m);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_denoise_strip), cmocka_unit_test(test_denoise_exact),
             cmocka_unit_test(test_denoise_bad_values))
