/* render_uncertainty: sky_filled and albedo_sigma_rel painted over the camera's view
 * (see render_uncertainty.h). */
#include "stages/render/render_uncertainty.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "common/faceprop.h"
#include "pipeline/stage.h"

static const char *const names[2] = {"sky_filled", "albedo_sigma"};
static const char *const props[2] = {"sky_filled", "albedo_sigma_rel"};
static const double full[2] = {RS_RENDER_SKY_FILLED_FULL, RS_RENDER_SIGMA_REL_FULL};

static int write_one(const rs_config *cfg, const double *v, size_t nf, const rs_image *ids, int which, rs_err *err)
{
    char path[4096], file[64], note[160];
    int w = ids->width, h = ids->height, rc = -1;
    rs_image *raw = rs_image_new(w, h, 1), *col = rs_image_new(w, h, 3);
    float *ramp = malloc(3 * nf * sizeof *ramp);
    if (!raw || !col || !ramp) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the %s image", names[which]);
        goto out;
    }
    /* The colour once per facet: per pixel, its sRGB decoding was a tenth of the stage (perf). */
    for (size_t f = 0; f < nf; f++) rs_image_ramp(v[f] / full[which], ramp + 3 * f);
    size_t npx = (size_t)w * h;
    for (size_t k = 0; k < npx; k++) {
        float id = ids->data[k];
        float *c = col->data + 3 * k;
        if (!(id >= 0 && id < (float)nf)) {
            raw->data[k] = -1;
            c[0] = c[1] = c[2] = 0.02f; /* dark grey: no facet (sky, or outside the model) */
            continue;
        }
        raw->data[k] = (float)v[(size_t)id];
        memcpy(c, ramp + 3 * (size_t)id, 3 * sizeof *c);
    }
    static const char *const y[1] = {"Y"};
    snprintf(file, sizeof file, "%s.exr", names[which]);
    snprintf(note, sizeof note, "rhoscan render: per-facet %s in the camera's view; -1 where no facet", props[which]);
    if (rs_image_write_exr(raw, rs_work_path(cfg, file, path, sizeof path), y, 0, note, err) != 0) goto out;
    snprintf(file, sizeof file, "%s.png", names[which]);
    if (rs_image_write_png(col, rs_work_path(cfg, file, path, sizeof path), 1.0f, err) != 0) goto out;
    rc = 0;
out:
    free(ramp);
    rs_image_free(raw);
    rs_image_free(col);
    return rc;
}

int rs_render_uncertainty_images(const rs_config *cfg, const rs_ply *alb, const char *file, size_t nf,
                                 const rs_image *ids, rs_err *err)
{
    const rs_ply_element *fe = rs_ply_find_element(alb, "face");
    if (!fe || !rs_ply_find_prop(fe, props[0]) || !rs_ply_find_prop(fe, props[1])) {
        /* Older albedo.ply: no images, and none left from an earlier run to mislead. */
        char path[4096], name[64];
        for (int i = 0; i < 2; i++)
            for (int e = 0; e < 2; e++) {
                snprintf(name, sizeof name, "%s.%s", names[i], e ? "png" : "exr");
                unlink(rs_work_path(cfg, name, path, sizeof path));
            }
        return 0;
    }
    double *v[2] = {malloc((nf ? nf : 1) * sizeof(double)), malloc((nf ? nf : 1) * sizeof(double))}; /* props[] */
    int rc = 1;
    if (!v[0] || !v[1]) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        rc = -1;
    }
    for (int i = 0; i < 2 && rc == 1; i++)
        if (rs_faceprop_get(alb, file, props[i], nf, v[i], err) != 0) rc = -1;
    /* The two images on both threads: written one after the other they left the second core
     * idle for a fifth of the render stage (perf). */
    rs_err werr[2];
    int wrc[2] = {0, 0};
    if (rc == 1) {
#pragma omp parallel for schedule(static, 1)
        for (int i = 0; i < 2; i++) {
            memset(&werr[i], 0, sizeof werr[i]);
            wrc[i] = write_one(cfg, v[i], nf, ids, i, &werr[i]);
        }
        for (int i = 0; i < 2 && rc == 1; i++)
            if (wrc[i] != 0) {
                if (err) *err = werr[i];
                rc = -1;
            }
    }
    free(v[0]);
    free(v[1]);
    return rc;
}
