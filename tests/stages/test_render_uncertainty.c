/* The render stage's uncertainty images (issue 8, part 4): sky_filled and albedo_sigma panoramas
 * exist after a run, hold each seen facet's value from albedo.ply (EXR raw, PNG on the ramp) and
 * -1 where no facet is seen; with an albedo.ply that lacks the properties they are not written. */
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "common/faceprop.h"
#include "common/image.h"
#include "common/mesh.h"
#include "stages/render/render_uncertainty.h"

static int exists(const char *dir, const char *name)
{
    char path[8192];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    return access(path, F_OK) == 0;
}

/* Compares image `name` (EXR) and its PNG with prop of albedo.ply over facet_id.exr. */
static void check_image(const char *work, const char *name, const char *prop, double full)
{
    char path[8192];
    rs_err err;
    snprintf(path, sizeof path, "%s/albedo.ply", work);
    rs_ply *alb = NULL;
    rs_mesh *m = rs_mesh_read(path, &alb, &err);
    if (!m) fail_msg("%s", err.msg);
    size_t nf = m->nfaces;
    double *v = malloc(nf * sizeof *v);
    assert_int_equal(rs_faceprop_get(alb, path, prop, nf, v, &err), 0);
    snprintf(path, sizeof path, "%s/facet_id.exr", work);
    rs_image *ids = rs_image_read(path, &err);
    if (!ids) fail_msg("%s", err.msg);
    snprintf(path, sizeof path, "%s/%s.exr", work, name);
    rs_image *raw = rs_image_read(path, &err);
    if (!raw) fail_msg("%s", err.msg);
    snprintf(path, sizeof path, "%s/%s.png", work, name);
    rs_image *png = rs_image_read(path, &err);
    if (!png) fail_msg("%s", err.msg);
    assert_int_equal(raw->width, ids->width);
    assert_int_equal(raw->height, ids->height);
    assert_int_equal(raw->channels, 1);
    assert_int_equal(png->width, ids->width);
    size_t npx = (size_t)ids->width * ids->height, seen = 0, bad_raw = 0, bad_png = 0, nonzero = 0;
    for (size_t k = 0; k < npx; k++) {
        float id = ids->data[k];
        if (!(id >= 0 && id < (float)nf)) {
            bad_raw += raw->data[k] != -1.0f;
            continue;
        }
        seen++;
        double x = v[(size_t)id];
        nonzero += x > 0;
        bad_raw += raw->data[k] != (float)x;
        float want[3];
        rs_image_ramp(x / full, want);
        /* 8-bit sRGB: compare in sRGB, one code value of slack */
        for (int ch = 0; ch < 3; ch++)
            if (fabsf(rs_linear_to_srgb(png->data[3 * k + ch]) - rs_linear_to_srgb(want[ch])) > 1.5f / 255) {
                bad_png++;
                break;
            }
    }
    print_message("%s: %zu facet pixels (%zu with a value > 0), %zu raw and %zu PNG mismatches\n", name, seen, nonzero,
                  bad_raw, bad_png);
    assert_true(seen > 1000);
    assert_true(nonzero > 0);
    assert_int_equal(bad_raw, 0);
    assert_int_equal(bad_png, 0);
    rs_image_free(png);
    rs_image_free(raw);
    rs_image_free(ids);
    free(v);
    rs_ply_free(alb);
    rs_mesh_free(m);
}

/* albedo.ply without two face properties (as written before they existed). */
static void strip_props(const char *work)
{
    char path[8192];
    rs_err err;
    snprintf(path, sizeof path, "%s/albedo.ply", work);
    rs_ply *ply = rs_ply_read(path, &err);
    if (!ply) fail_msg("%s", err.msg);
    rs_ply_element *fe = rs_ply_find_element(ply, "face");
    assert_non_null(fe);
    int kept = 0;
    for (int p = 0; p < fe->nprops; p++) {
        if (!strcmp(fe->props[p].name, "sky_filled") || !strcmp(fe->props[p].name, "albedo_sigma_rel")) {
            free(fe->props[p].data);
            free(fe->props[p].offsets);
            continue;
        }
        fe->props[kept++] = fe->props[p];
    }
    assert_int_equal(kept, fe->nprops - 2);
    fe->nprops = kept;
    if (rs_ply_write(ply, path, 1, &err) != 0) fail_msg("%s", err.msg);
    rs_ply_free(ply);
}

static void test_uncertainty_images(void **state)
{
    (void)state;
    const char *tmp = rs_test_tmpdir("render_unc");
    char cmd[8192], work[4096];
    snprintf(work, sizeof work, "%s/work", tmp);
    char *out = NULL;
    snprintf(cmd, sizeof cmd,
             "%s/rhoscan run %s/configs/two_planes.ini --set pipeline.workdir=%s "
             "--set irradiance.samples=32 --set irradiance.sky_samples=64 --set irradiance.sun_samples=16",
             rs_test_bin_dir(), rs_test_source_dir(), work);
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) fail_msg("rhoscan run: exit %d\n%s", rc, out);
    free(out);
    static const char *const files[] = {"sky_filled.exr", "sky_filled.png", "albedo_sigma.exr", "albedo_sigma.png"};
    for (int i = 0; i < 4; i++)
        if (!exists(work, files[i])) fail_msg("%s/%s was not written", work, files[i]);
    check_image(work, "sky_filled", "sky_filled", RS_RENDER_SKY_FILLED_FULL);
    check_image(work, "albedo_sigma", "albedo_sigma_rel", RS_RENDER_SIGMA_REL_FULL);

    /* An older albedo.ply: render runs, writes its other images and none of these. */
    strip_props(work);
    snprintf(cmd, sizeof cmd,
             "%s/rhoscan run --only render %s/configs/two_planes.ini --set pipeline.workdir=%s "
             "--set irradiance.samples=32 --set irradiance.sky_samples=64 --set irradiance.sun_samples=16",
             rs_test_bin_dir(), rs_test_source_dir(), work);
    out = NULL;
    rc = rs_test_run(cmd, &out);
    if (rc != 0) fail_msg("rhoscan run --only render on an older albedo.ply: exit %d\n%s", rc, out);
    free(out);
    assert_true(exists(work, "albedo.png"));
    for (int i = 0; i < 4; i++)
        if (exists(work, files[i])) fail_msg("%s/%s is there without the properties in albedo.ply", work, files[i]);
    rs_test_rmtree(tmp);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_uncertainty_images))
