/* skyground: the albedo of the ground beyond the model, taken from the model's own ground.
 * The sky map's ground model (skyfill.h: ground_albedo * E_horizontal / pi, for directions below
 * the horizon that no camera saw as ground nearby) needs the ground's albedo; the scan's lowest
 * level of upward facets is that ground, and its albedo follows from its observed radiance and a
 * gather of its own, which sees no direction below the horizon and so does not depend on it.
 * Exports rs_skyground_*. */
#ifndef RS_SKYGROUND_H
#define RS_SKYGROUND_H

#include <stddef.h>
#include <stdint.h>
#include "light/gather.h"
#include "common/mesh.h"

/* Facets used at most, spread evenly over the ground level, and at least (else no estimate). */
#define RS_SKYGROUND_MAX_FACETS 2000
#define RS_SKYGROUND_MIN_FACETS 30
/* The ground level: upward facets (normal z above this) ... */
#define RS_SKYGROUND_UP_Z 0.95
/* ... whose centroid lies within this height (m) of the lowest of them (its 2nd percentile), and
 * whose cosine-weighted hemisphere meets facets no camera saw on at most this share. */
#define RS_SKYGROUND_LEVEL_M    0.25
#define RS_SKYGROUND_MAX_UNSEEN 0.02

typedef struct rs_skyground {
    double albedo[3];       /* median over the facets of pi L / (E_sky + G), per channel */
    double spread[3];       /* half the distance between their 16th and 84th percentiles */
    size_t facets;          /* facets it came from (0: no estimate, albedo untouched) */
    size_t candidates;      /* observed upward facets at the ground level */
    size_t sees_unobserved; /* of those gathered, left out for seeing unobserved facets */
    double level_z;         /* the ground level's lowest centroid height (m) */
} rs_skyground;

/* Estimates the ground's albedo with the gather context g (its sky map as it is; radiance and
 * observed: the observe stage's per-facet values, 3 and 1 per facet). Returns 0 (out->facets 0
 * when fewer than RS_SKYGROUND_MIN_FACETS qualify), -1 out of memory (err set). */
int rs_skyground_albedo(const rs_gather_ctx *g, const rs_mesh *mesh, const double *radiance, const uint8_t *observed,
                        rs_skyground *out, rs_err *err);

#endif
