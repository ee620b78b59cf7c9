/* capture: a panorama with its pose: the image (linear, 3 channels, 2:1) and the camera centre
 * and rotation in the world frame. Loading one from a config section is the pipeline's
 * (pipeline/capture_load.h). */
#ifndef RS_CAPTURE_H
#define RS_CAPTURE_H

#include <math.h>
#include "common/image.h"
#include "common/pano.h"

typedef struct rs_capture {
    rs_image *pano; /* 3 channels; single-channel files are copied to R=G=B */
    rs_pose pose;
    char path[4096];
    size_t nonfinite; /* pixels with a NaN or Inf channel (left as they are) */
    size_t negative;  /* pixels with a negative channel (left as they are) */
} rs_capture;

void rs_capture_release(rs_capture *cap);

/* 1 when every channel of the pixel is finite and >= 0: the value can be used as radiance. */
static inline int rs_capture_pixel_ok(const float *px)
{
    return isfinite(px[0]) && isfinite(px[1]) && isfinite(px[2]) && px[0] >= 0 && px[1] >= 0 && px[2] >= 0;
}

#endif
