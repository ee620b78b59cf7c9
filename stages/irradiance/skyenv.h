/* skyenv: the environment a facet sees, taken from the sky portion of the panorama (every
 * pixel whose camera ray misses the model), with the directions the model hides from the
 * camera filled in, and the bright pixels (the sun) split off for explicit sampling. */
#ifndef RS_SKYENV_H
#define RS_SKYENV_H

#include <stddef.h>
#include <stdint.h>
#include "capture.h"

typedef struct rs_skyenv {
    int width, height;
    rs_pose pose;              /* the capture's: directions are looked up in its frame */
    float *radiance;           /* 3 * W * H: radiance an escaping ray sees; bright pixels are 0
                                  here when they are sampled explicitly */
    uint8_t *filled;           /* W * H: 1 where the value was filled in (not measured) */
    size_t nlights;            /* bright pixels sampled explicitly */
    uint32_t *light_pixel;     /* index r * W + c of each */
    float *light_power;        /* 3 per light: radiance * solid angle (W m^-2 at normal incidence) */
    double *light_cdf;         /* nlights + 1 entries over luminance power, last = total */
    double sky_median;         /* median luminance of the measured sky pixels */
    size_t sky_pixels, filled_pixels, bright_pixels;
} rs_skyenv;

/* facet_id: the observe stage's image (W x H, -1 where no facet). sun_threshold: pixels
 * brighter than this multiple of the median sky luminance are lights; explicit: split them off
 * (else they stay in radiance). Fill method: each hidden pixel takes the linear interpolation,
 * along its row (in azimuth, wrapping), of the nearest measured non-bright sky pixels on either
 * side; rows with none copy the nearest row that has some. Bright pixels never feed the fill. */
int rs_skyenv_build(const rs_capture *cap, const float *facet_id, double sun_threshold, int explicit,
                    rs_skyenv *env, rs_err *err);
void rs_skyenv_release(rs_skyenv *env);

/* Pixel index of world direction d. */
static inline size_t rs_skyenv_pixel(const rs_skyenv *env, rs_v3 d_world)
{
    int c, r;
    rs_pano_world_to_pixel(&env->pose, env->width, env->height, d_world, &c, &r);
    return (size_t)r * env->width + c;
}

/* Picks a light by luminance power from x in [0,1); returns its index. */
size_t rs_skyenv_pick_light(const rs_skyenv *env, double x);

#endif
