/* [calib] grey_card_region: a grey floor of known albedo under a uniform sky. With the floor's
 * pixels consistent with the sky, pi L / (E_sky + G) over the region is the albedo (ratio 1);
 * with the object's pixels exposed 1.25 x brighter than the sky's, the ratio says 1.25. Bad
 * regions give errors that name the key. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/image.h"
#include "tests/fixtures.h"
#include "tests/meshgen.h"
#include "common/pano.h"
#include "common/ply.h"
#include "tests/testutil.h"

#define W      256
#define ALBEDO 0.18

/* A 40 x 40 m grey floor at z = 0; the camera 1.5 m above its centre; a uniform sky of radiance
 * 1, the floor at ALBEDO x pi x 1 / pi times object_gain (lower hemisphere). */
static void sky_over_floor(rs_v3 d, size_t k, double rgb[3], void *object_gain)
{
    (void)k;
    rgb[0] = rgb[1] = rgb[2] = d.z > 0 ? 1.0 : ALBEDO * *(const double *)object_gain;
}

static void write_scene(const char *dir, double object_gain)
{
    rs_meshgen g = rs_meshgen_new(2000, 2000);
    rs_meshgen_rect(&g, rs_v3_make(-20, -20, 0), rs_v3_make(40, 0, 0), rs_v3_make(0, 40, 0), 20, 20);
    rs_mesh *m = rs_meshgen_done(&g);
    rs_meshgen_write(m, rs_test_path(dir, "mesh.ply"));
    rs_mesh_free(m);
    rs_image *img = rs_fx_pano(W, W / 2, sky_over_floor, &object_gain);
    rs_fx_write_pano(img, dir);
    rs_image_free(img);
}

static int run(const char *dir, const char *region, char **out)
{
    char extra[1024], cmd[4096];
    snprintf(extra, sizeof extra, "[calib]\ngrey_card_region = %s\ngrey_card_albedo = %g\n", region, ALBEDO);
    rs_fx_write_scene_ini(dir, "0 0 1.5", 64, 0, extra);
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/rhoscan' run scene.ini", dir, rs_test_bin_dir());
    return rs_test_run(cmd, out);
}

/* The number after "key": in the JSON text (the first occurrence after "grey_card"). */
static double json_num(const char *json, const char *key)
{
    char path[128];
    snprintf(path, sizeof path, "grey_card/%s", key);
    return rs_test_json_num(rs_test_json_text(json), path);
}

static const char *read_json(const char *dir)
{
    static char buf[1 << 16];
    FILE *f = fopen(rs_test_path(dir, "work/reflectance.json"), "rb");
    assert_non_null(f);
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = 0;
    return buf;
}

static void test_grey_card(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("greycard");
    /* The card: the floor within about 20 deg of the nadir (rows 110..127 of 128). */
    char region[64];
    snprintf(region, sizeof region, "0 %d %d %d", W / 2 - 14, W, W / 2);
    char *out = NULL;
    const double gains[2] = {1.0, 1.25};
    for (int i = 0; i < 2; i++) {
        write_scene(dir, gains[i]);
        int rc = run(dir, region, &out);
        if (rc != 0) print_message("%s\n", out);
        assert_int_equal(rc, 0);
        free(out);
        const char *json = read_json(dir);
        double implied = json_num(json, "albedo_implied_luminance"), ratio = json_num(json, "consistency_ratio");
        double err_pp = json_num(json, "albedo_error_pp");
        print_message("object gain %.2f: pi L / E = %.4f, ratio %.4f, pipeline albedo error %.3f pp\n", gains[i],
                      implied, ratio, err_pp);
        assert_true(fabs(implied - ALBEDO * gains[i]) < 0.01 * ALBEDO * gains[i]);
        assert_true(fabs(ratio - gains[i]) < 0.01 * gains[i]);
        assert_true(fabs(err_pp - 100 * ALBEDO * (gains[i] - 1)) < 0.5);
        assert_true(json_num(json, "pixels") > 1000);
    }
    /* The region in the sky sees no facet; one past the panorama; one malformed. */
    const char *bad[3][2] = {{"0 0 256 10", "none of its pixels"},
                             {"0 0 300 10", "expected x1 <= 256"},
                             {"0 0 10", "expected 4 pixel indices"}};
    for (int i = 0; i < 3; i++) {
        assert_int_equal(run(dir, bad[i][0], &out), 1);
        print_message("%s\n", out);
        assert_non_null(strstr(out, "grey_card_region"));
        assert_non_null(strstr(out, bad[i][1]));
        free(out);
    }
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_grey_card))
