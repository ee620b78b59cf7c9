/* skyenv: environment map from the panorama's sky portion (see skyenv.h). */
#include "skyenv.h"

#include <stdlib.h>
#include <string.h>

static double luminance(const float *rgb)
{
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
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

int rs_skyenv_build(const rs_capture *cap, const float *facet_id, double sun_threshold, int explicit,
                    rs_skyenv *env, rs_err *err)
{
    memset(env, 0, sizeof *env);
    int w = cap->pano->width, h = cap->pano->height;
    size_t npx = (size_t)w * h;
    env->width = w;
    env->height = h;
    env->pose = cap->pose;
    env->radiance = malloc(3 * npx * sizeof *env->radiance);
    env->filled = calloc(npx, 1);
    uint8_t *src = calloc(npx, 1);        /* measured, not bright: feeds the fill */
    double *lum = malloc(npx * sizeof *lum);
    if (!env->radiance || !env->filled || !src || !lum) {
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
    size_t nbright = 0;
    for (size_t k = 0; k < npx; k++)
        if (src[k] && luminance(cap->pano->data + 3 * k) > threshold) nbright++;
    env->bright_pixels = nbright;
    if (explicit && nbright) {
        env->light_pixel = malloc(nbright * sizeof *env->light_pixel);
        env->light_power = malloc(3 * nbright * sizeof *env->light_power);
        env->light_cdf = malloc((nbright + 1) * sizeof *env->light_cdf);
        if (!env->light_pixel || !env->light_power || !env->light_cdf) {
            free(src);
            rs_skyenv_release(env);
            return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for sky lights");
        }
        env->light_cdf[0] = 0;
    }
    for (size_t k = 0; k < npx; k++) {
        if (!src[k] || luminance(cap->pano->data + 3 * k) <= threshold) continue;
        src[k] = 0;                               /* never spread a sun into the fill */
        if (!explicit) continue;
        size_t i = env->nlights++;
        double omega = rs_pano_pixel_solid_angle(w, h, (int)(k / w));
        float *rad = env->radiance + 3 * k;
        for (int ch = 0; ch < 3; ch++) {
            env->light_power[3 * i + ch] = (float)(rad[ch] * omega);
            rad[ch] = 0;                          /* its light comes by explicit rays only */
        }
        env->light_pixel[i] = (uint32_t)k;
        env->light_cdf[i + 1] = env->light_cdf[i] + luminance(env->light_power + 3 * i);
    }

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
    return 0;
}

void rs_skyenv_release(rs_skyenv *env)
{
    free(env->radiance);
    free(env->filled);
    free(env->light_pixel);
    free(env->light_power);
    free(env->light_cdf);
    memset(env, 0, sizeof *env);
}

size_t rs_skyenv_pick_light(const rs_skyenv *env, double x)
{
    double target = x * env->light_cdf[env->nlights];
    size_t lo = 0, hi = env->nlights;          /* find the first i with cdf[i + 1] > target */
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (env->light_cdf[mid + 1] > target) hi = mid;
        else lo = mid + 1;
    }
    return lo < env->nlights ? lo : env->nlights - 1;
}
