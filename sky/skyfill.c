/* skyfill: filling the unmeasured directions of a sky map (see skyfill.h): row interpolation,
 * or a Perez + harmonics model above the horizon and the visible ground below it, with
 * held-out blocks of measured sky to measure each method's error. */
#include "sky/skyfill.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/log.h"
#include "sky/skydist.h"

#define CV_SECTORS   8    /* held-out azimuth sectors, plus one band of the lowest sky */
#define CV_LOW_SHARE 0.2  /* the low band: this share of the measured sky's solid angle */
#define CV_MIN_SR    0.01 /* a held-out block needs this much measured sky to count */
#define FIT_CELLS_W  64   /* the model is fitted on a grid of at most 64 x 32 cells */
#define CV_MAX_W     1024 /* held-out blocks are measured on a map at most this wide */

static double lum(const float *rgb)
{
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

static rs_v3 pixel_world(int w, int h, const rs_pose *pose, size_t k)
{
    return rs_pose_dir_to_world(pose, rs_pano_pixel_dir(w, h, (int)(k % (size_t)w), (int)(k / (size_t)w)));
}

/* Interpolates one row's fill pixels in azimuth between the nearest source pixels (wrapping);
 * returns 0 when the row has no source pixel. */
static int fill_row(float *row, const uint8_t *src, const uint8_t *fill, int w)
{
    int first = -1;
    for (int c = 0; c < w && first < 0; c++)
        if (src[c]) first = c;
    if (first < 0) return 0;
    int a = first;
    for (int step = 1; step <= w; step++) {
        int b = (first + step) % w;
        if (!src[b] && step < w) continue;
        int gap = (b - a + w) % w;
        if (gap == 0) gap = w;
        for (int k = 1; k < gap; k++) {
            int c = (a + k) % w;
            if (!fill[c]) continue;
            double t = (double)k / gap;
            for (int ch = 0; ch < 3; ch++) row[3 * c + ch] = (float)((1 - t) * row[3 * a + ch] + t * row[3 * b + ch]);
        }
        a = b;
    }
    return 1;
}

/* The row method over the whole map. -1: out of memory. */
static int row_fill(int w, int h, float *rad, const uint8_t *src, const uint8_t *fill)
{
    int *has = calloc((size_t)h, sizeof *has);
    if (!has) return -1;
    for (int r = 0; r < h; r++)
        has[r] = fill_row(rad + 3 * (size_t)r * w, src + (size_t)r * w, fill + (size_t)r * w, w);
    for (int r = 0; r < h; r++) {
        if (has[r]) continue;
        int best = -1;
        for (int d = 1; d < h && best < 0; d++) {
            if (r - d >= 0 && has[r - d])
                best = r - d;
            else if (r + d < h && has[r + d])
                best = r + d;
        }
        if (best < 0) break; /* no source anywhere: nothing to copy */
        for (int c = 0; c < w; c++)
            if (fill[(size_t)r * w + c])
                memcpy(rad + 3 * ((size_t)r * w + c), rad + 3 * ((size_t)best * w + c), 3 * sizeof *rad);
    }
    free(has);
    return 0;
}

/* Upper bound of build_samples' count for a w x h map. */
static size_t max_cells(int w, int h)
{
    int f = (w + FIT_CELLS_W - 1) / FIT_CELLS_W;
    return (size_t)((w + f - 1) / f) * (size_t)((h + f - 1) / f);
}

/* Fitting samples: source pixels above the horizon, farther than mask_rad from the sun (when
 * sun is not NULL), not excluded, averaged over cells of f x f pixels. Returns the count. */
static size_t build_samples(int w, int h, const rs_pose *pose, const float *rad, const uint8_t *src,
                            const uint8_t *exclude, const rs_v3 *sun, double mask_rad, rs_skysample *out)
{
    int f = (w + FIT_CELLS_W - 1) / FIT_CELLS_W, cw = (w + f - 1) / f, chh = (h + f - 1) / f;
    size_t n = 0;
    double cos_mask = cos(mask_rad);
    for (int cr = 0; cr < chh; cr++)
        for (int cc = 0; cc < cw; cc++) {
            double sw = 0, srgb[3] = {0, 0, 0};
            rs_v3 sd = rs_v3_make(0, 0, 0);
            for (int r = cr * f; r < (cr + 1) * f && r < h; r++) {
                double om = rs_pano_pixel_solid_angle(w, h, r);
                for (int c = cc * f; c < (cc + 1) * f && c < w; c++) {
                    size_t k = (size_t)r * w + c;
                    if (!src[k] || (exclude && exclude[k])) continue;
                    rs_v3 d = pixel_world(w, h, pose, k);
                    if (d.z <= 0 || (sun && rs_v3_dot(d, *sun) > cos_mask)) continue;
                    sw += om;
                    sd = rs_v3_add(sd, rs_v3_scale(d, om));
                    for (int ch = 0; ch < 3; ch++) srgb[ch] += om * rad[3 * k + ch];
                }
            }
            if (!(sw > 0)) continue;
            out[n].dir = rs_v3_norm(sd);
            if (out[n].dir.z <= 0) continue;
            for (int ch = 0; ch < 3; ch++) out[n].rgb[ch] = srgb[ch] / sw;
            out[n].weight = sw;
            n++;
        }
    return n;
}

/* Model values for the fill pixels above the horizon (parallel: the whole map at the end). */
static void model_fill_sky(int w, int h, const rs_pose *pose, float *rad, const uint8_t *fill, const rs_skymodel *m,
                           int parallel)
{
    size_t npx = (size_t)w * h;
#pragma omp parallel for schedule(static) if (parallel)
    for (size_t k = 0; k < npx; k++) {
        if (!fill[k]) continue;
        rs_v3 d = pixel_world(w, h, pose, k);
        if (d.z <= 0) continue;
        double rgb[3];
        rs_skymodel_eval(m, d, rgb);
        for (int ch = 0; ch < 3; ch++) rad[3 * k + ch] = (float)rgb[ch];
    }
}

/* The world elevation band (nb of them, 0 at the horizon) of a direction below the horizon. */
static int ground_band(rs_v3 d, int nb)
{
    int b = (int)(asin(fmin(1, -d.z)) / (M_PI / 2) * nb);
    return b >= nb ? nb - 1 : b;
}

long rs_skyfill_ground_from_bands(int w, int h, const rs_pose *pose, float *rad, const uint8_t *src, uint8_t *fill,
                                  uint8_t which, double max_rad, rs_err *err)
{
    int nb = h / 2 > 0 ? h / 2 : 1;
    size_t npx = (size_t)w * h;
    double *acc = calloc(4 * (size_t)nb, sizeof *acc);
    int *nearest = malloc((size_t)nb * sizeof *nearest), *band = malloc(npx * sizeof *band);
    if (!acc || !nearest || !band) {
        free(acc);
        free(nearest);
        free(band);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory copying the measured ground below the horizon");
    }
    /* Each pixel's band (-1 above the horizon) on every thread; the sums below stay serial, in
     * pixel order, so they do not depend on the thread count. */
#pragma omp parallel for schedule(static)
    for (int r = 0; r < h; r++)
        for (size_t k = (size_t)r * w; k < (size_t)(r + 1) * w; k++) {
            band[k] = -1;
            if (!src[k] && fill[k] != which) continue;
            rs_v3 d = pixel_world(w, h, pose, k);
            if (d.z <= 0) band[k] = ground_band(d, nb);
        }
    for (int r = 0; r < h; r++) {
        double om = rs_pano_pixel_solid_angle(w, h, r);
        for (size_t k = (size_t)r * w; k < (size_t)(r + 1) * w; k++) {
            if (!src[k] || band[k] < 0) continue;
            int b = band[k];
            for (int ch = 0; ch < 3; ch++) acc[4 * b + ch] += om * rad[3 * k + ch];
            acc[4 * b + 3] += om;
        }
    }
    /* Each band's nearest band with measured ground (below first, then above), found once per
     * band: searched per pixel it was the stage's largest serial loop (perf: most of
     * rs_skyfill_run's own time, up to nb steps for each of a million ground pixels); -1 when
     * it is farther than max_rad. */
    int reach = max_rad >= M_PI / 2 ? nb : (int)ceil(max_rad / (M_PI / 2) * nb);
    for (int b = 0; b < nb; b++) {
        int best = -1;
        for (int dd = 0; dd <= reach && best < 0; dd++) {
            if (b - dd >= 0 && acc[4 * (b - dd) + 3] > 0)
                best = b - dd;
            else if (b + dd < nb && acc[4 * (b + dd) + 3] > 0)
                best = b + dd;
        }
        nearest[b] = best;
    }
    long set = 0;
    for (size_t k = 0; k < npx; k++) {
        if (fill[k] != which || band[k] < 0) continue;
        int best = nearest[band[k]];
        if (best < 0) continue;
        for (int ch = 0; ch < 3; ch++) rad[3 * k + ch] = (float)(acc[4 * best + ch] / acc[4 * best + 3]);
        fill[k] = 1;
        set++;
    }
    free(band);
    free(nearest);
    free(acc);
    return set;
}

/* Fill pixels below the horizon: the ground model, albedo * E_horizontal / pi of the completed
 * sky, marked RS_SKYFILL_GROUND_MODEL in fill; then those within RS_SKYFILL_GROUND_NEAR_RAD of a
 * band with measured ground take that band's mean instead. A camera's ground beyond the model
 * is often seen at grazing angles only (a courtyard's camera sees it over a low wall, 1 to 2
 * degrees down, 60 m away): copied to a wall's view 30 degrees down onto the ground next to the
 * building, it was 25 % too dark there. */
static int ground_fill(int w, int h, const rs_pose *pose, float *rad, const uint8_t *src, uint8_t *fill, double albedo,
                       rs_skyfill_report *rep)
{
    size_t npx = (size_t)w * h, below = 0;
    double eh[3] = {0, 0, 0}, *up = malloc(npx * sizeof *up);
    if (!up) return -1;
        /* The directions on every thread, the sum serial in pixel order (thread-count independent). */
#pragma omp parallel for schedule(static)
    for (int r = 0; r < h; r++)
        for (size_t k = (size_t)r * w; k < (size_t)(r + 1) * w; k++) up[k] = pixel_world(w, h, pose, k).z;
    for (int r = 0; r < h; r++) { /* E_h, and the marks */
        double om = rs_pano_pixel_solid_angle(w, h, r);
        for (size_t k = (size_t)r * w; k < (size_t)(r + 1) * w; k++) {
            if (up[k] <= 0) {
                if (fill[k]) {
                    fill[k] = RS_SKYFILL_GROUND_MODEL;
                    below++;
                }
                continue;
            }
            for (int ch = 0; ch < 3; ch++) eh[ch] += rad[3 * k + ch] * up[k] * om;
        }
    }
    free(up);
    for (int ch = 0; ch < 3; ch++) {
        rep->horizontal_irradiance[ch] = eh[ch];
        rep->ground_rgb[ch] = albedo * eh[ch] / M_PI;
    }
    for (size_t k = 0; k < npx; k++)
        if (fill[k] == RS_SKYFILL_GROUND_MODEL)
            for (int ch = 0; ch < 3; ch++) rad[3 * k + ch] = (float)rep->ground_rgb[ch];
    long copied = rs_skyfill_ground_from_bands(w, h, pose, rad, src, fill, RS_SKYFILL_GROUND_MODEL,
                                               RS_SKYFILL_GROUND_NEAR_RAD, NULL); /* rs_skyfill_run names it */
    if (copied < 0) return -1;
    rep->ground_model_pixels = below - (size_t)copied;
    rep->ground_from_albedo = below > 0 && copied == 0;
    return 0;
}

/* Held-out blocks: bit s (s < CV_SECTORS) for the world azimuth sector of a measured sky pixel
 * above the horizon, bit CV_SECTORS for the lowest CV_LOW_SHARE of that sky by solid angle. */
static void assign_folds(int w, int h, const rs_pose *pose, const uint8_t *src, const rs_v3 *sun, double mask_rad,
                         uint16_t *fold)
{
    size_t npx = (size_t)w * h;
    enum { NBIN = 900 };
    double hist[NBIN] = {0}, total = 0, cos_mask = cos(mask_rad);
    for (size_t k = 0; k < npx; k++) {
        fold[k] = 0;
        if (!src[k]) continue;
        rs_v3 d = pixel_world(w, h, pose, k);
        if (d.z <= 0 || rs_v3_dot(d, *sun) > cos_mask) continue;
        int s = (int)((atan2(d.y, d.x) + M_PI) / (2 * M_PI) * CV_SECTORS);
        fold[k] = (uint16_t)(1u << (s >= CV_SECTORS ? CV_SECTORS - 1 : s));
        double om = rs_pano_pixel_solid_angle(w, h, (int)(k / (size_t)w));
        int b = (int)(asin(fmin(1, d.z)) / (M_PI / 2) * NBIN);
        hist[b >= NBIN ? NBIN - 1 : b] += om;
        total += om;
    }
    int cut = 0;
    for (double acc = 0; cut < NBIN && acc + hist[cut] <= CV_LOW_SHARE * total; cut++) acc += hist[cut];
    for (size_t k = 0; k < npx; k++) {
        if (!fold[k]) continue;
        rs_v3 d = pixel_world(w, h, pose, k);
        int b = (int)(asin(fmin(1, d.z)) / (M_PI / 2) * NBIN);
        if (b <= cut) fold[k] |= (uint16_t)(1u << CV_SECTORS);
    }
}

/* Relative error of the integrated luminance of block f's pixels: predicted (pred) vs measured. */
static double block_error(int w, int h, const float *meas, const float *pred, const uint16_t *fold, int f, double *sr)
{
    double sm = 0, sp = 0, om_sum = 0;
    for (size_t k = 0; k < (size_t)w * h; k++) {
        if (!(fold[k] >> f & 1)) continue;
        double om = rs_pano_pixel_solid_angle(w, h, (int)(k / (size_t)w));
        sm += om * lum(meas + 3 * k);
        sp += om * lum(pred + 3 * k);
        om_sum += om;
    }
    *sr = om_sum;
    return sm > 0 ? (sp - sm) / sm : 0;
}

/* The mean angle from block f's pixels to the nearest measured pixel outside it, weighted by
 * their light (the block's error is an error of its light); 0 when it cannot be measured. */
static double block_distance(int w, int h, const float *meas, const uint16_t *fold, int f, const float *dist)
{
    double sd = 0, sw = 0;
    for (size_t k = 0; k < (size_t)w * h; k++) {
        if (!(fold[k] >> f & 1)) continue;
        double wt = rs_pano_pixel_solid_angle(w, h, (int)(k / (size_t)w)) * lum(meas + 3 * k);
        sd += wt * dist[k];
        sw += wt;
    }
    return sw > 0 ? sd / sw : 0;
}

/* One held-out block f: the row method's relative error into *e_row and the model's at each
 * residual order (-1 .. max) into e_model, and the block's distance from the sky left
 * (block_distance) into *dist_f; returns 0 when the block has too little sky or the fit fails
 * (it is then left out), 1 when counted, -1 out of memory. */
static int cross_validate_block(int w, int h, const rs_pose *pose, const float *rad, const uint8_t *src,
                                const uint16_t *fold, int f, const rs_skyfill_opts *o, rs_v3 sun, double *e_row,
                                double *e_model, double *dist_f)
{
    size_t npx = (size_t)w * h;
    /* calloc, not malloc: GCC 12 does not see that the loop below writes every byte and warns
     * (-Wmaybe-uninitialized) where rs_skydist_to_source reads them. */
    uint8_t *src_f = calloc(npx, 1), *fill_f = calloc(npx, 1);
    float *tmp = malloc(3 * npx * sizeof *tmp);
    rs_skysample *samples = malloc(max_cells(w, h) * sizeof *samples);
    int rc = -1;
    if (!src_f || !fill_f || !tmp || !samples) goto out;
    for (size_t k = 0; k < npx; k++) {
        fill_f[k] = (uint8_t)(fold[k] >> f & 1);
        src_f[k] = (uint8_t)(src[k] && !fill_f[k]);
    }
    /* tmp's first w * h floats hold the distances until the row fill needs it. */
    if (rs_skydist_to_source(w, h, src_f, fill_f, tmp, NULL) != 0) goto out; /* parallel: rs_skyfill_run names it */
    *dist_f = block_distance(w, h, rad, fold, f, tmp);
    double sr;
    memcpy(tmp, rad, 3 * npx * sizeof *tmp);
    if (row_fill(w, h, tmp, src_f, fill_f) != 0) goto out;
    *e_row = block_error(w, h, rad, tmp, fold, f, &sr);
    rc = 0;
    rs_skymodel m;
    size_t n = build_samples(w, h, pose, rad, src_f, NULL, &sun, o->sun_mask_rad, samples);
    if (sr < CV_MIN_SR || rs_skymodel_fit(samples, n, sun, -1, o->sh_ridge, &m) != 0) goto out;
    for (int q = 0; q < o->sh_order + 2; q++) {
        rs_skymodel_refit_sh(samples, n, q - 1, o->sh_ridge, &m);
        model_fill_sky(w, h, pose, tmp, fill_f, &m, 0); /* overwrites exactly the block */
        e_model[q] = block_error(w, h, rad, tmp, fold, f, &sr);
    }
    rc = 1;
out:
    free(src_f);
    free(fill_f);
    free(tmp);
    free(samples);
    return rc;
}

/* Both methods' held-out errors, and the residual order the model does best with. Blocks run
 * in parallel; the sums are taken in block order afterwards, so the result is the same for any
 * thread count. */
static int cross_validate(int w, int h, const rs_pose *pose, const float *rad, const uint8_t *src,
                          const rs_skyfill_opts *o, rs_v3 sun, rs_skyfill_report *rep, int *best_order)
{
    size_t npx = (size_t)w * h;
    enum { NB = CV_SECTORS + 1, NQ = RS_SKYMODEL_MAX_SH + 2 };
    uint16_t *fold = malloc(npx * sizeof *fold);
    if (!fold) return -1;
    assign_folds(w, h, pose, src, &sun, o->sun_mask_rad, fold);
    double e_row[NB], e_model[NB][NQ], dist[NB];
    int status[NB];
#pragma omp parallel for schedule(dynamic, 1)
    for (int f = 0; f < NB; f++)
        status[f] = cross_validate_block(w, h, pose, rad, src, fold, f, o, sun, &e_row[f], e_model[f], &dist[f]);
    free(fold);
    int norders = o->sh_order + 2, nf = 0;
    double se_row = 0, se_model[NQ] = {0};
    for (int f = 0; f < NB; f++) {
        if (status[f] < 0) return -1;
        if (status[f] == 0) continue;
        nf++;
        se_row += e_row[f] * e_row[f];
        for (int q = 0; q < norders; q++) se_model[q] += e_model[f][q] * e_model[f][q];
    }
    rep->cv_folds = nf;
    if (nf > 0) {
        rep->cv_rel_row = sqrt(se_row / nf);
        int bq = 0;
        for (int q = 1; q < norders; q++)
            if (se_model[q] < se_model[bq]) bq = q;
        rep->cv_rel_model = sqrt(se_model[bq] / nf);
        *best_order = bq - 1;
        rep->cv_max_row = rep->cv_max_model = 0;
        rep->cv_rate_row = rep->cv_rate_model = 0;
        for (int f = 0; f < NB; f++)
            if (status[f] == 1) {
                rep->cv_max_row = fmax(rep->cv_max_row, fabs(e_row[f]));
                rep->cv_max_model = fmax(rep->cv_max_model, fabs(e_model[f][bq]));
                /* A block next to the data (distance below one grid cell) says nothing of the
                 * rate: its error counts as if one cell away. */
                double d = sqrt(fmax(dist[f], 2 * M_PI / RS_SKYDIST_CELLS_W));
                rep->cv_rate_row = fmax(rep->cv_rate_row, fabs(e_row[f]) / d);
                rep->cv_rate_model = fmax(rep->cv_rate_model, fabs(e_model[f][bq]) / d);
                rs_log_debug("skyfill: held-out block %d: %.1f deg from the sky left, error rows %+.4f, model %+.4f", f,
                             dist[f] * 180 / M_PI, e_row[f], e_model[f][bq]);
            }
    }
    return 0;
}

/* The RMS of about 9 blocks (the earlier choice) underestimates sigma more often than not, and
 * covered the fill's actual albedo change on 9 % of the courtyard's facets at 1 sigma. */
double rs_skyfill_sigma_from_blocks(int blocks, double largest_error)
{
    if (blocks < 1 || !(largest_error >= 0)) return 1;
    double p = (double)blocks / (blocks + 1), lo = 0, hi = 10;
    for (int k = 0; k < 100; k++) { /* bisection: erf(z / sqrt 2) = p */
        double mid = 0.5 * (lo + hi);
        if (erf(mid / sqrt(2.0)) < p)
            lo = mid;
        else
            hi = mid;
    }
    return largest_error / (0.5 * (lo + hi));
}

double rs_skyfill_rate_used(const rs_skyfill_report *rep, rs_skyfill_method method)
{
    double rate = method == RS_SKYFILL_MODEL && rep->fit_samples ? rep->cv_rate_model : rep->cv_rate_row;
    return rate >= 0 ? rs_skyfill_sigma_from_blocks(rep->cv_folds, rate) : -1;
}

int rs_skyfill_sigma_map(int w, int h, const uint8_t *src, const uint8_t *fill, const rs_skyfill_report *rep,
                         rs_skyfill_method method, float *sigma, rs_err *err)
{
    size_t npx = (size_t)w * h;
    double rate = rs_skyfill_rate_used(rep, method);
    if (!(rate >= 0)) {
        for (size_t k = 0; k < npx; k++) sigma[k] = fill[k] ? 1.0f : 0.0f;
        return 0;
    }
    if (rs_skydist_to_source(w, h, src, fill, sigma, err) != 0) return -1;
#pragma omp parallel for schedule(static)
    for (int r = 0; r < h; r++)
        for (size_t k = (size_t)r * w; k < (size_t)(r + 1) * w; k++)
            sigma[k] = fill[k] ? (float)fmin(1, rate * sqrt(fmax(sigma[k], 2 * M_PI / RS_SKYDIST_CELLS_W))) : 0.0f;
    return 0;
}

/* Every failure of rs_skyfill_run (its steps return a bare -1). */
static int fill_out_of_memory(rs_err *err)
{
    return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory filling the sky map");
}

int rs_skyfill_run(int w, int h, const rs_pose *pose, float *rad, const uint8_t *src, uint8_t *fill, const uint8_t *sun,
                   const rs_skyfill_opts *o, rs_skyfill_report *rep, rs_err *err)
{
    memset(rep, 0, sizeof *rep);
    rep->cv_rel_row = rep->cv_rel_model = -1;
    rep->cv_max_row = rep->cv_max_model = -1;
    rep->cv_rate_row = rep->cv_rate_model = -1;
    rep->model.sh_order = -1;
    size_t npx = (size_t)w * h;
    /* The sun: given, else the luminance-weighted centroid of the sun set, else searched. */
    rs_v3 sun_dir = o->sun_dir;
    rep->sun_source = RS_SUN_CONFIG;
    if (!o->sun_given) {
        rs_v3 acc = rs_v3_make(0, 0, 0);
        for (size_t k = 0; sun && k < npx; k++)
            if (sun[k])
                acc = rs_v3_add(acc,
                                rs_v3_scale(pixel_world(w, h, pose, k),
                                            lum(rad + 3 * k) * rs_pano_pixel_solid_angle(w, h, (int)(k / (size_t)w))));
        sun_dir = rs_v3_norm(acc);
        rep->sun_source = RS_SUN_PIXELS;
    }
    rs_skysample *samples = malloc(max_cells(w, h) * sizeof *samples);
    if (!samples) return fill_out_of_memory(err);
    if (rs_v3_len(sun_dir) == 0) {
        size_t n = build_samples(w, h, pose, rad, src, NULL, NULL, 0, samples);
        sun_dir = rs_skymodel_find_sun(samples, n);
        rep->sun_source = RS_SUN_SEARCH;
    }
    rep->sun_dir = sun_dir;
    int order = o->sh_order;
    if (o->cross_validate) {
        /* Block errors are integrals over large regions: a coarser map (box-filtered by f x f,
         * a source where all its pixels are) measures them as well, in bounded memory. */
        int f = 1;
        while (w / f > CV_MAX_W && w % (2 * f) == 0 && h % (2 * f) == 0) f *= 2;
        int w2 = w / f, h2 = h / f;
        float *rad2 = f > 1 ? calloc(3 * (size_t)w2 * h2, sizeof *rad2) : rad;
        uint8_t *src2 = f > 1 ? malloc((size_t)w2 * h2) : (uint8_t *)src;
        int rc_cv = -1;
        if (rad2 && src2) {
            for (int r2 = 0; f > 1 && r2 < h2; r2++)
                for (int c2 = 0; c2 < w2; c2++) {
                    size_t k2 = (size_t)r2 * w2 + c2;
                    int all = 1;
                    for (int r = r2 * f; r < (r2 + 1) * f; r++)
                        for (int c = c2 * f; c < (c2 + 1) * f; c++) {
                            size_t k = (size_t)r * w + c;
                            all &= src[k];
                            for (int ch = 0; ch < 3; ch++) rad2[3 * k2 + ch] += rad[3 * k + ch] / (float)(f * f);
                        }
                    src2[k2] = (uint8_t)all;
                }
            rc_cv = cross_validate(w2, h2, pose, rad2, src2, o, sun_dir, rep, &order);
        }
        if (f > 1) {
            free(rad2);
            free(src2);
        }
        if (rc_cv != 0) {
            free(samples);
            return fill_out_of_memory(err);
        }
    }
    int rc = 0;
    if (o->method == RS_SKYFILL_MODEL) {
        size_t n = build_samples(w, h, pose, rad, src, NULL, &sun_dir, o->sun_mask_rad, samples);
        rep->fit_samples = n;
        if (rs_skymodel_fit(samples, n, sun_dir, order, o->sh_ridge, &rep->model) == 0) {
            model_fill_sky(w, h, pose, rad, fill, &rep->model, 1);
            rc = ground_fill(w, h, pose, rad, src, fill, o->ground_albedo, rep);
        } else {
            rc = row_fill(w, h, rad, src, fill); /* too little sky to fit: rows at least */
            rep->fit_samples = 0;
        }
        rep->fill_sigma = rep->fit_samples ? rep->cv_rel_model : rep->cv_rel_row;
    } else {
        rc = row_fill(w, h, rad, src, fill);
        rep->fill_sigma = rep->cv_rel_row;
    }
    /* No held-out block had enough sky: the fill's error is unknown, call it 100 %. */
    if (!(rep->fill_sigma > 0)) rep->fill_sigma = 1;
    free(samples);
    return rc != 0 ? fill_out_of_memory(err) : 0;
}
