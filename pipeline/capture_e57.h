/* capture_e57: a capture's panorama taken from an E57 file ([capture] panorama = FILE.e57): the
 * images2D entry [capture] e57_image names (by name or 0-based index; unset: the only spherical
 * image, else the posed pinhole images), decoded from its JPEG or PNG blob and linearised by
 * [capture] response_file (or the sRGB curve, with a warning), clipped pixels (a channel at code
 * 255) flagged NaN so that no stage trusts them. A full-sphere sphericalRepresentation (2 pi x
 * pi) is the panorama and its pose the capture's. A pinhole image is stitched with the other
 * posed pinhole images of its scan the way a rig's frames are (calib/stitch.h, at infinite
 * depth; camera frame x right, y down, z forward; the Leica dist: extension's k1 k2 p1 p2 k3),
 * the capture at the cameras' mean centre with the world's axes. Cylindrical and
 * visual-reference images are refused as captures, an image whose blob does not decode is
 * refused naming it. */
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

/* The pose the capture path's E57 file gives (its selected image's; for stitched pinhole images
 * their mean centre and the world's axes): 1 with *pose, 0 when it has none or cannot be read
 * (the capture's loading then says why). */
int rs_capture_e57_pose(const rs_config *cfg, const char *section, const char *path, rs_pose *pose);

#endif
