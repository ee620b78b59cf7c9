/* skyscale_dir: the directional mode of the hidden sky's check against the facets (skyscale.h).
 * One mode scales all the filled sky alike; a fill that is too dark toward a hidden sun and too
 * bright away from it makes the walls facing each way disagree, and the one mode can only split
 * the difference. Here a filled direction d of radiance L and relative uncertainty sigma really
 * holds L (1 + (t0 + t1 d.x + t2 d.y) sigma), d.x and d.y its world horizontal components, so a
 * facet's irradiance is E + t0 S + t1 Sx + t2 Sy (S = fill_sigma_rgb, Sx and Sy its moments
 * fill_sigma_dir, gather.h). The same same-plane pairs' log-ratio residuals
 *     r_ij(t) = log(L_i / L_j) - log((E_i + t . s_i) / (E_j + t . s_j))
 * are fitted robustly (Huber, by reweighted Gauss-Newton) per channel and on luminance. The
 * curvature's information (each facet counted once) is divided by the largest ratio of a
 * delete-a-group jackknife's variance over the pairs' spatial blocks to the curvature's
 * (errors a wall's facets share move whole blocks), and the prior N(0, I) (what the fill's
 * uncertainty claims, for each term) is folded in: a combination of terms that no pair tells
 * apart (walls that all face one way) stays at the prior's. Exports rs_skyscale_dir_*. */
#ifndef RS_SKYSCALE_DIR_H
#define RS_SKYSCALE_DIR_H

#include "sky/skyscale.h"

/* The direction-dependent part (t1, t2) counts when its chi-square on two degrees of freedom
 * is at least this: the same false-alarm rate (4.55 %) as 2 sigma on one (skyscale's auto). */
#define RS_SKYSCALE_DIR_CHI2 6.18
/* Groups of blocks for the jackknife (block id modulo this). */
#define RS_SKYSCALE_DIR_GROUPS 32

typedef struct rs_skyscale_dir_input {
    rs_skyscale_input base; /* E, S, L, the pairs and their blocks as for rs_skyscale_estimate */
    const double *Sx, *Sy;  /* 3 nf each: S weighted by the filled directions' world x and y */
    double sigma_max;       /* the largest relative uncertainty of a filled direction (0 or above 1:
                               1): bounds how dark t may make a direction (rs_skyscale_dir_lowest),
                               unless limits are given */
    const double *limits;   /* 3 per limit, nlimits (NULL: sigma_max's rule): a filled direction's
                               world x, y and the lowest multiplier t0 + t1 x + t2 y it allows
                               (rs_skyscale_dir_limits) */
    size_t nlimits;
} rs_skyscale_dir_input;

typedef struct rs_skyscale_dir {
    double t[4][3];        /* [channel R, G, B, luminance][t0, t1, t2]: posterior mode */
    double cov[4][3][3];   /* its covariance */
    double chi2[4];        /* (t1, t2)'s chi-square against 0 under cov */
    double resid_mad[4];   /* robust spread of the pairs' residuals at the data's t */
    int at_bound;          /* the luminance fit reached the edge of t's range: some filled direction
                              would keep less than a tenth of its light (the limits, or sigma_max's
                              rule), or t0 + |(t1, t2)| above 12 (not applied) */
    double lowest;         /* sigma_max's rule: the lowest multiplier (rs_skyscale_dir_lowest) */
    size_t pairs;          /* informative pairs (luminance) */
    int groups;            /* non-empty jackknife groups (luminance; 0: the curvature alone) */
    double shared_ratio;   /* luminance: the jackknife's largest variance of a term over the
                              curvature's (at least 1), the factor the information was divided by */
} rs_skyscale_dir;

/* Returns 0 with the estimate, 1 when fewer than RS_SKYSCALE_MIN_PAIRS pairs are informative
 * (t then 0, covariance I), -1 out of memory (err set). */
int rs_skyscale_dir_estimate(const rs_skyscale_dir_input *in, rs_skyscale_dir *out, rs_err *err);

/* The lowest multiplier t0 + t1 x + t2 y allowed: -0.9 / sigma_max (every filled direction
 * keeps a tenth of its light), sigma_max taken as 1 when not in (0, 1]. */
double rs_skyscale_dir_lowest(double sigma_max);

/* The map's filled directions as limits (3 doubles each into *limits, malloc'd; caller frees):
 * per cell of 5 x 5 degrees (world azimuth and elevation) that holds filled pixels, the direction
 * of its most uncertain one and -0.9 / its sigma, so that every filled direction keeps a tenth
 * of its light (to within the multiplier's change over a cell, 0.09 |(t1, t2)| at most).
 * Returns 0, -1 out of memory (err set). */
struct rs_skyenv;
int rs_skyscale_dir_limits(const struct rs_skyenv *env, double **limits, size_t *n, rs_err *err);

/* The correction t . (S, Sx, Sy) of one channel (out's channel ch, 0..2). */
double rs_skyscale_dir_delta(const rs_skyscale_dir *d, int ch, double S, double Sx, double Sy);

#endif
