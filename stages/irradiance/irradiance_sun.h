/* irradiance_sun: the irradiance stage's sun: its options from the config, the explicit source
 * set up before the sky map and after it (sunsource.h), the search for a hidden sun in the
 * shadows, the explicit sun's term added to the gather, and what all that is reported as. */
#ifndef RS_IRRADIANCE_SUN_H
#define RS_IRRADIANCE_SUN_H

#include "common/config.h"
#include "common/err.h"
#include "common/json.h"
#include "pipeline/stage.h"
#include "stages/irradiance/irradiance_state.h"

/* [sky] sun_from_shadows, sun_irradiance, sun_color, sun_clip_level, sun_azimuth_deg and
 * [irradiance] sun_threshold, sun_max_cone_deg into o. sun_color must be three values >= 0, not
 * all 0, when the sun is explicit from the start (sun_irradiance or sun_from_shadows = on);
 * -1 with err naming the key otherwise. */
int rs_irradiance_sun_options(const rs_config *cfg, rs_sunsource_opts *o, rs_err *err);

/* Before the sky map: the explicit sun (rs_sunsource_setup on s->cap, s->so.fill), logged.
 * -1 with err, naming the config (o->config_file), when the sun is to be explicit and nothing
 * places it. */
int rs_irradiance_setup_sun(const rs_irradiance_opts *o, rs_irradiance_state *s, rs_err *err);

/* Once the sky map is built: rs_sunsource_auto, logged when it activates the sun. */
void rs_irradiance_sun_auto(const rs_irradiance_opts *o, rs_irradiance_state *s);

/* The fitted Perez circumsolar term c, -1 without a model (the row fill fits none). An overcast
 * sky (c below RS_SUNSEARCH_MIN_GLOW) casts no shadow to read: no sun is searched then. */
double rs_irradiance_sky_glow(const rs_skyfill_report *fill, rs_skyfill_method method);

/* With s->sun.search, after the gather: the sun looked for in the shadows (rs_sunsource_search,
 * with o->sun.lead_sigmas), unless the visible sky is overcast. */
int rs_irradiance_search_sun(const rs_irradiance_opts *o, rs_irradiance_state *s, rs_report *rep, rs_err *err);

/* With s->sun.active, after the gather: the explicit sun's term added to s->fg, its DNI first
 * estimated from the shadows when no one gave it. */
int rs_irradiance_explicit_sun(const rs_irradiance_opts *o, rs_irradiance_state *s, rs_report *rep, rs_err *err);

/* The explicit sun's figures under metrics "explicit_sun" (nothing when it is not active). */
void rs_irradiance_report_sun(const rs_sunsource *sun, rs_json *metrics);

/* Where the sky fill's sun came from, as the metrics and the log name it. */
const char *rs_irradiance_sun_source_name(rs_sun_source s);

#endif
