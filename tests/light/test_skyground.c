/* [sky] ground_albedo_from: the ground beyond the model, below the horizon where no camera saw
 * ground near, takes the albedo of the scan's own ground under the completed sky.
 * A 20 x 20 m ground with a wall on its east edge that faces out, over ground the scan does not
 * hold, under a uniform sky. A first run (ground_albedo_from = config) gives every ground facet's
 * E; the panorama is rendered from it with a known albedo. Then:
 * - the estimate (scan) gives that albedo back within 0.5 % per channel;
 * - the outward wall's E_sky is then that of a run given the albedo, and not that of the
 *   default 0.2 (so the wall does see the ground model);
 * - with an explicit sun the estimate is skipped, says why, and the ground copies the camera's
 *   far ground as before the ground model. */
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

#define W      512
#define L_SKY  1.0
#define L_FAR  0.3 /* measured ground beyond the model, seen at grazing angles */
#define L_WALL 0.25
#define EDGE   10.0 /* the ground spans [-EDGE, EDGE]^2; the wall stands at x = EDGE */
#define WALL_H 8.0

static const double albedo[3] = {0.45, 0.4, 0.3};

static double uniform_sky(rs_v3 d, const void *ctx)
{
    (void)d, (void)ctx;
    return L_SKY;
}

/* The camera at (0, 0, 1.6): sky, far ground, the wall, and the model's ground. */
static const rs_fx_wall_ground_view view = {
    {-EDGE, EDGE, -EDGE, EDGE, EDGE, -5, 5, WALL_H}, {0, 0, 1.6}, uniform_sky, NULL, L_FAR, L_WALL};

/* Green E_sky summed over the outward wall's facets (from wall0 on). */
static double wall_esky(const char *dir, size_t nf, size_t wall0)
{
    size_t n;
    double *e = rs_test_read_irradiance(dir, 0, &n), sum = 0;
    assert_int_equal(n, nf);
    for (size_t f = wall0; f < nf; f++) sum += e[3 * f + 1];
    free(e);
    return sum;
}

static void test_ground_albedo_from_scan(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("skyground");
    rs_meshgen g = rs_meshgen_new(10000, 10000);
    rs_meshgen_rect(&g, rs_v3_make(-EDGE, -EDGE, 0), rs_v3_make(2 * EDGE, 0, 0), rs_v3_make(0, 2 * EDGE, 0), 40, 40);
    /* e1 x e2 = +x: the wall faces out, over the ground the model does not hold. */
    size_t wall0 = rs_meshgen_rect(&g, rs_v3_make(EDGE, -5, 0), rs_v3_make(0, 10, 0), rs_v3_make(0, 0, WALL_H), 10, 8);
    rs_mesh *m = rs_meshgen_done(&g);
    size_t nf = m->nfaces;
    rs_meshgen_write(m, rs_test_path(dir, "mesh.ply"));
    rs_fx_write_wall_ground_pano(dir, W, &view, NULL, NULL);
    rs_fx_write_scene_ini(dir, "0 0 1.6", 128, 16, "skip_unseen = false\n[sky]\nfill = model\n");
    rs_test_rhoscan(dir, "--set sky.ground_albedo_from=config");
    size_t n;
    double *e = rs_test_read_irradiance(dir, 1, &n), *ground = calloc(3 * nf, sizeof *ground);
    assert_int_equal(n, nf);
    for (size_t f = 0; f < wall0; f++)
        for (int ch = 0; ch < 3; ch++) ground[3 * f + ch] = albedo[ch] / M_PI * e[3 * f + ch];
    rs_err err;
    rs_image *ids = rs_image_read(rs_test_path(dir, "work/facet_id.exr"), &err);
    assert_non_null(ids);
    rs_fx_write_wall_ground_pano(dir, W, &view, ids, ground);
    rs_image_free(ids);

    rs_test_rhoscan(dir, "");
    const char *json = rs_test_path(dir, "work/irradiance.json");
    const char *buf = rs_test_read_text(json);
    const struct cJSON *doc = rs_test_json_text(buf);
    assert_string_equal(rs_test_json_str(doc, "sky_ground_albedo_from"), "scan");
    double a[3];
    rs_test_json_vec3(doc, "sky_ground_albedo", a);
    double pixels = rs_test_json_number(json, "sky_ground_model_pixels");
    double used = rs_test_json_number(json, "sky_ground_albedo_facets");
    double left_out = rs_test_json_number(json, "sky_ground_albedo_left_out");
    print_message("from %g ground facets; %g left out for seeing facets no camera saw\n", used, left_out);
    assert_true(left_out > 0 && used >= 30); /* the wall's back, which the camera sees, is not observed */
    print_message("ground albedo from the scan %.4f %.4f %.4f (true %g %g %g), %g map pixels of ground model\n", a[0],
                  a[1], a[2], albedo[0], albedo[1], albedo[2], pixels);
    for (int ch = 0; ch < 3; ch++) assert_true(fabs(a[ch] - albedo[ch]) < 0.005 * albedo[ch]);
    assert_true(pixels > 0);
    double scan = wall_esky(dir, nf, wall0);

    /* The same albedo given (grey, so the green channel's), and the default. */
    rs_test_rhoscan(dir, "--set sky.ground_albedo_from=config --set sky.ground_albedo=0.4");
    double given = wall_esky(dir, nf, wall0);
    rs_test_rhoscan(dir, "--set sky.ground_albedo_from=config");
    double dflt = wall_esky(dir, nf, wall0);
    print_message("outward wall's green E_sky: from the scan %.4f, albedo 0.4 given %.4f, default 0.2 %.4f\n", scan,
                  given, dflt);
    assert_true(fabs(scan - given) < 0.003 * given);
    assert_true(scan > 1.05 * dflt);

    /* An explicit sun comes after the gather: no estimate, the summary says why, and the unseen
     * ground copies the camera's far ground (L_FAR = 0.3, seen 0 to 9 degrees down) as before the
     * model. The sun stands behind the wall (azimuth 180), which so keeps its E_sky from the sky
     * and the ground: between the default's model ground (0.2 E_h / pi = 0.2) and the scan's
     * (0.4). */
    rs_test_rhoscan(dir, "--set sky.sun_irradiance=5 --set sky.sun_azimuth_deg=180 --set sky.sun_elevation_deg=40");
    buf = rs_test_read_text(json);
    assert_string_equal(rs_test_json_str(rs_test_json_text(buf), "sky_ground_albedo_from"), "measured ground");
    assert_non_null(strstr(buf, "an explicit sun is added after the gather"));
    double copied = wall_esky(dir, nf, wall0);
    print_message("with an explicit sun, the wall's green E_sky from the copied far ground %.4f\n", copied);
    assert_true(copied > 1.02 * dflt && copied < scan / 1.02);
    free(e);
    free(ground);
    rs_mesh_free(m);
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_ground_albedo_from_scan))
