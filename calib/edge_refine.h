/* edge_refine: refines a capture's pose (rotation and centre) by aligning the edges of the
 * panorama with the edges of the model seen from the pose, so that a rough pose is enough.
 * Model edges (silhouettes against the sky, depth steps, creases) come from ray casting the
 * mesh per pixel; image edges from Canny on log luminance; the cost is a robust chamfer
 * distance, minimised by Levenberg-Marquardt coarse to fine over a panorama pyramid. */
#ifndef RS_EDGE_REFINE_H
#define RS_EDGE_REFINE_H

#include "common/err.h"
#include "common/image.h"
#include "common/pano.h"
#include "common/scene.h"

typedef struct rs_edge_refine_opts {
    int levels;              /* pyramid levels, each half the width of the next finer one */
    int max_width;           /* the finest level's width: the panorama's halved until <= this (px) */
    double edge_lo, edge_hi; /* Canny thresholds on |grad ln luminance|, per pixel of the level */
    double crease_deg;       /* angle between neighbouring faces' normals that makes a model edge */
    double robust_px;        /* Cauchy scale of the chamfer residuals, pixels of the level */
    double max_dist_px;      /* chamfer distances are clipped here (pixels of the level) */
    int min_edges;           /* fewer model or image edge pixels at a level: refused */
    int iterations;          /* Levenberg-Marquardt iterations per level at most */
} rs_edge_refine_opts;

/* The defaults the calib stage uses (3 levels, finest <= 2048 px wide). */
void rs_edge_refine_defaults(rs_edge_refine_opts *o);

typedef struct rs_edge_refine_result {
    rs_pose pose;                             /* refined: local -> world rotation and centre */
    double cost_before, cost_after;           /* mean robust chamfer cost at the finest level (px^2) */
    double median_px_before, median_px_after; /* median chamfer distance at the finest level (px) */
    int iterations;                           /* accepted and rejected LM steps, all levels */
    long model_edges, image_edges;            /* edge pixels at the finest level */
    int finest_width;                         /* px */
    double turn_deg, shift_m;                 /* the change from the start pose */
} rs_edge_refine_result;

/* Refines start against pano (linear RGB or grey, width = 2 x height, docs/DESIGN.md, section Frames) and
 * the scene's mesh. Errors (RS_ERR_INPUT): a panorama of the wrong shape, fewer than
 * opts->min_edges model edges visible from the pose or image edges at some level (the message
 * says which and how many, so that the caller can name its config key). */
int rs_edge_refine(const rs_scene *scene, const rs_image *pano, const rs_pose *start, const rs_edge_refine_opts *opts,
                   rs_edge_refine_result *res, rs_err *err);

#endif
