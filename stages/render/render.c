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
#include "common/par.h"
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

/* The [render] keys, read once. */
typedef struct {
    double tolerance;   /* relative change that ends the forward solve */
    int max_iterations; /* ... or this many iterations */
    int exposure_given; /* exposure is set: the previews' exposure; else from the observation */
    double exposure;
} render_opts;

static void render_opts_read(const rs_config *cfg, render_opts *o)
{
    o->tolerance = rs_config_real(cfg, "render", "tolerance");
    o->max_iterations = (int)rs_config_int(cfg, "render", "max_iterations");
    o->exposure_given = rs_config_has(cfg, "render", "exposure");
    o->exposure = o->exposure_given ? rs_config_real(cfg, "render", "exposure") : 0;
}

/* Per facet, 3 each: albedo.ply's, and the forward model's radiance and interreflection. */
typedef struct {
    size_t nf;
    double *rho, *esky, *Lobs; /* albedo, E_sky and observed radiance (albedo.ply) */
    double *L, *G;             /* the forward model's */
} render_facets;

static int render_facets_alloc(render_facets *fb, size_t nf)
{
    fb->nf = nf;
    double **all[] = {&fb->rho, &fb->esky, &fb->Lobs, &fb->L, &fb->G};
    int ok = 1;
    for (size_t k = 0; k < sizeof all / sizeof *all; k++)
        ok &= (*all[k] = malloc((3 * nf + 1) * sizeof(double))) != NULL;
    return ok ? 0 : -1;
}

static void render_facets_free(render_facets *fb)
{
    free(fb->rho);
    free(fb->esky);
    free(fb->Lobs);
    free(fb->L);
    free(fb->G);
}

/* The images of the camera's view (3 channels, the panorama's size). */
typedef struct {
    rs_image *irr, *albedo, *synth, *diff, *obs;
} render_images;

static int render_images_alloc(render_images *im, int w, int h)
{
    rs_image **all[] = {&im->irr, &im->albedo, &im->synth, &im->diff, &im->obs};
    int ok = 1;
    for (size_t k = 0; k < sizeof all / sizeof *all; k++) ok &= (*all[k] = rs_image_new(w, h, 3)) != NULL;
    return ok ? 0 : -1;
}

static void render_images_free(render_images *im)
{
    rs_image_free(im->irr);
    rs_image_free(im->albedo);
    rs_image_free(im->synth);
    rs_image_free(im->diff);
    rs_image_free(im->obs);
}

/* The figures of render.json. */
typedef struct {
    size_t capped;     /* albedo channels capped for the forward model */
    int iterations;    /* of the forward solve */
    double residual;   /* its last relative change */
    int converged;     /* below [render] tolerance */
    size_t used;       /* model pixels compared */
    double rel;        /* relative difference over them */
    double rel_facets; /* the same over the facets' observed radiance */
    double expo;       /* the previews' exposure */
    int uncertainty;   /* the uncertainty images were written */
} render_counts;

/* facet_id.exr, checked against the panorama's size. */
static rs_image *read_facet_ids(const rs_config *cfg, const rs_capture *cap, rs_err *err)
{
    char path[4096];
    const char *idp = rs_work_path(cfg, "facet_id.exr", path, sizeof path);
    rs_image *ids = rs_image_read(idp, err);
    if (ids && (ids->width != cap->pano->width || ids->height != cap->pano->height || ids->channels != 1)) {
        rs_err_set(err, RS_ERR_INPUT, idp, 0, "does not match the panorama's size (rerun observe)");
        rs_image_free(ids);
        return NULL;
    }
    return ids;
}

/* Caps rho[0..n) at rho_max (non-finite negatives at 0); returns how many it capped. */
static size_t cap_albedo(double *rho, size_t n, double rho_max)
{
    size_t capped = 0;
    for (size_t i = 0; i < n; i++)
        if (!(rho[i] <= rho_max)) {
            rho[i] = isfinite(rho[i]) || rho[i] > 0 ? rho_max : 0;
            capped++;
        }
    return capped;
}

/* The camera's view of the forward model in rows [row_lo, row_hi) (this MPI rank's band):
 * each model pixel takes its facet's irradiance, albedo and radiance, the sky stays as observed.
 * Each pixel's values depend on that pixel alone, so any split of the rows gives the same bytes.
 * Returns how many rows it composed. */
static size_t compose_rows(const rs_capture *cap, const rs_image *ids, const render_facets *fb, render_images *im,
                           size_t row_lo, size_t row_hi)
{
    size_t w = (size_t)cap->pano->width, nf = fb->nf;
    const double *esky = fb->esky, *G = fb->G, *rho = fb->rho, *L = fb->L;
    for (size_t k = row_lo * w; k < row_hi * w; k++) {
        const float *o = cap->pano->data + 3 * k;
        float id = ids->data[k];
        for (int ch = 0; ch < 3; ch++) im->obs->data[3 * k + ch] = isfinite(o[ch]) ? o[ch] : 0;
        if (!(id >= 0 && id < (float)nf)) {
            memcpy(im->synth->data + 3 * k, im->obs->data + 3 * k, 3 * sizeof(float)); /* sky as observed */
            continue;
        }
        size_t f = (size_t)id;
        for (int ch = 0; ch < 3; ch++) {
            im->irr->data[3 * k + ch] = (float)(esky[3 * f + ch] + G[3 * f + ch]);
            im->albedo->data[3 * k + ch] = (float)rho[3 * f + ch];
            im->synth->data[3 * k + ch] = (float)L[3 * f + ch];
        }
        if (!rs_capture_pixel_ok(o)) continue;
        for (int ch = 0; ch < 3; ch++) im->diff->data[3 * k + ch] = (float)(L[3 * f + ch] - o[ch]);
    }
    return row_hi - row_lo;
}

/* The relative difference of the forward model to the observation over the model pixels with
 * a usable value, into n: summed serially in pixel order over the whole view (rank 0, after the
 * rows are gathered), so its bits do not depend on how the rows were split. */
static void compare_view(const rs_capture *cap, const rs_image *ids, const render_facets *fb, render_counts *n)
{
    double sum_abs[3] = {0, 0, 0}, sum_obs[3] = {0, 0, 0};
    size_t npx = (size_t)cap->pano->width * cap->pano->height, used = 0, nf = fb->nf;
    for (size_t k = 0; k < npx; k++) {
        const float *o = cap->pano->data + 3 * k;
        float id = ids->data[k];
        if (!(id >= 0 && id < (float)nf) || !rs_capture_pixel_ok(o)) continue;
        size_t f = (size_t)id;
        used++;
        for (int ch = 0; ch < 3; ch++) {
            sum_abs[ch] += fabs(fb->L[3 * f + ch] - o[ch]);
            sum_obs[ch] += o[ch];
        }
    }
    double rel = 0;
    for (int ch = 0; ch < 3; ch++) rel += (sum_obs[ch] > 0 ? sum_abs[ch] / sum_obs[ch] : 0) / 3;
    n->used = used;
    n->rel = rel;
}

/* MPI: each rank composes its band of rows (common/par.h rs_par_range), rank 0 gathers them. */
static int compose_view(const rs_capture *cap, const rs_image *ids, const render_facets *fb, render_images *im,
                        rs_err *err)
{
    size_t h = (size_t)ids->height, row_bytes = (size_t)ids->width * 3 * sizeof(float), lo, hi;
    rs_par_range(h, &lo, &hi);
    rs_par_rows_done(compose_rows(cap, ids, fb, im, lo, hi));
    rs_image *all[] = {im->irr, im->albedo, im->synth, im->diff, im->obs};
    for (size_t k = 0; k < sizeof all / sizeof *all; k++)
        if (rs_par_gather_range(all[k]->data, h, row_bytes, err) != 0) return -1;
    return 0;
}

/* How well the facet-constant model explains the observed facets: the same figure per facet. */
static double facet_difference(const render_facets *fb)
{
    double fsum = 0, fobs = 0;
    for (size_t f = 0; f < fb->nf; f++)
        for (int ch = 0; ch < 3; ch++) {
            fsum += fabs(fb->L[3 * f + ch] - fb->Lobs[3 * f + ch]);
            fobs += fb->Lobs[3 * f + ch];
        }
    return fobs > 0 ? fsum / fobs : 0;
}

/* Nine independent files, written on all threads: one by one, with the EXR writer serial,
 * they were about a third of this stage and left the second core idle (perf). */
static int write_view(const rs_config *cfg, const render_images *im, const rs_image *ids, double expo, rs_err *err)
{
    float irr_expo = auto_exposure(im->irr, ids->data);
    rs_err werr[5];
    int wrc[5];
#pragma omp parallel for schedule(dynamic, 1)
    for (int k = 0; k < 5; k++) {
        char opath[4096];
        memset(&werr[k], 0, sizeof werr[k]);
        switch (k) {
        case 0: wrc[k] = write_pair(cfg, im->irr, "irradiance", irr_expo, &werr[k]); break;
        case 1: wrc[k] = write_pair(cfg, im->albedo, "albedo", 1.0f, &werr[k]); break;
        case 2: wrc[k] = write_pair(cfg, im->synth, "synth", (float)expo, &werr[k]); break;
        case 3: wrc[k] = write_pair(cfg, im->diff, "diff", (float)expo * 4, &werr[k]); break;
        default:
            wrc[k] = rs_image_write_png(im->obs, rs_work_path(cfg, "observed.png", opath, sizeof opath), (float)expo,
                                        &werr[k]);
        }
    }
    for (int k = 0; k < 5; k++)
        if (wrc[k] != 0) {
            if (err) *err = werr[k];
            return -1;
        }
    return 0;
}

static void report_render(rs_report *rep, const render_counts *n)
{
    rs_json_set_int(rep->metrics, "albedo_channels_capped", (long long)n->capped);
    rs_json_set_bool(rep->metrics, "uncertainty_images", n->uncertainty);
    rs_json_set_int(rep->metrics, "forward_iterations", n->iterations);
    rs_json_set_num(rep->metrics, "forward_residual", n->residual);
    rs_json_set_bool(rep->metrics, "forward_converged", n->converged);
    rs_json_set_int(rep->metrics, "model_pixels_compared", (long long)n->used);
    rs_json_set_num(rep->metrics, "relative_difference_model_pixels", n->rel);
    rs_json_set_num(rep->metrics, "relative_difference_facets", n->rel_facets);
    rs_json_set_num(rep->metrics, "preview_exposure", n->expo);
}

/* What the stage reads, and albedo.ply's per-facet values into fb. */
typedef struct {
    char alb_path[4096];
    rs_ply *alb; /* albedo.ply, kept for the uncertainty images */
    rs_mesh *mesh;
    rs_transport *K;
    rs_capture cap;
    rs_image *ids; /* facet_id.exr */
} render_inputs;

static int read_inputs(const rs_config *cfg, render_inputs *in, render_facets *fb, rs_err *err)
{
    const char *ap = rs_work_path(cfg, "albedo.ply", in->alb_path, sizeof in->alb_path);
    if (!(in->mesh = rs_mesh_read(ap, &in->alb, err))) return -1;
    size_t nf = in->mesh->nfaces;
    if (render_facets_alloc(fb, nf) != 0) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    if (rs_faceprop_get_rgb(in->alb, ap, "albedo", nf, fb->rho, err) != 0 ||
        rs_faceprop_get_rgb(in->alb, ap, "irradiance_sky", nf, fb->esky, err) != 0 ||
        rs_faceprop_get_rgb(in->alb, ap, "radiance", nf, fb->Lobs, err) != 0)
        return -1;
    char path[4096];
    if (!(in->K = rs_transport_read(rs_work_path(cfg, "transport.ply", path, sizeof path), nf, err))) return -1;
    if (rs_capture_load(cfg, "capture", &in->cap, err) != 0) return -1;
    return (in->ids = read_facet_ids(cfg, &in->cap, err)) ? 0 : -1;
}

static void render_inputs_free(render_inputs *in)
{
    rs_image_free(in->ids);
    rs_capture_release(&in->cap);
    rs_transport_free(in->K);
    rs_ply_free(in->alb);
    rs_mesh_free(in->mesh);
}

int rs_render_run(const rs_config *cfg, rs_report *rep, rs_err *err)
{
    render_opts o;
    render_opts_read(cfg, &o);
    int rc = -1;
    render_inputs in = {0};
    render_images im = {0};
    render_facets fb = {0};
    render_counts n = {0};
    if (read_inputs(cfg, &in, &fb, err) != 0) goto out;
    size_t nf = fb.nf;
    const rs_image *ids = in.ids;

    /* An estimate of 1 or more (the direct method in a concave corner, or a facet with too
     * little light) is not a physical albedo, and with it the forward model has no finite
     * solution: render with it capped just below 1, and say how many were. */
    const double rho_max = 0.999;
    if ((n.capped = cap_albedo(fb.rho, 3 * nf, rho_max)))
        rs_report_skip(rep, "albedo above 1", "%zu facet channels capped at %.3f for the forward model", n.capped,
                       rho_max);
    double t0 = rs_now();
    n.iterations = rs_transport_solve(in.K, fb.rho, fb.esky, fb.L, fb.G, o.tolerance, o.max_iterations, &n.residual);
    if (n.iterations < 0) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    rs_report_time(rep, "forward_solve", rs_now() - t0);
    n.converged = n.residual < o.tolerance;
    if (!n.converged)
        rs_log_warn("forward solve stopped after %d iterations with relative change %.3g", n.iterations, n.residual);
    /* A rank short of memory for the images fails them all (the gathers below are collective). */
    if (rs_par_any(render_images_alloc(&im, ids->width, ids->height) != 0)) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the rendered images");
        goto out;
    }
    if (compose_view(&in.cap, ids, &fb, &im, err) != 0) goto out;
    if (!rs_par_is_root()) { /* MPI: rank 0 writes */
        rc = 0;
        goto out;
    }
    compare_view(&in.cap, ids, &fb, &n);
    n.rel_facets = facet_difference(&fb);
    n.expo = o.exposure_given ? o.exposure : auto_exposure(im.obs, ids->data);
    if (write_view(cfg, &im, ids, n.expo, err) != 0) goto out;
    if ((n.uncertainty = rs_render_uncertainty_images(cfg, in.alb, in.alb_path, nf, ids, err)) < 0) goto out;
    report_render(rep, &n);
    rs_log_info("render: forward solve %d iterations (change %.2g); relative difference %.4f over %zu pixels",
                n.iterations, n.residual, n.rel, n.used);
    rc = 0;
out:
    render_images_free(&im);
    render_facets_free(&fb);
    render_inputs_free(&in);
    return rc;
}
