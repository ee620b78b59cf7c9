/* skyenv: environment map from the panorama's sky portion (see skyenv.h). */
#include "skyenv.h"

#include <stdlib.h>
#include <string.h>

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

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Fills the pixels of one row whose src flag is 0 by interpolating in azimuth between the
 * nearest pixels with src set; returns 0 when the row has no source pixel. */
static int fill_row(float *row, const uint8_t *src, int w)
{
    int first = -1;
    for (int c = 0; c < w; c++)
        if (src[c]) {
            first = c;
            break;
        }
    if (first < 0) return 0;
    /* Walk the ring from the first source pixel; between consecutive sources a and b
     * (b may wrap past the end) interpolate linearly. */
    int a = first;
    for (int step = 1; step <= w; step++) {
        int b = (first + step) % w;
        if (!src[b] && step < w) continue;
        int gap = (b - a + w) % w;
        if (gap == 0) gap = w;
        for (int k = 1; k < gap; k++) {
            int c = (a + k) % w;
            double t = (double)k / gap;
            for (int ch = 0; ch < 3; ch++)
                row[3 * c + ch] = (float)((1 - t) * row[3 * a + ch] + t * row[3 * b + ch]);
        }
        a = b;
    }
    return 1;
}

/* Cumulative distribution over the pixels selected by want(k) (1: sun set, 0: the rest),
 * proportional to luminance times solid angle. Returns the total, 0 when nothing has power. */
static double build_cdf(const rs_skyenv *env, double *cdf, int sun)
{
    size_t npx = (size_t)env->width * env->height;
    cdf[0] = 0;
    for (size_t k = 0; k < npx; k++) {
        double p = 0;
        if ((env->sun[k] != 0) == sun) {
            double y = luminance(env->radiance + 3 * k);
            if (y > 0) p = y * rs_pano_pixel_solid_angle(env->width, env->height, (int)(k / env->width));
        }
        cdf[k + 1] = cdf[k] + p;
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
    if (!(env->total_power > 0)) {
        free(env->sun);
    free(env->cdf);
    free(env->sun_cdf);
        env->cdf = NULL;
        env->total_power = 0;
    }
    if (!(env->sun_power > 0)) {
        free(env->sun_cdf);
        env->sun_cdf = NULL;
        env->sun_power = 0;
    }
    return 0;
}

int rs_skyenv_build(const rs_capture *cap, const float *facet_id, double sun_threshold, double max_sr,
                    int explicit, rs_skyenv *env, rs_err *err)
{
    memset(env, 0, sizeof *env);
    int w = cap->pano->width, h = cap->pano->height;
    size_t npx = (size_t)w * h;
    env->width = w;
    env->height = h;
    env->pose = cap->pose;
    env->radiance = malloc(3 * npx * sizeof *env->radiance);
    env->filled = calloc(npx, 1);
    env->sun = calloc(npx, 1);
    uint8_t *src = calloc(npx, 1);        /* measured, not bright: feeds the fill */
    double *lum = malloc(npx * sizeof *lum);
    if (!env->radiance || !env->filled || !env->sun || !src || !lum) {
        free(src);
        free(lum);
        rs_skyenv_release(env);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the sky map");
    }
    /* Measured sky: no facet under the pixel and a usable value. */
    size_t nsky = 0;
    for (size_t k = 0; k < npx; k++) {
        const float *px = cap->pano->data + 3 * k;
        if (facet_id[k] < 0 && rs_capture_pixel_ok(px)) {
            src[k] = 1;
            lum[nsky++] = luminance(px);
        }
    }
    if (nsky == 0) {
        free(src);
        free(lum);
        rs_skyenv_release(env);
        return rs_err_set(err, RS_ERR_INPUT, cap->path, 0,
                          "no sky pixels: every camera ray hits the model (is the camera inside it?)");
    }
    qsort(lum, nsky, sizeof *lum, cmp_double);
    env->sky_median = lum[nsky / 2];
    env->sky_pixels = nsky;
    free(lum);
    /* A black median sky (night, masked input) would make every pixel bright. */
    double threshold = sun_threshold * (env->sky_median > 0 ? env->sky_median : 1e-30);

    memcpy(env->radiance, cap->pano->data, 3 * npx * sizeof *env->radiance);
    /* Bright pixels (the sun and its nearest glow): above the threshold, brightest first, until
     * they cover max_sr. They keep their value in the map, but never feed the fill: spreading a
     * low sun along its row would light the whole horizon with it. */
    size_t nbright = 0;
    uint32_t *order = malloc(nsky * sizeof *order);
    double *key = malloc(npx * sizeof *key);
    if (!order || !key) {
        free(order);
        free(key);
        free(src);
        rs_skyenv_release(env);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the sky map");
    }
    for (size_t k = 0; k < npx; k++) {
        key[k] = src[k] ? luminance(cap->pano->data + 3 * k) : -1;
        if (key[k] > threshold) order[nbright++] = (uint32_t)k;
    }
    sort_by_key_desc(order, nbright, key);
    double omega_sum = 0;
    size_t keep = 0;
    while (keep < nbright) {
        double om = rs_pano_pixel_solid_angle(w, h, (int)(order[keep] / (uint32_t)w));
        if (omega_sum + om > max_sr) break;
        omega_sum += om;
        src[order[keep]] = 0;
        env->sun[order[keep]] = 1;
        keep++;
    }
    env->bright_pixels = keep;
    env->bright_sr = omega_sum;
    free(key);
    free(order);

    /* Hidden, invalid or bright-but-not-explicit pixels that are not measured sky get filled. */
    int *has = calloc((size_t)h, sizeof *has);
    if (!has) {
        free(src);
        rs_skyenv_release(env);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    }
    for (int r = 0; r < h; r++) {
        float *row = env->radiance + 3 * (size_t)r * w;
        const uint8_t *s = src + (size_t)r * w;
        for (int c = 0; c < w; c++) {
            size_t k = (size_t)r * w + c;
            int keep = s[c] || (facet_id[k] < 0 && rs_capture_pixel_ok(cap->pano->data + 3 * k));
            if (!keep) {
                env->filled[k] = 1;
                env->filled_pixels++;
            }
        }
        /* Interpolate into filled pixels only: bright pixels keep their value (or 0). */
        float *tmp = malloc(3 * (size_t)w * sizeof *tmp);
        if (!tmp) continue;
        memcpy(tmp, row, 3 * (size_t)w * sizeof *tmp);
        has[r] = fill_row(tmp, s, w);
        for (int c = 0; c < w; c++)
            if (env->filled[(size_t)r * w + c]) memcpy(row + 3 * c, tmp + 3 * c, 3 * sizeof *tmp);
        free(tmp);
    }
    /* Rows with no measured sky copy the filled values of the nearest row that has some. */
    for (int r = 0; r < h; r++) {
        if (has[r]) continue;
        int best = -1;
        for (int d = 1; d < h && best < 0; d++) {
            if (r - d >= 0 && has[r - d]) best = r - d;
            else if (r + d < h && has[r + d]) best = r + d;
        }
        if (best < 0) continue;   /* cannot happen: nsky > 0 */
        float *row = env->radiance + 3 * (size_t)r * w;
        const float *from = env->radiance + 3 * (size_t)best * w;
        for (int c = 0; c < w; c++)
            if (env->filled[(size_t)r * w + c]) memcpy(row + 3 * c, from + 3 * c, 3 * sizeof *row);
    }
    free(has);
    free(src);
    if (!explicit) memset(env->sun, 0, npx);     /* everything by cosine rays */
    if (explicit && build_distributions(env) != 0) {
        rs_skyenv_release(env);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the sky distribution");
    }
    return 0;
}

void rs_skyenv_release(rs_skyenv *env)
{
    free(env->radiance);
    free(env->filled);
    free(env->sun);
    free(env->cdf);
    free(env->sun_cdf);
    memset(env, 0, sizeof *env);
}

static size_t pick(const double *cdf, size_t npx, double x)
{
    double target = x * cdf[npx];
    size_t lo = 0, hi = npx;                   /* the first k with cdf[k + 1] > target */
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (cdf[mid + 1] > target) hi = mid;
        else lo = mid + 1;
    }
    if (lo >= npx) lo = npx - 1;
    while (lo > 0 && cdf[lo + 1] == cdf[lo]) lo--;   /* never a pixel without power */
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
