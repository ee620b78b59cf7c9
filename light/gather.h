/* gather: the per-facet hemisphere gather of the irradiance stage, usable on its own (tests,
 * benchmarks): E_sky from rays that escape, and the row of K from rays that hit other facets. */
#ifndef RS_GATHER_H
#define RS_GATHER_H

#include <stdint.h>
#include "common/capture.h"
#include "common/scene.h"
#include "sky/skyenv.h"

typedef struct rs_kentry {
    uint32_t col;      /* facet j */
    float k, k_unseen; /* K_ij (sr), and the part whose hit points the camera did not see */
} rs_kentry;

typedef struct rs_facet_gather {
    double esky[3];              /* E_sky (same unit as the panorama's radiance times sr) */
    double esun[3];              /* the part of esky from the sun set's pixels (and an explicit
                                  sun): sharp-edged, so never pooled between facets */
    double inv_dist;             /* mean over the cosine rays of 1 / hit distance (escapes: 0), 1/m:
                                  Ward's harmonic mean distance is its reciprocal */
    double gseen[3];             /* G read from the panorama at hit points the camera sees */
    double esky_lum, filled_lum; /* luminance of E_sky, and of its filled-in part */
    double fill_sigma_lum;       /* standard uncertainty of filled_lum: its light times each filled
                                  direction's fill uncertainty (env->fill_sigma_px), summed: a fill
                                  errs smoothly over neighbouring directions, not at random */
    double fill_sigma_rgb[3];    /* the same per channel, from the sky map's filled pixels alone (a
                                  sun from the shadows adds to fill_sigma_lum, not here): the
                                  light skyscale.h rescales */
    double fill_sigma_dir[2][3]; /* fill_sigma_rgb with each filled direction's light weighted by
                                  that direction's world x [0] and y [1] (its horizontal part):
                                  the moments skyscale_dir.h fits a direction-dependent error with */
    /* Monte Carlo noise, from the rays' own spread (luminance). Cosine rays: the sum and sum of
     * squares of each ray's value Y (E = mean Y): escapes carry their MIS-weighted sky, hits read
     * from the panorama pi L; hits through K carry 0 here, their pi L_j is added by the caller,
     * who knows L_j. Map and sun rays: the variance of their estimates (already / rays). */
    double cos_sum, cos_sum_sq, map_var;
    rs_kentry *entries; /* K row, sorted by col; caller frees */
    uint32_t nentries;
    uint32_t rays;        /* rays of this facet */
    uint32_t samples;     /* its base cosine-ray count (rs_gather_ctx samples; fewer for relays) */
    uint8_t relay;        /* rs_gather_run gathered it as a relay (relay_share) */
    uint8_t sees_nothing; /* the model lies below its plane: its rays were not traced */
    uint8_t rounds;       /* target_error: times its counts were doubled (0: the base counts) */
    uint8_t sky_sh;       /* E_sky from the sky's harmonic projection (skysh.h): no ray at all */
    double sh_sigma;      /* with sky_sh: the projection's error bound on esky_lum (not noise) */
} rs_facet_gather;

typedef struct rs_gather_ctx {
    const rs_scene *scene;
    const rs_skyenv *env;  /* NULL: no sky (escaping rays bring nothing) */
    const rs_capture *cap; /* NULL: no panorama readings (every hit goes through K) */
    const float *facet_id; /* the observe stage's facet-id image (with cap) */
    int samples;           /* cosine-weighted rays */
    int sky_samples;       /* rays drawn from the sky map (all but the sun set) */
    int sun_samples;       /* rays toward the sun set */
    uint32_t seed;
    double sun_target_error;       /* > 0: adaptive sun rays (up to 16 x sun_samples) until their
                                  standard error is below this share of E_sky; 0: off */
    int skip_convex;               /* facets with the whole model below their plane trace no ray */
    const struct rs_skysh *sky_sh; /* with skip_convex, those facets take E_sky from it when it
                                      applies (rs_skysh_facet); NULL: never */
    double target_error;           /* > 0: gather in rounds, doubling every ray count (up to
                                  2^RS_GATHER_MAX_ROUNDS x), until the standard error of E_sky + G
                                  is below this share of it; 0: the base counts (sun_target_error
                                  then applies to the sun rays alone) */
    double relay_share;            /* rs_gather_run: facets gathered only because their light reaches
                                  the needed ones (relays) trace this share of every ray count,
                                  rounded down to a power of two, without adaptive rounds; 0 or
                                  1: exactly as the needed facets */
    const double *radiance;        /* with target_error: facets' mean radiance (3 per facet), so that */
    const uint8_t *observed;       /* rays into K count pi L_j for observed j (NULL: they count 0) */
} rs_gather_ctx;

/* target_error's cap: at most 2^4 = 16 times the base counts. */
#define RS_GATHER_MAX_ROUNDS 4

/* Scratch for one thread; rs_gather_scratch_new(max(samples, sun_samples)). */
typedef struct rs_gather_scratch rs_gather_scratch;
rs_gather_scratch *rs_gather_scratch_new(size_t n);
void rs_gather_scratch_free(rs_gather_scratch *s);

/* The pixel rs_skyenv_pick (sun = 0) or rs_skyenv_pick_sun (sun = 1) returns for x in [0, 1),
 * found through the map's search guide (built with its distributions; a map without one gets
 * one in the scratch on first use, and a scratch serves one sky map for its life): the same
 * pixel with one or two memory accesses instead of a binary search's twenty over a map of
 * millions of pixels. */
size_t rs_gather_pick(rs_gather_scratch *s, const rs_skyenv *env, int sun, double x);

/* Gathers facet f into *out (zeroed first). Degenerate facets get nothing. -1: out of memory (a
 * bare -1: it runs on many threads at once; rs_gather_run and rs_gather_list name the failure). */
int rs_gather_facet(const rs_gather_ctx *g, uint32_t f, rs_gather_scratch *s, rs_facet_gather *out);

/* Standard error of the luminance of E_sky + G of a gathered facet from its rays' own spread
 * (Monte Carlo noise; independent-sample formula, which the stratified sequences only beat).
 * Rays that hit facet j through K carry pi L_j of
 * radiance[3 j..] when observed[j] (both may be NULL: they then carry 0). */
double rs_gather_mc_sigma(const rs_facet_gather *fg, const double *radiance, const uint8_t *observed);

/* G of a gathered facet from observed facets: the panorama readings (gseen) plus K_ij L_j for
 * the hits the camera did not see, over observed j (unobserved ones are the reflectance
 * stage's job). E_sky + G is what the albedo divides by. */
void rs_gather_inter_observed(const rs_facet_gather *fg, const double *radiance, const uint8_t *observed, double g[3]);

/* The independent-sample formula overstates the error of the scrambled Sobol sequences, by a
 * factor that depends on the scene (2.4 to 3.2 on the reference scenes, 1.25 on a test floor).
 * This measures it: every stride-th gathered facet that is not a relay (at most max_facets) is
 * gathered again at g's counts with another seed, and *factor = RMS over them of
 * (E - E') / (sqrt(2) rs_gather_mc_sigma), E the luminance of E_sky + G as rs_gather_mc_sigma
 * counts it: the ratio of the actual noise to the formula's (1 when no facet qualifies). *used: the facets it came from (may be NULL). The
 * result does not depend on the thread count. Returns 0, -1 out of memory (err set). */
int rs_gather_mc_calibration(const rs_gather_ctx *g, size_t nf, const rs_facet_gather *fg, const double *radiance,
                             const uint8_t *observed, size_t max_facets, double *factor, size_t *used, rs_err *err);

typedef struct rs_gather_stats {
    size_t gathered;     /* facets gathered */
    size_t relays;       /* of which relays, at relay_share of the rays */
    int waves;           /* rounds of the closure (1 when every facet is needed) */
    double rays;         /* rays traced */
    size_t sees_nothing; /* facets whose rays needed no tracing (skip_convex) */
} rs_gather_stats;

/* Gathers every facet into fg[nf] (zeroed first) on all OpenMP threads, in the spatial (Morton)
 * order of the facets' centroids so that consecutive rays traverse the same part of the BVH.
 * needed: NULL gathers every facet. Otherwise only the facets with needed[f] != 0 (the ones a
 * camera sees) and, wave after wave, every facet that the rays of a gathered facet hit, until no
 * new one is reached: the closure of the light paths that end at a needed facet. Every K row of
 * a gathered facet then points only at gathered facets, and its E_sky and row are the same as in
 * a full gather. With g->relay_share in (0, 1) that holds for the needed facets; the later
 * waves, the relays, trace that share of the rays (fg[f].relay): noisier, not biased. The
 * facets left out (no camera sees them and they light nothing that matters) keep a zeroed
 * fg[f]. gathered (may be NULL): nf flags. prog may be NULL. Returns 0, or -1 when out of
 * memory (err set). The result does not depend on the thread count. */
struct rs_progress;
struct rs_skysh;
/* Fills out for a facet with normal n that sees only sky (the model below its plane) from the
 * sky's harmonics when rs_skysh_sky_only accepts n: E_sky, its luminance and filled part,
 * sees_nothing and sky_sh set, sh_sigma = the bound x its luminance outside the sun set (an
 * error bound, not noise), no ray (rays = 0). Returns 1 when it did, else 0. */
int rs_skysh_facet(const struct rs_skysh *sh, rs_v3 n, rs_facet_gather *out);
/* Gathers facets list[0 .. n-1] into out[0 .. n-1] in parallel (out[k].entries: caller frees).
 * Returns 0, or -1 when out of memory (err set). */
int rs_gather_list(const rs_gather_ctx *g, const uint32_t *list, size_t n, rs_facet_gather *out, rs_err *err);
int rs_gather_run(const rs_gather_ctx *g, size_t nf, const uint8_t *needed, rs_facet_gather *fg, uint8_t *gathered,
                  struct rs_progress *prog, rs_gather_stats *stats, rs_err *err);

#endif
