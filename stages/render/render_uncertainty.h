/* render_uncertainty: false-colour panoramas, in the camera's view, of the per-facet sky fill
 * share (sky_filled) and albedo uncertainty (albedo_sigma_rel) that the reflectance stage writes. */
#ifndef RS_RENDER_UNCERTAINTY_H
#define RS_RENDER_UNCERTAINTY_H

#include <stddef.h>
#include "common/config.h"
#include "common/err.h"
#include "common/image.h"
#include "common/ply.h"

/* The value that the PNGs show as full red (the ramp of rs_image_ramp): sky_filled is a share
 * (0..1); albedo_sigma_rel at 20 %, the scale of rhoscan-eval's error image, so the two compare. */
#define RS_RENDER_SKY_FILLED_FULL 1.0
#define RS_RENDER_SIGMA_REL_FULL  0.2

/* When the face element of alb (read from file, nf faces) has both sky_filled and
 * albedo_sigma_rel: writes sky_filled.exr / .png and albedo_sigma.exr / .png into the work
 * folder. ids: the observe stage's facet_id image (-1 where no facet). EXR: one channel Y, the
 * facet's raw value where a facet is seen, -1 elsewhere. PNG: the value on the ramp over
 * [0, full scale], dark grey where no facet is seen. Returns 1 when written, 0 when the
 * properties are absent (an albedo.ply from before they existed; stale images of an earlier
 * run are removed then), -1 on error. */
int rs_render_uncertainty_images(const rs_config *cfg, const rs_ply *alb, const char *file, size_t nf,
                                 const rs_image *ids, rs_err *err);

#endif
