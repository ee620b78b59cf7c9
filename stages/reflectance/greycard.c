/* greycard: the grey-card check (see greycard.h). The card's radiance comes from the object's
 * pixels and its irradiance from the sky's: if both share one radiometric scale, pi L / E is
 * the card's albedo; their ratio is how far the object and sky exposures disagree. */
#include "stages/reflectance/greycard.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "common/capture.h"
#include "pipeline/capture_load.h"
#include "common/image.h"
#include "common/log.h"
#include "pipeline/stage.h"

static double lum3(const double *v)
{
    return 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2];
}

/* Larger than any panorama: a value beyond it is a typo, and never overflows an int. */
#define MAX_INDEX 1048576

/* x0 y0 x1 y1: four decimal integers from 0 to MAX_INDEX (sscanf's %d would wrap 4294967396 to 100). */
static int parse_region(const rs_config *cfg, const char *text, int *x0, int *y0, int *x1, int *y1, rs_err *err)
{
    int *v[4] = {x0, y0, x1, y1}, n = 0;
    const char *p = text;
    for (; n < 4; n++) {
        while (*p == ' ' || *p == '\t') p++;
        char *end;
        errno = 0;
        long x = strtol(p, &end, 10);
        if (end == p || (*end && *end != ' ' && *end != '\t') || errno == ERANGE || x < 0 || x > MAX_INDEX) break;
        *v[n] = (int)x;
        p = end;
    }
    while (*p == ' ' || *p == '\t') p++;
    char why[64];
    if (n < 4)
        snprintf(why, sizeof why, "value %d is not an integer from 0 to %d", n + 1, MAX_INDEX);
    else if (*p)
        snprintf(why, sizeof why, "more than 4 values");
    else if (*x1 <= *x0 || *y1 <= *y0)
        snprintf(why, sizeof why, "the region is empty");
    else
        return 0;
    return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                      "[calib] grey_card_region = \"%.80s\": %s; expected 4 pixel indices x0 y0 x1 y1 from 0 to %d "
                      "with x0 < x1, y0 < y1 (columns x0..x1-1, rows y0..y1-1)",
                      text, why, MAX_INDEX);
}

int rs_greycard_report(const rs_config *cfg, size_t nf, const double *esky, const double *g, const double *rho,
                       const uint8_t *estimable, rs_json *metrics, rs_err *err)
{
    const char *text = rs_config_string(cfg, "calib", "grey_card_region");
    if (!text) return 0;
    int x0, y0, x1, y1;
    if (parse_region(cfg, text, &x0, &y0, &x1, &y1, err) != 0) return -1;
    double albedo = rs_config_real(cfg, "calib", "grey_card_albedo");
    rs_capture cap = {0};
    rs_image *ids = NULL;
    char path[4096];
    int rc = -1;
    if (rs_capture_load(cfg, "capture", &cap, err) != 0) return -1;
    const char *id_path = rs_work_path(cfg, "facet_id.exr", path, sizeof path);
    if (!(ids = rs_image_read(id_path, err))) goto out;
    int w = cap.pano->width, h = cap.pano->height;
    if (ids->width != w || ids->height != h || ids->channels != 1) {
        rs_err_set(err, RS_ERR_INPUT, id_path, 0, "is %d x %d: expected the panorama's %d x %d (rerun observe)",
                   ids->width, ids->height, w, h);
        goto out;
    }
    if (x1 > w || y1 > h) {
        rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                   "[calib] grey_card_region = \"%s\" reaches past the "
                   "%d x %d panorama %s: expected x1 <= %d, y1 <= %d",
                   text, w, h, cap.path, w, h);
        goto out;
    }
    double L[3] = {0, 0, 0}, E[3] = {0, 0, 0}, R[3] = {0, 0, 0};
    size_t npx = 0, nrho = 0, nfacets = 0;
    uint8_t *seen = calloc(nf ? nf : 1, 1);
    if (!seen) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    for (int y = y0; y < y1; y++)
        for (int x = x0; x < x1; x++) {
            size_t k = (size_t)y * w + x;
            float id = ids->data[k];
            const float *px = cap.pano->data + 3 * k;
            if (!(id >= 0) || id >= (float)nf || !rs_capture_pixel_ok(px)) continue;
            size_t f = (size_t)id;
            nfacets += !seen[f];
            seen[f] = 1;
            npx++;
            for (int ch = 0; ch < 3; ch++) {
                L[ch] += px[ch];
                E[ch] += esky[3 * f + ch] + g[3 * f + ch];
            }
            if (estimable[f]) {
                nrho++;
                for (int ch = 0; ch < 3; ch++) R[ch] += rho[3 * f + ch];
            }
        }
    free(seen);
    if (!npx) {
        rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                   "[calib] grey_card_region = \"%s\": none of its pixels "
                   "of %s shows a facet of the model with a usable value: expected the region on the card",
                   text, cap.path);
        goto out;
    }
    double implied[3];
    for (int ch = 0; ch < 3; ch++) {
        L[ch] /= npx;
        E[ch] /= npx;
        implied[ch] = E[ch] > 0 ? M_PI * L[ch] / E[ch] : 0;
        if (nrho) R[ch] /= nrho;
    }
    double implied_lum = lum3(E) > 0 ? M_PI * lum3(L) / lum3(E) : 0, ratio = implied_lum / albedo;
    rs_json *o = rs_json_set_obj(metrics, "grey_card");
    rs_json_set_str(o, "region", text);
    rs_json_set_num(o, "albedo_known", albedo);
    rs_json_set_int(o, "pixels", (long long)npx);
    rs_json_set_int(o, "facets", (long long)nfacets);
    rs_json *a = rs_json_set_arr(o, "radiance");
    for (int ch = 0; ch < 3; ch++) rs_json_push_num(a, L[ch]);
    a = rs_json_set_arr(o, "irradiance");
    for (int ch = 0; ch < 3; ch++) rs_json_push_num(a, E[ch]);
    a = rs_json_set_arr(o, "albedo_implied");
    for (int ch = 0; ch < 3; ch++) rs_json_push_num(a, implied[ch]);
    rs_json_set_num(o, "albedo_implied_luminance", implied_lum);
    /* 1 when the object's pixels and the sky's share one radiometric scale. */
    rs_json_set_num(o, "consistency_ratio", ratio);
    /* The factor that brings the panorama's object radiance onto the sky's scale (absolute when
     * the sky is: e.g. a panorama in W m^-2 sr^-1 with [sky] sun_irradiance in W m^-2). */
    rs_json_set_num(o, "radiance_scale", ratio > 0 ? 1 / ratio : 0);
    if (nrho) {
        a = rs_json_set_arr(o, "albedo_estimated");
        for (int ch = 0; ch < 3; ch++) rs_json_push_num(a, R[ch]);
        rs_json_set_num(o, "albedo_error_pp", 100 * (lum3(R) - albedo));
    }
    rs_log_info("reflectance: grey card (%zu pixels, %zu facets): pi L / E = %.4f against %.4f known, ratio %.4f%s",
                npx, nfacets, implied_lum, albedo, ratio, nrho ? "" : "; no estimable facet under it");
    rc = 0;
out:
    rs_image_free(ids);
    rs_capture_release(&cap);
    return rc;
}
