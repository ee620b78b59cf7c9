/* sunshadow: the direct normal irradiance of a sun that no capture shows (hidden behind the
 * building, or clipped), from the shadows it casts on the model. A facet i in full sun and a
 * facet j in full shadow close to it on the same plane are taken to have the same albedo, so
 * the ratio of their radiances is the ratio of their irradiances:
 *     L_i / L_j = (E_i + D cos_i) / E_j   =>   D = (L_i E_j / L_j - E_i) / cos_i
 * per channel, E being E_sky + G without the sun and cos_i = max(0, n_i . s). The median over a
 * lit facet's partners, then over the lit facets, is robust to albedo edges. Facets within a
 * margin of the shadow edge are left out: a facet's observed radiance mixes pixels across the
 * edge, and the penumbra and the shadow rays blur it. Exports rs_sunshadow_*. */
#ifndef RS_SUNSHADOW_H
#define RS_SUNSHADOW_H

#include <stddef.h>
#include <stdint.h>
#include "common/err.h"
#include "common/mesh.h"
#include "common/vec.h"

/* Share of the sun's disc a facet must see to count as lit (at least) or shadowed (at most 1 - this). */
#define RS_SUNSHADOW_FULL 0.95
/* Fewest lit facets with a partner for an estimate. */
#define RS_SUNSHADOW_MIN_LIT 10

typedef struct rs_sunshadow_input {
    const rs_mesh *mesh;
    const float *vis;        /* nf: share of the sun's disc each facet sees; < 0 unknown */
    rs_v3 sun_dir;           /* unit, toward the sun */
    const double *E;         /* 3 nf: E_sky + G without the sun */
    const double *L;         /* 3 nf: observed radiance */
    const uint8_t *observed; /* nf */
    const double *E_sigma;   /* nf: standard uncertainty of E's luminance (the sky fill's); NULL: none */
    double margin;           /* m: a facet this close to one of another kind is left out */
    double radius;           /* m: partners within this distance (> margin) */
    int median_only;         /* 1: the median over every lit facet, as before the upper cluster (for tests) */
} rs_sunshadow_input;

/* The sun's cluster among values that leaks can outvote: per lit facet (or pair) a DNI or a
 * log contrast that is about 0 where the model let the sun through a gap it lacks (the lit end
 * is really in shadow) and about the sun's value where the shadow is real. The null cluster's
 * noise s0 is read from the values at or below 0 (1.4826 x their median magnitude); the sun's
 * cluster is the mode of the values above 3 s0 (medians within +- 2.5 MADs, iterated), its
 * consensus the values within 3 MADs of it. It is valid when it holds at least min_count values
 * and more than three times as many as the mirror tail below -3 s0 (a symmetric spread, no sun,
 * has as many of each). */
typedef struct rs_sunshadow_cluster {
    int valid;
    double location; /* the median of the consensus */
    double spread;   /* 1.4826 x its median absolute deviation */
    double null_noise;
    size_t consensus, positive, negative_tail, n;
} rs_sunshadow_cluster;

/* v[0..n) is not changed; scratch holds n floats. */
void rs_sunshadow_upper_cluster(const float *v, size_t n, size_t min_count, float *scratch, rs_sunshadow_cluster *out);

typedef struct rs_sunshadow {
    double dni[3];         /* per channel, the panorama's radiance unit x sr; >= 0 */
    double dni_lum;        /* its luminance */
    double sigma_stat_lum; /* standard error of dni_lum, from the spread between blocks of 2 x radius */
    double sigma_sys_lum;  /* what E_sigma makes of it (median over lit facets) */
    double sigma_lum;      /* both, in quadrature */
    size_t lit, shadowed;  /* observed facets in full sun and in full shadow beyond the margin */
    size_t lit_used;       /* lit facets that found a shadowed partner */
    size_t blocks;
    /* How the DNI was chosen: the median over every paired lit facet, or, when it lies outside
     * the sun's cluster (leaks outvote it), the cluster's consensus (rs_sunshadow_upper_cluster). */
    int upper_cluster; /* 1: the cluster's consensus gave the DNI */
    double median_lum; /* the median over every paired lit facet, luminance */
    size_t consensus;  /* lit facets behind the DNI */
    /* Albedo above 1 without the sun on lit facets: missing light. Each such facet needs a DNI of
     * at least (pi Y_L - Y_E) / cos_i (its albedo is at most 1); their median is a floor. */
    size_t above_one; /* lit, observed facets with pi Y_L / Y_E > RS_SUNSHADOW_ABOVE_ONE */
    double floor_lum; /* the median need over them (0 with fewer than RS_SUNSHADOW_MIN_LIT) */
    int floored;      /* 1: the DNI was raised to the floor */
} rs_sunshadow;

/* Albedo (pi L / E, luminance) without the sun above which a lit facet lacks light. */
#define RS_SUNSHADOW_ABOVE_ONE 1.05

/* The margin for a capture at cam with panoramas of the given height: the median over observed
 * facets of 4 pixel footprints at the facet's distance plus twice its longest edge. */
double rs_sunshadow_margin(const rs_mesh *mesh, const uint8_t *observed, rs_v3 cam, int pano_height);

/* Returns 0 with the estimate, 1 when fewer than RS_SUNSHADOW_MIN_LIT lit facets found a
 * partner (out still holds the counts), -1 out of memory (err set). */
int rs_sunshadow_estimate(const rs_sunshadow_input *in, rs_sunshadow *out, rs_err *err);

/* For the search of a sun whose direction nobody gave (sunsearch.h): pairs of observed facets
 * on one plane (as above) at a distance in [margin, radius], at most max_per_facet per facet
 * (the nearest beyond the margin are not preferred: the grid's order), each pair once. */
typedef struct rs_sunshadow_pairs {
    uint32_t *a, *b;
    size_t n;
} rs_sunshadow_pairs;

/* Returns 0, -1 out of memory (err set). rs_sunshadow_pairs_free releases. */
int rs_sunshadow_pairs_build(const rs_mesh *mesh, const uint8_t *observed, double margin, double radius,
                             int max_per_facet, rs_sunshadow_pairs *out, rs_err *err);
void rs_sunshadow_pairs_free(rs_sunshadow_pairs *p);

#endif
