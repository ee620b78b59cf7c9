/* image: float images in memory (row-major, channels interleaved, row 0 at the top) and
 * their files: OpenEXR through the core C API (read any compression, float or half;
 * write float or half, ZIP), Radiance .hdr, PNG and JPEG through stb_image (8-bit files
 * are sRGB-decoded to linear), PNG previews through stb_image_write. */
#ifndef RS_IMAGE_H
#define RS_IMAGE_H

#include "common/err.h"

typedef struct rs_image {
    int width, height, channels;
    float *data; /* width * height * channels values */
} rs_image;

/* New image, zero-filled; NULL on overflow or out of memory. Caller frees with rs_image_free. */
rs_image *rs_image_new(int width, int height, int channels);
void rs_image_free(rs_image *img);
static inline float *rs_image_px(const rs_image *img, int x, int y)
{
    return img->data + ((size_t)y * (size_t)img->width + (size_t)x) * (size_t)img->channels;
}

/* Reads by file content (EXR magic, "#?RADIANCE"/"#?RGBE", PNG, JPEG). Result has 1 or 3
 * channels: R,G,B (matched by name in EXR; A dropped), else Y, or a single channel when the
 * file has one (any name). An EXR result covers the display window (0 where the data window
 * has no pixels). PNG and JPEG (8 or 16 bit) are linearised from sRGB. Accepted sizes: up to
 * 65536 per side and 2^27 pixels. Negative and non-finite values are kept as they are: the
 * caller decides. Errors name the file and what was wrong. */
rs_image *rs_image_read(const char *path, rs_err *err);
rs_image *rs_image_read_mem(const void *data, size_t size, const char *name, rs_err *err);

/* Writes an EXR atomically (temporary file, then rename), ZIP compression.
 * names: one per channel (e.g. {"R","G","B"} or {"Y"}); half: store as 16-bit float
 * (finite values beyond +-65504 become Inf: keep float for skies and radiance with the sun).
 * note: optional text stored as the string attribute "rhoscan" (provenance), may be NULL. */
int rs_image_write_exr(const rs_image *img, const char *path, const char *const *names, int half, const char *note,
                       rs_err *err);

/* Writes an 8-bit sRGB PNG preview of linear values: clamp(scale * value) then sRGB-encode.
 * 1 channel -> grey, 3 -> RGB. Atomic. */
int rs_image_write_png(const rs_image *img, const char *path, float scale, rs_err *err);

/* False colour for t in [0, 1] (clamped): the sRGB ramp blue - cyan - green - yellow - red,
 * returned linear (for rs_image_write_png at scale 1). One ramp for every false-colour image. */
void rs_image_ramp(double t, float rgb[3]);

/* sRGB transfer functions (IEC 61966-2-1). */
float rs_srgb_to_linear(float v);
float rs_linear_to_srgb(float v);

#endif
