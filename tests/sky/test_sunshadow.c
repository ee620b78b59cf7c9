/* [sky] sun_from_shadows: a sun no camera sees, its DNI from the model's shadows.
 * - The estimator alone, on a plane with a shadow edge, an albedo edge, noise and pixels
 *   that bleed across the shadow edge: the DNI per channel within 2 %.
 * - End to end: a black wall hides the sun from the camera and shades the ground. A first run
 *   with the sun's DNI given computes each ground facet's irradiance; the panorama is then
 *   rendered from it with a known albedo; a second run, given only the sun's direction, finds
 *   the DNI within 2 % and the sunlit ground's E_sky with it. Given nothing, the shadows give
 *   the direction within 2 degrees; with no sun at all, or a sky whose glow puts the sun
 *   elsewhere (unless the sunlit facets' albedo without it is above 1), the search adds none. */
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
#include "sky/skymodel.h"
#include "sky/sunshadow.h"
#include "light/sunsource.h"
#include "tests/testutil.h"

/* Deterministic noise in [-1, 1]. */
static double noise(uint32_t k)
{
    k ^= k >> 16;
    k *= 0x7feb352dU;
    k ^= k >> 15;
    k *= 0x846ca68bU;
    k ^= k >> 16;
    return 2.0 * k / 4294967295.0 - 1;
}

/* A 10 x 10 m ground in 0.1 m cells, in shadow for x < 0 (a 0.1 m penumbra at the edge); the
 * sun at 40 degrees; the albedo 0.3 0.3 0.3, 0.6 0.5 0.4 for y > 2 (an edge across the shadow's);
 * 2 % noise on L; facets within 0.15 m of the shadow edge read the mean of both sides (pixels
 * that bleed). */
static void test_estimator(void **state)
{
    (void)state;
    rs_meshgen g = rs_meshgen_new(20000, 40000);
    rs_meshgen_rect(&g, rs_v3_make(-5, -5, 0), rs_v3_make(10, 0, 0), rs_v3_make(0, 10, 0), 100, 100);
    rs_mesh *m = rs_meshgen_done(&g);
    size_t nf = m->nfaces;
    const double D[3] = {5.0, 4.0, 2.0};
    const double el = 40 * M_PI / 180;
    rs_v3 s = rs_v3_make(cos(el), 0, sin(el));
    float *vis = malloc(nf * sizeof *vis);
    double *E = malloc(3 * nf * sizeof *E), *L = malloc(3 * nf * sizeof *L), *mix = malloc(3 * nf * sizeof *mix);
    uint8_t *observed = malloc(nf);
    for (size_t f = 0; f < nf; f++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(m, f, &c, &n, &a);
        vis[f] = c.x < -0.05 ? 0 : c.x > 0.05 ? 1 : 0.5f;
        observed[f] = 1;
        const double rho[3] = {c.y > 2 ? 0.6 : 0.3, c.y > 2 ? 0.5 : 0.3, c.y > 2 ? 0.4 : 0.3};
        for (int ch = 0; ch < 3; ch++) {
            E[3 * f + ch] = (3.0 + 0.05 * c.x + 0.2 * ch) * (1 + 0.1 * sin(c.y)); /* smooth, varies */
            double lit = rho[ch] / M_PI * (E[3 * f + ch] + D[ch] * sin(el) * 1.0);
            double dark = rho[ch] / M_PI * E[3 * f + ch];
            mix[3 * f + ch] = 0.5 * (lit + dark);
            L[3 * f + ch] = rho[ch] / M_PI * (E[3 * f + ch] + D[ch] * sin(el) * vis[f]);
            L[3 * f + ch] *= 1 + 0.02 * noise((uint32_t)(3 * f + ch));
        }
        if (fabs(c.x) < 0.15)
            for (int ch = 0; ch < 3; ch++) L[3 * f + ch] = mix[3 * f + ch];
    }
    rs_sunshadow_input in = {
        .mesh = m, .vis = vis, .sun_dir = s, .E = E, .L = L, .observed = observed, .margin = 0.3, .radius = 0.9};
    rs_sunshadow out;
    assert_int_equal(rs_sunshadow_estimate(&in, &out, NULL), 0);
    print_message("DNI %.4f %.4f %.4f (true %.1f %.1f %.1f), sigma %.4f; %zu lit (%zu paired), %zu shadowed, %zu "
                  "blocks\n",
                  out.dni[0], out.dni[1], out.dni[2], D[0], D[1], D[2], out.sigma_lum, out.lit, out.lit_used,
                  out.shadowed, out.blocks);
    for (int ch = 0; ch < 3; ch++) assert_true(fabs(out.dni[ch] - D[ch]) < 0.02 * D[ch]);
    double dl = 0.2126 * D[0] + 0.7152 * D[1] + 0.0722 * D[2];
    assert_true(out.sigma_lum > 0 && out.sigma_lum < 0.05 * dl);
    assert_true(out.blocks >= 3);
    assert_true(out.sigma_sys_lum == 0);
    /* E's uncertainty carries into D: hypot(r c, c) / cos_i with r = Y_lit / Y_dark in [1, 3]. */
    const double c = 0.1;
    double *esig = malloc(nf * sizeof *esig);
    for (size_t f = 0; f < nf; f++) esig[f] = c;
    in.E_sigma = esig;
    assert_int_equal(rs_sunshadow_estimate(&in, &out, NULL), 0);
    print_message("sigma from E's: %.4f (bounds %.4f %.4f)\n", out.sigma_sys_lum, c * sqrt(2) / sin(el),
                  c * hypot(3, 1) / sin(el));
    assert_true(out.sigma_sys_lum >= c * sqrt(2) / sin(el) && out.sigma_sys_lum <= c * hypot(3, 1) / sin(el));
    assert_true(fabs(out.sigma_lum - hypot(out.sigma_stat_lum, out.sigma_sys_lum)) < 1e-12);
    in.E_sigma = NULL;
    free(esig);
    /* The margin matters: with none the bleeding facets pull the estimate down. */
    in.margin = 0;
    assert_int_equal(rs_sunshadow_estimate(&in, &out, NULL), 0);
    print_message("without the margin: DNI %.4f %.4f %.4f\n", out.dni[0], out.dni[1], out.dni[2]);
    /* Bad values (NaN and infinite E, zero and negative radiance, NaN visibility, a NaN
     * uncertainty) leave their facets out; the rest still gives the estimate. */
    in.margin = 0.3;
    for (size_t f = 0; f < nf; f += 7) {
        E[3 * f + (f % 3)] = (f % 2) ? NAN : INFINITY;
        L[3 * f + (f / 7) % 3] = (f % 3) ? 0 : -1; /* one channel of the facet */
    }
    for (size_t f = 0; f < nf; f += 2003) vis[f] = NAN; /* few: unknown ones count as neither kind */
    double *nan_sigma = malloc(nf * sizeof *nan_sigma);
    for (size_t f = 0; f < nf; f++) nan_sigma[f] = (f % 11) ? 0.01 : NAN;
    in.E_sigma = nan_sigma;
    assert_int_equal(rs_sunshadow_estimate(&in, &out, NULL), 0);
    print_message("with bad values: DNI %.4f %.4f %.4f, sigma %.4f\n", out.dni[0], out.dni[1], out.dni[2],
                  out.sigma_lum);
    for (int ch = 0; ch < 3; ch++) assert_true(fabs(out.dni[ch] - D[ch]) < 0.03 * D[ch]);
    assert_true(isfinite(out.sigma_lum));
    in.E_sigma = NULL;
    free(nan_sigma);
    /* Nothing observed: no margin to size the search by, no estimate. */
    memset(observed, 0, nf);
    in.margin = rs_sunshadow_margin(m, observed, rs_v3_make(0, 0, 1.6), 512);
    in.radius = 3 * in.margin;
    assert_true(in.margin == 0);
    assert_int_equal(rs_sunshadow_estimate(&in, &out, NULL), 1);
    memset(observed, 1, nf);
    in.margin = 0.3;
    in.radius = 0.9;
    /* No shadow at all: no estimate. */
    for (size_t f = 0; f < nf; f++) vis[f] = 1;
    in.margin = 0.3;
    assert_int_equal(rs_sunshadow_estimate(&in, &out, NULL), 1);
    assert_int_equal(out.lit_used, 0);
    free(vis);
    free(E);
    free(L);
    free(mix);
    free(observed);
    rs_mesh_free(m);
}

/* sun_from_shadows = on where nothing is shadowed: the sun keeps what the panorama held of
 * its removed disc (DNI and colour), rather than vanishing. */
static void test_fallback(void **state)
{
    (void)state;
    rs_meshgen g = rs_meshgen_new(1000, 2000);
    rs_meshgen_rect(&g, rs_v3_make(-5, -5, 0), rs_v3_make(10, 0, 0), rs_v3_make(0, 10, 0), 20, 20);
    rs_mesh *m = rs_meshgen_done(&g);
    size_t nf = m->nfaces;
    float *vis = malloc(nf * sizeof *vis);
    double *L = malloc(3 * nf * sizeof *L);
    uint8_t *observed = malloc(nf);
    rs_facet_gather *fg = calloc(nf, sizeof *fg);
    for (size_t f = 0; f < nf; f++) {
        vis[f] = 1; /* all in the sun */
        observed[f] = 1;
        for (int ch = 0; ch < 3; ch++) {
            L[3 * f + ch] = 1;
            fg[f].esky[ch] = 3;
        }
    }
    rs_sunsource sun = {.active = 1,
                        .from_shadows = 1,
                        .dir_world = rs_v3_make(0.6, 0, 0.8),
                        .removed_power = 6.0,
                        .removed_rgb = {9.0, 5.5, 2.0}};
    assert_int_equal(rs_sunsource_from_shadows(&sun, m, vis, fg, L, observed, rs_v3_make(0, 0, 1.6), 512, NULL), 0);
    print_message("no shadow: rc %d, DNI %.3f, colour %.3f %.3f %.3f\n", sun.shadow_rc, sun.dni, sun.rgb[0], sun.rgb[1],
                  sun.rgb[2]);
    assert_int_equal(sun.shadow_rc, 1);
    assert_true(sun.fell_back);
    assert_true(sun.dni == 6.0);
    assert_true(fabs(sun.rgb[0] - 1.5) < 1e-12 && fabs(sun.rgb[2] - 2.0 / 6) < 1e-12);
    /* Applied, it is measured light (the panorama's), not filled: E_sky gains dni rgb cos. */
    rs_err err;
    rs_scene *scene = rs_scene_new(m, &err);
    assert_non_null(scene);
    rs_sunsource_apply(&sun, scene, nf, vis, fg);
    assert_true(fabs(fg[0].esky[0] - (3 + 6.0 * 1.5 * 0.8)) < 1e-9);
    assert_true(fg[0].filled_lum == 0 && fg[0].fill_sigma_lum == 0);
    rs_scene_free(scene);
    sun.removed_power = 0; /* a hidden sun: nothing to fall back on */
    sun.fell_back = 0;
    assert_int_equal(rs_sunsource_from_shadows(&sun, m, vis, fg, L, observed, rs_v3_make(0, 0, 1.6), 512, &err), 0);
    assert_true(!sun.fell_back && sun.dni == 0);
    free(vis);
    free(L);
    free(observed);
    free(fg);
    rs_mesh_free(m);
}

#define W          1024
#define SUN_EL_DEG 30.0
#define L_SKY      1.0
#define L_FAR      0.3 /* the ground beyond the model */
#define DNI        20.0
#define WALL_X     3.0
#define WALL_H     6.0

static double albedo[3] = {0.5, 0.4, 0.3}; /* the ground's; test_cues_disagree darkens it */

/* The sky: 1, or with glow the CIE clear sky (standard type 12: Perez a..e = -1, -0.32, 10,
 * -3, 0.45) around the sun at azimuth glow_az, 1 at the zenith: the circumsolar glow tells the
 * sky model where a clear sky's sun is. */
typedef struct {
    int glow;
    double glow_az;
} sky_glow;

static double sky_radiance(rs_v3 d, const void *ctx)
{
    static const double cie12[5] = {-1, -0.32, 10, -3, 0.45};
    const sky_glow *g = ctx;
    double el = SUN_EL_DEG * M_PI / 180;
    double cosang = (d.x * cos(g->glow_az) + d.y * sin(g->glow_az)) * cos(el) + d.z * sin(el);
    if (!g->glow) return L_SKY;
    return L_SKY * rs_skymodel_perez(cie12, d.z, acos(fmax(-1, fmin(1, cosang)))) /
        rs_skymodel_perez(cie12, 1, M_PI / 2 - el);
}

/* The panorama from (0, 0, 1.6): sky, far ground, the black wall (x = 3, y in [-10, 10], z in
 * [0, 6]), and the ground (x in [-14, 3], y in [-10, 10]) at ground[3 f..] of the facet facet_id
 * gives (NULL: 0.2, what the first run reads does not depend on it: flat ground sees no ground). */
static void write_pano(const char *dir, const rs_image *facet_id, const double *ground, int glow, double glow_az)
{
    sky_glow g = {glow, glow_az};
    rs_fx_wall_ground_view view = {
        {-14, WALL_X, -10, 10, WALL_X, -10, 10, WALL_H}, {0, 0, 1.6}, sky_radiance, &g, L_FAR, 0};
    rs_fx_write_wall_ground_pano(dir, W, &view, facet_id, ground);
}

#define SCENE_TAIL "skip_unseen = false\n[sky]\nfill = row\n"
#define SUN_GIVEN  "sun_azimuth_deg = 0\nsun_elevation_deg = 30\n"

/* The ground and the wall (10 m wide, narrower than the ground, so that the shadow has side
 * edges that fix the sun's azimuth); a clear sky around the sun when there is one. A first
 * run with the sun's DNI given (0: no sun, no glow) computes
 * every facet's E_sky + G; the panorama is then rendered from it with the known albedo, and the
 * config left with or without the sun's direction. model_fill: the first run fills the hidden sky
 * with the model (around the given sun), else by rows. Returns the mesh, and the first run's E_sky. */
static rs_mesh *hidden_sun_scene(const char *dir, double dni, int keep_direction, double glow_az, int model_fill,
                                 double **esky_given)
{
    rs_meshgen g = rs_meshgen_new(20000, 20000);
    rs_meshgen_rect(&g, rs_v3_make(-14, -10, 0), rs_v3_make(17, 0, 0), rs_v3_make(0, 20, 0), 68, 80);
    rs_meshgen_rect(&g, rs_v3_make(WALL_X, -5, 0), rs_v3_make(0, 0, WALL_H), rs_v3_make(0, 10, 0), 12, 20);
    rs_mesh *m = rs_meshgen_done(&g);
    rs_meshgen_write(m, rs_test_path(dir, "mesh.ply"));
    rs_err err;
    write_pano(dir, NULL, NULL, dni > 0, glow_az);
    rs_fx_write_scene_ini(dir, "0 0 1.6", 128, 16, SCENE_TAIL SUN_GIVEN);
    char sets[256];
    /* This run only makes the truth (the ground's radiance from its E): its panorama's ground is
     * a placeholder, so the hidden sky's brightness must not be read from the facets. */
    snprintf(sets, sizeof sets, "--set sky.sun_irradiance=%g --set sky.fill_from_facets=off%s", dni,
             model_fill ? " --set sky.fill=model" : "");
    rs_test_rhoscan(dir, sets);
    size_t nf;
    double *e = rs_test_read_irradiance(dir, 1, &nf);
    *esky_given = rs_test_read_irradiance(dir, 0, &nf);
    assert_int_equal(nf, m->nfaces);
    double *ground = malloc(3 * nf * sizeof *ground);
    for (size_t f = 0; f < nf; f++)
        for (int ch = 0; ch < 3; ch++) ground[3 * f + ch] = albedo[ch] / M_PI * e[3 * f + ch];
    rs_image *ids = rs_image_read(rs_test_path(dir, "work/facet_id.exr"), &err);
    assert_non_null(ids);
    write_pano(dir, ids, ground, dni > 0, glow_az);
    rs_image_free(ids);
    free(e);
    free(ground);
    rs_fx_write_scene_ini(dir, "0 0 1.6", 128, 16, keep_direction ? SCENE_TAIL SUN_GIVEN : SCENE_TAIL);
    return m;
}

/* Sum of the green E_sky of the sunlit ground (x < -9: beyond the shadow's end at
 * 3 - 6 cot 30 = -7.4) in the latest run. */
static double sunlit_ground(const char *dir, const rs_mesh *m)
{
    size_t nf;
    double *e = rs_test_read_irradiance(dir, 0, &nf), sum = 0;
    for (size_t f = 0; f < nf; f++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(m, f, &c, &n, &a);
        if (c.x <= -9 && c.z < 0.01) sum += e[3 * f + 1];
    }
    free(e);
    return sum;
}

static double given_sunlit_ground(const rs_mesh *m, const double *esky)
{
    double sum = 0;
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(m, f, &c, &n, &a);
        if (c.x <= -9 && c.z < 0.01) sum += esky[3 * f + 1];
    }
    return sum;
}

/* The direction given, the DNI from the shadows; off leaves the sun out. */
static void test_hidden_sun(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("sunshadow");
    double *esky1;
    rs_mesh *m = hidden_sun_scene(dir, DNI, 1, 0, 0, &esky1);
    rs_test_rhoscan(dir, "--set sky.sun_from_shadows=auto");
    const char *json = rs_test_path(dir, "work/irradiance.json");
    double dni = rs_test_json_number(json, "direct_normal_irradiance"), sigma = rs_test_json_number(json, "sigma"),
           stat = rs_test_json_number(json, "sigma_statistical");
    print_message("DNI from the shadows %.4f +- %.4f, statistical %.4f (true %g)\n", dni, sigma, stat, DNI);
    assert_true(fabs(dni - DNI) < 0.02 * DNI);
    assert_true(stat > 0 && stat < 0.05 * DNI && sigma >= stat);
    double s1 = given_sunlit_ground(m, esky1), s2 = sunlit_ground(dir, m);
    print_message("sunlit ground E_sky: DNI given %.4f, from the shadows %.4f\n", s1, s2);
    assert_true(fabs(s2 - s1) < 0.02 * s1);
    rs_test_rhoscan(dir, "--set sky.sun_from_shadows=off");
    assert_true(sunlit_ground(dir, m) < 0.5 * s1);
    free(esky1);
    rs_mesh_free(m);
    rs_test_rmtree(dir);
}

/* Nothing places the sun: the shadows give its direction, within 2 degrees, and its DNI. */
static void test_searched_sun(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("sunshadow");
    double *esky1;
    rs_mesh *m = hidden_sun_scene(dir, DNI, 0, 0, 0, &esky1);
    rs_test_rhoscan(dir, "");
    const char *json = rs_test_path(dir, "work/irradiance.json");
    double dni = rs_test_json_number(json, "direct_normal_irradiance");
    const struct cJSON *doc = rs_test_json_file(json);
    assert_string_equal(rs_test_json_str(doc, "direction_from"), "shadows");
    double d[3];
    rs_test_json_vec3(doc, "explicit_sun/direction", d);
    double el = SUN_EL_DEG * M_PI / 180, ang = acos(fmin(1, d[0] * cos(el) + d[2] * sin(el))) * 180 / M_PI;
    double s1 = given_sunlit_ground(m, esky1), s2 = sunlit_ground(dir, m);
    print_message("searched sun %.2f deg from the true one, DNI %.4f (true %g); sunlit ground E_sky %.4f against "
                  "%.4f\n",
                  ang, dni, DNI, s2, s1);
    assert_true(ang < 2);
    assert_true(fabs(dni - DNI) < 0.05 * DNI);
    assert_true(fabs(s2 - s1) < 0.02 * s1);
    free(esky1);
    rs_mesh_free(m);
    rs_test_rmtree(dir);
}

/* The model fill, the panorama rendered with the model's sky around the sun given: with nothing
 * placing the sun, the sky's glow (10 degrees of azimuth from the sun that casts the shadows)
 * puts the first fit's sun elsewhere; the map is fitted again around the searched sun
 * (sun_direction, the model's, moves onto it), and the DNI is the one the first run had. */
static void test_searched_sun_refits_model(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("sunshadow");
    double *esky1;
    rs_mesh *m = hidden_sun_scene(dir, DNI, 0, 10 * M_PI / 180, 1, &esky1);
    rs_test_rhoscan(dir, "--set sky.fill=model");
    const char *json = rs_test_path(dir, "work/irradiance.json");
    double off = rs_test_json_number(json, "search_off_sky_estimate_deg");
    double dni = rs_test_json_number(json, "direct_normal_irradiance");
    const struct cJSON *doc = rs_test_json_file(json);
    double d[3];
    rs_test_json_vec3(doc, "sun_direction", d);
    double el = SUN_EL_DEG * M_PI / 180, ang = acos(fmin(1, d[0] * cos(el) + d[2] * sin(el))) * 180 / M_PI;
    print_message("model fill: the glow put the sun %.1f deg from the searched one; the refitted model's sun is "
                  "%.2f deg from the true one; DNI %.4f (true %g)\n",
                  off, ang, dni, DNI);
    assert_string_equal(rs_test_json_str(doc, "sun_source"), "shadows");
    assert_true(off > 4); /* the first fit's sun was elsewhere: the refit moved it */
    assert_true(ang < 2);
    assert_true(fabs(dni - DNI) < 0.02 * DNI);
    free(esky1);
    rs_mesh_free(m);
    rs_test_rmtree(dir);
}

/* No sun at all (an overcast sky): the search adds none, with the row fill (its own tests
 * alone) and with the model fill (whose Perez fit finds no circumsolar glow: not searched). */
static void test_no_sun_to_find(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("sunshadow");
    double *esky1;
    rs_mesh *m = hidden_sun_scene(dir, 0, 0, 0, 0, &esky1);
    for (int model = 0; model < 2; model++) {
        rs_test_rhoscan(dir, model ? "--set sky.fill=model" : "");
        const char *buf = rs_test_read_text(rs_test_path(dir, "work/irradiance.json"));
        assert_null(strstr(buf, "\"explicit_sun\""));
        assert_true(!model || strstr(buf, "no circumsolar glow"));
        if (model) continue; /* the model fills the hidden sky its own way: only the row fill compares */
        double s1 = given_sunlit_ground(m, esky1), s2 = sunlit_ground(dir, m);
        print_message("overcast, row fill: no sun; open ground E_sky %.4f against %.4f\n", s2, s1);
        assert_true(fabs(s2 - s1) < 0.01 * s1);
    }
    free(esky1);
    rs_mesh_free(m);
    rs_test_rmtree(dir);
}

/* Shadows of a sun at azimuth 0 under a sky whose glow says azimuth 180 (the cues disagree).
 * On dark ground (albedo 0.1, 0.08, 0.06: below 1 without the sun even where it shines) nothing
 * says that light is missing: no sun is added, and the summary says why. On the brighter ground
 * (0.5 0.4 0.3) the sunlit facets come out with albedo above 1 without it, light no sky the
 * cameras saw can give: the sun is added where the shadows put it. */
static void test_cues_disagree(void **state)
{
    (void)state;
    const double bright[3] = {0.5, 0.4, 0.3}, dark[3] = {0.1, 0.08, 0.06};
    for (int variant = 0; variant < 2; variant++) {
        for (int ch = 0; ch < 3; ch++) albedo[ch] = variant ? bright[ch] : dark[ch];
        const char *dir = rs_test_tmpdir("sunshadow");
        double *esky1;
        rs_mesh *m = hidden_sun_scene(dir, DNI, 0, M_PI, 0, &esky1);
        rs_test_rhoscan(dir, "");
        const char *json = rs_test_path(dir, "work/irradiance.json");
        const char *buf = rs_test_read_text(json);
        print_message("%s ground: %s\n", variant ? "bright" : "dark",
                      strstr(buf, "\"explicit_sun\"") ? "sun added" : "no sun");
        if (!variant) {
            assert_null(strstr(buf, "\"explicit_sun\""));
            assert_non_null(strstr(buf, "from where the visible sky puts the sun"));
        } else {
            const struct cJSON *doc = rs_test_json_file(json);
            assert_string_equal(rs_test_json_str(doc, "direction_from"), "shadows");
            double d[3], el = SUN_EL_DEG * M_PI / 180;
            rs_test_json_vec3(doc, "explicit_sun/direction", d);
            double ang = acos(fmin(1, d[0] * cos(el) + d[2] * sin(el))) * 180 / M_PI;
            print_message("missing light: the sun added %.2f deg from the true one\n", ang);
            assert_true(ang < 2);
            assert_non_null(strstr(buf, "\"missing_light\":\ttrue"));
        }
        free(esky1);
        rs_mesh_free(m);
        rs_test_rmtree(dir);
    }
    for (int ch = 0; ch < 3; ch++) albedo[ch] = bright[ch];
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_estimator), cmocka_unit_test(test_fallback),
             cmocka_unit_test(test_hidden_sun), cmocka_unit_test(test_searched_sun),
             cmocka_unit_test(test_searched_sun_refits_model), cmocka_unit_test(test_no_sun_to_find),
             cmocka_unit_test(test_cues_disagree))
