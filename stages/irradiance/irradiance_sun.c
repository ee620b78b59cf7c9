/* irradiance_sun: the irradiance stage's sun (see irradiance_sun.h). */
#include "stages/irradiance/irradiance_sun.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/log.h"
#include "sky/sunsearch.h"

/* The colour is checked only when the sun is explicit from the start, as only then is it used. */
int rs_irradiance_sun_options(const rs_config *cfg, rs_sunsource_opts *o, rs_err *err)
{
    memset(o, 0, sizeof *o);
    const char *shadows = rs_config_string(cfg, "sky", "sun_from_shadows");
    o->from_shadows = strcmp(shadows, "on") == 0 ? RS_SUN_SHADOWS_ON
        : strcmp(shadows, "auto") == 0           ? RS_SUN_SHADOWS_AUTO
                                                 : RS_SUN_SHADOWS_OFF;
    o->dni_given = rs_config_has(cfg, "sky", "sun_irradiance");
    if (o->dni_given) o->dni = rs_config_real(cfg, "sky", "sun_irradiance");
    o->halo_factor = rs_config_real(cfg, "irradiance", "sun_threshold");
    o->cone_rad = rs_config_real(cfg, "irradiance", "sun_max_cone_deg") * M_PI / 180;
    o->clip_level_given = rs_config_has(cfg, "sky", "sun_clip_level");
    if (o->clip_level_given) o->clip_level = rs_config_real(cfg, "sky", "sun_clip_level");
    o->given_dir_from = rs_config_has(cfg, "sky", "sun_azimuth_deg") ? "config" : "solar position";
    o->lead_sigmas = rs_config_real(cfg, "sky", "sun_search_lead_sigmas");
    if (!o->dni_given && o->from_shadows != RS_SUN_SHADOWS_ON) return 0;
    double col[3];
    rs_config_reals(cfg, "sky", "sun_color", col);
    float colf[3] = {(float)col[0], (float)col[1], (float)col[2]};
    double col_lum = rs_skyenv_luminance(colf);
    if (!(col[0] >= 0 && col[1] >= 0 && col[2] >= 0 && col_lum > 0))
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[sky] sun_color = %g %g %g: expected three values >= 0, not all 0", col[0], col[1], col[2]);
    for (int ch = 0; ch < 3; ch++) o->rgb[ch] = col[ch] / col_lum;
    return 0;
}

int rs_irradiance_setup_sun(const rs_irradiance_opts *o, rs_irradiance_state *s, rs_err *err)
{
    if (o->solar_when)
        rs_log_info("irradiance: sun at azimuth %.2f, elevation %.2f degrees (NOAA solar position for %s)",
                    o->solar_az_deg, o->solar_el_deg, o->solar_when);
    const rs_sunsource *sun = &s->sun;
    const rs_capture *cap = &s->cap;
    int rc = rs_sunsource_setup(&o->sun, &s->cap, s->ids->data, &s->so.fill, &s->sun, err);
    if (rc < 0 || !sun->active) return rc;
    if (rc == 1)
        return rs_err_set(err, RS_ERR_INPUT, o->config_file, 0,
                          "[sky] %s is set but no sky pixel of %s reaches the clip level %g: "
                          "expected [sky] sun_azimuth_deg and sun_elevation_deg, or datetime, to place the sun",
                          sun->from_shadows ? "sun_from_shadows = on" : "sun_irradiance", cap->path, sun->clip_level);
    double el = asin(fmax(-1, fmin(1, sun->dir_world.z))) * 180 / M_PI;
    if (sun->from_shadows)
        rs_log_info("irradiance: explicit sun at elevation %.2f deg (%s), its DNI from the shadows; %zu panorama "
                    "pixels (%.3g sr) of its disc and halo removed, holding %.3g of it",
                    el, sun->dir_from, sun->removed_px, sun->removed_sr, sun->removed_power);
    else
        rs_log_info("irradiance: explicit sun of %g (DNI; colour %.3g %.3g %.3g) at elevation %.2f deg (%s); %zu "
                    "panorama pixels (%.3g sr) of its disc and halo removed, holding %.3g of it",
                    sun->dni, sun->rgb[0], sun->rgb[1], sun->rgb[2], el, sun->dir_from, sun->removed_px,
                    sun->removed_sr, sun->removed_power);
    if (sun->removed_px == 0 && !sun->from_shadows)
        rs_log_warn("irradiance: no bright sky pixel within %.2f deg of the given sun: is the sun hidden, or its "
                    "direction wrong?",
                    sun->cone_rad * 180 / M_PI);
    else if (!sun->from_shadows && sun->removed_power > sun->dni)
        rs_log_warn("irradiance: [sky] sun_irradiance = %g is less than the %.4g the panorama already holds "
                    "around the sun: is it in the panorama's units (radiance x sr)?",
                    sun->dni, sun->removed_power);
    return 0;
}

void rs_irradiance_sun_auto(const rs_irradiance_opts *o, rs_irradiance_state *s)
{
    if (rs_sunsource_auto(&o->sun, &s->env, &s->so.fill, &s->sun))
        rs_log_info("irradiance: no camera saw the sun at elevation %.2f deg (%s): its DNI comes from the model's "
                    "shadows ([sky] sun_from_shadows = auto)",
                    asin(fmin(1, s->sun.dir_world.z)) * 180 / M_PI, s->sun.dir_from);
}

double rs_irradiance_sky_glow(const rs_skyfill_report *fill, rs_skyfill_method method)
{
    return method == RS_SKYFILL_MODEL && fill->fit_samples ? fill->model.perez[1][2] : -1;
}

/* [sky] sun_from_shadows = auto with nothing placing the sun and no bright sky pixel. */
int rs_irradiance_search_sun(const rs_irradiance_opts *o, rs_irradiance_state *s, rs_report *rep, rs_err *err)
{
    rs_sunsource *sun = &s->sun;
    const rs_skyfill_report *fill = &s->info.fill;
    double glow = rs_irradiance_sky_glow(fill, s->so.fill.method);
    if (glow >= 0 && glow < RS_SUNSEARCH_MIN_GLOW) {
        rs_report_skip(rep, "sun from the shadows",
                       "no bright sky pixel and no sun placed by the config, and the "
                       "visible sky has no circumsolar glow (Perez c = %.2f < %g): overcast, no sun searched",
                       glow, RS_SUNSEARCH_MIN_GLOW);
        return 0;
    }
    double t0 = rs_now();
    if (rs_sunsource_search(sun, s->scene, &s->env, s->fg, s->radiance, s->observed, s->cap.pose.position,
                            s->cap.pano->height, fill->sun_dir, o->sun.lead_sigmas, err) != 0)
        return -1;
    rs_report_time(rep, "sun_search", rs_now() - t0);
    if (sun->searched)
        rs_log_info("irradiance: no camera saw a sun and nothing placed one; the shadows put it at azimuth %.2f, "
                    "elevation %.2f deg +- %.2f (%s log contrast %.3f over %zu lit-shadowed pairs, median %.3f; %d "
                    "directions tried; %.1f deg from where the visible sky puts it%s)",
                    atan2(sun->dir_world.y, sun->dir_world.x) * 180 / M_PI,
                    asin(fmin(1, sun->dir_world.z)) * 180 / M_PI, sun->found.dir_sigma_deg,
                    sun->found.upper_cluster ? "sun cluster's" : "median", sun->found.score, sun->found.pairs,
                    sun->found.median_score, sun->found.candidates, sun->found_off_deg,
                    sun->found.ridge    ? ", on the ridge of directions as good as the best, nearest the sky's"
                        : sun->decisive ? ", taken on evidence: its shadows beat the best direction near the sky's"
                                          " and it lights most facets whose albedo is above 1 without it"
                                        : "");
    else if (sun->found.score >= RS_SUNSEARCH_MIN_SCORE)
        rs_report_skip(rep, "sun from the shadows",
                       "the shadows' best direction (median log contrast %.3f) is "
                       "%.1f deg from where the visible sky puts the sun (at most %g): no sun added",
                       sun->found.score, sun->found_off_deg, RS_SUNSOURCE_AGREE_DEG);
    else
        rs_report_skip(rep, "sun from the shadows",
                       "no bright sky pixel and no sun placed by the config; no direction "
                       "the cameras did not see casts shadows that match the radiance (best median log contrast %.3f, "
                       "%g needed): no sun added",
                       sun->found.score, RS_SUNSEARCH_MIN_SCORE);
    return 0;
}

/* The shadows' estimate, logged or reported as skipped. */
static void log_sun_from_shadows(const rs_sunsource *sun, rs_report *rep)
{
    const rs_sunshadow *e = &sun->shadow;
    if (sun->shadow_rc == 0)
        rs_log_info("irradiance: sun from the shadows: DNI %.4g +- %.2g (statistical %.2g, from the sky fill "
                    "%.2g; colour %.3g %.3g %.3g) from %zu lit facets paired with shadowed ones within %.2f m on "
                    "their plane (%zu blocks; margin %.2f m); %s over %zu of them (median over all %.4g); %zu lit "
                    "facets with albedo above %.2f without it%s",
                    sun->dni, e->sigma_lum, e->sigma_stat_lum, e->sigma_sys_lum, sun->rgb[0], sun->rgb[1], sun->rgb[2],
                    e->lit_used, 3 * sun->margin, e->blocks, sun->margin,
                    e->upper_cluster ? "the sun cluster's median (leaks outvoted the median)" : "the median",
                    e->consensus, e->median_lum, e->above_one, RS_SUNSHADOW_ABOVE_ONE,
                    e->floored ? ", whose need raised the DNI" : "");
    else if (sun->shadow_rc == 2)
        rs_report_skip(rep, "sun from the shadows",
                       "the searched sun's DNI %.3g is within 5 standard errors "
                       "(%.2g) of 0: no sun added",
                       e->dni_lum, e->sigma_stat_lum);
    else
        rs_report_skip(rep, "sun from the shadows",
                       "only %zu observed facets in full sun found one in full "
                       "shadow within %.2f m on their plane (%zu lit, %zu shadowed beyond a %.2f m margin; %d "
                       "needed): %s",
                       e->lit_used, 3 * sun->margin, e->lit, e->shadowed, sun->margin, RS_SUNSHADOW_MIN_LIT,
                       sun->fell_back ? "the sun keeps the power the panorama held of it"
                                      : "the hidden sun adds nothing, give [sky] sun_irradiance");
}

int rs_irradiance_explicit_sun(const rs_irradiance_opts *o, rs_irradiance_state *s, rs_report *rep, rs_err *err)
{
    rs_sunsource *sun = &s->sun;
    const rs_scene *scene = s->scene;
    const rs_mesh *mesh = rs_scene_mesh(scene);
    size_t nf = mesh->nfaces;
    rs_facet_gather *fg = s->fg;
    float *vis = malloc((nf ? nf : 1) * sizeof *vis);
    double t0 = rs_now();
    if (!vis) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory adding the explicit sun");
    if (rs_sunsource_visibility(sun, scene, o->sun_samples, o->seed, nf, fg, vis, err) != 0 ||
        (sun->from_shadows &&
         rs_sunsource_from_shadows(sun, mesh, vis, fg, s->radiance, s->observed, s->cap.pose.position,
                                   s->cap.pano->height, err) != 0)) {
        free(vis);
        return -1;
    }
    if (sun->from_shadows) log_sun_from_shadows(sun, rep);
    rs_sunsource_apply(sun, scene, nf, vis, fg);
    rs_report_time(rep, "explicit_sun", rs_now() - t0);
    free(vis);
    return 0;
}

/* Why a searched sun was or was not added, from what the search and the estimate left. */
static const char *search_decision(const rs_sunsource *sun)
{
    if (!sun->found.candidates)
        return "not searched: the visible sky is overcast (no circumsolar glow), or no direction is hidden";
    if (!sun->searched)
        return sun->found.score >= RS_SUNSEARCH_MIN_SCORE
            ? "not added: the shadows' best direction is too far from where the visible sky puts the sun"
            : "not added: no direction the cameras did not see casts shadows that match the radiance";
    if (sun->shadow_rc == 2) return "not added: its DNI is within 5 standard errors of 0";
    if (sun->shadow_rc == 1) return "not added: too few lit facets paired with shadowed ones";
    if (sun->shadow_rc == 0 && sun->dni > 0) return "added";
    return "not estimated yet";
}

/* The search for a sun nobody placed, under metrics "sun_search" (nothing when it was not due):
 * the direction found, its uncertainty (a bootstrap over blocks of pairs), the scores, the
 * estimator, and why a sun was or was not added. */
static void report_search(const rs_sunsource *sun, rs_json *metrics)
{
    if (!sun->search) return;
    const rs_sunsearch *f = &sun->found;
    rs_json *o = rs_json_set_obj(metrics, "sun_search");
    rs_json_set_bool(o, "added", sun->searched && sun->shadow_rc == 0 && sun->dni > 0);
    rs_json_set_str(o, "why", search_decision(sun));
    if (!f->candidates) return;
    rs_json_set_num(o, "azimuth_deg", atan2(f->dir.y, f->dir.x) * 180 / M_PI);
    rs_json_set_num(o, "elevation_deg", asin(fmax(-1, fmin(1, f->dir.z))) * 180 / M_PI);
    rs_json_set_num(o, "direction_sigma_deg", f->dir_sigma_deg);
    rs_json_set_num(o, "log_contrast", f->score);
    rs_json_set_num(o, "median_log_contrast", f->median_score);
    rs_json_set_str(o, "contrast_estimator", f->upper_cluster ? "sun cluster" : "median");
    rs_json_set_bool(o, "ridge_toward_sky_estimate", f->ridge);
    rs_json_set_int(o, "albedo_above_one_lit", (long long)f->above_one_lit);
    rs_json_set_int(o, "albedo_above_one_shadowed", (long long)f->above_one_dark);
    rs_json_set_bool(o, "missing_light", sun->missing_light);
    if (isfinite(f->cone_sigmas)) { /* beyond the sky's cone, none inside it tied */
        rs_json_set_num(o, "lead_over_sky_cone_sigmas", f->cone_sigmas);
        rs_json_set_num(o, "sky_cone_best_azimuth_deg", atan2(f->cone_dir.y, f->cone_dir.x) * 180 / M_PI);
        rs_json_set_num(o, "sky_cone_best_elevation_deg", asin(fmax(-1, fmin(1, f->cone_dir.z))) * 180 / M_PI);
        rs_json_set_bool(o, "taken_on_evidence", sun->decisive);
    }
    rs_json_set_int(o, "pairs", (long long)f->pairs);
    rs_json_set_int(o, "candidates", f->candidates);
    rs_json_set_num(o, "off_sky_estimate_deg", sun->found_off_deg);
    if (sun->searched && sun->shadow_rc != 1) {
        rs_json_set_num(o, "direct_normal_irradiance", sun->shadow.dni_lum);
        rs_json_set_num(o, "direct_normal_irradiance_sigma", sun->shadow.sigma_lum);
    }
}

void rs_irradiance_report_sun(const rs_sunsource *sun, rs_json *metrics)
{
    report_search(sun, metrics);
    if (!sun->active) return;
    rs_json *o = rs_json_set_obj(metrics, "explicit_sun");
    rs_json_set_num(o, "direct_normal_irradiance", sun->dni);
    rs_json_set_str(o, "irradiance_from", sun->fell_back ? "panorama" : sun->from_shadows ? "shadows" : "config");
    if (sun->from_shadows) {
        rs_json *e = rs_json_set_obj(o, "from_shadows");
        rs_json_set_bool(e, "estimated", sun->shadow_rc == 0);
        rs_json_set_bool(e, "fell_back_to_panorama", sun->fell_back);
        if (sun->searched) {
            rs_json_set_num(e, "search_score", sun->found.score);
            rs_json_set_int(e, "search_pairs", (long long)sun->found.pairs);
            rs_json_set_int(e, "search_candidates", sun->found.candidates);
            rs_json_set_num(e, "search_off_sky_estimate_deg", sun->found_off_deg);
            rs_json_set_num(e, "search_direction_sigma_deg", sun->found.dir_sigma_deg);
        }
        rs_json_set_str(e, "dni_estimator", sun->shadow.upper_cluster ? "sun cluster" : "median");
        rs_json_set_num(e, "median_over_paired_facets", sun->shadow.median_lum);
        rs_json_set_int(e, "consensus_facets", (long long)sun->shadow.consensus);
        rs_json_set_int(e, "albedo_above_one_facets", (long long)sun->shadow.above_one);
        rs_json_set_num(e, "albedo_floor", sun->shadow.floor_lum);
        rs_json_set_bool(e, "raised_to_albedo_floor", sun->shadow.floored);
        rs_json_set_num(e, "sigma", sun->shadow.sigma_lum);
        rs_json_set_num(e, "sigma_statistical", sun->shadow.sigma_stat_lum);
        rs_json_set_num(e, "sigma_from_sky_fill", sun->shadow.sigma_sys_lum);
        rs_json_set_num(e, "margin_m", sun->margin);
        rs_json_set_num(e, "radius_m", 3 * sun->margin);
        rs_json_set_int(e, "lit_facets", (long long)sun->shadow.lit);
        rs_json_set_int(e, "shadowed_facets", (long long)sun->shadow.shadowed);
        rs_json_set_int(e, "lit_facets_paired", (long long)sun->shadow.lit_used);
        rs_json_set_int(e, "blocks", (long long)sun->shadow.blocks);
    }
    rs_json *d = rs_json_set_arr(o, "direction");
    rs_json_push_num(d, sun->dir_world.x);
    rs_json_push_num(d, sun->dir_world.y);
    rs_json_push_num(d, sun->dir_world.z);
    rs_json_set_str(o, "direction_from", sun->dir_from);
    rs_json *c = rs_json_set_arr(o, "color_at_unit_luminance");
    for (int ch = 0; ch < 3; ch++) rs_json_push_num(c, sun->rgb[ch]);
    rs_json_set_num(o, "clip_level", sun->clip_level);
    rs_json_set_int(o, "removed_pixels", (long long)sun->removed_px);
    rs_json_set_num(o, "removed_solid_angle_sr", sun->removed_sr);
    rs_json_set_num(o, "removed_power", sun->removed_power);
}

const char *rs_irradiance_sun_source_name(rs_sun_source s)
{
    return s == RS_SUN_CONFIG ? "config"
        : s == RS_SUN_PIXELS  ? "sun pixels"
        : s == RS_SUN_SEARCH  ? "searched"
                              : "shadows";
}
