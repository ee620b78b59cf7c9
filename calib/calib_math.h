/* calib_math: the small dense linear algebra calibration needs (symmetric eigenproblems up to
 * 4 x 4, rotations from axis-angle, Horn/Umeyama absolute orientation; linear systems are
 * common/linsolve.h's). */
#ifndef RS_CALIB_MATH_H
#define RS_CALIB_MATH_H

#include "common/vec.h"

/* Eigen-decomposition of the symmetric n x n matrix a (row-major, n <= 8; destroyed) by cyclic
 * Jacobi rotations: eigenvalues in descending order into evals, unit eigenvectors as the
 * columns of evecs (row-major n x n). */
void rs_calib_sym_eigen(int n, double *a, double *evals, double *evecs);

/* Rotation matrix (row-major) of the axis-angle vector w (radians): exp([w]x). */
void rs_calib_rot_exp(const double w[3], double r[9]);
/* out = a b (3 x 3 row-major; out may alias neither). */
void rs_calib_m3_mul(const double a[9], const double b[9], double out[9]);
/* Angle (radians) of the rotation a^T b: the distance between two rotations. */
double rs_calib_rot_angle(const double a[9], const double b[9]);

/* Similarity (or, with with_scale 0, rigid) transform taking src to dst in the least-squares
 * sense, dst ~ s R src + t (Horn 1987, unit quaternions; the scale is Umeyama's 1991 estimate).
 * n >= 3 points not all on one line. Returns -1 when the points are degenerate. */
int rs_calib_align(int n, const rs_v3 *src, const rs_v3 *dst, int with_scale, double r[9], rs_v3 *t, double *s);

/* Ratio of the second to the largest principal spread of the points (0 when they are all on one
 * line or coincide, about 1 when they spread in at least two directions). */
double rs_calib_spread_ratio(int n, const rs_v3 *p);

#endif
