/* skyenv: environment map from the panorama's sky portion (see skyenv.h). */
#include "sky/skyenv.h"

#include <stdlib.h>
#include <string.h>
#include "common/select.h"

static double luminance(const float *rgb)
{
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

static const double *sort_key;

static int cmp_by_key_desc(const void *a, const void *b)
{
    uint32_t i = *(const uint32_t *)a, j = *(const uint32_t *)b;
    if (sort_key[i] != sort_key[j]) return sort_key[i] < sort_key[j] ? 1 : -1;
    return (i > j) - (i < j);
}

/* Not thread-safe (qsort has no context argument in C11); the sky map is built once. */
static void sort_by_key_desc(uint32_t *idx, size_t n, const double *key)
{
    sort_key = key;
    qsort(idx, n, sizeof *idx, cmp_by_key_desc);
}

/* Cumulative distribution over the pixels selected by want(k) (1: sun set, 0: the rest),
 * proportional to luminance times solid angle. Returns the total, 0 when nothing has power. */
static double build_cdf(const rs_skyenv *env, double *cdf, int sun)
{
    size_t npx = (size_t)env->width * env->height, w = (size_t)env->width;
    cdf[0] = 0;
    for (int r = 0; r < env->height; r++) {
        double om = rs_pano_pixel_solid_angle(env->width, env->height, r); /* a sin: once per row */
        for (size_t k = (size_t)r * w; k < (size_t)(r + 1) * w; k++) {
            double p = 0;
            if ((env->sun[k] != 0) == sun) {
                double y = luminance(env->radiance + 3 * k);
                if (y > 0) p = y * om;
            }
            cdf[k + 1] = cdf[k] + p;
        }
    }
    return cdf[npx];
}

/* Sampling distributions so that rays go where the light is: one over the sun set (the bright
 * pixels), one over the rest of the map. */
static int build_distributions(rs_skyenv *env)
{
    size_t npx = (size_t)env->width * env->height;
    env->cdf = malloc((npx + 1) * sizeof *env->cdf);
    env->sun_cdf = malloc((npx + 1) * sizeof *env->sun_cdf);
    if (!env->cdf || !env->sun_cdf) return -1;
    env->total_power = build_cdf(env, env->cdf, 0);
    env->sun_power = build_cdf(env, env->sun_cdf, 1);
    /* A non-finite total (an infinite pixel) would make every sample walk the whole map. */
    if (!(env->total_power > 0 && isfinite(env->total_power))) {
        free(env->cdf);
        env->cdf = NULL;
        env->total_power = 0;
    }
    if (!(env->sun_power > 0 && isfinite(env->sun_power))) {
        free(env->sun_cdf);
        env->sun_cdf = NULL;
        env->sun_power = 0;
    }
    size_t ng = RS_SKYENV_GUIDE_BUCKETS + 1;
    if ((env->cdf && !(env->cdf_guide = malloc(ng * sizeof *env->cdf_guide))) ||
        (env->sun_cdf && !(env->sun_cdf_guide = malloc(ng * sizeof *env->sun_cdf_guide))))
        return -1;
    if (env->cdf) rs_skyenv_guide_build(env->cdf, npx, env->cdf_guide);
    if (env->sun_cdf) rs_skyenv_guide_build(env->sun_cdf, npx, env->sun_cdf_guide);
    return 0;
}

void rs_skyenv_guide_build(const double *cdf, size_t npx, uint32_t *guide)
{
    double total = cdf[npx];
    size_t k = 0;
    for (size_t b = 0; b <= RS_SKYENV_GUIDE_BUCKETS; b++) {
        double target = (double)b / RS_SKYENV_GUIDE_BUCKETS * total;
        while (k < npx && !(cdf[k + 1] > target)) k++;
        guide[b] = (uint32_t)k;
    }
}

/* Median of x[0..n) (reordered): the element a sort puts at n / 2, by selection (two sorts of
 * a million values were a seventh of the sky map's time, perf). */
static double median(double *x, size_t n)
{
    return n ? rs_select_kth_double(x, n, n / 2) : 0;
}

/* How directly a capture saw the direction of each of its sky pixels (mask): a sky pixel next to
 * the model's silhouette is a mixed pixel (part model, part sky, smeared further by the
 * panorama's reconstruction filter), so its value is not the sky's. Weight by the Chebyshev
 * distance in pixels to the nearest non-sky pixel (azimuth wraps): 1 px -> SILHOUETTE_W1,
 * 2 px -> SILHOUETTE_W2, further -> 1. Small but not zero: where no other capture saw the
 * direction the mixed value is still the best there is (weights only matter against others). */
#define SILHOUETTE_W1 0.02
#define SILHOUETTE_W2 0.2

static void silhouette_weights(int w, int h, const uint8_t *mask, float *q)
{
    for (int r = 0; r < h; r++)
        for (int c = 0; c < w; c++) {
            size_t k = (size_t)r * w + c;
            if (!mask[k]) {
                q[k] = 0;
                continue;
            }
            int dmin = 3;
            for (int dr = -2; dr <= 2 && dmin > 1; dr++) {
                int rr = r + dr < 0 ? 0 : r + dr >= h ? h - 1 : r + dr;
                for (int dc = -2; dc <= 2; dc++) {
                    int d = abs(dr) > abs(dc) ? abs(dr) : abs(dc);
                    if (d >= dmin) continue;
                    if (!mask[(size_t)rr * w + (size_t)((c + dc + w) % w)]) dmin = d;
                }
            }
            q[k] = dmin == 1 ? (float)SILHOUETTE_W1 : dmin == 2 ? (float)SILHOUETTE_W2 : 1.0f;
        }
}

/* Spreads the sky pixels of capture c (mask) onto the map pixels holding their directions:
 * acc[4k..4k+2] = weighted radiance sums, acc[4k+3] = the weights. A source pixel's weight is
 * its solid angle (an area-weighted mean, so that a small sun keeps its power) times q (its
 * silhouette weight; NULL: 1) times min(1, map pixel solid angle / its solid angle)^2: a pixel
 * larger than the map's saw the direction blurred over that many map pixels, and lands in only
 * one of them, so a panorama half as fine weighs a quarter of an equally clean fine one there. Map pixels that got nothing take the pixel under their
 * centre when it is sky (weight 1e-12 x its solid angle x q). acc: 4 * W * H, zeroed. */
static void splat_capture(const rs_skyenv *env, const rs_capture *c, const uint8_t *mask, const float *q, double *acc)
{
    int w = env->width, h = env->height, sw = c->pano->width, sh = c->pano->height;
    size_t npx = (size_t)w * h, nsrc = (size_t)sw * sh;
    for (size_t j = 0; j < nsrc; j++) {
        if (!mask[j]) continue;
        int r = (int)(j / (size_t)sw), cc, rr;
        rs_v3 d = rs_pose_dir_to_world(&c->pose, rs_pano_pixel_dir(sw, sh, (int)(j % (size_t)sw), r));
        rs_pano_world_to_pixel(&env->pose, w, h, d, &cc, &rr);
        size_t k = (size_t)rr * w + cc;
        double om = rs_pano_pixel_solid_angle(sw, sh, r), om_map = rs_pano_pixel_solid_angle(w, h, rr);
        double fp = om > om_map ? om_map / om : 1, wt = om * (q ? q[j] : 1) * fp * fp;
        for (int ch = 0; ch < 3; ch++) acc[4 * k + ch] += wt * c->pano->data[3 * j + ch];
        acc[4 * k + 3] += wt;
    }
    for (size_t k = 0; k < npx; k++) {
        if (acc[4 * k + 3] > 0) continue;
        int cc, r;
        rs_v3 d = rs_pose_dir_to_world(&env->pose, rs_pano_pixel_dir(w, h, (int)(k % (size_t)w), (int)(k / (size_t)w)));
        rs_pano_world_to_pixel(&c->pose, sw, sh, d, &cc, &r);
        size_t j = (size_t)r * sw + cc;
        if (!mask[j]) continue;
        double om = 1e-12 * rs_pano_pixel_solid_angle(w, h, (int)(k / (size_t)w)) * (q ? q[j] : 1);
        for (int ch = 0; ch < 3; ch++) acc[4 * k + ch] = om * c->pano->data[3 * j + ch];
        acc[4 * k + 3] = om;
    }
}

/* Exposure factor capture / c per channel: the median ratio over the directions both saw as sky,
 * bright ones left out; 1 when they share less than 0.01 sr. ref: the capture's own panorama
 * (map pixels = its pixels). ratio: 3 * W * H scratch. */
static void exposure_factor(const rs_skyenv *env, const float *ref, const uint8_t *cap_meas, const double *acc,
                            double bright_lum, double *ratio, double scale[3], double *overlap_sr)
{
    int w = env->width, h = env->height;
    size_t npx = (size_t)w * h, nov = 0;
    *overlap_sr = 0;
    for (size_t k = 0; k < npx; k++) {
        if (!(acc[4 * k + 3] > 0) || !cap_meas[k]) continue;
        float v[3];
        for (int ch = 0; ch < 3; ch++) v[ch] = (float)(acc[4 * k + ch] / acc[4 * k + 3]);
        const float *p = ref + 3 * k;
        if (luminance(p) > bright_lum || luminance(v) > bright_lum || !(v[0] > 0 && v[1] > 0 && v[2] > 0)) continue;
        for (int ch = 0; ch < 3; ch++) ratio[ch * npx + nov] = p[ch] / v[ch];
        nov++;
        *overlap_sr += rs_pano_pixel_solid_angle(w, h, (int)(k / (size_t)w));
    }
    for (int ch = 0; ch < 3; ch++) scale[ch] = *overlap_sr >= 0.01 ? median(ratio + ch * npx, nov) : 1;
}

/* The sky panorama over everything it sees as sky; then, everywhere else, the weighted mean of
 * every capture that saw the direction as sky: the capture itself (its pixel's solid angle x its
 * silhouette weight) and the further captures (splat_capture's weights, their values scaled to
 * the capture's exposure). So a clean view wins over a mixed pixel at another capture's
 * silhouette, and a fine panorama over a coarse one; with equal standing the values average.
 * Flags what they gave in meas. cap_meas: the capture's own sky. */
static int merge_other_skies(rs_skyenv *env, const rs_capture *cap, const uint8_t *cap_meas, double bright_lum,
                             const rs_skyenv_opts *o, uint8_t *meas, rs_skyenv_info *info)
{
    int w = env->width, h = env->height;
    size_t npx = (size_t)w * h;
    double *acc = malloc(4 * npx * sizeof *acc), *ratio = malloc(3 * npx * sizeof *ratio);
    double *sum = o->nothers ? calloc(4 * npx, sizeof *sum) : NULL;
    uint8_t *from_sky = calloc(npx, 1);
    size_t qn = (size_t)w * h;
    for (int i = 0; i < o->nothers && i < RS_SKYENV_MAX_OTHERS; i++) {
        size_t n = (size_t)o->others[i]->pano->width * o->others[i]->pano->height;
        if (n > qn) qn = n;
    }
    float *q = o->nothers ? malloc(qn * sizeof *q) : NULL;
    int rc = -1;
    if (!acc || !ratio || !from_sky || (o->nothers && (!sum || !q))) goto out;
    if (o->sky) {
        memset(acc, 0, 4 * npx * sizeof *acc);
        splat_capture(env, o->sky, o->sky_mask, NULL, acc);
        exposure_factor(env, cap->pano->data, cap_meas, acc, bright_lum, ratio, info->sky_pano_scale,
                        &info->sky_overlap_sr);
        for (size_t k = 0; k < npx; k++) {
            if (!(acc[4 * k + 3] > 0)) continue;
            for (int ch = 0; ch < 3; ch++)
                env->radiance[3 * k + ch] = (float)(info->sky_pano_scale[ch] * acc[4 * k + ch] / acc[4 * k + 3]);
            meas[k] = from_sky[k] = 1;
            info->sky_pano_pixels++;
        }
    }
    if (o->nothers) {
        /* The capture's own weights; sum[] gathers the further captures', apart, so that it
         * is known where they gave anything. */
        silhouette_weights(w, h, cap_meas, q);
        for (int i = 0; i < o->nothers && i < RS_SKYENV_MAX_OTHERS; i++) {
            const rs_capture *oc = o->others[i];
            memset(acc, 0, 4 * npx * sizeof *acc);
            silhouette_weights(oc->pano->width, oc->pano->height, o->other_masks[i], q);
            splat_capture(env, oc, o->other_masks[i], q, acc);
            double *sc = info->other_scale[i];
            exposure_factor(env, cap->pano->data, cap_meas, acc, bright_lum, ratio, sc, &info->other_overlap_sr[i]);
            for (size_t k = 0; k < npx; k++) {
                if (from_sky[k] || !(acc[4 * k + 3] > 0)) continue;
                for (int ch = 0; ch < 3; ch++) sum[4 * k + ch] += sc[ch] * acc[4 * k + ch];
                sum[4 * k + 3] += acc[4 * k + 3];
            }
        }
        silhouette_weights(w, h, cap_meas, q);
        for (size_t k = 0; k < npx; k++) {
            if (!(sum[4 * k + 3] > 0)) continue;
            double wc = cap_meas[k] ? q[k] * rs_pano_pixel_solid_angle(w, h, (int)(k / (size_t)w)) : 0;
            for (int ch = 0; ch < 3; ch++)
                env->radiance[3 * k + ch] =
                    (float)((sum[4 * k + ch] + wc * cap->pano->data[3 * k + ch]) / (sum[4 * k + 3] + wc));
            if (cap_meas[k]) {
                info->blended_pixels++;
            } else {
                meas[k] = 1;
                info->other_pixels++;
            }
        }
    }
    rc = 0;
out:
    free(acc);
    free(ratio);
    free(sum);
    free(from_sky);
    free(q);
    return rc;
}

void rs_skyenv_sky_mask(const rs_scene *scene, const rs_capture *sky, uint8_t *mask)
{
    int w = sky->pano->width, h = sky->pano->height;
#pragma omp parallel for schedule(dynamic, 4)
    for (int r = 0; r < h; r++) {
        rs_ray ray[1024];
        rs_hit hit[1024];
        for (int c0 = 0; c0 < w; c0 += 1024) {
            int n = w - c0 < 1024 ? w - c0 : 1024;
            for (int i = 0; i < n; i++) {
                ray[i].org = sky->pose.position;
                ray[i].dir = rs_pose_dir_to_world(&sky->pose, rs_pano_pixel_dir(w, h, c0 + i, r));
                ray[i].tnear = 0;
                ray[i].tfar = INFINITY;
            }
            rs_scene_intersect(scene, ray, hit, (size_t)n);
            for (int i = 0; i < n; i++) {
                size_t k = (size_t)r * w + c0 + i;
                mask[k] = (uint8_t)(hit[i].face == RS_NO_HIT && rs_capture_pixel_ok(sky->pano->data + 3 * k));
            }
        }
    }
}

int rs_skyenv_build(const rs_capture *cap, const float *facet_id, double sun_threshold, double max_sr, int explicit,
                    rs_skyenv *env, rs_err *err)
{
    rs_skyenv_opts o;
    memset(&o, 0, sizeof o);
    o.sun_threshold = sun_threshold;
    o.max_sr = max_sr;
    o.explicit_sun = explicit;
    o.fill.method = RS_SKYFILL_ROW;
    return rs_skyenv_build_opts(cap, facet_id, &o, env, NULL, err);
}

int rs_skyenv_build_opts(const rs_capture *cap, const float *facet_id, const rs_skyenv_opts *o, rs_skyenv *env,
                         rs_skyenv_info *info, rs_err *err)
{
    rs_skyenv_info scratch;
    if (!info) info = &scratch;
    memset(info, 0, sizeof *info);
    memset(env, 0, sizeof *env);
    int w = cap->pano->width, h = cap->pano->height;
    size_t npx = (size_t)w * h;
    env->width = w;
    env->height = h;
    env->pose = cap->pose;
    env->radiance = malloc(3 * npx * sizeof *env->radiance);
    env->filled = calloc(npx, 1);
    env->sun = calloc(npx, 1);
    uint8_t *meas = calloc(npx, 1), *cap_meas = calloc(npx, 1); /* measured sky (incl. bright) */
    uint8_t *src = calloc(npx, 1);                              /* measured, not bright: sources */
    double *lum = malloc(npx * sizeof *lum);
    uint32_t *order = malloc(npx * sizeof *order);
    double *key = malloc(npx * sizeof *key);
    int rc = -1;
    if (!env->radiance || !env->filled || !env->sun || !meas || !cap_meas || !src || !lum || !order || !key) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the sky map");
        goto out;
    }
    /* The capture's sky: no facet under the pixel and a usable value. */
    memcpy(env->radiance, cap->pano->data, 3 * npx * sizeof *env->radiance);
    size_t ncap = 0;
    for (size_t k = 0; k < npx; k++)
        if (facet_id[k] < 0 && rs_capture_pixel_ok(cap->pano->data + 3 * k)) {
            meas[k] = cap_meas[k] = 1;
            lum[ncap++] = luminance(cap->pano->data + 3 * k);
        }
    double cap_median = median(lum, ncap);
    if ((o->sky || o->nothers) &&
        merge_other_skies(env, cap, cap_meas, o->sun_threshold * (cap_median > 0 ? cap_median : 1e-30), o, meas,
                          info) != 0) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory merging the sky panorama");
        goto out;
    }
    size_t nsky = 0;
    for (size_t k = 0; k < npx; k++)
        if (meas[k]) lum[nsky++] = luminance(env->radiance + 3 * k);
    if (nsky == 0) {
        rs_err_set(err, RS_ERR_INPUT, cap->path, 0,
                   "no sky pixels: every camera ray hits the model (is the camera inside it?)");
        goto out;
    }
    env->sky_median = median(lum, nsky);
    env->sky_pixels = nsky;
    /* A black median sky (night, masked input) would make every pixel bright. */
    double threshold = o->sun_threshold * (env->sky_median > 0 ? env->sky_median : 1e-30);

    /* Bright pixels (the sun and its nearest glow): above the threshold, brightest first, until
     * they cover max_sr. They keep their value in the map, but never feed the fill: spreading a
     * low sun along its row would light the whole horizon with it. */
    size_t nbright = 0;
    for (size_t k = 0; k < npx; k++) {
        key[k] = meas[k] ? luminance(env->radiance + 3 * k) : -1;
        src[k] = meas[k];
        if (key[k] > threshold) order[nbright++] = (uint32_t)k;
    }
    sort_by_key_desc(order, nbright, key);
    double omega_sum = 0;
    size_t keep = 0;
    while (keep < nbright) {
        double om = rs_pano_pixel_solid_angle(w, h, (int)(order[keep] / (uint32_t)w));
        if (omega_sum + om > o->max_sr) break;
        omega_sum += om;
        src[order[keep]] = 0;
        env->sun[order[keep]] = 1;
        keep++;
    }
    env->bright_pixels = keep;
    env->bright_sr = omega_sum;
    for (size_t k = 0; k < npx; k++)
        if (!meas[k]) {
            env->filled[k] = 1;
            env->filled_pixels++;
        }
    if (rs_skyfill_run(w, h, &env->pose, env->radiance, src, env->filled, env->sun, &o->fill, &info->fill, err) != 0)
        goto out;
    env->fill_sigma = info->fill.fill_sigma > 0 ? info->fill.fill_sigma : 0;
    if (!(env->fill_sigma_px = malloc(npx * sizeof *env->fill_sigma_px))) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the sky fill's uncertainty");
        goto out;
    }
    if (rs_skyfill_sigma_map(w, h, src, env->filled, &info->fill, o->fill.method, env->fill_sigma_px, err) != 0)
        goto out;
    if (!o->explicit_sun) memset(env->sun, 0, npx); /* everything by cosine rays */
    if (o->explicit_sun && build_distributions(env) != 0) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the sky distribution");
        goto out;
    }
    rc = 0;
out:
    free(meas);
    free(cap_meas);
    free(src);
    free(lum);
    free(order);
    free(key);
    if (rc != 0) rs_skyenv_release(env);
    return rc;
}

/* After the map's values changed: the sampling distributions again. */
static int rebuild_distributions(rs_skyenv *env)
{
    free(env->cdf);
    free(env->sun_cdf);
    free(env->cdf_guide);
    free(env->sun_cdf_guide);
    env->cdf = env->sun_cdf = NULL;
    env->cdf_guide = env->sun_cdf_guide = NULL;
    return build_distributions(env);
}

/* Every failure of rs_skyenv_set_ground and rs_skyenv_ground_from_bands. */
static long distribution_out_of_memory(rs_err *err)
{
    return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the sky distribution");
}

long rs_skyenv_set_ground(rs_skyenv *env, const double rgb[3], int explicit_sun, rs_err *err)
{
    size_t npx = (size_t)env->width * env->height;
    long n = 0;
    for (size_t k = 0; k < npx; k++)
        if (env->filled[k] == RS_SKYFILL_GROUND_MODEL) {
            for (int ch = 0; ch < 3; ch++) env->radiance[3 * k + ch] = (float)rgb[ch];
            n++;
        }
    if (!n || !explicit_sun) return n;
    return rebuild_distributions(env) == 0 ? n : distribution_out_of_memory(err);
}

long rs_skyenv_ground_from_bands(rs_skyenv *env, int explicit_sun, rs_err *err)
{
    size_t npx = (size_t)env->width * env->height;
    uint8_t *src = malloc(npx ? npx : 1);
    if (!src) return distribution_out_of_memory(err);
    for (size_t k = 0; k < npx; k++) src[k] = !env->filled[k] && !env->sun[k];
    long n = rs_skyfill_ground_from_bands(env->width, env->height, &env->pose, env->radiance, src, env->filled,
                                          RS_SKYFILL_GROUND_MODEL, M_PI, err);
    free(src);
    if (n <= 0 || !explicit_sun) return n;
    return rebuild_distributions(env) == 0 ? n : distribution_out_of_memory(err);
}

void rs_skyenv_release(rs_skyenv *env)
{
    free(env->radiance);
    free(env->filled);
    free(env->fill_sigma_px);
    free(env->sun);
    free(env->cdf);
    free(env->sun_cdf);
    free(env->cdf_guide);
    free(env->sun_cdf_guide);
    memset(env, 0, sizeof *env);
}

static size_t pick(const double *cdf, size_t npx, double x)
{
    double target = x * cdf[npx];
    size_t lo = 0, hi = npx; /* the first k with cdf[k + 1] > target */
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (cdf[mid + 1] > target)
            hi = mid;
        else
            lo = mid + 1;
    }
    if (lo >= npx) lo = npx - 1;
    while (lo > 0 && cdf[lo + 1] == cdf[lo]) lo--; /* never a pixel without power */
    return lo;
}

size_t rs_skyenv_pick(const rs_skyenv *env, double x)
{
    return pick(env->cdf, (size_t)env->width * env->height, x);
}

size_t rs_skyenv_pick_sun(const rs_skyenv *env, double x)
{
    return pick(env->sun_cdf, (size_t)env->width * env->height, x);
}
