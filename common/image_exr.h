/* image_exr: OpenEXR reading and writing through the OpenEXR core C API (reading: scanline or
 * tiled, any compression the library decodes, DWA through common/exr_dwa.h; writing: ZIP,
 * float or half, rs_image_write_exr, declared in image.h). common/image_format.c chooses this
 * reader by the file's magic number. */
#ifndef RS_IMAGE_EXR_H
#define RS_IMAGE_EXR_H

#include <stddef.h>
#include "common/image.h"

/* The EXR behind rs_image_read_mem (data starts with the EXR magic number 76 2f 31 01). */
rs_image *rs_image_exr_read_mem(const void *data, size_t size, const char *name, rs_err *err);

#endif
