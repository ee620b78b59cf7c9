/* capture: a panorama with its pose, as given by a [capture] section: the image (linear,
 * 3 channels, 2:1) and the camera centre and rotation in the world frame. */
#ifndef RS_CAPTURE_H
#define RS_CAPTURE_H

#include "config.h"
#include "image.h"
#include "pano.h"

typedef struct rs_capture {
    rs_image *pano; /* 3 channels; single-channel files are copied to R=G=B */
    rs_pose pose;
    char path[4096];
    size_t nonfinite; /* pixels with a NaN or Inf channel (left as they are) */
    size_t negative;  /* pixels with a negative channel (left as they are) */
} rs_capture;

/* Loads [capture] panorama, position, rotation (section may be "capture.NAME").
 * Errors: panorama not set, unreadable, or not 2:1. */
int rs_capture_load(const rs_config *cfg, const char *section, rs_capture *cap, rs_err *err);
void rs_capture_release(rs_capture *cap);

/* 1 when every channel of the pixel is finite and >= 0: the value can be used as radiance. */
static inline int rs_capture_pixel_ok(const float *px)
{
    return isfinite(px[0]) && isfinite(px[1]) && isfinite(px[2]) && px[0] >= 0 && px[1] >= 0 && px[2] >= 0;
}

#endif
