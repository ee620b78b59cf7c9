/* skyfill: fills the directions of a sky map that no camera measured, by row interpolation or
 * by a fitted sky model (skymodel.h) with the ground from the visible ground, and measures how
 * well each method predicts held-out measured sky. Exports rs_skyfill_*. */
#ifndef RS_SKYFILL_H
#define RS_SKYFILL_H

#include <stdint.h>
#include "common/err.h"
#include "common/pano.h"
#include "sky/skymodel.h"

typedef enum { RS_SKYFILL_ROW = 0, RS_SKYFILL_MODEL = 1 } rs_skyfill_method;

typedef struct rs_skyfill_opts {
    rs_skyfill_method method;
    int sun_given;       /* 1: sun_dir is known (config); else from sun pixels or a search */
    rs_v3 sun_dir;       /* unit, world */
    double sun_mask_rad; /* sky within this angle of the sun stays out of the model fit */
    int sh_order;        /* highest residual order tried (-1: Perez alone) */
    double sh_ridge;
    double ground_albedo; /* ground radiance = albedo E_horizontal / pi when no ground is seen */
    int cross_validate;   /* 1: held-out errors of both methods (fill_sigma needs it) */
} rs_skyfill_opts;

/* SEARCH: from the visible sky's glow (rs_skymodel_find_sun); SHADOWS: set by the caller when the
 * map is built again around the direction the model's shadows gave (irradiance.c). */
typedef enum { RS_SUN_CONFIG, RS_SUN_PIXELS, RS_SUN_SEARCH, RS_SUN_SHADOWS } rs_sun_source;

typedef struct rs_skyfill_report {
    rs_v3 sun_dir; /* used by the model (world, unit) */
    rs_sun_source sun_source;
    rs_skymodel model;                 /* the final fit (method model) */
    double cv_rel_row, cv_rel_model;   /* RMS over held-out blocks of the relative error of
                                          their integrated luminance; -1 when not computed */
    double cv_max_row, cv_max_model;   /* the largest |relative error| over those blocks (the
                                          model's at its chosen order); -1 when not computed */
    double cv_rate_row, cv_rate_model; /* the largest |relative error| over the square root of
                                          the block's mean distance (radians) from the sky left
                                          (skydist.h); -1 when not computed */
    int cv_folds;                      /* held-out blocks with enough sky */
    double fill_sigma;                 /* cv of the method used: relative uncertainty of filled light
                                  (1 when no held-out block could be measured) */
    double ground_rgb[3];              /* the ground model's radiance: ground_albedo * E_horizontal / pi */
    double horizontal_irradiance[3];   /* E_horizontal of the completed sky (model fill) */
    size_t ground_model_pixels;        /* filled pixels below the horizon that took it */
    int ground_from_albedo;            /* 1: every filled pixel below the horizon took it */
    size_t fit_samples;
} rs_skyfill_report;

/* The standard uncertainty (relative) of filled light from the held-out blocks: the hidden
 * directions are one more block whose error is one more draw. The largest |error| of n blocks
 * exceeds a new draw with probability n / (n + 1) whatever their distribution; under a normal
 * error that is the two-sided quantile z with P(|N(0, 1)| <= z) = n / (n + 1), so
 * sigma = largest / z (the same for the largest rate, error / sqrt(distance)). 1
 * (100 %) when no block was measured. */
double rs_skyfill_sigma_from_blocks(int blocks, double largest_error);

/* The standard uncertainty per square root of radian of distance from the measured sky: the
 * largest held-out rate (cv_rate_*) of the method that filled (the row method when the model
 * could not be fitted) through rs_skyfill_sigma_from_blocks; -1 when no block was measured. */
double rs_skyfill_rate_used(const rs_skyfill_report *rep, rs_skyfill_method method);

/* Per pixel of the map, the relative standard uncertainty of a filled value: the rate above times
 * the square root of its angle to the nearest source pixel (at least one skydist cell), at most
 * 1; 1 for every filled pixel when no rate was measured; 0 where not filled. A fill interpolates
 * next to the measured sky and extrapolates far from it: sqrt(d) is the kriging standard error of
 * a field with a linear variogram. Returns 0, -1 out of memory (err set). */
int rs_skyfill_sigma_map(int w, int h, const uint8_t *src, const uint8_t *fill, const rs_skyfill_report *rep,
                         rs_skyfill_method method, float *sigma, rs_err *err);

/* A filled pixel below the horizon copies measured ground at most this far (in depression
 * angle) from its own band; farther, it takes the ground model. */
#define RS_SKYFILL_GROUND_NEAR_RAD (10 * M_PI / 180)
/* fill's mark for a pixel the ground model filled (rs_skyenv_set_ground sets them again). */
#define RS_SKYFILL_GROUND_MODEL 2

/* Each pixel below the horizon with fill[k] == which takes the mean of the source (src) pixels
 * below the horizon in the nearest world elevation band that has some, within max_rad of its
 * own (M_PI / 2 or more: any), and is marked 1. Returns the pixels set, -1 out of memory (err
 * set; err may be NULL). */
long rs_skyfill_ground_from_bands(int w, int h, const rs_pose *pose, float *radiance, const uint8_t *src, uint8_t *fill,
                                  uint8_t which, double max_rad, rs_err *err);

/* radiance: 3 * w * h floats of a map in frame pose (rs_pano conventions), read and filled in
 * place. src (w * h): 1 for measured sky usable as a source (not the sun set). fill: 1 for the
 * pixels to fill. sun (w * h, may be NULL): the sun set, whose luminance-weighted centroid is
 * the sun direction when the config gives none.
 * Row: each pixel to fill takes the linear interpolation along its row (azimuth, wrapping) of
 * the nearest source pixels on either side; rows with none copy the nearest row with some.
 * Model: above the horizon the fitted Perez + harmonics model; below, the mean of the source
 * pixels in the same world elevation band (or the nearest band that has some, within
 * RS_SKYFILL_GROUND_NEAR_RAD), else ground_albedo * E_horizontal / pi per channel from the
 * completed sky, those pixels marked RS_SKYFILL_GROUND_MODEL in fill. Returns 0, -1 out of
 * memory (err set). */
int rs_skyfill_run(int w, int h, const rs_pose *pose, float *radiance, const uint8_t *src, uint8_t *fill,
                   const uint8_t *sun, const rs_skyfill_opts *o, rs_skyfill_report *rep, rs_err *err);

#endif
