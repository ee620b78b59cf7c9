/* sunsearch: the direction of a sun that nobody placed and no camera saw, from the shadows on
 * the model. Among the directions the sky map filled (no camera saw sky there), it looks for
 * the one whose predicted shadow edges line up with jumps of the observed radiance over the
 * irradiance without the sun. Score of a direction s: every facet of rs_sunshadow_pairs facing
 * s (n.s > 0.1) is lit or shadowed by one ray from its centroid; over the pairs with one end of
 * each, the median of log(Y_lit / E_lit) - log(Y_dark / E_dark), Y the luminance of the observed
 * radiance and E of E_sky + G. With equal albedos that is log(1 + D cos / E) at the true
 * direction, and about 0 where the predicted edges cross no real one. That median sets a
 * threshold for an edge score which also counts real edges a direction fails to predict, and
 * that picks the direction, coarse to fine: an 8 degree grid, then 2 and 0.5 degree grids
 * around the best three. Exports rs_sunsearch_*. */
#ifndef RS_SUNSEARCH_H
#define RS_SUNSEARCH_H

#include <stddef.h>
#include <stdint.h>
#include "common/scene.h"
#include "sky/skyenv.h"
#include "sky/sunshadow.h"

/* Fewest lit-shadowed pairs for a direction to be scored. */
#define RS_SUNSEARCH_MIN_PAIRS 50
/* Most pairs a direction is scored on (every k-th beyond): it bounds the rays per direction,
 * about 2 per pair, so the search costs the same at 10^6 facets as at 10^5. */
#define RS_SUNSEARCH_MAX_PAIRS 100000
/* Smallest median log contrast taken for a sun (a 10.5 % jump): an overcast sky's shadows
 * score about 0. */
#define RS_SUNSEARCH_MIN_SCORE 0.1

/* Smallest circumsolar term c of the Perez fit to the visible sky (green; CIE clear skies 10,
 * overcast 0; the reference skies 5.9 to 8.2) for a search: below it the sky is overcast and
 * no sun casts shadows, while an albedo edge could still look like one. */
#define RS_SUNSEARCH_MIN_GLOW 2.0

/* Albedo above 1 without the sun on facets a direction lights is light missing from the model;
 * a dim sun the cameras saw cannot make it. With at least this many such facets, and four times
 * as many lit as shadowed by it, a direction farther from the visible sky's sun than the cues'
 * agreement allows is taken all the same (light/sunsource.c). */
#define RS_SUNSEARCH_MIN_ABOVE_ONE 30

/* Evidence instead of the cone: a direction beyond the prior's cone is taken when its edge score
 * beats the best inside the cone by at least this many standard errors (cone_sigmas; the
 * default of [sky] sun_search_lead_sigmas), it lights at least RS_SUNSEARCH_MIN_ABOVE_ONE pair
 * facets whose albedo is above 1 without the sun and more than it shadows, and its DNI is
 * significant (light/sunsource.c). */
#define RS_SUNSEARCH_LEAD_SIGMAS 4.0

typedef struct rs_sunsearch {
    rs_v3 dir;           /* unit, world, toward the sun */
    double score;        /* its log contrast: the median, or the sun cluster's (upper_cluster) */
    double median_score; /* the median log contrast over every lit-shadowed pair there */
    double edge_score;   /* its edge score (sunsearch.c), what picked it */
    size_t pairs;        /* lit-shadowed pairs behind it (the cluster's consensus with upper_cluster) */
    size_t above_one_lit, above_one_dark; /* pair facets with albedo above RS_SUNSHADOW_ABOVE_ONE without
                                             the sun that it lights, that it shadows: missing light */
    int ridge;            /* 1: the best was beyond the prior's cone, and this direction inside it is tied with it */
    int candidates;       /* directions scored */
    int upper_cluster;    /* 1: the best median was below RS_SUNSEARCH_MIN_SCORE (leaks can outvote it), so
                             every direction was scored by the sun's cluster of contrasts instead
                             (rs_sunshadow_upper_cluster), and the edge score forgave predicted edges
                             the radiance does not show */
    double cone_sigmas;   /* the best lies beyond the prior's cone and none inside it is tied: its edge-score lead
                             over the best direction inside (refined there), in standard errors over the blocks
                             of pairs; NAN when not measured (inside the cone, a ridge, or nothing scored there) */
    rs_v3 cone_dir;       /* with cone_sigmas: that best direction inside the cone */
    double dir_sigma_deg; /* the direction's uncertainty: RMS angle of the best direction over a
                             bootstrap of blocks of pairs, on a 1 degree grid within 6 degrees */
} rs_sunsearch;

/* E and L: 3 per facet (E_sky + G without a sun, and the observed radiance). prior (or NULL):
 * where the visible sky puts the sun; when the best direction lies more than prior_deg from it,
 * a direction within prior_deg whose edge score is statistically tied with the best (a ridge of
 * directions that put the long shadow lines in the same place) replaces it (ridge). Returns 0
 * with the best direction, 1 when no direction had RS_SUNSEARCH_MIN_PAIRS pairs, -1 out of
 * memory (err set). */
int rs_sunsearch_run(const rs_scene *scene, const rs_skyenv *env, const rs_sunshadow_pairs *pairs, const double *E,
                     const double *L, const uint8_t *observed, const rs_v3 *prior, double prior_deg, rs_sunsearch *out,
                     rs_err *err);

/* Whether the stage takes the direction found (light/sunsource.c), off_deg from the visible
 * sky's sun: its contrast reaches RS_SUNSEARCH_MIN_SCORE and it lies within agree_deg of the sky's
 * sun, or lights at least RS_SUNSEARCH_MIN_ABOVE_ONE pair facets whose albedo is above 1 without
 * it, four times as many as it shadows (*missing_light), or (lead_sigmas > 0) leads the best
 * direction inside the cone by lead_sigmas standard errors (cone_sigmas) and lights at least
 * RS_SUNSEARCH_MIN_ABOVE_ONE of those facets, more than it shadows (*decisive). The DNI's
 * significance is the estimate's to check. */
int rs_sunsearch_accept(const rs_sunsearch *f, double off_deg, double agree_deg, double lead_sigmas, int *missing_light,
                        int *decisive);

/* The same scored by the median contrast alone, never by the sun's cluster: the search as it
 * was before leaks were guarded against, for tests that show the difference. */
int rs_sunsearch_run_median_only(const rs_scene *scene, const rs_skyenv *env, const rs_sunshadow_pairs *pairs,
                                 const double *E, const double *L, const uint8_t *observed, rs_sunsearch *out,
                                 rs_err *err);

#endif
