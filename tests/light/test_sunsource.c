/* [sky] sun_irradiance: a synthetic sky whose sun is clipped. Without the key a roof's E_sky
 * lacks the clipped energy; with it (sun placed by the config or by the clipped disc) E_sky is
 * within 1 % of the analytic value, and a facet in the roof's shadow gets no sun term.
 * [sky] sun_color gives each channel its share of the DNI. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/faceprop.h"
#include "common/image.h"
#include "tests/fixtures.h"
#include "tests/meshgen.h"
#include "common/pano.h"
#include "common/ply.h"
#include "tests/testutil.h"

#define W          1024
#define SUN_EL_DEG 40.0
#define L_SKY      1.0
#define L_GROUND   0.3
#define L_SUN      15000.0 /* true radiance of the disc (1 deg radius, widened for the grid) */
#define L_HALO     200.0   /* 1 to 2 deg: bright, below the clip level, real light */
#define CLIP       500.0   /* the sensor's ceiling: the disc reads this */

static rs_v3 sun_dir(void)
{
    double el = SUN_EL_DEG * M_PI / 180;
    return rs_v3_make(cos(el), 0, sin(el));
}

/* True radiance of direction d (the panorama stores min(true, CLIP)). */
static double true_radiance(rs_v3 d)
{
    if (d.z <= 0) return L_GROUND;
    double ang = acos(fmin(1, rs_v3_dot(d, sun_dir()))) * 180 / M_PI;
    return ang <= 1 ? L_SUN : ang <= 2 ? L_HALO : L_SKY;
}

/* Ground 8 x 4 m at z = 0 and a 1 x 2 m roof at z = 1 over x in [-2, -1], both facing up; the
 * camera 2 m above the origin; the clipped panorama. Returns, through the pointers, the direct
 * normal irradiance of the sun and halo over the sky (what a pyrheliometer reads) and the part
 * of it the clip took away, both over the panorama's pixels. */
typedef struct {
    double dni, clipped_dni;
} sun_sums;

/* The clipped panorama's pixel, adding the pixel's part of the DNI and of what the clip took. */
static void clipped_radiance(rs_v3 d, size_t k, double rgb[3], void *ctx)
{
    sun_sums *sums = ctx;
    double L = true_radiance(d), om = rs_pano_pixel_solid_angle(W, W / 2, (int)(k / W));
    if (L > L_SKY && d.z > 0) sums->dni += (L - L_SKY) * om;
    if (L > CLIP) sums->clipped_dni += (L - CLIP) * om;
    rgb[0] = rgb[1] = rgb[2] = fmin(L, CLIP);
}

static void write_scene(const char *dir, double *dni, double *clipped_dni)
{
    rs_meshgen g = rs_meshgen_new(1000, 1000);
    rs_meshgen_rect(&g, rs_v3_make(-4, -2, 0), rs_v3_make(8, 0, 0), rs_v3_make(0, 4, 0), 16, 8);
    rs_meshgen_rect(&g, rs_v3_make(-2, -1, 1), rs_v3_make(1, 0, 0), rs_v3_make(0, 2, 0), 2, 4);
    rs_mesh *m = rs_meshgen_done(&g);
    rs_meshgen_write(m, rs_test_path(dir, "mesh.ply"));
    rs_mesh_free(m);
    sun_sums sums = {0, 0};
    rs_image *img = rs_fx_pano(W, W / 2, clipped_radiance, &sums);
    *dni = sums.dni;
    *clipped_dni = sums.clipped_dni;
    rs_fx_write_pano(img, dir);
    rs_image_free(img);
    rs_fx_write_scene_ini(dir, "0 0 2", 128, 16, "skip_unseen = false\n[sky]\nfill = row\n");
}

/* Runs the pipeline up to irradiance with extra --set options; reads E_sky of channel ch per
 * facet and the facet centroids. */
static void run_channel(const char *dir, const char *sets, int ch, double **esky, rs_v3 **centroid, size_t *nf)
{
    rs_test_rhoscan(dir, sets);
    rs_err err;
    const char *path = rs_test_path(dir, "work/irradiance.ply");
    rs_mesh *m = rs_mesh_read(path, NULL, &err);
    rs_ply *ply = rs_ply_read(path, &err);
    assert_non_null(m);
    assert_non_null(ply);
    *nf = m->nfaces;
    double *rgb = malloc(3 * *nf * sizeof *rgb);
    *esky = malloc(*nf * sizeof **esky);
    *centroid = malloc(*nf * sizeof **centroid);
    assert_int_equal(rs_faceprop_get_rgb(ply, path, "irradiance_sky", *nf, rgb, &err), 0);
    for (size_t f = 0; f < *nf; f++) {
        rs_v3 n;
        double a;
        rs_mesh_face(m, f, &(*centroid)[f], &n, &a);
        (*esky)[f] = rgb[3 * f + ch];
    }
    free(rgb);
    rs_ply_free(ply);
    rs_mesh_free(m);
}

/* The same for the green channel. */
static void run(const char *dir, const char *sets, double **esky, rs_v3 **centroid, size_t *nf)
{
    run_channel(dir, sets, 1, esky, centroid, nf);
}

/* Mean E over the facets whose centroid lies in the box. */
static double mean_in(const double *e, const rs_v3 *c, size_t nf, double x0, double x1, double y0, double y1, double z0,
                      double z1)
{
    double sum = 0;
    int n = 0;
    for (size_t f = 0; f < nf; f++)
        if (c[f].x > x0 && c[f].x < x1 && c[f].y > y0 && c[f].y < y1 && c[f].z > z0 && c[f].z < z1) {
            sum += e[f];
            n++;
        }
    assert_true(n > 0);
    return sum / n;
}

/* rhoscan run in dir with sets fails with exit 1 and a message naming both words. */
static void expect_input_error(const char *dir, const char *sets, const char *word1, const char *word2)
{
    char cmd[4096], *out = NULL;
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/rhoscan' run --force %s scene.ini", dir, rs_test_bin_dir(), sets);
    int rc = rs_test_run(cmd, &out);
    print_message("exit %d: %s\n", rc, out);
    assert_int_equal(rc, 1);
    assert_non_null(strstr(out, word1));
    assert_non_null(strstr(out, word2));
    free(out);
}

static void test_clipped_sun(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("sunsource");
    double dni, clipped;
    write_scene(dir, &dni, &clipped);
    double s = sin(SUN_EL_DEG * M_PI / 180);
    double e_true = M_PI * L_SKY + dni * s; /* open horizontal facet: sky + sun and halo */
    double e_clipped = clipped * s;
    print_message("DNI %.4f, clipped %.4f; roof E_sky analytic %.4f\n", dni, clipped, e_true);
    assert_true(e_clipped > 0.5 * e_true); /* the clip matters */

    double *e0, *e1, *e2;
    rs_v3 *c;
    size_t nf;
    run(dir, "", &e0, &c, &nf);
    free(c);
    char sets[512];
    snprintf(sets, sizeof sets,
             "--set sky.sun_irradiance=%.9g --set sky.sun_azimuth_deg=0 --set "
             "sky.sun_elevation_deg=%g",
             dni, SUN_EL_DEG);
    run(dir, sets, &e1, &c, &nf);
    const char *json = rs_test_read_text(rs_test_path(dir, "work/irradiance.json"));
    const struct cJSON *doc = rs_test_json_text(json);
    assert_string_equal(rs_test_json_str(doc, "direction_from"), "config");
    /* The gather's noise is calibrated against a second gather without the sun term, so the sun
     * must not be in the first either (it was: a factor of 12 to 24 on the reference scenes). */
    double factor = rs_test_json_num(doc, "mc_sigma_factor");
    print_message("mc_sigma_factor with the explicit sun: %.3f\n", factor);
    assert_true(factor > 0 && factor < 2);
    free(c);
    snprintf(sets, sizeof sets, "--set sky.sun_irradiance=%.9g", dni);
    run(dir, sets, &e2, &c, &nf);
    json = rs_test_read_text(rs_test_path(dir, "work/irradiance.json"));
    assert_string_equal(rs_test_json_str(rs_test_json_text(json), "direction_from"), "clipped disc");

    /* The roof (z = 1): nothing above it. */
    double roof0 = mean_in(e0, c, nf, -2, -1, -1, 1, 0.5, 1.5), roof1 = mean_in(e1, c, nf, -2, -1, -1, 1, 0.5, 1.5),
           roof2 = mean_in(e2, c, nf, -2, -1, -1, 1, 0.5, 1.5);
    print_message("roof E_sky: no key %.4f (expected %.4f), sun given %.4f, sun from the disc %.4f\n", roof0,
                  e_true - e_clipped, roof1, roof2);
    assert_true(fabs(roof0 - (e_true - e_clipped)) < 0.01 * e_true);
    assert_true(fabs(roof1 - e_true) < 0.01 * e_true);
    assert_true(fabs(roof2 - e_true) < 0.01 * e_true);

    /* Ground in the roof's shadow (x + cot 40 deg within the roof: x in [-3.19, -2.19]) gets no
     * sun term: the key changes it by much less than the sun would add; open ground gains the
     * clipped energy. */
    double sh0 = mean_in(e0, c, nf, -3, -2.5, -0.9, 0.9, -0.5, 0.5),
           sh1 = mean_in(e1, c, nf, -3, -2.5, -0.9, 0.9, -0.5, 0.5);
    double op0 = mean_in(e0, c, nf, 2, 3.5, -1.9, 1.9, -0.5, 0.5),
           op1 = mean_in(e1, c, nf, 2, 3.5, -1.9, 1.9, -0.5, 0.5);
    print_message("shadowed ground: %.4f -> %.4f; open ground: %.4f -> %.4f\n", sh0, sh1, op0, op1);
    assert_true(fabs(sh1 - sh0) < 0.01 * dni * s);
    assert_true(sh1 < 0.5 * op1);
    assert_true(fabs((op1 - op0) - e_clipped) < 0.02 * e_true);
    free(e0);
    free(e1);
    free(e2);
    free(c);
    rs_test_rmtree(dir);
}

/* A coloured sun: each channel of the roof's E_sky gains dni x sin(el) x its share of the colour
 * at luminance 1 (the sky is grey), within 1 %; a black colour is an error naming the key. */
static void test_sun_color(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("sunsource");
    double dni, clipped;
    write_scene(dir, &dni, &clipped);
    const double col[3] = {2.0, 1.0, 0.5}, lum = 0.2126 * col[0] + 0.7152 * col[1] + 0.0722 * col[2];
    double s = sin(SUN_EL_DEG * M_PI / 180);
    char sets[512];
    snprintf(sets, sizeof sets,
             "--set sky.sun_irradiance=%.9g --set sky.sun_azimuth_deg=0 --set "
             "sky.sun_elevation_deg=%g --set 'sky.sun_color=%g %g %g'",
             dni, SUN_EL_DEG, col[0], col[1], col[2]);
    for (int ch = 0; ch < 3; ch++) {
        double *e;
        rs_v3 *c;
        size_t nf;
        /* Rerunning with the same settings is skipped by the driver; the work folder is reread. */
        run_channel(dir, sets, ch, &e, &c, &nf);
        double roof = mean_in(e, c, nf, -2, -1, -1, 1, 0.5, 1.5), expect = M_PI * L_SKY + dni * s * col[ch] / lum;
        print_message("channel %d: roof E_sky %.4f, expected %.4f\n", ch, roof, expect);
        assert_true(fabs(roof - expect) < 0.01 * expect);
        free(e);
        free(c);
    }
    strncat(sets, " --set 'sky.sun_color=0 0 0'", sizeof sets - strlen(sets) - 1);
    expect_input_error(dir, sets, "sun_color", "expected three values >= 0");
    rs_test_rmtree(dir);
}

/* The key without a direction on a panorama with nothing clipped is an error naming it. */
static void test_no_sun_found(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("sunsource");
    double dni, clipped;
    write_scene(dir, &dni, &clipped);
    expect_input_error(dir, "--set sky.sun_irradiance=10 --set sky.sun_clip_level=1e9", "sun_irradiance",
                       "sun_azimuth_deg");
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_clipped_sun), cmocka_unit_test(test_sun_color),
             cmocka_unit_test(test_no_sun_found))
