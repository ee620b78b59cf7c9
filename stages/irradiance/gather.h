/* gather: the per-facet hemisphere gather of the irradiance stage, usable on its own (tests,
 * benchmarks): E_sky from rays that escape, and the row of K from rays that hit other facets. */
#ifndef RS_GATHER_H
#define RS_GATHER_H

#include <stdint.h>
#include "capture.h"
#include "scene.h"
#include "skyenv.h"

typedef struct rs_kentry {
    uint32_t col;              /* facet j */
    float k, k_unseen;         /* K_ij (sr), and the part whose hit points the camera did not see */
} rs_kentry;

typedef struct rs_facet_gather {
    double esky[3];            /* E_sky (same unit as the panorama's radiance times sr) */
    double gseen[3];           /* G read from the panorama at hit points the camera sees */
    double esky_lum, filled_lum; /* luminance of E_sky, and of its filled-in part */
    rs_kentry *entries;        /* K row, sorted by col; caller frees */
    uint32_t nentries;
} rs_facet_gather;

typedef struct rs_gather_ctx {
    const rs_scene *scene;
    const rs_skyenv *env;      /* NULL: no sky (escaping rays bring nothing) */
    const rs_capture *cap;     /* NULL: no panorama readings (every hit goes through K) */
    const float *facet_id;     /* the observe stage's facet-id image (with cap) */
    int samples;               /* cosine-weighted rays */
    int sky_samples;           /* rays drawn from the sky map (all but the sun set) */
    int sun_samples;           /* rays toward the sun set */
    uint32_t seed;
} rs_gather_ctx;

/* Scratch for one thread; rs_gather_scratch_new(max(samples, sun_samples)). */
typedef struct rs_gather_scratch rs_gather_scratch;
rs_gather_scratch *rs_gather_scratch_new(size_t n);
void rs_gather_scratch_free(rs_gather_scratch *s);

/* Gathers facet f into *out (zeroed first). Degenerate facets get nothing. -1: out of memory. */
int rs_gather_facet(const rs_gather_ctx *g, uint32_t f, rs_gather_scratch *s, rs_facet_gather *out);

#endif
