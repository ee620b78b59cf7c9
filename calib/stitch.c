/* stitch: rig frames -> equirectangular panorama (see stitch.h). Each panorama pixel's direction
 * is projected into every camera (infinite depth: the cameras' offsets from the rig centre are
 * ignored), sampled bilinearly where the lens model is usable, and blended with weights that fall
 * smoothly to 0 at the usable edge, so seams do not show as steps. */
#include "stitch.h"

#include <stdlib.h>
#include <string.h>
#include "calib_math.h"
#include "linsolve.h"
#include "pano.h"

#define MIN_OVERLAP_PX 64      /* fewer shared pixels say too little about a gain ratio */

int rs_stitch_default_width(const rs_rig *rig)
{
    double f = 0;
    for (int i = 0; i < rig->count; i++) f = fmax(f, fmax(rig->cams[i].fx, rig->cams[i].fy));
    int w = (int)ceil(2 * M_PI * f);
    w += w & 1;
    return w < 16 ? 16 : w > 65536 ? 65536 : w;
}

int rs_stitch_width(const rs_rig *rig, int configured_width)
{
    int w = configured_width > 0 ? configured_width : rs_stitch_default_width(rig);
    return w + (w & 1);
}

/* Camera i's bilinear sample of the rig direction d and its blending weight; 0 when the
 * camera does not see d through the usable part of its lens. */
static int sample_camera(const rs_rig_camera *c, const rs_image *img, rs_v3 d_rig, double feather, float rgb[3],
                         double *weight)
{
    double x, y, margin;
    if (!rs_rig_project(c, rs_m3_mul_vt(c->r_rig_cam, d_rig), &x, &y, &margin)) return 0;
    int x0 = (int)floor(x), y0 = (int)floor(y);
    int x1 = x0 + 1 < img->width ? x0 + 1 : x0, y1 = y0 + 1 < img->height ? y0 + 1 : y0;
    double fx = x - x0, fy = y - y0;
    const float *p00 = rs_image_px(img, x0, y0), *p10 = rs_image_px(img, x1, y0);
    const float *p01 = rs_image_px(img, x0, y1), *p11 = rs_image_px(img, x1, y1);
    for (int ch = 0; ch < 3; ch++) {
        double v = (1 - fy) * ((1 - fx) * p00[ch] + fx * p10[ch]) + fy * ((1 - fx) * p01[ch] + fx * p11[ch]);
        if (!isfinite(v)) return 0;
        rgb[ch] = (float)v;
    }
    double t = fmin(fmax(margin / feather, 0), 1);
    /* smoothstep: no kink in the blend at either end of the ramp; the floor keeps pixels that
     * only one camera sees, right at its edge. */
    *weight = t * t * (3 - 2 * t) + 1e-6;
    return 1;
}

static double luminance(const float *rgb)
{
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

/* Per-camera log corrections x from the overlaps: for each camera pair with enough shared
 * pixels, x_i + ln S_ij = x_j + ln S_ji in the least-squares sense (S_ij: camera i's summed
 * luminance over the pixels it shares with j), weighted by the shared pixel count, with
 * sum x_i = 0. The correction divides out gain_i = exp(-x_i). */
static int solve_gains(int n, const double *sum, const double *count, double *gains, int *pairs)
{
    double *a = calloc((size_t)n * n, sizeof *a), *b = calloc((size_t)n, sizeof *b);
    if (!a || !b) {
        free(a);
        free(b);
        return -1;
    }
    double wsum = 0;
    *pairs = 0;
    for (int i = 0; i < n; i++)
        for (int j = i + 1; j < n; j++) {
            double w = count[i * n + j];
            if (w < MIN_OVERLAP_PX || !(sum[i * n + j] > 0) || !(sum[j * n + i] > 0)) continue;
            double c = log(sum[i * n + j]) - log(sum[j * n + i]);
            a[i * n + i] += w;
            a[j * n + j] += w;
            a[i * n + j] -= w;
            a[j * n + i] -= w;
            b[i] -= w * c;
            b[j] += w * c;
            wsum += w;
            (*pairs)++;
        }
    double lam = wsum > 0 ? wsum / n : 1;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) a[i * n + j] += lam / n + (i == j ? 1e-9 * lam : 0);
    int rc = rs_solve_dense(a, b, (size_t)n);
    for (int i = 0; i < n; i++) gains[i] = rc == 0 ? exp(-b[i]) : 1;
    free(a);
    free(b);
    return 0;
}

int rs_stitch(const rs_rig *rig, rs_image *const *frames, const rs_stitch_opts *opts, rs_image **pano,
              double *gains, rs_stitch_stats *stats, rs_err *err)
{
    int n = rig->count, w = opts->width, h = opts->width / 2;
    *pano = NULL;
    if (n > 64) return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "%d cameras: at most 64 are supported", n);
    for (int i = 0; i < n; i++) {
        gains[i] = 1;
        if (frames[i]->width != rig->cams[i].width || frames[i]->height != rig->cams[i].height ||
            frames[i]->channels != 3)
            return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "frame %d is %d x %d x %d: expected %d x %d x 3 (camera %s)",
                              i, frames[i]->width, frames[i]->height, frames[i]->channels, rig->cams[i].width,
                              rig->cams[i].height, rig->cams[i].name);
    }
    rs_image *out = rs_image_new(w, h, 3);
    /* Per-row overlap sums, reduced in row order afterwards so the result does not depend on
     * the thread count. */
    size_t nn = (size_t)n * n;
    double *row_sum = opts->estimate_gain ? calloc((size_t)h * nn, sizeof *row_sum) : NULL;
    double *row_cnt = opts->estimate_gain ? calloc((size_t)h * nn, sizeof *row_cnt) : NULL;
    if (!out || (opts->estimate_gain && (!row_sum || !row_cnt))) {
        rs_image_free(out);
        free(row_sum);
        free(row_cnt);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for a %d x %d panorama", w, h);
    }
    if (opts->estimate_gain) {
#pragma omp parallel for schedule(dynamic, 8)
        for (int r = 0; r < h; r++) {
            float rgb[64][3];
            int seen[64];
            double *s = row_sum + (size_t)r * nn, *c = row_cnt + (size_t)r * nn, wt;
            for (int col = 0; col < w; col++) {
                rs_v3 d = rs_pano_pixel_dir(w, h, col, r);
                for (int i = 0; i < n; i++) seen[i] = sample_camera(&rig->cams[i], frames[i], d, 1, rgb[i], &wt);
                for (int i = 0; i < n; i++)
                    for (int j = i + 1; j < n; j++)
                        if (seen[i] && seen[j]) {
                            s[i * n + j] += luminance(rgb[i]);
                            s[j * n + i] += luminance(rgb[j]);
                            c[i * n + j] += 1;
                        }
            }
        }
        for (int r = 1; r < h; r++)
            for (size_t k = 0; k < nn; k++) {
                row_sum[k] += row_sum[(size_t)r * nn + k];
                row_cnt[k] += row_cnt[(size_t)r * nn + k];
            }
        if (solve_gains(n, row_sum, row_cnt, gains, &stats->overlap_pairs) != 0) {
            rs_image_free(out);
            free(row_sum);
            free(row_cnt);
            return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        }
    } else {
        stats->overlap_pairs = 0;
    }
    free(row_sum);
    free(row_cnt);
    double *row_cover = calloc((size_t)h, sizeof *row_cover);
    if (!row_cover) {
        rs_image_free(out);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    }
#pragma omp parallel for schedule(dynamic, 8)
    for (int r = 0; r < h; r++) {
        for (int col = 0; col < w; col++) {
            rs_v3 d = rs_pano_pixel_dir(w, h, col, r);
            double acc[3] = {0, 0, 0}, wsum = 0, wt;
            float rgb[3];
            for (int i = 0; i < n; i++) {
                if (!sample_camera(&rig->cams[i], frames[i], d, opts->feather_px, rgb, &wt)) continue;
                for (int ch = 0; ch < 3; ch++) acc[ch] += wt * rgb[ch] / gains[i];
                wsum += wt;
            }
            float *px = rs_image_px(out, col, r);
            for (int ch = 0; ch < 3; ch++) px[ch] = wsum > 0 ? (float)(acc[ch] / wsum) : NAN;
            if (wsum > 0) row_cover[r] += rs_pano_pixel_solid_angle(w, h, r);
        }
    }
    double cover = 0;
    for (int r = 0; r < h; r++) cover += row_cover[r];
    free(row_cover);
    stats->coverage = cover / (4 * M_PI);
    *pano = out;
    return 0;
}
