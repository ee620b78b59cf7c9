/* calib_files: the files through which the calib stage hands its results to the stages that load
 * the capture (pipeline/capture_load.c): the stitched panorama and the solved pose, in the work folder. */
#ifndef RS_CALIB_FILES_H
#define RS_CALIB_FILES_H

#include <stddef.h>
#include "common/config.h"
#include "common/err.h"
#include "common/pano.h"

#define RS_CALIB_PANO_FILE "pano_stitched.exr" /* written when [rig] is set (pipeline/panorama.h) */
#define RS_CALIB_POSE_FILE "capture_pose.txt"  /* poses from [capture] correspondences and [colmap] */

/* 1 when the calib stage solves the section's pose: [capture] correspondences or refine_edges,
 * or colmap_panorama in [capture] or [capture.NAME]. Position and rotation then only seed it. */
int rs_calib_pose_solved(const rs_config *cfg, const char *section);

/* When rs_calib_pose_solved, replaces *pose by the one the calib stage solved. Otherwise leaves
 * it alone. */
int rs_calib_pose_apply(const rs_config *cfg, const char *section, rs_pose *pose, rs_err *err);

/* The pose file: blocks `section NAME`, `position X Y Z`, `rotation R00 ... R22` (row-major
 * local -> world), full precision; lines before any `section` line belong to [capture].
 * rs_calib_pose_write sets one section's block, keeping the others (atomic rewrite); the calib
 * stage removes the file before it solves anything. */
int rs_calib_pose_write(const char *path, const char *section, const rs_pose *pose, rs_err *err);
/* Errors: no block for the section, malformed lines. */
int rs_calib_pose_read(const char *path, const char *section, rs_pose *pose, rs_err *err);

/* A solved pose into a report object: "position" [x, y, z] (m) and "rotation" (camera -> world,
 * row-major), as calib.json writes every pose it found. */
struct rs_json;
void rs_calib_pose_json(struct rs_json *o, const rs_pose *pose);

#endif
