/* register: the pose of a spherical panorama from pixel <-> world correspondences (the pairs
 * file of docs/DESIGN.md, section Pairs file): P3P on bearing vectors inside RANSAC, then Levenberg-Marquardt
 * on the inliers' angular residuals. No pinhole assumption: points may lie anywhere on the sphere. */
#ifndef RS_REGISTER_H
#define RS_REGISTER_H

#include <stdint.h>
#include "common/err.h"
#include "common/pano.h"

typedef struct rs_pair {
    double col, row; /* continuous pixel coordinates, pixel centres at integers */
    rs_v3 world;     /* m, world frame */
    long line;       /* line in the pairs file (0 when made in code) */
} rs_pair;

/* Reads a pairs file: `column row X Y Z` per line (spaces, tabs or commas between the numbers),
 * `#` starts a comment. The numbers must be finite and the pixel lie on a width x height
 * panorama. Caller frees *pairs with free(). Errors name the file, the line, the text and what
 * was expected; fewer than 4 pairs, more than 10^6, and a pair listed twice are errors. */
int rs_pairs_read(const char *path, int width, int height, rs_pair **pairs, int *count, rs_err *err);
/* The same from size bytes of text (a NUL byte is an error); path names it in errors. */
int rs_pairs_parse(const char *data, size_t size, const char *path, int width, int height, rs_pair **pairs, int *count,
                   rs_err *err);

/* Unit bearing (panorama local frame) of a pixel position with pixel centres at integers. */
rs_v3 rs_pair_bearing(double col, double row, int width, int height);

typedef struct rs_register_opts {
    int iterations;    /* RANSAC samples of 3 pairs */
    double inlier_deg; /* a pair is an inlier when its angular residual is below this */
    uint64_t seed;
    const rs_pose *guess; /* optional initial pose, scored with the RANSAC candidates */
} rs_register_opts;

typedef struct rs_register_result {
    rs_pose pose; /* local -> world rotation and centre */
    int inliers;
    double rms_deg, max_deg; /* over the inliers, after refinement */
} rs_register_result;

/* Solves the pose from n >= 4 bearings (local frame, unit) and their world points. Fills
 * residual_deg[i] (angle between the observed and the predicted bearing, every pair) and
 * inlier[i] (1 or 0). Errors: n < 4, the world points on one line, fewer than 4 inliers. */
int rs_register_solve(const rs_v3 *bearing, const rs_v3 *world, int n, const rs_register_opts *opts,
                      rs_register_result *res, double *residual_deg, uint8_t *inlier, rs_err *err);

/* Angle (degrees) between bearing b (local) and world point x seen from pose p. */
double rs_register_residual_deg(const rs_pose *p, rs_v3 b, rs_v3 x);

#endif
