/* colmap_poses: the calib stage's [colmap] step: a COLMAP model aligned to the scan by control
 * points poses every capture that names a panorama of the views file (capture_pose.txt). */
#ifndef RS_COLMAP_POSES_H
#define RS_COLMAP_POSES_H

#include "common/config.h"
#include "common/err.h"
#include "pipeline/stage.h"

/* Does nothing (returns 0) without [colmap] model. Otherwise aligns the model (residuals per
 * control point into the report's "colmap" object), then writes the pose of each [capture] or
 * [capture.NAME] with colmap_panorama into the work folder's pose file. Errors: colmap_panorama
 * without [colmap] model, views or control_points missing, bad files, an RMS residual above
 * [colmap] max_rms_m, a capture both registered from pairs and posed by COLMAP. */
int rs_calib_colmap_run(const rs_config *cfg, rs_report *rep, rs_err *err);

#endif
