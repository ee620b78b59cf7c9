/* irradiance: per facet, one hemisphere gather with Embree gives
 *   E_sky,i = integral of L_env(w) V_i(w) cos dw   (rays that escape read the sky map), and
 *   G_i     = sum_j K_ij L_j                        (rays that hit facet j),
 * with cosine-weighted Owen-scrambled Sobol directions from Sobol points spread over the facet,
 * plus shadow rays toward the bright sky pixels (the sun), which cosine rays would miss.
 * Where the camera sees a hit point, G reads the panorama there (sub-facet detail); elsewhere
 * it goes through K and the hit facet's mean radiance. The sky map takes [sky] panorama where it
 * sees sky, the capture's sky next, and fills the rest ([sky] fill, skyfill.h). Writes
 * irradiance.ply (mesh + E_sky, G, G from panorama readings, sky_filled, irradiance_sky_sigma,
 * irradiance_mc_sigma)
 * and transport.ply (the sparse K: per (i, j) the total
 * weight and the weight not read from the panorama). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/capture.h"
#include "pipeline/capture_load.h"
#include "common/faceprop.h"
#include "common/log.h"
#include "common/sampling.h"
#include "common/scene.h"
#include "light/gather.h"
#include "light/kernel_out.h"
#include "sky/skyenv.h"
#include "light/skyground.h"
#include "sky/skysh.h"
#include "sky/solar.h"
#include "light/sunsource.h"
#include "stages/stages.h"

static int write_outputs(const rs_config *cfg, const rs_mesh *mesh, const rs_facet_gather *fg, const double *radiance,
                         const uint8_t *observed, double fill_rate, double mc_factor, rs_report *rep, rs_err *err)
{
    size_t nf = mesh->nfaces, ne = 0;
    double *esky = malloc(3 * nf * sizeof *esky), *g = malloc(3 * nf * sizeof *g),
           *gseen = malloc(3 * nf * sizeof *gseen), *filled = malloc(nf * sizeof *filled),
           *sigma = malloc(nf * sizeof *sigma), *mc = malloc(nf * sizeof *mc), *esun = malloc(3 * nf * sizeof *esun),
           *inv_dist = malloc(nf * sizeof *inv_dist), *gathered = malloc(nf * sizeof *gathered);
    rs_ply *ply = rs_ply_new();
    int rc = -1;
    char path[4096];
    if (!esky || !g || !gseen || !filled || !sigma || !mc || !esun || !inv_dist || !gathered || !ply) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory writing the irradiance outputs");
        goto out;
    }
    for (size_t f = 0; f < nf; f++) {
        for (int ch = 0; ch < 3; ch++) {
            esky[3 * f + ch] = fg[f].esky[ch];
            esun[3 * f + ch] = fg[f].esun[ch];
            gseen[3 * f + ch] = fg[f].gseen[ch];
        }
        inv_dist[f] = fg[f].inv_dist;
        gathered[f] = fg[f].rays > 0 || fg[f].sky_sh;
        rs_gather_inter_observed(&fg[f], radiance, observed, g + 3 * f);
        filled[f] = fg[f].esky_lum > 0 ? fg[f].filled_lum / fg[f].esky_lum : 0;
        sigma[f] = fg[f].fill_sigma_lum; /* rs_facet_gather: summed, not in quadrature */
        /* Monte Carlo noise of E_sky + G (rays toward unobserved facets count 0 here), the
         * independent-sample formula scaled by what a second seed showed (rs_gather_mc_calibration). */
        mc[f] = mc_factor * rs_gather_mc_sigma(&fg[f], radiance, observed);
        if (fg[f].sky_sh) mc[f] = fg[f].sh_sigma; /* no rays: the projection's measured error bound */
    }
    rs_ply_element *faces = rs_mesh_to_ply(mesh, ply);
    if (!faces || rs_faceprop_add_rgb(faces, "irradiance_sky", esky) != 0 ||
        rs_faceprop_add_rgb(faces, "irradiance_inter", g) != 0 ||
        rs_faceprop_add_rgb(faces, "irradiance_inter_seen", gseen) != 0 ||
        !rs_ply_add_scalar(faces, "sky_filled", RS_PLY_FLOAT32, filled) ||
        !rs_ply_add_scalar(faces, "irradiance_sky_sigma", RS_PLY_FLOAT32, sigma) ||
        !rs_ply_add_scalar(faces, "irradiance_mc_sigma", RS_PLY_FLOAT32, mc) ||
        rs_faceprop_add_rgb(faces, "irradiance_sun", esun) != 0 ||
        !rs_ply_add_scalar(faces, "hit_distance_inv", RS_PLY_FLOAT32, inv_dist) ||
        !rs_ply_add_scalar(faces, "gathered", RS_PLY_UINT8, gathered)) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory building irradiance.ply");
        goto out;
    }
    rs_ply_add_comment(ply,
                       "rhoscan %s irradiance: E_sky and G (W m^-2 per unit radiance scale); "
                       "irradiance_inter counts observed facets only",
                       RHOSCAN_VERSION);
    rs_ply_add_comment(ply,
                       "sky_filled: luminance share of E_sky from filled-in directions; irradiance_sky_sigma: "
                       "standard uncertainty of E_sky's luminance = the sum over filled directions of their "
                       "light x %.4g sqrt(their angle in radians to the nearest measured sky) (at most 1)",
                       fill_rate);
    rs_ply_add_comment(ply,
                       "irradiance_mc_sigma: standard error of the luminance of E_sky + G from the gather's "
                       "own sample spread times %.4g, the ratio of the actual spread between two seeds to it on "
                       "sampled facets (Monte Carlo noise; rays toward unobserved facets count 0)",
                       mc_factor);
    rs_ply_add_comment(ply,
                       "irradiance_sun: the part of irradiance_sky from the sun set's pixels and an explicit "
                       "sun; hit_distance_inv: mean of 1 / distance (1/m) over the cosine rays, escapes 0 (Ward's "
                       "harmonic mean distance is its reciprocal); gathered: 0 for facets left out of the gather");
    if (rs_ply_write(ply, rs_work_path(cfg, "irradiance.ply", path, sizeof path), 1, err) != 0) goto out;

    rs_ply_free(ply); /* before the kernel's file, streamed from the rows (kernel_out.c) */
    ply = NULL;
    if (rs_kernel_write(rs_work_path(cfg, "transport.ply", path, sizeof path), fg, nf, &ne, err) != 0) goto out;
    rs_json_set_int(rep->metrics, "kernel_entries", (long long)ne);
    rc = 0;
out:
    rs_ply_free(ply);
    free(esky);
    free(g);
    free(gseen);
    free(filled);
    free(sigma);
    free(mc);
    free(esun);
    free(inv_dist);
    free(gathered);
    return rc;
}

/* [sky] keys into the fill options: the method, and the sun when the config fixes it (an
 * explicit direction first, else date, time and place). */
static int sky_fill_options(const rs_config *cfg, rs_skyfill_opts *o, rs_err *err)
{
    memset(o, 0, sizeof *o);
    o->method = strcmp(rs_config_string(cfg, "sky", "fill"), "model") == 0 ? RS_SKYFILL_MODEL : RS_SKYFILL_ROW;
    o->sun_mask_rad = rs_config_real(cfg, "sky", "sun_mask_deg") * M_PI / 180;
    o->sh_order = (int)rs_config_int(cfg, "sky", "sh_order");
    o->sh_ridge = rs_config_real(cfg, "sky", "sh_ridge");
    o->ground_albedo = rs_config_real(cfg, "sky", "ground_albedo");
    o->cross_validate = 1;
    int has_az = rs_config_has(cfg, "sky", "sun_azimuth_deg"), has_el = rs_config_has(cfg, "sky", "sun_elevation_deg");
    if (has_az != has_el)
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[sky] sun_%s_deg is set without sun_%s_deg: "
                          "expected both or neither",
                          has_az ? "azimuth" : "elevation", has_az ? "elevation" : "azimuth");
    if (has_az) {
        double az = rs_config_real(cfg, "sky", "sun_azimuth_deg") * M_PI / 180;
        double el = rs_config_real(cfg, "sky", "sun_elevation_deg") * M_PI / 180;
        o->sun_given = 1;
        o->sun_dir = rs_v3_make(cos(el) * cos(az), cos(el) * sin(az), sin(el));
        return 0;
    }
    const char *when = rs_config_string(cfg, "sky", "datetime");
    if (!when) return 0;
    if (!rs_config_has(cfg, "sky", "latitude_deg") || !rs_config_has(cfg, "sky", "longitude_deg"))
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[sky] datetime is set without latitude_deg "
                          "and longitude_deg: expected the site's position for the solar position");
    double jd, az, el;
    if (rs_solar_parse_datetime(when, &jd, err) != 0) {
        rs_err_set_file(err, rs_config_file(cfg));
        return -1;
    }
    rs_solar_position(jd, rs_config_real(cfg, "sky", "latitude_deg"), rs_config_real(cfg, "sky", "longitude_deg"), &az,
                      &el);
    o->sun_given = 1;
    o->sun_dir = rs_solar_world_dir(az, el, rs_config_real(cfg, "sky", "north_deg"));
    rs_log_info("irradiance: sun at azimuth %.2f, elevation %.2f degrees (NOAA solar position for %s)", az, el, when);
    return 0;
}

/* The explicit sun's term, its DNI first estimated from the shadows when no one gave it. */
static int add_explicit_sun(const rs_config *cfg, rs_report *rep, rs_sunsource *sun, const rs_scene *scene,
                            const rs_capture *cap, rs_facet_gather *fg, const double *radiance, const uint8_t *observed,
                            rs_err *err)
{
    const rs_mesh *mesh = rs_scene_mesh(scene);
    size_t nf = mesh->nfaces;
    float *vis = malloc((nf ? nf : 1) * sizeof *vis);
    double t0 = rs_now();
    if (!vis ||
        rs_sunsource_visibility(sun, scene, (int)rs_config_int(cfg, "irradiance", "sun_samples"),
                                (uint32_t)rs_config_int(cfg, "irradiance", "seed"), nf, fg, vis) != 0 ||
        (sun->from_shadows &&
         rs_sunsource_from_shadows(sun, mesh, vis, fg, radiance, observed, cap->pose.position, cap->pano->height) !=
             0)) {
        free(vis);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory adding the explicit sun");
    }
    if (sun->from_shadows) {
        const rs_sunshadow *e = &sun->shadow;
        if (sun->shadow_rc == 0)
            rs_log_info("irradiance: sun from the shadows: DNI %.4g +- %.2g (statistical %.2g, from the sky fill "
                        "%.2g; colour %.3g %.3g %.3g) from %zu lit facets paired with shadowed ones within %.2f m on "
                        "their plane (%zu blocks; margin %.2f m)",
                        sun->dni, e->sigma_lum, e->sigma_stat_lum, e->sigma_sys_lum, sun->rgb[0], sun->rgb[1],
                        sun->rgb[2], e->lit_used, 3 * sun->margin, e->blocks, sun->margin);
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
    rs_sunsource_apply(sun, scene, nf, vis, fg);
    rs_report_time(rep, "explicit_sun", rs_now() - t0);
    free(vis);
    return 0;
}

/* The fitted Perez circumsolar term c, -1 without a model (the row fill fits none). An overcast
 * sky (c below RS_SUNSEARCH_MIN_GLOW) casts no shadow to read: no sun is searched then. */
static double sky_glow(const rs_skyfill_report *fill, rs_skyfill_method method)
{
    return method == RS_SKYFILL_MODEL && fill->fit_samples ? fill->model.perez[1][2] : -1;
}

/* [sky] sun_from_shadows = auto with nothing placing the sun and no bright sky pixel: look for
 * it in the shadows (rs_sunsource_search), unless the visible sky is overcast. */
static int search_hidden_sun(rs_report *rep, rs_sunsource *sun, const rs_scene *scene, const rs_skyenv *env,
                             const rs_skyfill_report *fill, rs_skyfill_method method, const rs_capture *cap,
                             const rs_facet_gather *fg, const double *radiance, const uint8_t *observed, rs_err *err)
{
    double glow = sky_glow(fill, method);
    if (glow >= 0 && glow < RS_SUNSEARCH_MIN_GLOW) {
        rs_report_skip(rep, "sun from the shadows",
                       "no bright sky pixel and no sun placed by the config, and the "
                       "visible sky has no circumsolar glow (Perez c = %.2f < %g): overcast, no sun searched",
                       glow, RS_SUNSEARCH_MIN_GLOW);
        return 0;
    }
    double t0 = rs_now();
    if (rs_sunsource_search(sun, scene, env, fg, radiance, observed, cap->pose.position, cap->pano->height,
                            fill->sun_dir) != 0)
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory searching the shadows for the sun");
    rs_report_time(rep, "sun_search", rs_now() - t0);
    if (sun->searched)
        rs_log_info("irradiance: no camera saw a sun and nothing placed one; the shadows put it at azimuth %.2f, "
                    "elevation %.2f deg (median log contrast %.3f over %zu lit-shadowed pairs, %d directions tried; "
                    "%.1f deg from where the visible sky puts it)",
                    atan2(sun->dir_world.y, sun->dir_world.x) * 180 / M_PI,
                    asin(fmin(1, sun->dir_world.z)) * 180 / M_PI, sun->found.score, sun->found.pairs,
                    sun->found.candidates, sun->found_off_deg);
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

static const char *sun_source_name(rs_sun_source s)
{
    return s == RS_SUN_CONFIG ? "config"
        : s == RS_SUN_PIXELS  ? "sun pixels"
        : s == RS_SUN_SEARCH  ? "searched"
                              : "shadows";
}

/* One gather of the facets over the sky map g->env, and the measure of its noise. */
typedef struct gather_pass {
    rs_skysh sh; /* [irradiance] sh_max_error: harmonics for facets that see only sky */
    double sh_tol;
    size_t sh_candidates;
    rs_gather_stats gs;
    double seconds;
    double mc_factor;
    size_t mc_facets;
} gather_pass;

/* Fills fg (zeroed, nf facets) and p; g->sky_sh points into p. suffix names its timings. */
static int gather_pass_run(const rs_config *cfg, rs_report *rep, rs_gather_ctx *g, const rs_image *ids, size_t nf,
                           rs_facet_gather *fg, gather_pass *p, const char *suffix, rs_err *err)
{
    char key[64];
    memset(p, 0, sizeof *p);
    g->sky_sh = NULL;
    p->sh_tol = rs_config_real(cfg, "irradiance", "sh_max_error");
    p->sh_candidates = g->skip_convex && p->sh_tol > 0 ? rs_skysh_candidates(g->scene) : 0;
    double t0;
    if (p->sh_candidates) { /* the test costs a pass over the map: only when a facet can use it */
        t0 = rs_now();
        if (rs_skysh_build(g->env, p->sh_tol, 256, &p->sh, err) != 0) return -1;
        snprintf(key, sizeof key, "sky_sh%s", suffix);
        rs_report_time(rep, key, rs_now() - t0);
        if (p->sh.usable) g->sky_sh = &p->sh;
    }
    /* [irradiance] skip_unseen: only what a camera sees and what lights it (rs_gather_run). */
    int skip_unseen = rs_config_bool(cfg, "irradiance", "skip_unseen");
    uint8_t *needed = skip_unseen ? calloc(nf, 1) : NULL;
    if (needed) {
        for (size_t k = 0; k < (size_t)ids->width * ids->height; k++)
            if (ids->data[k] >= 0 && ids->data[k] < (float)nf) needed[(size_t)ids->data[k]] = 1;
        for (size_t f = 0; f < nf; f++) needed[f] |= g->observed[f];
    }
    t0 = rs_now();
    rs_progress *prog = rs_progress_start("irradiance: gather", nf);
    int failed = (skip_unseen && !needed) || rs_gather_run(g, nf, needed, fg, NULL, prog, &p->gs) != 0;
    free(needed);
    rs_progress_end(prog);
    p->seconds = rs_now() - t0;
    snprintf(key, sizeof key, "gather%s", suffix);
    rs_report_time(rep, key, p->seconds);
    if (failed) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory during the gather");
    /* Before the explicit sun is added: the second gather has no sun term, and its difference
     * from the first must be noise alone (with the sun in one of them the factor was 12 to 24). */
    t0 = rs_now();
    if (rs_gather_mc_calibration(g, nf, fg, g->radiance, g->observed, 512, &p->mc_factor, &p->mc_facets) != 0)
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory measuring the gather's noise");
    snprintf(key, sizeof key, "mc_calibration%s", suffix);
    rs_report_time(rep, key, rs_now() - t0);
    rs_json_set_num(rep->metrics, "mc_sigma_factor", p->mc_factor);
    rs_json_set_int(rep->metrics, "mc_calibration_facets", (long long)p->mc_facets);
    rs_log_info("irradiance: Monte Carlo noise from %zu facets gathered twice: %.3g x the independent-sample formula",
                p->mc_facets, p->mc_factor);
    return 0;
}

/* The sky map's ground model (directions below the horizon that no camera saw as ground near
 * them: skyfill.h) set to the albedo of the scan's own ground under the completed sky ([sky]
 * ground_albedo_from = scan). When that albedo cannot be had, the model's pixels copy the
 * nearest measured ground band at any distance instead, as before the model (and keep [sky]
 * ground_albedo when no camera saw ground at all). */
static int ground_from_scan(const rs_config *cfg, rs_report *rep, const rs_gather_ctx *g, rs_skyenv *env,
                            const rs_skyenv_opts *so, const rs_skyfill_report *fill, const rs_sunsource *sun,
                            const rs_mesh *mesh, rs_err *err)
{
    if (so->fill.method != RS_SKYFILL_MODEL || !fill->ground_model_pixels) return 0;
    rs_json_set_int(rep->metrics, "sky_ground_model_pixels", (long long)fill->ground_model_pixels);
    const char *from = "config", *why = NULL;
    char few[160];
    double albedo[3] = {so->fill.ground_albedo, so->fill.ground_albedo, so->fill.ground_albedo};
    rs_skyground gr = {0};
    if (strcmp(rs_config_string(cfg, "sky", "ground_albedo_from"), "scan") != 0) {
        /* as asked */
    } else if (sun->active) {
        why = "an explicit sun is added after the gather, so the ground's own E would miss it";
    } else if (sun->search && !(sky_glow(fill, so->fill.method) < RS_SUNSEARCH_MIN_GLOW)) {
        why = "a sun no camera saw may be found in the shadows after the gather, and the ground's own E would miss it";
    } else {
        double t0 = rs_now();
        if (rs_skyground_albedo(g, mesh, g->radiance, g->observed, &gr) != 0)
            return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory estimating the ground's albedo");
        rs_report_time(rep, "ground_albedo", rs_now() - t0);
        if (!gr.facets) {
            snprintf(few, sizeof few,
                     "fewer than %d of the %zu observed upward facets at the scan's ground "
                     "level see only observed ones",
                     RS_SKYGROUND_MIN_FACETS, gr.candidates);
            why = few;
        }
    }
    if (gr.facets) {
        double rgb[3];
        for (int ch = 0; ch < 3; ch++) {
            albedo[ch] = fmin(1, gr.albedo[ch]);
            rgb[ch] = albedo[ch] * fill->horizontal_irradiance[ch] / M_PI;
        }
        if (rs_skyenv_set_ground(env, rgb, so->explicit_sun) < 0)
            return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the sky distribution");
        from = "scan";
        rs_json_set_int(rep->metrics, "sky_ground_albedo_facets", (long long)gr.facets);
        rs_json_set_int(rep->metrics, "sky_ground_albedo_left_out", (long long)gr.sees_unobserved);
        rs_json *sp = rs_json_set_arr(rep->metrics, "sky_ground_albedo_spread");
        for (int ch = 0; ch < 3; ch++) rs_json_push_num(sp, gr.spread[ch]);
        rs_log_info("irradiance: unseen ground below the horizon (%zu map pixels): albedo %.3g %.3g %.3g (+- %.2g "
                    "%.2g %.2g between facets) from %zu of the scan's %zu observed ground facets at z %.2f m (%zu "
                    "left out: they see facets no camera saw)",
                    fill->ground_model_pixels, albedo[0], albedo[1], albedo[2], gr.spread[0], gr.spread[1],
                    gr.spread[2], gr.facets, gr.candidates, gr.level_z, gr.sees_unobserved);
    } else if (why) {
        long n = rs_skyenv_ground_from_bands(env, so->explicit_sun);
        if (n < 0) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the sky distribution");
        if (n > 0) from = "measured ground";
        rs_report_skip(rep, "ground albedo from the scan", "%s: the unseen ground %s", why,
                       n > 0 ? "copies the nearest band of measured ground"
                             : "keeps [sky] ground_albedo (no camera saw ground beyond the model)");
    }
    if (strcmp(from, "measured ground") != 0) {
        rs_json *ga = rs_json_set_arr(rep->metrics, "sky_ground_albedo");
        for (int ch = 0; ch < 3; ch++) rs_json_push_num(ga, albedo[ch]);
    }
    rs_json_set_str(rep->metrics, "sky_ground_albedo_from", from);
    return 0;
}

int rs_irradiance_run(const rs_config *cfg, rs_report *rep, rs_err *err)
{
    char path[4096];
    int rc = -1;
    rs_capture cap = {0}, sky = {0}, others[RS_SKYENV_MAX_OTHERS];
    uint8_t *other_masks[RS_SKYENV_MAX_OTHERS];
    int nothers = 0;
    rs_skyenv env = {0};
    rs_sunsource sun = {0}; /* [sky] sun_irradiance: the sun as an explicit source */
    rs_skyenv_info info;
    uint8_t *sky_mask = NULL;
    rs_scene *scene = NULL;
    rs_image *ids = NULL;
    rs_ply *obs = NULL;
    rs_facet_gather *fg = NULL;
    double *radiance = NULL, *obsd = NULL;
    uint8_t *observed = NULL;
    rs_mesh *mesh = rs_mesh_read(rs_work_path(cfg, "mesh.ply", path, sizeof path), NULL, err);
    if (!mesh) return -1;
    size_t nf = mesh->nfaces;
    const char *obs_path = rs_work_path(cfg, "observe.ply", path, sizeof path);
    if (!(obs = rs_ply_read(obs_path, err))) goto out;
    radiance = malloc(3 * nf * sizeof *radiance);
    obsd = malloc(nf * sizeof *obsd);
    observed = malloc(nf);
    if (!radiance || !obsd || !observed) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    if (rs_faceprop_get_rgb(obs, obs_path, "radiance", nf, radiance, err) != 0 ||
        rs_faceprop_get(obs, obs_path, "observed", nf, obsd, err) != 0)
        goto out;
    for (size_t f = 0; f < nf; f++) observed[f] = obsd[f] > 0;
    if (rs_capture_load(cfg, "capture", &cap, err) != 0) goto out;
    const char *id_path = rs_work_path(cfg, "facet_id.exr", path, sizeof path);
    if (!(ids = rs_image_read(id_path, err))) goto out;
    if (ids->width != cap.pano->width || ids->height != cap.pano->height || ids->channels != 1) {
        rs_err_set(err, RS_ERR_INPUT, id_path, 0,
                   "is %dx%d with %d channels: expected %dx%d, 1 channel "
                   "(rerun observe)",
                   ids->width, ids->height, ids->channels, cap.pano->width, cap.pano->height);
        goto out;
    }
    int sun_samples = (int)rs_config_int(cfg, "irradiance", "sun_samples");
    double t0 = rs_now();
    if (!(scene = rs_scene_new(mesh, err))) goto out;
    rs_report_time(rep, "bvh", rs_now() - t0);
    t0 = rs_now();
    double cone = rs_config_real(cfg, "irradiance", "sun_max_cone_deg") * M_PI / 180;
    rs_skyenv_opts so;
    memset(&so, 0, sizeof so);
    so.sun_threshold = rs_config_real(cfg, "irradiance", "sun_threshold");
    so.max_sr = 2 * M_PI * (1 - cos(cone));
    so.explicit_sun = sun_samples > 0 || rs_config_int(cfg, "irradiance", "sky_samples") > 0;
    if (sky_fill_options(cfg, &so.fill, err) != 0) goto out;
    if (rs_sunsource_setup(cfg, &cap, ids->data, &so.fill, &sun, err) != 0) goto out;
    if (rs_config_has(cfg, "sky", "panorama")) {
        if (rs_capture_load(cfg, "sky", &sky, err) != 0) goto out;
        rs_sunsource_remove(&sun, &sky, NULL, 0);
        if (!(sky_mask = malloc((size_t)sky.pano->width * sky.pano->height))) {
            rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the sky panorama's mask");
            goto out;
        }
        rs_skyenv_sky_mask(scene, &sky, sky_mask);
        so.sky = &sky;
        so.sky_mask = sky_mask;
    }
    /* Further captures ([capture.NAME]): their sky fills what this capture cannot see. */
    const char *sections[RS_SKYENV_MAX_OTHERS + 1];
    int nsec = rs_config_sections(cfg, "capture", sections, RS_SKYENV_MAX_OTHERS + 1);
    for (int i = 0; i < nsec && i < RS_SKYENV_MAX_OTHERS + 1; i++) {
        if (strcmp(sections[i], "capture") == 0 || nothers == RS_SKYENV_MAX_OTHERS) continue;
        if (rs_capture_load(cfg, sections[i], &others[nothers], err) != 0) goto out;
        rs_sunsource_remove(&sun, &others[nothers], NULL, 0);
        nothers++;
        size_t n = (size_t)others[nothers - 1].pano->width * others[nothers - 1].pano->height;
        if (!(other_masks[nothers - 1] = malloc(n))) {
            rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for [%s]'s sky mask", sections[i]);
            goto out;
        }
        rs_skyenv_sky_mask(scene, &others[nothers - 1], other_masks[nothers - 1]);
    }
    if (nsec > RS_SKYENV_MAX_OTHERS + 1)
        rs_log_warn("irradiance: only the first %d further captures feed the sky map", RS_SKYENV_MAX_OTHERS);
    const rs_capture *other_ptrs[RS_SKYENV_MAX_OTHERS];
    const uint8_t *mask_ptrs[RS_SKYENV_MAX_OTHERS];
    for (int i = 0; i < nothers; i++) {
        other_ptrs[i] = &others[i];
        mask_ptrs[i] = other_masks[i];
    }
    so.others = other_ptrs;
    so.other_masks = mask_ptrs;
    so.nothers = nothers;
    if (rs_skyenv_build_opts(&cap, ids->data, &so, &env, &info, err) != 0) goto out;
    rs_sunsource_auto(cfg, &env, &so.fill, &sun);
    for (int i = 0; i < nothers; i++)
        rs_log_info("irradiance: capture %s: exposure factor %.4g %.4g %.4g from %.3g sr of shared sky", others[i].path,
                    info.other_scale[i][0], info.other_scale[i][1], info.other_scale[i][2], info.other_overlap_sr[i]);
    if (nothers) rs_log_info("irradiance: further captures gave %zu map pixels", info.other_pixels);
    rs_report_time(rep, "sky_map", rs_now() - t0);
    rs_log_info("irradiance: sky %zu pixels (median luminance %.4g), %zu filled (%s), %zu bright kept out of the fill",
                env.sky_pixels, env.sky_median, env.filled_pixels, rs_config_string(cfg, "sky", "fill"),
                env.bright_pixels);
    if (sky.pano)
        rs_log_info("irradiance: sky panorama %s gave %zu map pixels; exposure factor %.4g %.4g %.4g from %.3g sr "
                    "of shared sky",
                    sky.path, info.sky_pano_pixels, info.sky_pano_scale[0], info.sky_pano_scale[1],
                    info.sky_pano_scale[2], info.sky_overlap_sr);
    if (info.fill.cv_folds)
        rs_log_info("irradiance: held-out sky blocks (%d): relative error of their light filled by rows %.3f, by the "
                    "model %.3f; sun %s",
                    info.fill.cv_folds, info.fill.cv_rel_row, info.fill.cv_rel_model,
                    sun_source_name(info.fill.sun_source));
    if (so.fill.method == RS_SKYFILL_MODEL && !info.fill.fit_samples)
        rs_log_warn("irradiance: too little visible sky to fit the sky model: filled by rows");
    if (!sun_samples)
        rs_report_skip(rep, "sun sampling", "[irradiance] sun_samples = 0: cosine-weighted rays only");
    else if (!env.sun_cdf)
        rs_report_skip(rep, "sun sampling", "no sky pixel is brighter than %g x the median sky",
                       rs_config_real(cfg, "irradiance", "sun_threshold"));

    rs_gather_ctx g = {.scene = scene,
                       .env = &env,
                       .cap = &cap,
                       .facet_id = ids->data,
                       .samples = (int)rs_config_int(cfg, "irradiance", "samples"),
                       .sky_samples = (int)rs_config_int(cfg, "irradiance", "sky_samples"),
                       .sun_samples = sun_samples,
                       .seed = (uint32_t)rs_config_int(cfg, "irradiance", "seed"),
                       .sun_target_error = rs_config_real(cfg, "irradiance", "sun_target_error"),
                       .skip_convex = rs_config_bool(cfg, "irradiance", "skip_convex"),
                       .relay_share = rs_config_real(cfg, "irradiance", "relay_share"),
                       /* [irradiance] target_error: rounds of rays per facet until its E_sky + G is
                        * known that well (gather.h); rays into K then count with the radiance of
                        * the facets they hit. */
                       .target_error = rs_config_real(cfg, "irradiance", "target_error"),
                       .radiance = radiance,
                       .observed = observed};
    fg = calloc(nf, sizeof *fg);
    if (!fg) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu facets", nf);
        goto out;
    }
    if (ground_from_scan(cfg, rep, &g, &env, &so, &info.fill, &sun, mesh, err) != 0) goto out;
    gather_pass gp;
    double first_pass_rays = 0; /* rays of a gather done again around a searched sun */
    if (gather_pass_run(cfg, rep, &g, ids, nf, fg, &gp, "", err) != 0) goto out;
    if (sun.search &&
        search_hidden_sun(rep, &sun, scene, &env, &info.fill, so.fill.method, &cap, fg, radiance, observed, err) != 0)
        goto out;
    /* The model fill placed its sun where the visible sky's glow put it, degrees from where the
     * shadows do: fitted again around the searched sun, the circumsolar sky and so the E that the
     * DNI estimate divides by move with it (street canyon: 12.6 % -> 10.8 % albedo error). */
    if (sun.searched && so.fill.method == RS_SKYFILL_MODEL && info.fill.fit_samples) {
        rs_log_info("irradiance: the sky model fitted again around the searched sun (%.1f deg from its first "
                    "direction), and the facets gathered again",
                    sun.found_off_deg);
        so.fill.sun_given = 1;
        so.fill.sun_dir = sun.dir_world;
        rs_skyenv_release(&env);
        t0 = rs_now();
        if (rs_skyenv_build_opts(&cap, ids->data, &so, &env, &info, err) != 0) goto out;
        rs_report_time(rep, "sky_map_searched_sun", rs_now() - t0);
        info.fill.sun_source = RS_SUN_SHADOWS;
        /* The sun is explicit now: the unseen ground copies the measured ground, as the first map's
         * did (ground_from_scan said why), unless the config asked for its albedo. */
        if (strcmp(rs_config_string(cfg, "sky", "ground_albedo_from"), "scan") == 0 &&
            rs_skyenv_ground_from_bands(&env, so.explicit_sun) < 0) {
            rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the sky distribution");
            goto out;
        }
        first_pass_rays = gp.gs.rays;
        for (size_t f = 0; f < nf; f++) free(fg[f].entries);
        memset(fg, 0, nf * sizeof *fg);
        if (gather_pass_run(cfg, rep, &g, ids, nf, fg, &gp, "_searched_sun", err) != 0) goto out;
    }
    if (sun.active && add_explicit_sun(cfg, rep, &sun, scene, &cap, fg, radiance, observed, err) != 0) goto out;
    if (gp.gs.gathered < nf)
        rs_report_skip(rep, "gather of unseen facets",
                       "%zu facets that no camera sees light no facet it sees "
                       "(closure of the light paths in %d waves)",
                       nf - gp.gs.gathered, gp.gs.waves);
    if (gp.gs.sees_nothing)
        rs_report_skip(rep, "tracing of convex facets",
                       "%zu facets have the whole model below their plane: "
                       "their rays escape without tracing",
                       gp.gs.sees_nothing);
    if (gp.gs.relays)
        rs_report_skip(rep, "full ray counts for relays",
                       "%zu facets that no camera sees, gathered for their light on "
                       "seen ones, traced %g of the rays ([irradiance] relay_share)",
                       gp.gs.relays, g.relay_share);
    rs_json_set_int(rep->metrics, "facets_gathered", (long long)gp.gs.gathered);
    rs_json_set_int(rep->metrics, "facets_relays", (long long)gp.gs.relays);
    rs_json_set_int(rep->metrics, "facets_seeing_nothing", (long long)gp.gs.sees_nothing);
    size_t nsh = 0;
    for (size_t f = 0; f < nf; f++) nsh += fg[f].sky_sh;
    rs_json_set_int(rep->metrics, "facets_sky_sh", (long long)nsh);
    rs_json_set_num(rep->metrics, "sky_sh_max_error", gp.sh.max_error);
    rs_json_set_num(rep->metrics, "sky_sh_max_error_filled", gp.sh.max_error_filled);
    rs_json_set_num(rep->metrics, "sky_sh_passed_share", gp.sh.passed_share);
    if (!g.skip_convex || !(gp.sh_tol > 0))
        rs_report_skip(rep, "sky harmonics", "[irradiance] %s: every facet gathers with rays",
                       g.skip_convex ? "sh_max_error = 0" : "skip_convex = false");
    else if (!gp.sh_candidates)
        rs_report_skip(rep, "sky harmonics", "no facet has the whole model below its plane");
    else if (!gp.sh.usable)
        rs_report_skip(rep, "sky harmonics",
                       "the sky map's order-2 irradiance is off by more than [irradiance] "
                       "sh_max_error = %g at every one of %d normals (up to %.2f %%, at %.2f %.2f %.2f): facets that "
                       "see only sky gather with rays",
                       gp.sh.tol, gp.sh.normals, 100 * gp.sh.max_error, gp.sh.worst_normal.x, gp.sh.worst_normal.y,
                       gp.sh.worst_normal.z);
    else
        rs_log_info("irradiance: %zu of %zu facets that see only sky took E_sky from the sky's order-2 harmonics, "
                    "no rays (error within %g on %.0f %% of the normals, up to %.2f %% at %.2f %.2f %.2f); the other "
                    "%zu face a normal above that or cut the sun set's cone, and gathered",
                    nsh, gp.gs.sees_nothing, gp.sh.tol, 100 * gp.sh.passed_share, 100 * gp.sh.max_error,
                    gp.sh.worst_normal.x, gp.sh.worst_normal.y, gp.sh.worst_normal.z, gp.gs.sees_nothing - nsh);
    double rays = gp.gs.rays + first_pass_rays;
    rs_json_set_num(rep->metrics, "rays", rays);
    rs_json_set_num(rep->metrics, "rays_per_second", gp.seconds > 0 ? gp.gs.rays / gp.seconds : 0);
    if (g.target_error > 0) {
        size_t refined = 0, capped = 0;
        for (size_t f = 0; f < nf; f++) {
            refined += fg[f].rounds > 0;
            capped += fg[f].rounds == RS_GATHER_MAX_ROUNDS;
        }
        rs_json_set_int(rep->metrics, "facets_refined", (long long)refined);
        rs_json_set_int(rep->metrics, "facets_refined_to_cap", (long long)capped);
        rs_log_info("irradiance: target_error %g: %zu facets took more rays than the base counts, %zu of them "
                    "%d x (the cap)",
                    g.target_error, refined, capped, 1 << RS_GATHER_MAX_ROUNDS);
    }
    rs_json_set_int(rep->metrics, "sky_pixels", (long long)env.sky_pixels);
    rs_json_set_int(rep->metrics, "filled_pixels", (long long)env.filled_pixels);
    rs_json_set_int(rep->metrics, "bright_pixels", (long long)env.bright_pixels);
    rs_json_set_num(rep->metrics, "bright_solid_angle_sr", env.bright_sr);
    rs_json_set_num(rep->metrics, "sky_median_luminance", env.sky_median);
    rs_json_set_str(rep->metrics, "sky_fill", rs_config_string(cfg, "sky", "fill"));
    rs_json_set_num(rep->metrics, "sky_fill_sigma", env.fill_sigma);
    rs_json_set_num(rep->metrics, "sky_cv_rel_row", info.fill.cv_rel_row);
    rs_json_set_num(rep->metrics, "sky_cv_rel_model", info.fill.cv_rel_model);
    rs_json_set_int(rep->metrics, "sky_cv_blocks", info.fill.cv_folds);
    rs_json_set_str(rep->metrics, "sun_source", sun_source_name(info.fill.sun_source));
    rs_sunsource_report(&sun, rep->metrics);
    rs_json *sd = rs_json_set_arr(rep->metrics, "sun_direction");
    rs_json_push_num(sd, info.fill.sun_dir.x);
    rs_json_push_num(sd, info.fill.sun_dir.y);
    rs_json_push_num(sd, info.fill.sun_dir.z);
    if (so.fill.method == RS_SKYFILL_MODEL) {
        rs_json_set_int(rep->metrics, "sky_model_sh_order", info.fill.model.sh_order);
        rs_json_set_num(rep->metrics, "sky_model_fit_rms_log", info.fill.model.fit_rms_log);
        rs_json *pz = rs_json_set_arr(rep->metrics, "sky_model_perez_green"); /* a b c d e */
        for (int k = 0; k < 5; k++) rs_json_push_num(pz, info.fill.model.perez[1][k]);
        rs_json_set_int(rep->metrics, "sky_ground_from_albedo", info.fill.ground_from_albedo);
    }
    if (nothers) rs_json_set_int(rep->metrics, "sky_other_capture_pixels", (long long)info.other_pixels);
    if (sky.pano) {
        rs_json_set_int(rep->metrics, "sky_panorama_pixels", (long long)info.sky_pano_pixels);
        rs_json_set_num(rep->metrics, "sky_panorama_overlap_sr", info.sky_overlap_sr);
        rs_json *sc = rs_json_set_arr(rep->metrics, "sky_panorama_exposure");
        for (int ch = 0; ch < 3; ch++) rs_json_push_num(sc, info.sky_pano_scale[ch]);
    }
    double fl = 0, el = 0;
    for (size_t f = 0; f < nf; f++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(mesh, f, &c, &n, &a);
        fl += a * fg[f].filled_lum;
        el += a * fg[f].esky_lum;
    }
    rs_json_set_num(rep->metrics, "sky_filled_share", el > 0 ? fl / el : 0);
    /* The fill's uncertainty grows with the distance from the measured sky at the largest
     * held-out rate (rs_skyfill_sigma_map); the flat figure from the largest held-out error, and
     * their RMS (env.fill_sigma), stay in the metrics for comparison. */
    int use_model = so.fill.method == RS_SKYFILL_MODEL && info.fill.fit_samples;
    double fill_unc =
        rs_skyfill_sigma_from_blocks(info.fill.cv_folds, use_model ? info.fill.cv_max_model : info.fill.cv_max_row);
    double fill_rate = rs_skyfill_rate_used(&info.fill, so.fill.method);
    rs_json_set_num(rep->metrics, "sky_fill_sigma_flat", fill_unc);
    rs_json_set_num(rep->metrics, "sky_fill_sigma_per_sqrt_rad", fill_rate);
    double fs = 0;
    for (size_t f = 0; f < nf; f++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(mesh, f, &c, &n, &a);
        fs += a * fg[f].fill_sigma_lum;
    }
    rs_json_set_num(rep->metrics, "sky_fill_sigma_used", fl > 0 ? fs / fl : 0);
    rs_json_set_num(rep->metrics, "sky_cv_max_row", info.fill.cv_max_row);
    rs_json_set_num(rep->metrics, "sky_cv_max_model", info.fill.cv_max_model);
    rc = write_outputs(cfg, mesh, fg, radiance, observed, fill_rate, gp.mc_factor, rep, err);
out:
    if (fg)
        for (size_t f = 0; f < nf; f++) free(fg[f].entries);
    free(fg);
    free(radiance);
    free(obsd);
    free(observed);
    rs_ply_free(obs);
    rs_image_free(ids);
    rs_skyenv_release(&env);
    rs_scene_free(scene);
    rs_capture_release(&cap);
    rs_capture_release(&sky);
    free(sky_mask);
    for (int i = 0; i < nothers; i++) {
        rs_capture_release(&others[i]);
        free(other_masks[i]);
    }
    rs_mesh_free(mesh);
    return rc;
}
