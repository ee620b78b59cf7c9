/* image_internal: what image.c (stb formats, dispatch) and image_exr.c (OpenEXR) share.
 * Not for other modules: use image.h. */
#ifndef RS_IMAGE_INTERNAL_H
#define RS_IMAGE_INTERNAL_H

#include <stddef.h>
#include "common/image.h"

/* Largest accepted width or height: beyond any panorama we expect, and small enough that a
 * corrupt header cannot ask for absurd allocations one side at a time. */
#define RS_IMAGE_MAX_SIDE 65536
/* Largest accepted pixel count of a file's image: a 16K panorama (16384 x 8192), 1.5 GiB as
 * 3-channel floats. An EXR header alone can ask for a display window far larger than the
 * data it holds; this keeps such files (and fuzzers) within reasonable memory. */
#define RS_IMAGE_MAX_PIXELS (1LL << 27)

/* 0, or -1 with *err naming the file when w x h is outside the limits above. */
int rs_image_check_size(long long w, long long h, const char *name, rs_err *err);
/* rs_image_new, or NULL with *err set (out of memory). */
rs_image *rs_image_new_or_fail(int w, int h, int c, const char *name, rs_err *err);
/* The EXR reader behind rs_image_read_mem (data starts with the EXR magic number). */
rs_image *rs_image_exr_read_mem(const void *data, size_t size, const char *name, rs_err *err);

#endif
