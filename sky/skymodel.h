/* skymodel: a clear-sky model fitted to the visible sky: the Perez all-weather luminance
 * distribution per colour channel times a smooth residual (real spherical harmonics of the log
 * radiance). Exports rs_skymodel_* (fit, evaluate, find the sun in a sunless sky). */
#ifndef RS_SKYMODEL_H
#define RS_SKYMODEL_H

#include <stddef.h>
#include "common/vec.h"

#define RS_SKYMODEL_MAX_SH 4 /* highest residual order; (order + 1)^2 coefficients */

/* One fitting point: a patch of measured sky (the sun left out). */
typedef struct rs_skysample {
    rs_v3 dir;     /* unit, world frame, z > 0 */
    double rgb[3]; /* mean radiance over the patch */
    double weight; /* measured solid angle of the patch, sr */
} rs_skysample;

typedef struct rs_skymodel {
    rs_v3 sun;           /* unit world direction toward the sun */
    double perez[3][5];  /* a b c d e per channel (Perez, Seals, Michalsky 1993) */
    double log_scale[3]; /* log of the channel's radiance where the Perez factor is 1 */
    int sh_order;        /* -1: no residual; else 0..RS_SKYMODEL_MAX_SH */
    double sh[3][(RS_SKYMODEL_MAX_SH + 1) * (RS_SKYMODEL_MAX_SH + 1)];
    double fit_rms_log; /* weighted RMS of the log residual after the fit (luminance) */
} rs_skymodel;

/* Perez relative luminance (1 + a exp(b / cos theta)) (1 + c exp(d gamma) + e cos^2 gamma) with
 * theta the zenith angle of the sky element (cos clamped to >= 0.01 at the horizon) and gamma
 * its angle to the sun (rad). */
double rs_skymodel_perez(const double p[5], double cos_theta, double gamma);

/* Fits the Perez parameters of each channel (Levenberg-Marquardt on the log radiance from
 * three CIE standard-sky starts, Huber-reweighted so trees and roofs in the sky do not drag
 * the fit), then residual harmonics up to sh_order (-1: none) by ridge regression with a
 * penalty sh_ridge * (l (l + 1))^2 that keeps the extrapolation into unseen directions smooth.
 * The sun direction is given. Returns 0, or -1 with fewer than 12 usable samples. */
int rs_skymodel_fit(const rs_skysample *s, size_t n, rs_v3 sun, int sh_order, double sh_ridge, rs_skymodel *m);

/* Refits only the residual harmonics of a fitted model at another order (the Perez part and
 * the samples must be those of the fit): cheap order selection. */
void rs_skymodel_refit_sh(const rs_skysample *s, size_t n, int sh_order, double sh_ridge, rs_skymodel *m);

/* Model radiance toward world direction dir (unit; meaningful for dir.z > 0). */
void rs_skymodel_eval(const rs_skymodel *m, rs_v3 dir, double rgb[3]);

/* For a sky where the sun is neither seen nor given: the direction (elevation -5 to 90 degrees)
 * whose clear-sky Perez distribution explains the samples' luminance best (grid search, 2.5
 * degree steps). The circumsolar glow seen beside a hidden sun fixes it. */
rs_v3 rs_skymodel_find_sun(const rs_skysample *s, size_t n);

#endif
