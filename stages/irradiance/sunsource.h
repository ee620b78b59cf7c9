/* sunsource: a sun whose irradiance the config gives ([sky] sun_irradiance, e.g. from a
 * pyrheliometer) as an explicit source: its clipped disc leaves the panoramas, the gather adds
 * E_sun = DNI max(0, n.s) V per facet. Exports rs_sunsource_*. */
#ifndef RS_SUNSOURCE_H
#define RS_SUNSOURCE_H

#include <stddef.h>
#include <stdint.h>
#include "capture.h"
#include "json.h"
#include "config.h"
#include "gather.h"
#include "scene.h"
#include "skyfill.h"

/* Half-angle of the sun's disc seen from the Earth (0.53 deg across, mean distance). */
#define RS_SUN_RADIUS_RAD (0.2665 * M_PI / 180)

typedef struct rs_sunsource {
    int active;                /* 0: no [sky] sun_irradiance, everything here does nothing */
    double dni;                /* direct normal irradiance (luminance), the panorama's radiance unit x sr */
    double rgb[3];             /* [sky] sun_color at luminance 1: the DNI per channel is dni x rgb */
    rs_v3 dir_world;           /* unit, toward the sun */
    const char *dir_from;      /* "config", "solar position" or "clipped disc" */
    double clip_level;         /* luminance from which a capture pixel is the clipped disc */
    double halo_factor;        /* pixels within cone_rad above this x the median sky go too */
    double cone_rad;
    size_t removed_px;         /* pixels taken out of the panoramas (all of them) */
    double removed_sr;         /* their solid angle in the capture */
    double removed_power;      /* sum of luminance x solid angle over the capture's removed pixels:
                                  what the panorama had of the sun (a lower bound when clipped) */
} rs_sunsource;

/* Reads [sky] sun_irradiance, sun_color and sun_clip_level; when set, takes the sun's direction from fill
 * (the config's azimuth and elevation or the solar position, when fill->sun_given) or else from
 * the centroid of the largest blob of capture sky pixels at or above the clip level (and then
 * sets fill->sun_given and sun_dir, so the fill knows where the removed sun was), and removes
 * the sun from cap's panorama (rs_sunsource_remove). Returns 0, or -1 with err when the key is
 * set but no direction is given and no pixel reaches the clip level. */
int rs_sunsource_setup(const rs_config *cfg, rs_capture *cap, const float *facet_id, rs_skyfill_opts *fill,
                       rs_sunsource *sun, rs_err *err);

/* Marks unusable (-1) every pixel of c's panorama that sees sky (facet_id < 0; every pixel when
 * facet_id is NULL) within cone_rad of the sun and at or above min(clip_level, halo_factor x the
 * median luminance of c's sky pixels): the disc and its bright halo, so that the sky map fills
 * them in as sky and the sun is not counted twice. Returns the pixels removed; counts them in
 * sun (and their solid angle and power when count_power). Does nothing when !sun->active. */
size_t rs_sunsource_remove(rs_sunsource *sun, rs_capture *c, const float *facet_id, int count_power);

/* Adds E_sun = dni rgb max(0, n.s) V to E_sky (each channel, and dni max(0, n.s) V to its luminance) of every
 * gathered facet (fg[f].rays > 0 or fg[f].sky_sh), V being the share of rays shadow rays (from Sobol points on
 * the facet toward Sobol points on the sun's disc) that escape. rays >= 1. -1: out of memory. */
int rs_sunsource_add(const rs_sunsource *sun, const rs_scene *scene, int rays, uint32_t seed, size_t nf,
                     rs_facet_gather *fg);

/* The source's figures under metrics "explicit_sun". */
void rs_sunsource_report(const rs_sunsource *sun, rs_json *metrics);

#endif
