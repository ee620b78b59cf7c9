/* test_sky_range: a float panorama spanning eight orders of magnitude (a sun of 1e5 over a sky
 * of 1 and shadows of 1e-3): the sky map, its sampling tables and the gather stay finite and
 * the irradiance of an open facet matches the exact sum over the map's pixels; a sky scaled
 * to 1e30 per pixel (float range) does not overflow. */
#include "tests/stress/stress.h"

#include "common/pano.h"
#include "tests/fixtures.h"

/* E of an upward facet with nothing above it, for the panorama: the exact sum of L cos dOmega
 * over the map's upper hemisphere, in double. */
static double exact_E(const rs_image *pano)
{
    double E = 0;
    for (int r = 0; r < pano->height; r++)
        for (int c = 0; c < pano->width; c++) {
            rs_v3 d = rs_pano_pixel_dir(pano->width, pano->height, c, r);
            if (d.z > 0)
                E += rs_image_px(pano, c, r)[0] * rs_pano_pixel_solid_angle(pano->width, pano->height, r) * d.z;
        }
    return E;
}

static double gather_E(const rs_image *src, float scale, double *expect)
{
    int w = src->width, h = src->height;
    rs_capture cap = rs_fx_capture(w, h, NULL, NULL);
    for (size_t k = 0; k < 3 * (size_t)w * h; k++) cap.pano->data[k] = src->data[k] * scale;
    *expect = exact_E(cap.pano);
    rs_skyenv env;
    rs_fx_sky_env(&cap, 0.01, 1, &env);
    rs_mesh *m = rs_fx_unit_square();
    rs_scene *scene = rs_fx_scene(m);
    rs_gather_ctx gc = {.scene = scene, .env = &env, .samples = 256, .sky_samples = 512, .sun_samples = 64, .seed = 1};
    rs_gather_scratch *s = rs_gather_scratch_new(512);
    rs_facet_gather out;
    assert_int_equal(rs_gather_facet(&gc, 0, s, &out), 0);
    for (int ch = 0; ch < 3; ch++) assert_true(isfinite(out.esky[ch]));
    double E = out.esky[0];
    free(out.entries);
    rs_gather_scratch_free(s);
    rs_fx_release(&env, &cap, scene, m);
    return E;
}

static void test_sun_over_shadows(void **state)
{
    int w = 1024, h = 512;
    rs_image *pano = rs_image_new(w, h, 3);
    /* Sky of 1 with a gradient, shadows of 1e-3 below the horizon and in a band of the sky,
     * and a sun of 1e5 (a 3 x 3 pixel disc) at 40 degrees elevation. */
    for (int r = 0; r < h; r++)
        for (int c = 0; c < w; c++) {
            float v = r < h / 2 ? 0.5f + (float)r / h : 1e-3f;
            if (r > h / 4 && r < h / 4 + 20 && c < w / 3) v = 1e-3f;
            float *p = rs_image_px(pano, c, r);
            p[0] = p[1] = p[2] = v;
        }
    int sr = (int)(h * 50.0 / 180), sc = w / 2;
    for (int dr = -1; dr <= 1; dr++)
        for (int dc = -1; dc <= 1; dc++) {
            float *p = rs_image_px(pano, sc + dc, sr + dr);
            p[0] = p[1] = p[2] = 1e5f;
        }
    double expect;
    double E = gather_E(pano, 1.0f, &expect);
    print_message("dynamic range 1e8: E = %.6g, exact %.6g (%.2g relative)\n", E, expect, E / expect - 1);
    /* Sun and sky sampled separately: the sun's part is exact up to its pixels' cosine spread,
     * the sky's carries the sampling error of 768 rays on a smooth map (well under 1 %). */
    assert_true(fabs(E / expect - 1) < 0.01);

    /* The same sky times 1e33 (the sun at 1e38, near FLT_MAX): no overflow anywhere. */
    double expect_big;
    double Ebig = gather_E(pano, 1e33f, &expect_big);
    print_message("scaled by 1e33: E = %.6g, exact %.6g\n", Ebig, expect_big);
    assert_true(isfinite(Ebig));
    assert_true(fabs(Ebig / expect_big - E / expect) < 1e-6); /* the same relative result */
    rs_image_free(pano);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_sun_over_shadows))
