#include "stages/irradiance/irradiance_share.h"

#include <stdint.h>
#include <string.h>
#include "common/par.h"

/* Collective: rank 0's array of n bytes at *p to every rank; present says (on every rank)
 * whether rank 0 has one, and *p stays NULL elsewhere when it has not. */
static int share_array(void **p, int present, size_t n, rs_err *err)
{
    if (!present) return 0;
    return rs_par_bcast_alloc(p, &n, err);
}

int rs_irradiance_share_sky_map(rs_skyenv *env, rs_skyenv_info *info, rs_sunsource *sun, rs_err *err)
{
    if (rs_par_size() <= 1) return 0;
    rs_par_bcast(info, sizeof *info);
    rs_par_bcast(&sun->removed_px, sizeof sun->removed_px);
    rs_par_bcast(env, sizeof *env);
    /* The pointers are rank 0's addresses: on the others only whether they are NULL counts. */
    int has_cdf = env->cdf != NULL, has_sun_cdf = env->sun_cdf != NULL, has_sigma = env->fill_sigma_px != NULL;
    if (!rs_par_is_root()) {
        env->radiance = NULL, env->filled = env->sun = NULL, env->cdf = env->sun_cdf = NULL;
        env->cdf_guide = env->sun_cdf_guide = NULL, env->fill_sigma_px = NULL;
    }
    size_t npx = (size_t)env->width * env->height, guide = (RS_SKYENV_GUIDE_BUCKETS + 1) * sizeof(uint32_t);
    if (share_array((void **)&env->radiance, 1, 3 * npx * sizeof *env->radiance, err) != 0 ||
        share_array((void **)&env->filled, 1, npx, err) != 0 || share_array((void **)&env->sun, 1, npx, err) != 0 ||
        share_array((void **)&env->cdf, has_cdf, (npx + 1) * sizeof *env->cdf, err) != 0 ||
        share_array((void **)&env->cdf_guide, has_cdf, guide, err) != 0 ||
        share_array((void **)&env->sun_cdf, has_sun_cdf, (npx + 1) * sizeof *env->sun_cdf, err) != 0 ||
        share_array((void **)&env->sun_cdf_guide, has_sun_cdf, guide, err) != 0 ||
        share_array((void **)&env->fill_sigma_px, has_sigma, npx * sizeof *env->fill_sigma_px, err) != 0)
        return -1;
    return 0;
}

void rs_irradiance_share_sky_sh(rs_skysh *sh)
{
    if (rs_par_size() > 1) rs_par_bcast(sh, sizeof *sh);
}
