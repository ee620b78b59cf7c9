/* pool: irradiance shared between neighbouring facets of one plane, after Ward's irradiance
 * caching (Ward, Rubinstein, Clear 1988; Radiance's -aa). A facet's sky-and-interreflection
 * irradiance changes over a distance of the order of R, the harmonic mean distance to what its
 * hemisphere sees; within a small share `a` of R, on (nearly) the same plane, the neighbours'
 * gathers estimate the same quantity with independent rays, so their weighted mean has less
 * Monte Carlo noise at a bias of order a. On a fine mesh (10^5 to 10^6 facets) a facet is much
 * smaller than R almost everywhere, and that is where the noise per ray budget is won.
 *
 * Facet j enters facet i's mean when Ward's error estimate
 *     eps_ij = |x_j - x_i| / min(R_i, R_j) + sqrt(1 - n_i . n_j)
 * is at most a, j lies within a of i's plane (|n_i . (x_j - x_i)| <= a |x_j - x_i|: not a
 * parallel step), and |x_j - x_i| is within the disk of about RS_POOL_FACETS facets of i's own
 * size. Weight: area_j (1 - eps_ij / a), so that the edge of the disk fades in. The sun's sharp
 * shadow is never pooled: callers pool what the sun set's rays did not bring. */
#ifndef RS_POOL_H
#define RS_POOL_H

#include <stddef.h>
#include <stdint.h>
#include "common/mesh.h"

/* The disk's size in facets of a facet's own area, and a hard cap on the neighbours kept. */
#define RS_POOL_FACETS         32
#define RS_POOL_MAX_NEIGHBOURS 64

typedef struct rs_pool {
    size_t nf;
    size_t *start; /* nf + 1: facet i's neighbours are nbr[start[i] .. start[i + 1]) */
    uint32_t *nbr; /* itself first */
    float *w;      /* their weights, summing to 1 per facet */
} rs_pool;

/* Builds the neighbour lists. inv_dist: per facet, mean 1 / hit distance (1/m, 0: R infinite);
 * usable: facets whose gather may be pooled (NULL: all); wanted: facets that get a list (NULL:
 * all; the reflectance stage asks for the observed ones, whose albedo divides by E). A facet
 * that is not wanted, not usable, or degenerate keeps itself alone. Returns 0, or -1 when out of
 * memory. */
int rs_pool_build(const rs_mesh *mesh, const double *inv_dist, const uint8_t *usable, const uint8_t *wanted,
                  double accuracy, rs_pool *p);
void rs_pool_free(rs_pool *p);

/* out[3 i + ch] = sum_j w_ij v[3 j + ch] (v and out must differ). */
void rs_pool_apply3(const rs_pool *p, const double *v, double *out);
/* Standard error of the pooled mean of independent values with standard errors sigma[]:
 * out[i] = sqrt(sum_j w_ij^2 sigma_j^2). */
void rs_pool_sigma(const rs_pool *p, const double *sigma, double *out);
/* Over the facets that asked for a list (wanted as in rs_pool_build; NULL: all): the mean
 * neighbour count (itself included), how many have at least one other, and how many asked. */
void rs_pool_stats(const rs_pool *p, const uint8_t *wanted, double *mean_count, size_t *pooled, size_t *asked);

#endif
