/* exr_dwa: EXR files whose compression OpenEXR's C library cannot decode (DWAA, DWAB in
 * OpenEXR 3.1, the compression of Debian's blender-data skies), read through OpenEXR's C++
 * library behind this C header. Every exception is caught at the boundary. */
#ifndef RS_EXR_DWA_H
#define RS_EXR_DWA_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Reads the channels named in names[0..nnames-1] of part 0 from an in-memory EXR file into
 * out (caller-allocated, width x height x nnames floats, interleaved), where the image covers
 * the display window [x0, x0 + width) x [y0, y0 + height); pixels outside the data window stay
 * as they are. Returns 0, or -1 with a message in msg. */
int rs_exr_cxx_read(const void *data, size_t size, const char *const *names, int nnames, int x0, int y0, int width,
                    int height, float *out, char *msg, size_t msg_size);

#ifdef __cplusplus
}
#endif

#endif
