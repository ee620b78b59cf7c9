/* albpool: the albedo pooled within same-material planar regions, edges kept (issue 28, part 4).
 * A facet of a few panorama pixels carries the camera's noise into its albedo; its neighbours on
 * the same plane, if of the same material, estimate the same albedo with independent pixels.
 *
 * For each estimable facet i, the candidates j are its same-plane neighbours within the disk of
 * about RS_POOL_FACETS facets of its own area (pool.h with R far beyond it: normals within about 8
 * degrees, off i's plane by at most a tenth of the distance). j is kept when its albedo agrees
 * with i's within `sigmas` combined standard errors in every channel,
 *     |rho_i - rho_j| <= sigmas rho_ij sqrt(s_i^2 + s_j^2 + 2 floor^2),
 * s being the facet's independent relative noise (radiance_sigma_rel and the Monte Carlo part of
 * E in quadrature): a real step (paint, a stain, brick against mortar) larger than that survives.
 * A neighbour whose albedo is above 1 in a channel (light the model missed, pixels mixed across an
 * edge) is not kept. Over the kept set, weights w_j = area_j / (s_j^2 + floor^2) (inverse variance:
 * a badly observed facet does not pull a well observed one), normalised, m_i = sum w_j rho_j
 * (pool.h's disk taper included in area_j). What the facets resolve
 * (a pattern below the test's reach) shows as scatter beyond the noise: with S = sum w_j
 * (rho_j - m_i)^2 / m_i^2 (luminance) and N = sum w_j s_j^2 - sum w_j^2 s_j^2 its expectation
 * under noise alone, the real variance is tau^2 = max(0, S - N) / (1 - sum w_j^2). The estimate
 * shrinks i toward m_i by B = s_i^2 / (s_i^2 + tau^2) (empirical Bayes): pure noise pools fully,
 * a resolved texture keeps its own value. rho'_i = sum_j c_j rho_j, c_j = B w_j + (1 - B) [j = i].
 *
 * Uncertainty (relative): the radiance noise falls to sqrt(sum c_j^2 sL_j^2); the Monte Carlo
 * part of E is taken as wholly correlated (neighbours' irradiance was pooled over overlapping
 * sets): sum c_j sMC_j, not averaged away; the sky fill's and the floor stay the facet's own; the
 * bias of pooling over a real texture adds B tau sqrt(1 - 2 w_i + sum w_j^2). */
#ifndef RS_ALBPOOL_H
#define RS_ALBPOOL_H

#include <stddef.h>
#include <stdint.h>
#include "common/mesh.h"

typedef struct {
    size_t nf;
    const double *rho;     /* 3 per facet */
    const uint8_t *usable; /* estimable facets: the only ones pooled, and pooled with */
    const double *s_rad;   /* radiance_sigma_rel */
    const double *s_mc;    /* Monte Carlo relative noise of E (irradiance_mc_sigma / E) */
    double floor;          /* albedo_sigma_floor */
    double sigmas;         /* the test's threshold, in combined standard errors (> 0) */
} rs_albpool_in;

typedef struct {
    double *rho;    /* 3 per facet: pooled (unusable facets: copied) */
    double *s_rad;  /* per facet: the pooled radiance noise (relative) */
    double *s_mc;   /* the Monte Carlo part, correlated */
    double *s_bias; /* the bias of pooling over a resolved texture */
    double *neff;   /* effective facets, 1 / sum c_j^2 (1: not pooled) */
    /* summary over usable facets */
    size_t pooled;          /* facets pooled with at least one other */
    double mean_neff;       /* mean effective facets */
    double mean_kept_share; /* mean share of candidates the test kept */
    double mean_shrink;     /* mean B */
} rs_albpool_out;

/* Returns 0, or -1 when out of memory. out's arrays are the caller's (nf or 3 nf). */
int rs_albpool_run(const rs_mesh *mesh, const rs_albpool_in *in, rs_albpool_out *out);

#endif
