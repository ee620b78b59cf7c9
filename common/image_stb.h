/* image_stb: Radiance .hdr, PNG and JPEG reading through stb_image, and PNG previews through
 * stb_image_write (rs_image_write_png, declared in image.h). common/image_format.c chooses
 * the reader by the file's magic bytes; the readers assume the data starts with them. */
#ifndef RS_IMAGE_STB_H
#define RS_IMAGE_STB_H

#include <stddef.h>
#include "common/image.h"

/* Radiance RGBE (data starts with "#?RADIANCE" or "#?RGBE"): 3 linear channels. */
rs_image *rs_image_hdr_read_mem(const void *data, size_t size, const char *name, rs_err *err);
/* PNG (data starts with the 8-byte PNG signature), 8 or 16 bit: sRGB-decoded to linear;
 * grey (+alpha) gives 1 channel, colour (+alpha) 3; alpha is dropped. */
rs_image *rs_image_png_read_mem(const void *data, size_t size, const char *name, rs_err *err);
/* JPEG (data starts with FF D8 FF): as PNG. */
rs_image *rs_image_jpeg_read_mem(const void *data, size_t size, const char *name, rs_err *err);

/* The 8-bit codes of a PNG or JPEG (16-bit PNGs reduced to 8 bits), 3 channels (grey
 * repeated), row by row, as its camera wrote them: for linearising with a response curve. The
 * same checks as the readers above; caller frees. */
unsigned char *rs_image_ldr_codes_mem(const void *data, size_t size, const char *name, int *width, int *height,
                                      rs_err *err);

#endif
