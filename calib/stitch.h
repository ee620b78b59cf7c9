/* stitch: a rig's frames -> one equirectangular panorama in the rig frame (docs/DESIGN.md, section Frames),
 * at infinite depth or, given the model, with each pixel's parallax corrected by the model's depth;
 * feathered blending and per-camera gains estimated from the overlaps. */
#ifndef RS_STITCH_H
#define RS_STITCH_H

#include "common/image.h"
#include "common/pano.h"
#include "calib/rig.h"
#include "common/scene.h"
#include "calib/gains.h"

typedef struct rs_stitch_opts {
    int width;             /* panorama width (px); height = width / 2 */
    double feather_px;     /* blending weight reaches 1 this many camera pixels inside the usable edge */
    int estimate_gain;     /* 1: estimate and divide out one gain per camera */
    const rs_scene *scene; /* NULL: infinite depth. Else the model (world frame): each pixel's
                                  point is where its ray from the rig centre hits the model, and
                                  every camera looks at that point from its own centre (cameras
                                  that the model hides it from are left out); rays that miss the
                                  model (sky) keep infinite depth, without the cameras whose own
                                  ray in that direction hits the model */
    rs_pose pose;          /* with scene: rig -> world (the rig centre and rotation) */
} rs_stitch_opts;

typedef struct rs_stitch_stats {
    double coverage;       /* share of the sphere (solid angle) that some camera sees */
    int overlap_pairs;     /* camera pairs that share enough pixels for the gain estimate */
    double model_coverage; /* share of the sphere whose depth came from the model (0 without) */
    double hidden_share;   /* with a model: share of the camera samples (model points and sky)
                                  dropped because the model hides them from that camera */
    rs_gain_report gain;   /* with estimate_gain: per pair and overall; free with rs_gain_report_free */
} rs_stitch_stats;

/* Stitches frames[i] (3 channels, rig->cams[i]'s size, linear) into *pano (3 channels; NaN
 * where no camera sees), each camera's vignetting divided out and its masked pixels left out.
 * gains[i] gets camera i's gain (observed = gain x true): the rig file's where it gives one,
 * the others estimated robustly from the overlaps (calib/gains.h; geometric mean 1 over the
 * cameras when none is given); without estimate_gain the given gains or 1. Deterministic for
 * any thread count. Caller frees *pano with rs_image_free and stats->gain with
 * rs_gain_report_free. */
int rs_stitch(const rs_rig *rig, rs_image *const *frames, const rs_stitch_opts *opts, rs_image **pano, double *gains,
              rs_stitch_stats *stats, rs_err *err);

/* The panorama width that matches the finest camera: 2 pi times its largest focal length, even. */
int rs_stitch_default_width(const rs_rig *rig);

/* The width of the panorama the calib stage stitches: configured_width ([rig] width) when > 0,
 * else rs_stitch_default_width; made even. Stages before calib (the mesh's facet size) use it. */
int rs_stitch_width(const rs_rig *rig, int configured_width);

#endif
