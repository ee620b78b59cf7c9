/* sunsource: a sun that the panoramas do not hold as an explicit source: its clipped disc (if
 * any) leaves the panoramas, the gather adds E_sun = DNI max(0, n.s) V per facet. The DNI is
 * given (e.g. by a pyrheliometer) or, for a sun hidden from every capture or when asked,
 * estimated from the model's shadows (sunshadow.h). The caller reports what the source holds
 * (rs_sunsource's fields). Exports rs_sunsource_*. */
#ifndef RS_SUNSOURCE_H
#define RS_SUNSOURCE_H

#include <stddef.h>
#include <stdint.h>
#include "common/capture.h"
#include "common/err.h"
#include "light/gather.h"
#include "common/scene.h"
#include "sky/skyenv.h"
#include "sky/skyfill.h"
#include "sky/sunsearch.h"
#include "sky/sunshadow.h"

/* Half-angle of the sun's disc seen from the Earth (0.53 deg across, mean distance). */
#define RS_SUN_RADIUS_RAD (0.2665 * M_PI / 180)

/* When the DNI comes from the shadows: only when a sun no camera saw is placed or found (AUTO),
 * always unless the DNI is given (ON), never (OFF). */
typedef enum { RS_SUN_SHADOWS_AUTO, RS_SUN_SHADOWS_ON, RS_SUN_SHADOWS_OFF } rs_sun_shadows;

/* What the caller knows of the sun (the irradiance stage: its [sky] and [irradiance] keys). */
typedef struct rs_sunsource_opts {
    int dni_given; /* 1: dni is measured; it wins over the shadows */
    double dni;    /* with dni_given: direct normal irradiance (luminance), radiance unit x sr */
    rs_sun_shadows from_shadows;
    double rgb[3];              /* the sun's colour at luminance 1 (>= 0), with dni_given or ON */
    double halo_factor;         /* pixels within cone_rad above this x the median sky leave with the disc */
    double cone_rad;            /* the cone around the sun of its disc and halo */
    int clip_level_given;       /* 1: clip_level is given; else 0.9 x the brightest sky pixel (near a given sun) */
    double clip_level;          /* luminance from which a capture pixel is the clipped disc */
    const char *given_dir_from; /* what placed the fill's sun when it is given: "config" or "solar position" */
    double lead_sigmas;         /* a searched sun beyond the sky's cone is taken on evidence when it leads the best
                                   inside by this many standard errors (RS_SUNSEARCH_LEAD_SIGMAS); 0: never */
} rs_sunsource_opts;

typedef struct rs_sunsource {
    int active;           /* 0: no explicit sun, everything here does nothing */
    int from_shadows;     /* dni and rgb are estimated from the shadows (rs_sunsource_from_shadows) */
    double dni;           /* direct normal irradiance (luminance), the panorama's radiance unit x sr */
    double rgb[3];        /* [sky] sun_color at luminance 1: the DNI per channel is dni x rgb */
    rs_v3 dir_world;      /* unit, toward the sun */
    const char *dir_from; /* "config", "solar position", "clipped disc" or "shadows" */
    rs_sunshadow shadow;  /* with from_shadows: the estimate (dni_lum 0 when it failed) */
    int shadow_rc;        /* its rs_sunshadow_estimate result; 2: a searched sun, not significant */
    int search;           /* auto, nothing places the sun and no camera saw one: search the shadows */
    int searched;         /* the direction came from rs_sunsource_search */
    rs_sunsearch found;   /* its result */
    double found_off_deg; /* its angle to the sky's own estimate (rs_sunsource_search) */
    int missing_light;    /* it lights enough facets whose albedo is above 1 without it (RS_SUNSEARCH_MIN_ABOVE_ONE) */
    int decisive;         /* beyond the cone, taken on evidence: its shadows beat the cone's best by lead_sigmas
                             standard errors and it lights most of the pair facets whose albedo is above 1 */
    double margin;        /* its margin (m) */
    double clip_level;    /* luminance from which a capture pixel is the clipped disc */
    double halo_factor;   /* pixels within cone_rad above this x the median sky go too */
    double cone_rad;
    size_t removed_px;     /* pixels taken out of the panoramas (all of them) */
    double removed_sr;     /* their solid angle in the capture */
    double removed_power;  /* sum of luminance x solid angle over the capture's removed pixels:
                                  what the panorama had of the sun (a lower bound when clipped) */
    double removed_rgb[3]; /* the same per channel */
    int fell_back;         /* on, no estimate: the DNI is removed_power (what the panorama held) */
} rs_sunsource;

/* With o->dni_given or from_shadows ON, activates sun: takes its direction from fill (when
 * fill->sun_given; dir_from o->given_dir_from) or else from the centroid of the largest blob of
 * capture sky pixels at or above the clip level (and then sets fill->sun_given and sun_dir, so
 * the fill knows where the removed sun was), and removes the sun from cap's panorama
 * (rs_sunsource_remove). Otherwise leaves sun inactive (zeroed). Returns 0; 1 when the sun is
 * to be explicit but nothing places it (no direction given, no pixel reaches
 * sun->clip_level); -1 out of memory (err set). */
int rs_sunsource_setup(const rs_sunsource_opts *o, rs_capture *cap, const float *facet_id, rs_skyfill_opts *fill,
                       rs_sunsource *sun, rs_err *err);

/* Marks unusable (-1) every pixel of c's panorama that sees sky (facet_id < 0; every pixel when
 * facet_id is NULL) within cone_rad of the sun and at or above min(clip_level, halo_factor x the
 * median luminance of c's sky pixels): the disc and its bright halo, so that the sky map fills
 * them in as sky and the sun is not counted twice. Returns the pixels removed; counts them in
 * sun (and their solid angle and power when count_power). Does nothing when !sun->active. */
size_t rs_sunsource_remove(rs_sunsource *sun, rs_capture *c, const float *facet_id, int count_power);

/* With from_shadows AUTO and sun not active (no DNI given), once the sky map is built: when
 * fill places the sun (fill->sun_given) above the horizon and no camera saw it (the map's pixel
 * toward it is filled and no measured pixel brighter than o->halo_factor x the median sky lies
 * within o->cone_rad of it), activates sun with from_shadows (dir_from o->given_dir_from).
 * When nothing places the sun and the map has no bright pixel at all, sets sun->search instead
 * (rs_sunsource_search). Returns whether it activated. */
int rs_sunsource_auto(const rs_sunsource_opts *o, const rs_skyenv *env, const rs_skyfill_opts *fill, rs_sunsource *sun);

/* V per facet into vis[nf]: the share of `rays` shadow rays (from Sobol points on the facet
 * toward Sobol points on the sun's disc) that escape, for every gathered facet (fg[f].rays > 0
 * or fg[f].sky_sh) facing the sun; -1 for the others. rays >= 1. Returns 0, -1 out of memory
 * (err set). */
int rs_sunsource_visibility(const rs_sunsource *sun, const rs_scene *scene, int rays, uint32_t seed, size_t nf,
                            const rs_facet_gather *fg, float *vis, rs_err *err);

/* With sun->search, after the gather: the direction from the shadows (sunsearch.h) among the
 * directions the map filled. It is taken only within RS_SUNSOURCE_AGREE_DEG of sky_dir (or
 * farther when it lights at least RS_SUNSEARCH_MIN_ABOVE_ONE facets whose albedo without it is
 * above 1, four times as many as it shadows: missing_light), the
 * direction whose clear-sky distribution explains the visible sky best (the model fill's
 * search): two independent cues must agree, so that shadows cast by a dim sun the cameras did
 * see cannot put a second one behind the building. Or farther on evidence (decisive): with
 * lead_sigmas > 0, when its edge score leads the best direction inside the cone by at least
 * lead_sigmas standard errors (rs_sunsearch cone_sigmas) and it lights at least
 * RS_SUNSEARCH_MIN_ABOVE_ONE pair facets whose albedo is above 1 without it, more than it
 * shadows. When taken, activates sun with from_shadows and searched (its DNI must then come out
 * above 5 standard errors, else it adds nothing). Returns 0, -1 out of memory (err set). */
#define RS_SUNSOURCE_AGREE_DEG 30.0
int rs_sunsource_search(rs_sunsource *sun, const rs_scene *scene, const rs_skyenv *env, const rs_facet_gather *fg,
                        const double *radiance, const uint8_t *observed, rs_v3 cam, int pano_height, rs_v3 sky_dir,
                        double lead_sigmas, rs_err *err);

/* With from_shadows: estimates dni and rgb (rs_sunshadow_estimate; E = E_sky + G from fg and
 * the observed radiance, the margin from the capture at cam with panoramas pano_height high).
 * When there is too little evidence (shadow_rc says why) a sun whose disc was removed from the
 * panorama gets back what the panorama held of it (fell_back), any other adds nothing (dni 0).
 * Returns 0, -1 out of memory (err set). */
int rs_sunsource_from_shadows(rs_sunsource *sun, const rs_mesh *mesh, const float *vis, const rs_facet_gather *fg,
                              const double *radiance, const uint8_t *observed, rs_v3 cam, int pano_height, rs_err *err);

/* Adds E_sun = dni rgb max(0, n.s) V to E_sky (each channel, and dni max(0, n.s) V to its
 * luminance) of every facet with vis >= 0. With from_shadows the sun counts as filled light
 * (filled_lum), and its standard error shadow.sigma_lum max(0, n.s) V joins fill_sigma_lum in
 * quadrature. */
void rs_sunsource_apply(const rs_sunsource *sun, const rs_scene *scene, size_t nf, const float *vis,
                        rs_facet_gather *fg);

#endif
