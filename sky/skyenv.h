/* skyenv: the environment a facet sees, taken from the sky portion of the panorama (every
 * pixel whose camera ray misses the model) and of an optional sky-only panorama, with the
 * directions no camera saw filled in (skyfill.h), and the bright pixels (the sun) split off
 * for explicit sampling. */
#ifndef RS_SKYENV_H
#define RS_SKYENV_H

#include <stddef.h>
#include <stdint.h>
#include "common/capture.h"
#include "common/scene.h"
#include "sky/skyfill.h"

typedef struct rs_skyenv {
    int width, height;
    rs_pose pose;                        /* the capture's: directions are looked up in its frame */
    float *radiance;                     /* 3 * W * H: radiance an escaping ray sees */
    uint8_t *filled;                     /* W * H: 1 where the value was filled in (not measured) */
    uint8_t *sun;                        /* W * H: 1 for the sun set (bright pixels sampled on their own) */
    double *cdf;                         /* W * H + 1: cumulative luminance x solid angle over the pixels not
                                  in the sun set; NULL when not importance-sampled */
    double total_power;                  /* cdf[W * H] */
    double *sun_cdf;                     /* the same over the sun set; NULL when it is empty */
    uint32_t *cdf_guide, *sun_cdf_guide; /* search guides of cdf and sun_cdf
                                             (rs_skyenv_guide_build), NULL with them */
    double sun_power;
    double sky_median; /* median luminance of the measured sky pixels */
    size_t sky_pixels, filled_pixels, bright_pixels;
    double bright_sr;     /* solid angle of the bright pixels */
    double fill_sigma;    /* relative standard uncertainty of the light from filled pixels
                                  (held-out error of the fill method); 0 when not measured */
    float *fill_sigma_px; /* W * H: each filled pixel's relative standard uncertainty
                                  (rs_skyfill_sigma_map), 0 where measured */
} rs_skyenv;

/* What the map is built from and how it is completed. */
typedef struct rs_skyenv_opts {
    double sun_threshold; /* see rs_skyenv_build */
    double max_sr;
    int explicit_sun;
    rs_skyfill_opts fill;
    const rs_capture *sky;             /* sky-only panorama ([sky] panorama) or NULL */
    const uint8_t *sky_mask;           /* its pixels whose rays miss the model (rs_skyenv_sky_mask) */
    const rs_capture *const *others;   /* further captures ([capture.NAME]), nothers of them */
    const uint8_t *const *other_masks; /* their sky pixels, as sky_mask */
    int nothers;
} rs_skyenv_opts;

#define RS_SKYENV_MAX_OTHERS 16

/* What rs_skyenv_build_opts found besides the map. */
typedef struct rs_skyenv_info {
    rs_skyfill_report fill;
    size_t sky_pano_pixels;                      /* map pixels taken from the sky panorama */
    double sky_pano_scale[3];                    /* exposure factor applied to the sky panorama (capture / sky) */
    double sky_overlap_sr;                       /* solid angle both saw as sky: where the factor comes from */
    size_t other_pixels;                         /* map pixels the capture did not see, taken from further captures */
    size_t blended_pixels;                       /* map pixels the capture saw that further captures saw too */
    double other_scale[RS_SKYENV_MAX_OTHERS][3]; /* their exposure factors, the same way */
    double other_overlap_sr[RS_SKYENV_MAX_OTHERS];
} rs_skyenv_info;

/* facet_id: the observe stage's image (W x H, -1 where no facet). sun_threshold: pixels
 * brighter than this multiple of the median sky luminance are lights, brightest first, up to a
 * total solid angle of max_sr (sr): the sun set. It never feeds the fill.
 * explicit: the sun set is sampled on its own and the rest by importance (rs_skyenv_pick_sun,
 * rs_skyenv_pick, rs_skyenv_pdf); otherwise there is no sun set and cosine rays see everything.
 * Fill method: each hidden pixel takes the linear interpolation,
 * along its row (in azimuth, wrapping), of the nearest measured non-bright sky pixels on either
 * side; rows with none copy the nearest row that has some. Bright pixels never feed the fill. */
int rs_skyenv_build(const rs_capture *cap, const float *facet_id, double sun_threshold, double max_sr, int explicit,
                    rs_skyenv *env, rs_err *err);

/* The same with a choice of fill (o->fill) and an optional sky-only panorama. The map keeps the
 * capture's frame and size. Every direction the sky panorama sees as sky takes its value, times
 * a per-channel exposure factor: the median ratio capture / sky panorama over the directions
 * both see as sky (outside the bright pixels); 1 when they share less than 0.01 sr. Elsewhere
 * each direction takes the weighted mean of every capture that saw it as sky (the capture and
 * the further captures, each scaled to the capture's exposure the same way; up to
 * RS_SKYENV_MAX_OTHERS). A capture's weight there is its pixels' solid angle times how directly
 * it saw the direction: low for a mixed pixel 1 or 2 pixels from the model's silhouette in that
 * capture, lower for a panorama whose pixels are larger than the map's (skyenv.c). With no
 * further capture the capture's sky is used as it is. What none saw is filled. info may be NULL. */
int rs_skyenv_build_opts(const rs_capture *cap, const float *facet_id, const rs_skyenv_opts *o, rs_skyenv *env,
                         rs_skyenv_info *info, rs_err *err);

/* mask[k] = 1 for each pixel of the sky panorama whose ray from its position misses the
 * model (and whose value is usable). mask: width * height bytes, caller-owned. */
void rs_skyenv_sky_mask(const rs_scene *scene, const rs_capture *sky, uint8_t *mask);
void rs_skyenv_release(rs_skyenv *env);

/* Sets the map's pixels that the ground model filled (RS_SKYFILL_GROUND_MODEL) to rgb, then
 * rebuilds the sampling distributions when the map has them (explicit_sun, as built). Returns
 * the pixels changed, -1 out of memory (err set; the caller then releases the map). */
long rs_skyenv_set_ground(rs_skyenv *env, const double rgb[3], int explicit_sun, rs_err *err);
/* Sets them instead to the mean measured ground of the nearest elevation band that has any, at
 * any distance (when the ground model's albedo cannot be had), marked filled (1), and rebuilds
 * the distributions as above. Returns the pixels set (0: no measured ground), -1 out of memory
 * (err set). */
long rs_skyenv_ground_from_bands(rs_skyenv *env, int explicit_sun, rs_err *err);

/* Pixel index of world direction d. */
static inline size_t rs_skyenv_pixel(const rs_skyenv *env, rs_v3 d_world)
{
    int c, r;
    rs_pano_world_to_pixel(&env->pose, env->width, env->height, d_world, &c, &r);
    return (size_t)r * env->width + c;
}

/* Search guide of a distribution (Chen's indexed search): guide[b] (b = 0 ..
 * RS_SKYENV_GUIDE_BUCKETS) is the first pixel k with cdf[k + 1] > b / RS_SKYENV_GUIDE_BUCKETS of
 * the total, so that a pick searches only between guide[b] and guide[b + 1] and finds the same
 * pixel as a binary search over the whole map without its cache misses (gather.c). Built once
 * per map: every thread of the gather reads it. */
#define RS_SKYENV_GUIDE_BUCKETS (1u << 18)
void rs_skyenv_guide_build(const double *cdf, size_t npx, uint32_t *guide);

/* Picks a pixel outside (rs_skyenv_pick) or inside (rs_skyenv_pick_sun) the sun set with
 * probability proportional to luminance x solid angle, from x in [0,1). */
size_t rs_skyenv_pick(const rs_skyenv *env, double x);
size_t rs_skyenv_pick_sun(const rs_skyenv *env, double x);

static inline double rs_skyenv_luminance(const float *rgb)
{
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}
static inline double rs_skyenv_luminance3(const double *rgb)
{
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

/* Solid-angle density (1/sr) with which rs_skyenv_pick + uniform jitter in the pixel yields a
 * direction in pixel pix (not in the sun set): luminance / total power. */
static inline double rs_skyenv_pdf(const rs_skyenv *env, size_t pix)
{
    return env->cdf && !env->sun[pix] ? rs_skyenv_luminance(env->radiance + 3 * pix) / env->total_power : 0;
}

#endif
