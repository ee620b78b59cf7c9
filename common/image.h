/* image: float images in memory (row-major, channels interleaved, row 0 at the top), their
 * basic operations (image.c), and the file functions every user of images calls, declared
 * here and defined by the format modules: common/image_format.c maps a file to its reader or
 * writer (OpenEXR: common/image_exr.c; Radiance .hdr, PNG, JPEG through stb: image_stb.c).
 * The format modules include this header; image.c includes none of them. */
#ifndef RS_IMAGE_H
#define RS_IMAGE_H

#include <stddef.h>
#include "common/err.h"

typedef struct rs_image {
    int width, height, channels;
    float *data; /* width * height * channels values */
} rs_image;

/* Largest accepted width or height: beyond any panorama we expect, and small enough that a
 * corrupt header cannot ask for absurd allocations one side at a time. */
#define RS_IMAGE_MAX_SIDE 65536
/* Largest accepted pixel count of a file's image: a 16K panorama (16384 x 8192), 1.5 GiB as
 * 3-channel floats. An EXR header alone can ask for a display window far larger than the
 * data it holds; this keeps such files (and fuzzers) within reasonable memory. */
#define RS_IMAGE_MAX_PIXELS (1LL << 27)

/* New image, zero-filled; NULL on overflow or out of memory. Caller frees with rs_image_free. */
rs_image *rs_image_new(int width, int height, int channels);
void rs_image_free(rs_image *img);
static inline float *rs_image_px(const rs_image *img, int x, int y)
{
    return img->data + ((size_t)y * (size_t)img->width + (size_t)x) * (size_t)img->channels;
}

/* For the readers and writers: 0, or -1 with *err naming the file (name) when w x h is
 * outside the limits above. */
int rs_image_check_size(long long w, long long h, const char *name, rs_err *err);
/* rs_image_new, or NULL with *err set (out of memory) naming the file. */
rs_image *rs_image_new_or_fail(int w, int h, int c, const char *name, rs_err *err);

/* False colour for t in [0, 1] (clamped): the sRGB ramp blue - cyan - green - yellow - red,
 * returned linear (for rs_image_write_png at scale 1). One ramp for every false-colour image. */
void rs_image_ramp(double t, float rgb[3]);

/* sRGB transfer functions (IEC 61966-2-1). */
float rs_srgb_to_linear(float v);
float rs_linear_to_srgb(float v);

/* ---- files (common/image_format.c, the formats' table) ---- */

/* Reads by file content (EXR magic, "#?RADIANCE"/"#?RGBE", PNG, JPEG). Result has 1 or 3
 * channels: R,G,B (matched by name in EXR; A dropped), else Y, or a single channel when the
 * file has one (any name). An EXR result covers the display window (0 where the data window
 * has no pixels). PNG and JPEG (8 or 16 bit) are linearised from sRGB. Accepted sizes: up to
 * 65536 per side and 2^27 pixels. Negative and non-finite values are kept as they are: the
 * caller decides. Errors name the file and what was wrong. */
rs_image *rs_image_read(const char *path, rs_err *err);
rs_image *rs_image_read_mem(const void *data, size_t size, const char *name, rs_err *err);

/* How rs_image_write stores an image; NULL or zeros give the defaults. */
typedef struct rs_image_write_opts {
    const char *const *names; /* EXR: one per channel; NULL: {"R","G","B"} or {"Y"} */
    int half;                 /* EXR: 16-bit floats (see rs_image_write_exr) */
    const char *note;         /* EXR: provenance text, may be NULL */
    float scale;              /* PNG: multiplies the values; 0 means 1 */
} rs_image_write_opts;

/* Writes by the path's extension: .exr (rs_image_write_exr) or .png (rs_image_write_png);
 * any other extension is an RS_ERR_INPUT error naming the path. */
int rs_image_write(const rs_image *img, const char *path, const rs_image_write_opts *opts, rs_err *err);

/* Writes an EXR atomically (temporary file, then rename), ZIP compression.
 * names: one per channel (e.g. {"R","G","B"} or {"Y"}); half: store as 16-bit float
 * (finite values beyond +-65504 become Inf: keep float for skies and radiance with the sun).
 * note: optional text stored as the string attribute "rhoscan" (provenance), may be NULL.
 * Defined in common/image_exr.c. */
int rs_image_write_exr(const rs_image *img, const char *path, const char *const *names, int half, const char *note,
                       rs_err *err);

/* Writes an 8-bit sRGB PNG preview of linear values: clamp(scale * value) then sRGB-encode.
 * 1 channel -> grey, 3 -> RGB. Atomic. Defined in common/image_stb.c. */
int rs_image_write_png(const rs_image *img, const char *path, float scale, rs_err *err);
/* Writes 8-bit codes as they are (already sRGB-encoded: false-colour images), width x height x
 * channels (1 or 3), rows top first, every row Sub-filtered (rs_image_write_png lets stb try
 * all five filters per row: smaller files, five times the filtering). Atomic. Defined in
 * common/image_stb.c. */
int rs_image_write_png8(const unsigned char *px, int width, int height, int channels, const char *path, rs_err *err);

#endif
