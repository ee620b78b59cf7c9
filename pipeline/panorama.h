/* panorama: which file is a capture's panorama. With [rig] file, the calib stage stitches the
 * rig's frames into the work folder and that panorama is [capture]'s; otherwise a section's
 * own panorama key names it. Setting both for [capture] is refused. */
#ifndef RS_PANORAMA_H
#define RS_PANORAMA_H

#include <stddef.h>
#include "common/config.h"
#include "common/err.h"
#include "common/pano.h"

/* -1 with the refusal when both [rig] file and [capture] panorama are set, else 0. The calib
 * stage asks before it stitches; the functions below refuse the same. */
int rs_capture_panorama_check(const rs_config *cfg, rs_err *err);

/* The file of [section]'s panorama ("capture", "capture.NAME", "sky"): the stitched panorama
 * (pipeline/calib_files.h: RS_CALIB_PANO_FILE) when [rig] file is set and section is
 * "capture", else [section] panorama. Returns 1 with the path in out; 0 when there is none
 * (the caller says what needed one); -1 with err when rs_capture_panorama_check refuses or
 * the stitched panorama has not been made yet (run the calib stage). */
int rs_capture_panorama_path(const rs_config *cfg, const char *section, char *out, size_t n, rs_err *err);

/* The width (px) of [capture]'s panorama, known before the calib stage runs: [capture]
 * panorama's, or the width the calib stage will stitch [rig] file's frames to. Returns 1 with
 * *width and the file it was read from (the panorama or the rig file) in from; 0 when neither
 * is set; -1 with err when rs_capture_panorama_check refuses or the file cannot be read. */
int rs_capture_panorama_width(const rs_config *cfg, int *width, char *from, size_t n, rs_err *err);

/* [capture]'s camera centre for the stages that need it before the capture is loaded (the mesh
 * stage): the pose of the E57 image when [capture] panorama is an E57 file whose image has one
 * (pipeline/capture_e57.h), else [capture] position. 0 with pos, -1 when neither gives one. */
int rs_capture_position(const rs_config *cfg, double pos[3]);
/* The same with the rotation: the E57 image's, else [capture] rotation. */
int rs_capture_config_pose(const rs_config *cfg, rs_pose *pose);

#endif
