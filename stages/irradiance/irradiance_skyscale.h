/* irradiance_skyscale: [sky] fill_from_facets, the filled (hidden) sky's brightness from the
 * observed facets that see it (sky/skyscale.h), applied to the gathered E_sky. */
#ifndef RS_IRRADIANCE_SKYSCALE_H
#define RS_IRRADIANCE_SKYSCALE_H

#include "common/err.h"
#include "common/json.h"
#include "pipeline/stage.h"
#include "stages/irradiance/irradiance_state.h"

/* After every gather and the explicit sun: estimates t (skyscale.h) and, with [sky]
 * fill_from_facets_modes = directional, t0 t1 t2 (skyscale_dir.h). When the directional part is
 * significant (chi-square RS_SKYSCALE_DIR_CHI2) and within range, adds t0 fill_sigma_rgb + t1
 * fill_sigma_dir x + t2 fill_sigma_dir y to each gathered facet's E_sky; otherwise, with `on`,
 * or with `auto` when |t| is at least 2 of its standard uncertainties, adds t x fill_sigma_rgb
 * (and either's luminance to filled_lum). The fill's uncertainty is left as it
 * was: the correction removes one smooth mode of its error, not the others. Reports the estimate
 * in irradiance.json (fill_from_facets) and the skip when not applied. Skipped when the sun
 * came from the shadows (its DNI rests on the same ratios). Returns 0, -1 out of
 * memory (err set). */
int rs_irradiance_skyscale(const rs_irradiance_opts *o, rs_irradiance_state *s, rs_report *rep, rs_err *err);

#endif
