/* eval_view: the measures taken in the camera's view: coverage of the visible model, E_sky and G
 * against Cycles' pi * DiffDir and pi * DiffInd, the re-render against pano.exr, and the error image. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "tools/eval/eval_priv.h"
#include "common/fileio.h"

/* Relative error that the false-colour image shows as full red. */
#define ERROR_IMAGE_FULL_SCALE 0.2

static int write_error_images(const rs_image *rel, const rs_image *color, const char *out_dir, rs_err *err)
{
    char path[4096];
    const char *names[1] = {"Y"};
    if (rs_image_write_exr(rel, rs_path_join(path, sizeof path, out_dir, "eval_error.exr"), names, 0,
                           "rhoscan-eval: relative albedo error per pixel; -1 model not covered; 0 sky", err) != 0)
        return -1;
    return rs_image_write_png(color, rs_path_join(path, sizeof path, out_dir, "eval_error.png"), 1.0f, err);
}

static int has_albedo(const rs_image *dc, int x, int y)
{
    x = (x + dc->width) % dc->width; /* azimuth wraps */
    y = y < 0 ? 0 : y >= dc->height ? dc->height - 1 : y;
    const float *p = rs_image_px(dc, x, y);
    return isfinite(p[0] + p[1] + p[2]) && p[0] + p[1] + p[2] > 0;
}

/* A model pixel: DiffCol > 0 on it and its four neighbours. Cycles' pixel filter (Blackman-
 * Harris, 1.5 px) spreads DiffCol about a pixel beyond the silhouette into the sky; those
 * mixed pixels show the sky as much as the model and would count as uncovered model. */
static int is_model(const rs_image *dc, int x, int y)
{
    return has_albedo(dc, x, y) && has_albedo(dc, x - 1, y) && has_albedo(dc, x + 1, y) && has_albedo(dc, x, y - 1) &&
        has_albedo(dc, x, y + 1);
}

int rs_eval_camera(const ev *e, const uint8_t *good, rs_json *doc, const char *out_dir, double *part_gshare,
                   rs_err *err)
{
    int w = e->ids->width, h = e->ids->height, rc = -1;
    size_t npx = (size_t)w * h, nf = e->nf, np = (size_t)e->nparts;
    double *acc = calloc(3 * nf + 2 * np + 1, sizeof *acc);
    rs_image *rel = rs_image_new(w, h, 1), *color = rs_image_new(w, h, 3);
    if (!acc || !rel || !color) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the camera view");
        goto out;
    }
    double *n = acc, *sdd = acc + nf, *sdi = acc + 2 * nf, *pdd = acc + 3 * nf, *pdi = pdd + np;
    size_t model_px = 0, covered = 0, synth_px = 0;
    double sum_abs[3] = {0, 0, 0}, sum_obs[3] = {0, 0, 0};
    for (size_t k = 0; k < npx; k++) {
        const float *dc = e->dc->data + 3 * k, *pano = e->pano->data + 3 * k, *syn = e->synth->data + 3 * k;
        float id = e->ids->data[k];
        int valid = id >= 0 && id < (float)nf && id == floorf(id);
        size_t f = valid ? (size_t)id : 0;
        int model = is_model(e->dc, (int)(k % w), (int)(k / w));
        /* Truth irradiance: the passes hold E / pi (docs/DESIGN.md, section Reference scenes). Every pixel of a
         * facet counts, as in tests/playback/reference_scene.py's compare_irradiance. */
        double ddm = M_PI * (e->dd->data[3 * k] + e->dd->data[3 * k + 1] + e->dd->data[3 * k + 2]) / 3;
        double dim = M_PI * (e->di->data[3 * k] + e->di->data[3 * k + 1] + e->di->data[3 * k + 2]) / 3;
        if (valid && isfinite(ddm) && isfinite(dim)) {
            n[f] += 1;
            sdd[f] += ddm;
            sdi[f] += dim;
            int p = e->m.part[f];
            if (p >= 0 && model) {
                pdd[p] += ddm;
                pdi[p] += dim;
            }
        }
        float *col = rs_image_px(color, (int)(k % w), (int)(k / w));
        if (!model) {
            /* the sky, in grey, so that the image stays readable */
            double lum = isfinite(pano[0] + pano[1] + pano[2]) ? (pano[0] + pano[1] + pano[2]) / 3 : 0;
            lum = lum > 0 ? lum : 0;
            col[0] = col[1] = col[2] = rs_srgb_to_linear((float)(0.5 * lum / (lum + 1)));
            continue;
        }
        model_px++;
        const double *a = e->alb + 3 * f;
        if (valid && good[f] && isfinite(a[0] + a[1] + a[2])) {
            covered++;
            double r = 0;
            for (int c = 0; c < 3; c++) r += fabs(a[c] - dc[c]) / (dc[c] > 1e-6 ? dc[c] : 1e-6) / 3;
            rel->data[k] = (float)r;
            rs_image_ramp(r / ERROR_IMAGE_FULL_SCALE, col);
        } else {
            rel->data[k] = -1;
            col[0] = col[2] = 1;
            col[1] = 0;
        }
        if (valid && isfinite(pano[0] + pano[1] + pano[2]) && isfinite(syn[0] + syn[1] + syn[2])) {
            synth_px++;
            for (int c = 0; c < 3; c++) {
                sum_abs[c] += fabs(syn[c] - pano[c]);
                sum_obs[c] += pano[c];
            }
        }
    }
    rs_json *cov = rs_json_set_obj(doc, "coverage");
    rs_json_set_int(cov, "model_pixels", (long long)model_px);
    rs_json_set_int(cov, "covered_pixels", (long long)covered);
    rs_json_set_num(cov, "share", model_px ? (double)covered / model_px : 0);

    /* Per facet seen on at least 4 pixels and estimable: the pixel-weighted mean relative
     * error and the bias of the weighted sums, for E_sky, G and E_sky + G. */
    double wsum = 0, er[3] = {0, 0, 0}, num[3] = {0, 0, 0}, den[3] = {0, 0, 0};
    size_t nsel = 0;
    for (size_t f = 0; f < nf; f++) {
        if (!(n[f] >= 4 && e->est[f] > 0)) continue;
        double est[3], tru[3];
        est[0] = (e->esky[3 * f] + e->esky[3 * f + 1] + e->esky[3 * f + 2]) / 3;
        est[1] = (e->g[3 * f] + e->g[3 * f + 1] + e->g[3 * f + 2]) / 3;
        est[2] = est[0] + est[1];
        tru[0] = sdd[f] / n[f];
        tru[1] = sdi[f] / n[f];
        tru[2] = tru[0] + tru[1];
        if (!isfinite(est[0] + est[1])) continue;
        nsel++;
        wsum += n[f];
        for (int q = 0; q < 3; q++) {
            er[q] += fabs(est[q] - tru[q]) / (tru[q] > 1e-9 ? tru[q] : 1e-9) * n[f];
            num[q] += est[q] * n[f];
            den[q] += tru[q] * n[f];
        }
    }
    rs_json *irr = rs_json_set_obj(doc, "irradiance");
    const char *qn[3][2] = {{"esky_rel", "esky_bias"}, {"g_rel", "g_bias"}, {"total_rel", "total_bias"}};
    rs_json_set_int(irr, "facets", (long long)nsel);
    for (int q = 0; q < 3; q++) {
        rs_json_set_num(irr, qn[q][0], wsum > 0 ? er[q] / wsum : NAN);
        rs_json_set_num(irr, qn[q][1], den[q] > 0 ? num[q] / den[q] - 1 : NAN);
    }
    rs_json_set_num(irr, "truth_interreflection_share", den[2] > 0 ? den[1] / den[2] : NAN);
    rs_json *sy = rs_json_set_obj(doc, "synth");
    double rd = 0;
    for (int c = 0; c < 3; c++) rd += (sum_obs[c] > 0 ? sum_abs[c] / sum_obs[c] : 0) / 3;
    rs_json_set_int(sy, "pixels", (long long)synth_px);
    rs_json_set_num(sy, "rel_diff", synth_px ? rd : NAN);
    rs_json_set_num(doc, "error_image_full_scale", ERROR_IMAGE_FULL_SCALE);
    for (size_t p = 0; p < np; p++) part_gshare[p] = pdd[p] + pdi[p] > 0 ? pdi[p] / (pdd[p] + pdi[p]) : NAN;
    rc = write_error_images(rel, color, out_dir, err);
out:
    free(acc);
    rs_image_free(rel);
    rs_image_free(color);
    return rc;
}
