/* capture_load: a capture as a config section gives it: [capture] panorama (or the calib
 * stage's stitched panorama when the section has a rig), position and rotation (or the pose
 * the calib stage solved from correspondences). */
#ifndef RS_CAPTURE_LOAD_H
#define RS_CAPTURE_LOAD_H

#include "common/capture.h"
#include "common/config.h"
#include "common/err.h"

/* Loads [capture] panorama, position, rotation (section may be "capture.NAME").
 * Errors: panorama not set, unreadable, or not 2:1. */
int rs_capture_load(const rs_config *cfg, const char *section, rs_capture *cap, rs_err *err);

#endif
