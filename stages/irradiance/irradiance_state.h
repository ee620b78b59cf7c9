/* irradiance_state: what the irradiance stage's files share: its options (every config key it
 * reads, read once by irradiance.c's read_opts) and its working state, filled step by step. */
#ifndef RS_IRRADIANCE_STATE_H
#define RS_IRRADIANCE_STATE_H

#include <stddef.h>
#include <stdint.h>
#include "common/capture.h"
#include "common/image.h"
#include "common/mesh.h"
#include "common/scene.h"
#include "light/gather.h"
#include "light/sunsource.h"
#include "sky/skyenv.h"
#include "sky/skysh.h"

enum { RS_FILL_FROM_FACETS_OFF, RS_FILL_FROM_FACETS_AUTO, RS_FILL_FROM_FACETS_ON };

typedef struct rs_irradiance_opts {
    const char *config_file; /* for messages about its keys */
    /* [irradiance] */
    int samples, sky_samples, sun_samples; /* rays per facet (gather.h) */
    uint32_t seed;
    double sun_target_error, target_error, relay_share;
    int skip_convex, skip_unseen;
    double sh_max_error; /* harmonics for facets that see only sky (skysh.h); 0: never */
    /* [sky] */
    rs_skyenv_opts sky;                /* thresholds and fill; no sources yet (the stage loads them) */
    const char *fill_name;             /* [sky] fill as written, for the log and the metrics */
    int sky_panorama;                  /* [sky] panorama is set */
    int ground_from_scan;              /* [sky] ground_albedo_from = scan */
    const char *solar_when;            /* [sky] datetime when it placed the sun (no azimuth given), else NULL */
    double solar_az_deg, solar_el_deg; /* with solar_when: the NOAA solar position */
    rs_sunsource_opts sun;
    int fill_from_facets; /* [sky] fill_from_facets (irradiance_skyscale.h) */
    int fill_directional; /* [sky] fill_from_facets_modes = directional (sky/skyscale_dir.h) */
    /* The config's capture sections ("capture" and "capture.NAME"), in file order. */
    const char *captures[RS_SKYENV_MAX_OTHERS + 1];
    int ncaptures; /* all of them, also those beyond the array */
} rs_irradiance_opts;

/* One gather of the facets over the sky map, and the measure of its noise. */
typedef struct rs_irradiance_pass {
    rs_skysh sh; /* [irradiance] sh_max_error: harmonics for facets that see only sky */
    double sh_tol;
    size_t sh_candidates;
    rs_gather_stats gs;
    double seconds;
    double mc_factor;
    size_t mc_facets;
} rs_irradiance_pass;

/* The stage's inputs and what it has made of them so far; zeroed at the start. */
typedef struct rs_irradiance_state {
    rs_mesh *mesh; /* mesh.ply */
    size_t nf;
    double *radiance;  /* observe.ply: 3 per facet */
    uint8_t *observed; /* observe.ply: 1 per facet */
    rs_capture cap;    /* [capture]; the explicit sun's disc taken out */
    rs_image *ids;     /* facet_id.exr: the facet under each of cap's pixels, -1 none */
    rs_scene *scene;
    rs_mesh *occ;                            /* [irradiance] occluders: their faces (NULL without), attached to scene */
    uint32_t *occ_proxy;                     /* per occluder face: the facet standing for it */
    double occ_cell;                         /* the free-space cell, m (occluder_near's unit) */
    rs_capture sky;                          /* [sky] panorama (pano NULL without one) */
    uint8_t *sky_mask;                       /* its pixels that see sky */
    rs_capture others[RS_SKYENV_MAX_OTHERS]; /* further captures ([capture.NAME]) */
    uint8_t *other_masks[RS_SKYENV_MAX_OTHERS];
    const char *other_names[RS_SKYENV_MAX_OTHERS];      /* their sections ("capture.NAME"), borrowed */
    const rs_capture *other_ptrs[RS_SKYENV_MAX_OTHERS]; /* the same, as so wants them */
    const uint8_t *other_mask_ptrs[RS_SKYENV_MAX_OTHERS];
    int nothers;
    rs_skyenv_opts so; /* opts' with the sources and the sun as placed */
    rs_skyenv env;     /* the sky map */
    rs_skyenv_info info;
    rs_sunsource sun; /* the sun as an explicit source (sunsource.h) */
    rs_gather_ctx g;
    rs_facet_gather *fg;     /* nf */
    rs_irradiance_pass pass; /* the last gather */
    double first_pass_rays;  /* rays of a gather done again around a searched sun */
} rs_irradiance_state;

#endif
