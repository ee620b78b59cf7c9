/* image: float images in memory and their basic operations (see image.h). The file formats
 * are modules of their own (image_format.c and the readers it lists); this file knows none. */
#include "common/image.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

rs_image *rs_image_new(int width, int height, int channels)
{
    if (width <= 0 || height <= 0 || width > RS_IMAGE_MAX_SIDE || height > RS_IMAGE_MAX_SIDE || channels <= 0 ||
        channels > 64)
        return NULL;
    size_t n = (size_t)width * (size_t)height;
    if (n > SIZE_MAX / (size_t)channels || n * (size_t)channels > SIZE_MAX / sizeof(float)) return NULL;
    rs_image *img = malloc(sizeof *img);
    if (!img) return NULL;
    img->data = calloc(n * (size_t)channels, sizeof(float));
    if (!img->data) {
        free(img);
        return NULL;
    }
    img->width = width;
    img->height = height;
    img->channels = channels;
    return img;
}

void rs_image_free(rs_image *img)
{
    if (!img) return;
    free(img->data);
    free(img);
}

/* IEC 61966-2-1 piecewise curves. */
float rs_srgb_to_linear(float v)
{
    return v <= 0.04045f ? v / 12.92f : powf((v + 0.055f) / 1.055f, 2.4f);
}

float rs_linear_to_srgb(float v)
{
    return v <= 0.0031308f ? v * 12.92f : 1.055f * powf(v, 1.0f / 2.4f) - 0.055f;
}

void rs_image_ramp(double t, float rgb[3])
{
    static const double stop[5][3] = {
        {0.10, 0.20, 0.90}, {0.00, 0.80, 0.90}, {0.10, 0.85, 0.20}, {1.00, 0.90, 0.00}, {0.90, 0.10, 0.10}};
    t = t < 0 ? 0 : t > 1 ? 1 : t; /* NaN takes the first stop below */
    int k = t >= 1 ? 3 : t > 0 ? (int)(t * 4) : 0;
    double s = t > 0 ? t * 4 - k : 0;
    for (int c = 0; c < 3; c++) rgb[c] = rs_srgb_to_linear((float)(stop[k][c] * (1 - s) + stop[k + 1][c] * s));
}

int rs_image_check_size(long long w, long long h, const char *name, rs_err *err)
{
    if (w <= 0 || h <= 0 || w > RS_IMAGE_MAX_SIDE || h > RS_IMAGE_MAX_SIDE)
        return rs_err_set(err, RS_ERR_INPUT, name, 0, "image size %lld x %lld: expected 1 to %d pixels per side", w, h,
                          RS_IMAGE_MAX_SIDE);
    if (w * h > RS_IMAGE_MAX_PIXELS)
        return rs_err_set(err, RS_ERR_INPUT, name, 0, "image size %lld x %lld: expected at most %lld pixels", w, h,
                          RS_IMAGE_MAX_PIXELS);
    return 0;
}

rs_image *rs_image_new_or_fail(int w, int h, int c, const char *name, rs_err *err)
{
    rs_image *img = rs_image_new(w, h, c);
    if (!img) rs_err_set(err, RS_ERR_SYSTEM, name, 0, "out of memory for a %d x %d x %d image", w, h, c);
    return img;
}
