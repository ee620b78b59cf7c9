/* skyscale: the brightness of the filled-in (hidden) sky checked against the facets that see
 * it. Two observed facets on one plane are taken to share an albedo (as in sunshadow.h), so
 * the ratio of their radiances is the ratio of their irradiances. When they see different
 * amounts of the hidden sky, that ratio says how bright the hidden sky is. The fill's error is
 * modelled as one smooth mode in units of its own uncertainty: a filled direction of radiance
 * L and relative standard uncertainty sigma (rs_skyfill_sigma_map) really holds L (1 + t sigma),
 * so a facet's irradiance is E + t S, S being the sum over its filled directions of their
 * light times sigma (rs_facet_gather fill_sigma_rgb). t has the prior N(0, 1) (what the fill's
 * uncertainty claims); the pairs' log-ratio residuals
 *     r_ij(t) = log(L_i / L_j) - log((E_i + t S_i) / (E_j + t S_j))
 * are fitted robustly (Huber, scale from their MAD) for the posterior mode of t per channel.
 * Exports rs_skyscale_*. */
#ifndef RS_SKYSCALE_H
#define RS_SKYSCALE_H

#include <stddef.h>
#include <stdint.h>
#include "common/err.h"

/* A pair counts only when the two facets' shares of uncertain filled light differ by this much
 * (|S_i / E_i - S_j / E_j|, luminance): below it the pair says nothing of t. */
#define RS_SKYSCALE_MIN_CONTRAST 0.01
/* Fewest informative pairs for an estimate. */
#define RS_SKYSCALE_MIN_PAIRS 50

typedef struct rs_skyscale_input {
    size_t nf;
    const double *E;       /* 3 nf: E_sky + G (observed facets' G) as gathered */
    const double *S;       /* 3 nf: the filled light's standard uncertainty per channel */
    const double *L;       /* 3 nf: observed radiance */
    const uint32_t *a, *b; /* npairs same-plane pairs (rs_sunshadow_pairs_build) */
    size_t npairs;
    const uint32_t *block; /* npairs: each pair's spatial block (a few metres), whose own estimates'
                               spread measures the errors a wall's facets share; NULL: none (the
                               curvature alone, which knows nothing of them) */
    double max_per_facet;  /* pairs per facet at most: the residuals are that much less independent */
} rs_skyscale_input;

typedef struct rs_skyscale {
    double t[3];             /* posterior mode per channel (0: no change) */
    double sigma[3];         /* its standard uncertainty (from the curvature, the pairs' dependence
                               counted) */
    double t_lum, sigma_lum; /* the same on luminance: what decides whether it is applied */
    double resid_mad;        /* robust spread of the pairs' log-ratio residuals at t_lum */
    int at_bound;            /* the data's luminance t lies at the edge of its range [-0.9, 12]: the one
                     mode does not explain the pairs (auto does not apply it) */
    size_t pairs;            /* informative pairs (luminance) */
    size_t facets;           /* facets in them */
} rs_skyscale;

/* Returns 0 with the estimate, 1 when fewer than RS_SKYSCALE_MIN_PAIRS pairs are informative
 * (out then holds t = 0 and the counts), -1 out of memory (err set). */
int rs_skyscale_estimate(const rs_skyscale_input *in, rs_skyscale *out, rs_err *err);

#endif
