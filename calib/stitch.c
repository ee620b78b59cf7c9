/* stitch: rig frames -> equirectangular panorama (see stitch.h). Each panorama pixel's direction,
 * or with the model the point its ray from the rig centre hits, is projected into every camera
 * (from the camera's own centre when the point is at a finite depth), sampled bilinearly where
 * the lens model is usable, and blended with weights that fall smoothly to 0 at the usable edge,
 * so seams do not show as steps. */
#include "calib/stitch.h"

#include <stdlib.h>
#include <string.h>
#include "calib/calib_math.h"
#include "calib/gains.h"
#include "common/linsolve.h"
#include "common/pano.h"

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

/* Where one panorama pixel falls in one camera: ok = 0 when the camera does not see it through the
 * usable part of its lens, or (with the model) when the model hides the point from the camera. */
typedef struct {
    double x, y, margin;
    int ok;
} cam_px;

/* The panorama row r seen by every camera: plan[col * n + i]. Without a scene the cameras look
 * along the pixel's direction (infinite depth). With one, each pixel's ray from the rig centre
 * is cast into the model; a hit at depth t is the rig-frame point t d, which camera i sees along
 * R_i^T (t d - t_i), provided nothing lies between the camera's centre and the point. Returns
 * the row's solid angle with model depth in *model_sa and the hidden camera samples in *hidden
 * (of *candidates). */
static int plan_row(const rs_rig *rig, const rs_stitch_opts *o, int r, cam_px *plan, double *model_sa, double *hidden,
                    double *candidates)
{
    int n = rig->count, w = o->width, h = o->width / 2;
    rs_ray *rays = NULL;
    rs_hit *hits = NULL;
    uint8_t *occ = NULL;
    int *map = NULL;
    if (o->scene) {
        rays = malloc((size_t)w * (n + 1) * sizeof *rays); /* the row's rays, then the cameras' */
        hits = malloc((size_t)w * sizeof *hits);
        occ = malloc((size_t)w * n);
        map = malloc((size_t)w * n * sizeof *map);
        if (!rays || !hits || !occ || !map) {
            free(rays);
            free(hits);
            free(occ);
            free(map);
            return -1;
        }
        for (int col = 0; col < w; col++) {
            rays[col].org = o->pose.position;
            rays[col].dir = rs_pose_dir_to_world(&o->pose, rs_pano_pixel_dir(w, h, col, r));
            rays[col].tnear = 0;
            rays[col].tfar = INFINITY;
        }
        rs_scene_intersect(o->scene, rays, hits, (size_t)w);
    }
    int nocc = 0;
    for (int col = 0; col < w; col++) {
        rs_v3 d = rs_pano_pixel_dir(w, h, col, r);
        double t = hits && hits[col].face != RS_NO_HIT ? hits[col].t : INFINITY;
        if (isfinite(t)) *model_sa += rs_pano_pixel_solid_angle(w, h, r);
        for (int i = 0; i < n; i++) {
            const rs_rig_camera *c = &rig->cams[i];
            cam_px *p = &plan[(size_t)col * n + i];
            rs_v3 d_rig = isfinite(t) ? rs_v3_sub(rs_v3_scale(d, t), c->t_rig_cam) : d;
            p->ok = rs_rig_project(c, rs_m3_mul_vt(c->r_rig_cam, d_rig), &p->x, &p->y, &p->margin);
            if (!p->ok || !o->scene) continue;
            /* Is the point hidden from this camera? A ray from the camera's centre to just short
             * of the point: the scan's mesh is only approximately where the surface is, so stop
             * 1 % of the distance short (occluders that close shift the view very little). For
             * the sky the ray is the pixel's direction from the camera's centre: near a roof
             * line, a camera closer to the wall sees the wall where the rig centre sees sky. */
            rs_v3 cw = rs_v3_add(o->pose.position, rs_pose_dir_to_world(&o->pose, c->t_rig_cam));
            rs_ray *q = &rays[w + nocc];
            q->org = cw;
            if (isfinite(t)) {
                rs_v3 pw = rs_v3_add(o->pose.position, rs_v3_scale(rays[col].dir, t));
                q->dir = rs_v3_sub(pw, cw);
                double len = rs_v3_len(q->dir);
                q->tnear = len > 0 ? rs_scene_offset(o->scene, cw) / len : 0;
                q->tfar = 1 - fmax(0.01, len > 0 ? rs_scene_offset(o->scene, pw) / len : 0);
            } else {
                q->dir = rays[col].dir;
                q->tnear = rs_scene_offset(o->scene, cw);
                q->tfar = INFINITY;
            }
            map[nocc++] = col * n + i;
        }
    }
    if (nocc) {
        rs_scene_occluded(o->scene, rays + w, occ, (size_t)nocc);
        *candidates += nocc;
        for (int k = 0; k < nocc; k++)
            if (occ[k]) {
                plan[map[k]].ok = 0;
                *hidden += 1;
            }
    }
    free(rays);
    free(hits);
    free(occ);
    free(map);
    return 0;
}

/* Camera c's bilinear sample at its planned pixel, vignetting divided out, and its blending
 * weight; 0 when the camera does not see the pixel, its mask rules the pixel out, or its frame
 * holds no finite value there. */
static int sample_camera(const rs_rig_camera *cam, const cam_px *p, const rs_image *img, double feather, float rgb[3],
                         double *weight)
{
    if (!p->ok) return 0;
    double x = p->x, y = p->y;
    int x0 = (int)floor(x), y0 = (int)floor(y);
    int x1 = x0 + 1 < img->width ? x0 + 1 : x0, y1 = y0 + 1 < img->height ? y0 + 1 : y0;
    if (cam->mask) { /* every tap of the bilinear sample valid */
        const unsigned char *m = cam->mask;
        size_t w = (size_t)cam->width;
        if (!m[y0 * w + x0] || !m[y0 * w + x1] || !m[y1 * w + x0] || !m[y1 * w + x1]) return 0;
    }
    double fx = x - x0, fy = y - y0, vig = rs_rig_vignetting(cam, x, y);
    const float *p00 = rs_image_px(img, x0, y0), *p10 = rs_image_px(img, x1, y0);
    const float *p01 = rs_image_px(img, x0, y1), *p11 = rs_image_px(img, x1, y1);
    for (int ch = 0; ch < 3; ch++) {
        double v = (1 - fy) * ((1 - fx) * p00[ch] + fx * p10[ch]) + fy * ((1 - fx) * p01[ch] + fx * p11[ch]);
        if (!isfinite(v)) return 0;
        rgb[ch] = (float)(v / vig);
    }
    double t = fmin(fmax(p->margin / feather, 0), 1);
    /* smoothstep: no kink in the blend at either end of the ramp; the floor keeps pixels that
     * only one camera sees, right at its edge. */
    *weight = t * t * (3 - 2 * t) + 1e-6;
    return 1;
}

static double luminance(const float *rgb)
{
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

/* Pixels the gain estimate leaves out: the outer quarter of the feathering ramp (where the lens
 * model, vignetting and flare are least trustworthy), pixels at or near the frame's saturation
 * (0.99 of its largest value), and pixels where log luminance changes by more than
 * GAIN_MAX_LOG_GRADIENT per camera pixel (roof lines against the sky, the sun's halo: a
 * fraction of a pixel of registration error there is a large ratio error). */
#define GAIN_EDGE_SHARE       0.25
#define GAIN_SATURATION       0.99
#define GAIN_MAX_LOG_GRADIENT 0.25

static double log_lum_at(const rs_image *img, int x, int y)
{
    double l = luminance(rs_image_px(img, x, y));
    return l > 0 ? log(l) : -INFINITY;
}

/* Whether camera c's sample at p may enter the gain estimate, and its weight there. */
static int gain_usable(const cam_px *p, const rs_image *img, const float *rgb, double saturation, double feather,
                       double *weight)
{
    if (p->margin < GAIN_EDGE_SHARE * feather) return 0;
    if (fmaxf(rgb[0], fmaxf(rgb[1], rgb[2])) >= saturation || !(luminance(rgb) > 0)) return 0;
    int x = (int)lround(p->x), y = (int)lround(p->y);
    x = x < 1 ? 1 : x > img->width - 2 ? img->width - 2 : x;
    y = y < 1 ? 1 : y > img->height - 2 ? img->height - 2 : y;
    if (img->width >= 3 && img->height >= 3) {
        double gx = 0.5 * (log_lum_at(img, x + 1, y) - log_lum_at(img, x - 1, y));
        double gy = 0.5 * (log_lum_at(img, x, y + 1) - log_lum_at(img, x, y - 1));
        if (!(fabs(gx) <= GAIN_MAX_LOG_GRADIENT && fabs(gy) <= GAIN_MAX_LOG_GRADIENT)) return 0;
    }
    double t = fmin(p->margin / feather, 1);
    *weight = t * t * (3 - 2 * t);
    return 1;
}

/* The largest finite channel value of a frame, times GAIN_SATURATION: at or above it a pixel
 * may be clipped. */
static double saturation_level(const rs_image *img)
{
    double m = 0;
    size_t n = (size_t)img->width * img->height * img->channels;
    for (size_t k = 0; k < n; k++)
        if (isfinite(img->data[k])) m = fmax(m, img->data[k]);
    return m > 0 ? GAIN_SATURATION * m : INFINITY;
}

/* One row's gain samples: pair index i * n + j with the log ratio and weight. */
typedef struct {
    size_t count, cap;
    int *pair;
    float *log_ratio, *weight;
} row_samples;

static int row_add(row_samples *r, int pair, double lr, double w)
{
    if (r->count == r->cap) {
        size_t cap = r->cap ? 2 * r->cap : 1024;
        int *pp = realloc(r->pair, cap * sizeof *pp);
        if (pp) r->pair = pp;
        float *lp = realloc(r->log_ratio, cap * sizeof *lp);
        if (lp) r->log_ratio = lp;
        float *wp = realloc(r->weight, cap * sizeof *wp);
        if (wp) r->weight = wp;
        if (!pp || !lp || !wp) return -1;
        r->cap = cap;
    }
    r->pair[r->count] = pair;
    r->log_ratio[r->count] = (float)lr;
    r->weight[r->count++] = (float)w;
    return 0;
}

/* Row r's samples: every pair of cameras that both may use a pixel. */
static int gain_row(const rs_rig *rig, rs_image *const *frames, const rs_stitch_opts *o, const double *sat, int r,
                    row_samples *out)
{
    int n = rig->count, w = o->width;
    double unused[3] = {0, 0, 0};
    cam_px *plan = malloc((size_t)w * n * sizeof *plan);
    if (!plan || plan_row(rig, o, r, plan, &unused[0], &unused[1], &unused[2]) != 0) {
        free(plan);
        return -1;
    }
    for (int col = 0; col < w; col++) {
        float rgb[64][3];
        double wt[64], unused_w;
        int use[64];
        for (int i = 0; i < n; i++) {
            const cam_px *p = &plan[(size_t)col * n + i];
            use[i] = sample_camera(&rig->cams[i], p, frames[i], o->feather_px, rgb[i], &unused_w) &&
                gain_usable(p, frames[i], rgb[i], sat[i], o->feather_px, &wt[i]);
        }
        for (int i = 0; i < n; i++)
            for (int j = i + 1; j < n; j++)
                if (use[i] && use[j] &&
                    row_add(out, i * n + j, log(luminance(rgb[i]) / luminance(rgb[j])), wt[i] * wt[j]) != 0) {
                    free(plan);
                    return -1;
                }
    }
    free(plan);
    return 0;
}

/* The gains: samples of every row, gathered per pair in row order (the result is the same for
 * any thread count), then rs_gains_solve with the rig's known gains. */
static int estimate_gains(const rs_rig *rig, rs_image *const *frames, const rs_stitch_opts *o, double *gains,
                          rs_gain_report *report)
{
    int n = rig->count, h = o->width / 2, failed = 0;
    double sat[64], known[64];
    for (int i = 0; i < n; i++) sat[i] = saturation_level(frames[i]), known[i] = rig->cams[i].gain;
    row_samples *rows = calloc((size_t)h, sizeof *rows);
    rs_gain_samples *pairs = calloc((size_t)n * n, sizeof *pairs);
    if (!rows || !pairs) failed = 1;
#pragma omp parallel for schedule(dynamic, 8)
    for (int r = 0; r < h; r++) {
        if (failed) continue;
        if (gain_row(rig, frames, o, sat, r, &rows[r]) != 0) {
#pragma omp atomic write
            failed = 1;
        }
    }
    for (int r = 0; r < h && !failed; r++)
        for (size_t k = 0; k < rows[r].count && !failed; k++)
            failed = rs_gain_samples_add(&pairs[rows[r].pair[k]], rows[r].log_ratio[k], rows[r].weight[k]) != 0;
    for (int r = 0; rows && r < h; r++) free(rows[r].pair), free(rows[r].log_ratio), free(rows[r].weight);
    free(rows);
    if (!failed && rs_gains_solve(n, pairs, known, gains, report) != 0) failed = 1;
    for (int k = 0; pairs && k < n * n; k++) rs_gain_samples_free(&pairs[k]);
    free(pairs);
    return failed ? -1 : 0;
}

int rs_stitch(const rs_rig *rig, rs_image *const *frames, const rs_stitch_opts *opts, rs_image **pano, double *gains,
              rs_stitch_stats *stats, rs_err *err)
{
    int n = rig->count, w = opts->width, h = opts->width / 2;
    *pano = NULL;
    memset(stats, 0, sizeof *stats);
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
    double *row_stat = calloc((size_t)h * 4, sizeof *row_stat);
    int failed = 0;
    if (!out || !row_stat) goto oom;
    if (opts->estimate_gain) {
        if (estimate_gains(rig, frames, opts, gains, &stats->gain) != 0) goto oom;
        stats->overlap_pairs = stats->gain.npairs;
    } else
        for (int i = 0; i < n; i++) gains[i] = rig->cams[i].gain > 0 ? rig->cams[i].gain : 1;
#pragma omp parallel for schedule(dynamic, 8)
    for (int r = 0; r < h; r++) {
        double *st = row_stat + (size_t)r * 4;
        cam_px *plan = malloc((size_t)w * n * sizeof *plan);
        if (!plan || plan_row(rig, opts, r, plan, &st[1], &st[2], &st[3]) != 0) {
#pragma omp atomic write
            failed = 1;
            free(plan);
            continue;
        }
        for (int col = 0; col < w; col++) {
            double acc[3] = {0, 0, 0}, wsum = 0, wt;
            float rgb[3];
            for (int i = 0; i < n; i++) {
                if (!sample_camera(&rig->cams[i], &plan[(size_t)col * n + i], frames[i], opts->feather_px, rgb, &wt))
                    continue;
                for (int ch = 0; ch < 3; ch++) acc[ch] += wt * rgb[ch] / gains[i];
                wsum += wt;
            }
            float *px = rs_image_px(out, col, r);
            for (int ch = 0; ch < 3; ch++) px[ch] = wsum > 0 ? (float)(acc[ch] / wsum) : NAN;
            if (wsum > 0) st[0] += rs_pano_pixel_solid_angle(w, h, r);
        }
        free(plan);
    }
    if (failed) goto oom;
    double sum[4] = {0, 0, 0, 0};
    for (int r = 0; r < h; r++)
        for (int k = 0; k < 4; k++) sum[k] += row_stat[(size_t)r * 4 + k];
    stats->coverage = sum[0] / (4 * M_PI);
    stats->model_coverage = sum[1] / (4 * M_PI);
    stats->hidden_share = sum[3] > 0 ? sum[2] / sum[3] : 0;
    free(row_stat);
    *pano = out;
    return 0;
oom:
    rs_image_free(out);
    free(row_stat);
    rs_gain_report_free(&stats->gain);
    return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for a %d x %d panorama from %d cameras", w, h, n);
}
