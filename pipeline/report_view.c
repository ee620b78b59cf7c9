/* report_view: the report's camera-view images (see report_view.h). */
#include "pipeline/report_view.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/capture.h"
#include "common/faceprop.h"
#include "common/fileio.h"
#include "common/image.h"
#include "common/ply.h"
#include "common/select.h"

#define MAX_WIDTH  640  /* report images are at most this wide (every image the same size) */
#define NO_VALUE   0x40 /* grey of pixels without a value (sRGB) */
#define SIGMA_FULL 0.2  /* albedo_sigma_rel at the top of its bar: render's albedo_sigma.png scale */
#define ERROR_FULL 0.2  /* the truth error map: +-20 %, rhoscan-eval's error image scale */

static double lum(const double *v)
{
    return 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2];
}

int rs_report_facets_read(const char *path, rs_report_facets *f, rs_err *err)
{
    memset(f, 0, sizeof *f);
    rs_ply *ply = rs_ply_read(path, err);
    if (!ply) return -1;
    rs_ply_element *faces = rs_ply_find_element(ply, "face");
    size_t nf = faces ? faces->count : 0;
    f->nf = nf;
    double **rgb[] = {&f->alb, &f->rad, &f->esky, &f->g};
    const char *names[] = {"albedo", "radiance", "irradiance_sky", "irradiance_inter"};
    double *obs = malloc((nf + 1) * sizeof *obs), *est = malloc((nf + 1) * sizeof *est);
    f->observed = malloc(nf + 1);
    f->estimable = malloc(nf + 1);
    int rc = obs && est && f->observed && f->estimable ? 0 : -1;
    if (rc) rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory for the report");
    for (int k = 0; k < 4 && rc == 0; k++) {
        if (!(*rgb[k] = malloc((3 * nf + 1) * sizeof(double))))
            rc = rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory for the report");
        else
            rc = rs_faceprop_get_rgb(ply, path, names[k], nf, *rgb[k], err);
    }
    if (rc == 0) rc = rs_faceprop_get(ply, path, "observed", nf, obs, err);
    if (rc == 0) rc = rs_faceprop_get(ply, path, "estimable", nf, est, err);
    if (rc == 0 && faces && rs_ply_find_prop(faces, "albedo_sigma_rel")) {
        if (!(f->sigma = malloc((nf + 1) * sizeof *f->sigma)))
            rc = rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory for the report");
        else
            rc = rs_faceprop_get(ply, path, "albedo_sigma_rel", nf, f->sigma, err);
    }
    for (size_t i = 0; rc == 0 && i < nf; i++) {
        f->observed[i] = obs[i] != 0;
        f->estimable[i] = est[i] != 0;
    }
    free(obs);
    free(est);
    rs_ply_free(ply);
    if (rc != 0) rs_report_facets_free(f);
    return rc;
}

void rs_report_facets_free(rs_report_facets *f)
{
    free(f->alb);
    free(f->rad);
    free(f->esky);
    free(f->g);
    free(f->sigma);
    free(f->observed);
    free(f->estimable);
    memset(f, 0, sizeof *f);
}

/* The report's pixel grid: every step-th panorama pixel (nearest, no averaging). */
typedef struct {
    int w, h, step, pw, ph; /* report size, step, panorama size */
    long *facet;            /* w * h: the facet seen, -1 for none (or no facet_id.exr) */
    const char *workdir;
} grid;

static size_t src_index(const grid *g, int x, int y)
{
    int sx = x * g->step + g->step / 2, sy = y * g->step + g->step / 2;
    if (sx >= g->pw) sx = g->pw - 1;
    if (sy >= g->ph) sy = g->ph - 1;
    return (size_t)sy * (size_t)g->pw + (size_t)sx;
}

/* q-quantile of the finite values v[0..n) (reordered); fallback when there are none. */
static double quantile(double *v, size_t n, double q, double fallback)
{
    size_t m = 0;
    for (size_t k = 0; k < n; k++)
        if (isfinite(v[k])) v[m++] = v[k];
    if (m == 0) return fallback;
    double r = rs_select_kth_double(v, m, (size_t)(q * (double)(m - 1)));
    return r > 0 ? r : fallback;
}

/* 8-bit sRGB rgb[3 * w * h] to workdir/report/name.png. */
static int write_png8(const grid *g, const unsigned char *rgb, const char *name, rs_report_image *im, rs_err *err)
{
    char rel[64], path[4096];
    snprintf(rel, sizeof rel, "report/%s.png", name);
    snprintf(im->file, sizeof im->file, "%s", rel);
    return rs_image_write_png8(rgb, g->w, g->h, 3, rs_path_join(path, sizeof path, g->workdir, rel), err);
}

/* The 8-bit sRGB code of a linear value in [0, 1], from a table (the report's images need no
 * more precision than 1 / SRGB_STEPS; a powf per channel was most of their cost). */
enum { SRGB_STEPS = 4096 };
static double srgb8(double t)
{
    static unsigned char lut[SRGB_STEPS + 1];
    static int ready;
    if (!ready) {
        for (int k = 0; k <= SRGB_STEPS; k++)
            lut[k] = (unsigned char)lrintf(255 * rs_linear_to_srgb((float)k / SRGB_STEPS));
        ready = 1;
    }
    return lut[(int)lrint((t < 0 ? 0 : t > 1 ? 1 : t) * SRGB_STEPS)];
}

/* v[w * h] (NAN: no value) through map over [lo, hi] into an image. */
static int false_colour(const grid *g, const double *v, double lo, double hi, rs_colormap_fn map, const char *name,
                        rs_report_image *im, rs_err *err)
{
    size_t n = (size_t)g->w * g->h;
    unsigned char *rgb = malloc(3 * n);
    if (!rgb) return rs_err_set(err, RS_ERR_SYSTEM, name, 0, "out of memory for the report's image");
        /* Serial at report sizes (at most 640 px wide): the loop takes a millisecond, less than
     * OpenMP's threads then spin waiting for more work. */
#pragma omp parallel for schedule(static) if (n > (1 << 22))
    for (size_t k = 0; k < n; k++) {
        if (isfinite(v[k]))
            map((v[k] - lo) / (hi - lo), rgb + 3 * k);
        else
            rgb[3 * k] = rgb[3 * k + 1] = rgb[3 * k + 2] = NO_VALUE;
    }
    im->lo = lo;
    im->hi = hi;
    im->map = map;
    int rc = write_png8(g, rgb, name, im, err);
    free(rgb);
    return rc;
}

/* Per-facet luminance (or a scalar when rgb is 0) in the grid's pixels; NAN off the model. */
static void facet_values(const grid *g, const double *per_facet, int rgb, double *out)
{
    for (size_t k = 0; k < (size_t)g->w * g->h; k++) {
        long f = g->facet[k];
        out[k] = f < 0 ? NAN : rgb ? lum(per_facet + 3 * f) : per_facet[f];
    }
}

/* How an RGB image is filled: from a panorama-size image or per facet, over the model only or
 * everywhere, with the filled-in sky marked. */
typedef struct {
    const float *px;     /* panorama-size RGB, or NULL */
    const double *facet; /* 3 per facet, or NULL */
    double scale;        /* linear value x scale, clipped to [0, 1], sRGB-encoded */
    int model_only;      /* grey off the model */
    int mark_fill;       /* magenta over pixels whose sky was filled in (model or unusable) */
} rgb_src;

static int rgb_image(const grid *g, const rgb_src *s, const char *name, rs_report_image *im, rs_err *err)
{
    size_t n = (size_t)g->w * g->h;
    unsigned char *rgb = malloc(3 * n);
    if (!rgb) return rs_err_set(err, RS_ERR_SYSTEM, name, 0, "out of memory for the report's image");
    srgb8(0); /* the table, before the threads */
#pragma omp parallel for schedule(static) if (n > (1 << 22))
    for (int y = 0; y < g->h; y++)
        for (int x = 0; x < g->w; x++) {
            size_t k = (size_t)y * g->w + x;
            long f = g->facet[k];
            const float *p = s->px ? s->px + 3 * src_index(g, x, y) : NULL;
            double v[3] = {0, 0, 0};
            int have = s->facet ? f >= 0 : p != NULL && (!s->model_only || f >= 0);
            for (int c = 0; c < 3 && have; c++) v[c] = s->facet ? s->facet[3 * f + c] : p[c];
            int filled = s->mark_fill && (f >= 0 || !p || !rs_capture_pixel_ok(p));
            for (int c = 0; c < 3; c++) {
                double t = isfinite(v[c]) ? v[c] * s->scale : 0;
                t = t < 0 ? 0 : t > 1 ? 1 : t;
                double e = have ? srgb8(t) : NO_VALUE;
                if (filled) e = 0.45 * e + 0.55 * (c == 1 ? 0 : 255); /* magenta over it */
                rgb[3 * k + c] = (unsigned char)lrint(e);
            }
        }
    im->lo = 0;
    im->hi = 1 / s->scale;
    im->map = rs_colormap_grey;
    int rc = write_png8(g, rgb, name, im, err);
    free(rgb);
    return rc;
}

/* 1 / the 99th percentile of the luminance of img's pixels (model pixels only when model). */
static double exposure_of(const grid *g, const rs_image *img, int model, double *work)
{
    size_t m = 0;
    for (int y = 0; y < g->h; y++)
        for (int x = 0; x < g->w; x++) {
            if (model && g->facet[(size_t)y * g->w + x] < 0) continue;
            const float *p = img->data + 3 * src_index(g, x, y);
            double d[3] = {p[0], p[1], p[2]};
            if (rs_capture_pixel_ok(p)) work[m++] = lum(d);
        }
    return 1 / quantile(work, m, 0.99, 1);
}

static void set_text(rs_report_image *im, const char *title, const char *unit, const char *tone)
{
    snprintf(im->title, sizeof im->title, "%s", title);
    snprintf(im->unit, sizeof im->unit, "%s", unit);
    snprintf(im->tone, sizeof im->tone, "%s", tone);
}

static void add_missing(rs_report_views *v, const char *what)
{
    size_t l = strlen(v->missing);
    snprintf(v->missing + l, sizeof v->missing - l, "%s%s", l ? "; " : "", what);
}

/* An image file of the work folder, or NULL (with the reason in v->missing) when absent. */
static rs_image *read_optional(const char *workdir, const char *name, int channels, rs_report_views *v, rs_err *err,
                               int *failed)
{
    char path[4096], why[160];
    rs_path_join(path, sizeof path, workdir, name);
    if (!rs_file_exists(path)) {
        snprintf(why, sizeof why, "%s not written yet", name);
        add_missing(v, why);
        return NULL;
    }
    rs_image *img = rs_image_read(path, err);
    if (img && img->channels != channels) {
        rs_err_set(err, RS_ERR_INPUT, path, 0, "has %d channels, expected %d", img->channels, channels);
        rs_image_free(img);
        img = NULL;
    }
    if (!img) *failed = 1;
    return img;
}

enum { IM_OBS, IM_ESKY, IM_G, IM_ALB, IM_SYNTH, IM_DIFF, IM_SIGMA, IM_PANO, IM_ERROR, IM_COUNT };

/* The images from the panorama and synth.exr: observed, re-rendered (one exposure), panorama. */
static int view_radiance(const grid *g, const rs_image *pano, const rs_image *synth, double *work,
                         rs_report_image *slot, uint8_t *made, rs_err *err)
{
    double expo = exposure_of(g, pano, 1, work);
    char tone[400];
    snprintf(tone, sizeof tone,
             "RGB x %.4g (the 99th percentile of the observed model pixels' luminance at 1), clipped, sRGB-encoded; "
             "grey: no facet",
             expo);
    rgb_src s = {pano->data, NULL, expo, 1, 0};
    if (rgb_image(g, &s, "observed", &slot[IM_OBS], err) != 0) return -1;
    set_text(&slot[IM_OBS], "observed radiance", "radiance per channel, W m^-2 sr^-1", tone);
    made[IM_OBS] = 1;
    if (synth) {
        s.px = synth->data;
        if (rgb_image(g, &s, "synth", &slot[IM_SYNTH], err) != 0) return -1;
        set_text(&slot[IM_SYNTH], "re-rendered radiance", "radiance per channel, W m^-2 sr^-1",
                 "the same exposure as the observed radiance, clipped, sRGB-encoded; grey: no facet");
        made[IM_SYNTH] = 1;
    }
    double pexpo = exposure_of(g, pano, 0, work);
    snprintf(tone, sizeof tone,
             "RGB x %.4g (the 99th percentile of every pixel's luminance at 1), clipped, sRGB-encoded; magenta "
             "tint: sky the camera did not see (behind the model or unusable pixels), filled in by the sky "
             "completion ([sky] fill) unless a sky panorama or another capture saw it",
             pexpo);
    rgb_src p = {pano->data, NULL, pexpo, 0, 1};
    if (rgb_image(g, &p, "panorama_fill", &slot[IM_PANO], err) != 0) return -1;
    set_text(&slot[IM_PANO], "panorama, filled sky marked", "radiance per channel, W m^-2 sr^-1", tone);
    made[IM_PANO] = 1;
    return 0;
}

/* synth - observed (diff.exr) as signed luminance on a diverging map, symmetric range. */
static int view_diff(const grid *g, const rs_image *diff, double *vals, double *work, rs_report_image *im, rs_err *err)
{
    size_t n = (size_t)g->w * g->h, m = 0, neg = 0;
    for (int y = 0; y < g->h; y++)
        for (int x = 0; x < g->w; x++) {
            size_t k = (size_t)y * g->w + x;
            const float *p = diff->data + 3 * src_index(g, x, y);
            double d[3] = {p[0], p[1], p[2]};
            vals[k] = g->facet[k] >= 0 && isfinite(lum(d)) ? lum(d) : NAN;
            if (isfinite(vals[k])) {
                work[m++] = fabs(vals[k]);
                neg += vals[k] < 0;
            }
        }
    double r = quantile(work, m, 0.99, 1);
    if (false_colour(g, vals, -r, r, rs_colormap_diverging, "diff_signed", im, err) != 0) return -1;
    char tone[400];
    snprintf(tone, sizeof tone,
             "luminance of re-rendered minus observed radiance; diverging map centred on 0 (white), symmetric "
             "range +-%.4g (the 99th percentile of |difference|; beyond it clipped); %.1f %% of the %zu model "
             "pixels are negative (blue)",
             r, m ? 100.0 * (double)neg / (double)m : 0, m);
    set_text(im, "signed difference (re-rendered - observed)", "radiance, W m^-2 sr^-1", tone);
    (void)n;
    return 0;
}

/* The per-facet images: E_sky, G, albedo, uncertainty, truth error. */
static int view_facets(const grid *g, const rs_report_facets *f, const double *truth_err, double *vals, double *work,
                       rs_report_image *slot, uint8_t *made, rs_err *err)
{
    size_t n = (size_t)g->w * g->h;
    char tone[400];
    const double *irr[2] = {f->esky, f->g};
    const char *irr_name[2] = {"irradiance_sky", "irradiance_inter"};
    const char *irr_title[2] = {"sky irradiance E_sky", "interreflected irradiance G"};
    for (int k = 0; k < 2; k++) {
        facet_values(g, irr[k], 1, vals);
        memcpy(work, vals, n * sizeof *work);
        double hi = quantile(work, n, 0.99, 1);
        if (false_colour(g, vals, 0, hi, rs_colormap_ramp, irr_name[k], &slot[IM_ESKY + k], err) != 0) return -1;
        snprintf(tone, sizeof tone,
                 "luminance per facet, linear from 0 to %.4g (the 99th percentile over the model pixels; above "
                 "it clipped); grey: no facet",
                 hi);
        set_text(&slot[IM_ESKY + k], irr_title[k], "irradiance, W m^-2", tone);
        made[IM_ESKY + k] = 1;
    }
    rgb_src s = {NULL, f->alb, 1, 1, 0};
    if (rgb_image(g, &s, "albedo", &slot[IM_ALB], err) != 0) return -1;
    set_text(&slot[IM_ALB], "albedo", "albedo per channel, unitless",
             "RGB linear 0 to 1, clipped, sRGB-encoded (the colour the facet has under white light); grey: no facet");
    made[IM_ALB] = 1;
    if (f->sigma) {
        facet_values(g, f->sigma, 0, vals);
        if (false_colour(g, vals, 0, SIGMA_FULL, rs_colormap_ramp, "albedo_sigma", &slot[IM_SIGMA], err) != 0)
            return -1;
        set_text(&slot[IM_SIGMA], "albedo uncertainty", "relative standard uncertainty (1 sigma), unitless",
                 "albedo_sigma_rel per facet, linear 0 to 0.2 (above it clipped); grey: no facet");
        made[IM_SIGMA] = 1;
    }
    if (truth_err) {
        facet_values(g, truth_err, 0, vals);
        if (false_colour(g, vals, -ERROR_FULL, ERROR_FULL, rs_colormap_diverging, "truth_error", &slot[IM_ERROR],
                         err) != 0)
            return -1;
        set_text(&slot[IM_ERROR], "albedo error against the truth", "relative error (rho - truth) / truth, unitless",
                 "mean over R, G, B per facet, diverging map centred on 0, symmetric range +-0.2 (beyond it clipped); "
                 "grey: no facet or not matched to a truth part");
        made[IM_ERROR] = 1;
    }
    return 0;
}

/* The grid over the panorama and the facets it sees (facet_id.exr, when present and of the
 * panorama's size; else no facet anywhere). */
static int make_grid(const char *workdir, const rs_image *pano, const rs_image *ids, size_t nf, grid *g, rs_err *err)
{
    g->workdir = workdir;
    g->pw = pano->width;
    g->ph = pano->height;
    g->step = (pano->width + MAX_WIDTH - 1) / MAX_WIDTH;
    g->w = (pano->width + g->step - 1) / g->step;
    g->h = (pano->height + g->step - 1) / g->step;
    g->facet = malloc((size_t)g->w * g->h * sizeof *g->facet);
    if (!g->facet) return rs_err_set(err, RS_ERR_SYSTEM, workdir, 0, "out of memory for the report");
    int ok = ids && ids->width == pano->width && ids->height == pano->height;
    for (int y = 0; y < g->h; y++)
        for (int x = 0; x < g->w; x++) {
            float id = ok ? ids->data[src_index(g, x, y)] : -1;
            g->facet[(size_t)y * g->w + x] = id >= 0 && id < (float)nf ? (long)id : -1;
        }
    return 0;
}

int rs_report_views_write(const char *workdir, const char *pano_path, const rs_report_facets *f,
                          const double *truth_err, rs_report_views *v, rs_err *err)
{
    memset(v, 0, sizeof *v);
    char dir[4096];
    if (rs_mkdir_p(rs_path_join(dir, sizeof dir, workdir, "report"), err) != 0) return -1;
    if (!pano_path || !rs_file_exists(pano_path)) {
        add_missing(v, "no panorama: no camera-view images");
        return 0;
    }
    int failed = 0, rc = -1;
    rs_image *pano = rs_image_read(pano_path, err);
    if (pano && pano->channels != 3) {
        rs_err_set(err, RS_ERR_INPUT, pano_path, 0, "has %d channels, expected 3 (R, G, B)", pano->channels);
        rs_image_free(pano);
        pano = NULL;
    }
    if (!pano) return -1;
    rs_image *ids = read_optional(workdir, "facet_id.exr", 1, v, err, &failed);
    rs_image *synth = failed ? NULL : read_optional(workdir, "synth.exr", 3, v, err, &failed);
    rs_image *diff = failed ? NULL : read_optional(workdir, "diff.exr", 3, v, err, &failed);
    grid g = {0};
    double *vals = NULL, *work = NULL;
    rs_report_image slot[IM_COUNT];
    uint8_t made[IM_COUNT] = {0};
    memset(slot, 0, sizeof slot);
    if (failed || make_grid(workdir, pano, ids, f ? f->nf : 0, &g, err) != 0) goto out;
    size_t n = (size_t)g.w * g.h;
    vals = calloc(n, sizeof *vals);
    work = malloc(n * sizeof *work);
    if (!vals || !work) {
        rs_err_set(err, RS_ERR_SYSTEM, workdir, 0, "out of memory for the report");
        goto out;
    }
    if (view_radiance(&g, pano, synth, work, slot, made, err) != 0) goto out;
    if (diff && view_diff(&g, diff, vals, work, &slot[IM_DIFF], err) != 0) goto out;
    made[IM_DIFF] = diff != NULL;
    if (f && ids && view_facets(&g, f, truth_err, vals, work, slot, made, err) != 0) goto out;
    if (!f) add_missing(v, "albedo.ply not written yet");
    for (int k = 0; k < IM_COUNT; k++)
        if (made[k]) v->img[v->n++] = slot[k];
    v->width = g.w;
    v->height = g.h;
    rc = 0;
out:
    free(vals);
    free(work);
    free(g.facet);
    rs_image_free(pano);
    rs_image_free(ids);
    rs_image_free(synth);
    rs_image_free(diff);
    return rc;
}
