/* capture_e57: a capture's panorama taken from an E57 file ([capture] panorama = FILE.e57): the
 * images2D entry [capture] e57_image names (by name or 0-based index; unset: the only spherical
 * image), a full-sphere sphericalRepresentation (2 pi x pi), decoded from its JPEG or PNG blob
 * and linearised by [capture] response_file (or the sRGB curve, with a warning), clipped pixels
 * (a channel at code 255) flagged NaN so that no stage trusts them; its pose becomes the
 * capture's. Cylindrical and visual-reference images are refused as captures, pinhole ones
 * until their stitching lands, an image whose blob does not decode is refused naming it. */
#ifndef RS_CAPTURE_E57_H
#define RS_CAPTURE_E57_H

#include "common/capture.h"
#include "common/config.h"
#include "common/err.h"

/* 1 when path starts with the E57 signature. */
int rs_capture_is_e57(const char *path);

/* Loads cap->pano (3 channels, linear) and, when the image has a pose, cap->pose from
 * cap->path (an E57 file); *posed: the image had a pose. *clipped: the pixels flagged. */
int rs_capture_load_e57(const rs_config *cfg, const char *section, rs_capture *cap, int *posed, size_t *clipped,
                        rs_err *err);

/* The width of the panorama [section] panorama's E57 file holds (for rs_capture_panorama_width). */
int rs_capture_e57_width(const rs_config *cfg, const char *section, const char *path, int *width, rs_err *err);

#endif
