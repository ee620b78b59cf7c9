/* greycard: the radiometric check of a reference target of known albedo ([calib] grey_card_region,
 * grey_card_albedo) in the capture's panorama. Exports rs_greycard_report. */
#ifndef RS_GREYCARD_H
#define RS_GREYCARD_H

#include <stddef.h>
#include <stdint.h>
#include "common/config.h"
#include "common/err.h"
#include "common/json.h"

/* When [calib] grey_card_region is set: over the capture panorama's pixels in the region that
 * show a facet (facet_id.exr) and hold a usable value, the card's mean radiance L and the mean
 * irradiance E = E_sky + G of the facets under those pixels (esky, g: 3 per facet, the
 * reflectance stage's), the albedo they imply, pi L / E, against the known albedo, and the
 * pipeline's albedo of those facets (rho, 3 per facet, where estimable). Writes the figures
 * under metrics "grey_card"; returns 0, or -1 with err when the region is malformed, leaves the
 * panorama, or holds no facet pixel. Does nothing when the key is unset. */
int rs_greycard_report(const rs_config *cfg, size_t nf, const double *esky, const double *g, const double *rho,
                       const uint8_t *estimable, rs_json *metrics, rs_err *err);

#endif
