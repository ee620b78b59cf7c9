/* render: re-renders the panorama from the estimated albedo with the forward model
 *   L = L_s + P K L,  L_s,i = rho_i E_sky,i / pi,  P = diag(rho) / pi,
 * solved by Jacobi iteration (converges since row sums of K are <= pi and rho < 1), then
 * compares it with the observation. Writes, in the camera's view: irradiance.exr (E = E_sky + K L),
 * albedo.exr, synth.exr, diff.exr (synth - observed on model pixels), PNG previews of each and
 * of the observation, and when albedo.ply carries them (issue 8, part 4) false-colour images of
 * sky_filled and albedo_sigma_rel over the facets (render_uncertainty.c). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/capture.h"
#include "pipeline/capture_load.h"
#include "common/mesh.h"
#include "common/faceprop.h"
#include "common/log.h"
#include "common/select.h"
#include "stages/stages.h"
#include "light/transport.h"
#include "stages/render/render_uncertainty.h"

/* Exposure that maps the 99th percentile of the given pixels' luminance to 1. */
static float auto_exposure(const rs_image *img, const float *ids)
{
    size_t n = (size_t)img->width * img->height, m = 0;
    float *v = malloc(n * sizeof *v);
    if (!v) return 1;
    for (size_t k = 0; k < n; k++) {
        const float *p = img->data + 3 * k;
        float y = 0.2126f * p[0] + 0.7152f * p[1] + 0.0722f * p[2];
        if ((!ids || ids[k] >= 0) && isfinite(y) && y > 0) v[m++] = y;
    }
    float e = 1;
    if (m) e = 1.0f / rs_select_kth(v, m, (size_t)(0.99 * (m - 1)));
    free(v);
    return isfinite(e) && e > 0 ? e : 1;
}

static int write_pair(const rs_config *cfg, const rs_image *img, const char *name, float png_scale, rs_err *err)
{
    char path[4096], file[256];
    static const char *const rgb[] = {"R", "G", "B"};
    snprintf(file, sizeof file, "%s.exr", name);
    if (rs_image_write_exr(img, rs_work_path(cfg, file, path, sizeof path), rgb, 0, "rhoscan render", err) != 0)
        return -1;
    snprintf(file, sizeof file, "%s.png", name);
    return rs_image_write_png(img, rs_work_path(cfg, file, path, sizeof path), png_scale, err);
}

int rs_render_run(const rs_config *cfg, rs_report *rep, rs_err *err)
{
    char path[4096];
    int rc = -1;
    rs_capture cap = {0};
    rs_ply *alb = NULL;
    rs_transport *K = NULL;
    rs_image *ids = NULL, *img[5] = {NULL, NULL, NULL, NULL, NULL};
    double *buf = NULL;
    const char *ap = rs_work_path(cfg, "albedo.ply", path, sizeof path);
    rs_mesh *mesh = rs_mesh_read(ap, &alb, err);
    if (!mesh) return -1;
    size_t nf = mesh->nfaces;
    buf = malloc((15 * nf + 1) * sizeof *buf);
    if (!buf) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    double *rho = buf, *esky = buf + 3 * nf, *L = buf + 6 * nf, *G = buf + 9 * nf, *Lobs = buf + 12 * nf;
    if (rs_faceprop_get_rgb(alb, ap, "albedo", nf, rho, err) != 0 ||
        rs_faceprop_get_rgb(alb, ap, "irradiance_sky", nf, esky, err) != 0 ||
        rs_faceprop_get_rgb(alb, ap, "radiance", nf, Lobs, err) != 0)
        goto out;
    if (!(K = rs_transport_read(rs_work_path(cfg, "transport.ply", path, sizeof path), nf, err))) goto out;
    if (rs_capture_load(cfg, "capture", &cap, err) != 0) goto out;
    const char *idp = rs_work_path(cfg, "facet_id.exr", path, sizeof path);
    if (!(ids = rs_image_read(idp, err))) goto out;
    if (ids->width != cap.pano->width || ids->height != cap.pano->height || ids->channels != 1) {
        rs_err_set(err, RS_ERR_INPUT, idp, 0, "does not match the panorama's size (rerun observe)");
        goto out;
    }
    /* An estimate of 1 or more (the direct method in a concave corner, or a facet with too
     * little light) is not a physical albedo, and with it the forward model has no finite
     * solution: render with it capped just below 1, and say how many were. */
    const double rho_max = 0.999;
    size_t capped = 0;
    for (size_t i = 0; i < 3 * nf; i++)
        if (!(rho[i] <= rho_max)) {
            rho[i] = isfinite(rho[i]) || rho[i] > 0 ? rho_max : 0;
            capped++;
        }
    if (capped)
        rs_report_skip(rep, "albedo above 1", "%zu facet channels capped at %.3f for the forward model", capped,
                       rho_max);
    rs_json_set_int(rep->metrics, "albedo_channels_capped", (long long)capped);
    double residual, t0 = rs_now();
    int iters = rs_transport_solve(K, rho, esky, L, G, rs_config_real(cfg, "render", "tolerance"),
                                   (int)rs_config_int(cfg, "render", "max_iterations"), &residual);
    if (iters < 0) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    rs_report_time(rep, "forward_solve", rs_now() - t0);
    int converged = residual < rs_config_real(cfg, "render", "tolerance");
    if (!converged) rs_log_warn("forward solve stopped after %d iterations with relative change %.3g", iters, residual);

    int w = cap.pano->width, h = cap.pano->height;
    for (int k = 0; k < 5; k++)
        if (!(img[k] = rs_image_new(w, h, 3))) {
            rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
            goto out;
        }
    rs_image *irr = img[0], *albi = img[1], *syn = img[2], *diff = img[3], *obs = img[4];
    double sum_abs[3] = {0, 0, 0}, sum_obs[3] = {0, 0, 0};
    size_t npx = (size_t)w * h, used = 0;
    for (size_t k = 0; k < npx; k++) {
        const float *o = cap.pano->data + 3 * k;
        float id = ids->data[k];
        for (int ch = 0; ch < 3; ch++) obs->data[3 * k + ch] = isfinite(o[ch]) ? o[ch] : 0;
        if (!(id >= 0 && id < (float)nf)) {
            memcpy(syn->data + 3 * k, obs->data + 3 * k, 3 * sizeof(float)); /* sky as observed */
            continue;
        }
        size_t f = (size_t)id;
        for (int ch = 0; ch < 3; ch++) {
            irr->data[3 * k + ch] = (float)(esky[3 * f + ch] + G[3 * f + ch]);
            albi->data[3 * k + ch] = (float)rho[3 * f + ch];
            syn->data[3 * k + ch] = (float)L[3 * f + ch];
        }
        if (!rs_capture_pixel_ok(o)) continue;
        used++;
        for (int ch = 0; ch < 3; ch++) {
            diff->data[3 * k + ch] = (float)(L[3 * f + ch] - o[ch]);
            sum_abs[ch] += fabs(L[3 * f + ch] - o[ch]);
            sum_obs[ch] += o[ch];
        }
    }
    double rel = 0;
    for (int ch = 0; ch < 3; ch++) rel += (sum_obs[ch] > 0 ? sum_abs[ch] / sum_obs[ch] : 0) / 3;
    /* How well the facet-constant model explains the observed facets: the same figure per facet. */
    double fsum = 0, fobs = 0;
    for (size_t f = 0; f < nf; f++)
        for (int ch = 0; ch < 3; ch++) {
            fsum += fabs(L[3 * f + ch] - Lobs[3 * f + ch]);
            fobs += Lobs[3 * f + ch];
        }

    double expo = rs_config_has(cfg, "render", "exposure") ? rs_config_real(cfg, "render", "exposure")
                                                           : auto_exposure(obs, ids->data);
    /* Nine independent files, written on all threads: one by one, with the EXR writer serial,
     * they were about a third of this stage and left the second core idle (perf). */
    float irr_expo = auto_exposure(irr, ids->data);
    rs_err werr[5];
    int wrc[5];
#pragma omp parallel for schedule(dynamic, 1)
    for (int k = 0; k < 5; k++) {
        char opath[4096];
        memset(&werr[k], 0, sizeof werr[k]);
        switch (k) {
        case 0: wrc[k] = write_pair(cfg, irr, "irradiance", irr_expo, &werr[k]); break;
        case 1: wrc[k] = write_pair(cfg, albi, "albedo", 1.0f, &werr[k]); break;
        case 2: wrc[k] = write_pair(cfg, syn, "synth", (float)expo, &werr[k]); break;
        case 3: wrc[k] = write_pair(cfg, diff, "diff", (float)expo * 4, &werr[k]); break;
        default:
            wrc[k] =
                rs_image_write_png(obs, rs_work_path(cfg, "observed.png", opath, sizeof opath), (float)expo, &werr[k]);
        }
    }
    for (int k = 0; k < 5; k++)
        if (wrc[k] != 0) {
            if (err) *err = werr[k];
            goto out;
        }
    int unc = rs_render_uncertainty_images(cfg, alb, ap, nf, ids, err);
    if (unc < 0) goto out;
    rs_json_set_bool(rep->metrics, "uncertainty_images", unc);
    rs_json_set_int(rep->metrics, "forward_iterations", iters);
    rs_json_set_num(rep->metrics, "forward_residual", residual);
    rs_json_set_bool(rep->metrics, "forward_converged", converged);
    rs_json_set_int(rep->metrics, "model_pixels_compared", (long long)used);
    rs_json_set_num(rep->metrics, "relative_difference_model_pixels", rel);
    rs_json_set_num(rep->metrics, "relative_difference_facets", fobs > 0 ? fsum / fobs : 0);
    rs_json_set_num(rep->metrics, "preview_exposure", expo);
    rs_log_info("render: forward solve %d iterations (change %.2g); relative difference %.4f over %zu pixels", iters,
                residual, rel, used);
    rc = 0;
out:
    for (int k = 0; k < 5; k++) rs_image_free(img[k]);
    rs_image_free(ids);
    rs_capture_release(&cap);
    rs_transport_free(K);
    rs_ply_free(alb);
    free(buf);
    rs_mesh_free(mesh);
    return rc;
}
