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
 * weight and the weight not read from the panorama).
 * This file: the options, the inputs, the sky map and the gathers, and rs_irradiance_run, the
 * script over them; irradiance_sun.c: the sun; irradiance_out.c: the report and the files. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/faceprop.h"
#include "common/log.h"
#include "common/par.h"
#include "common/ply.h"
#include "light/skyground.h"
#include "pipeline/capture_load.h"
#include "sky/solar.h"
#include "stages/irradiance/irradiance_close.h"
#include "stages/irradiance/irradiance_out.h"
#include "stages/irradiance/irradiance_share.h"
#include "stages/irradiance/irradiance_skyscale.h"
#include "stages/irradiance/irradiance_state.h"
#include "stages/irradiance/irradiance_sun.h"
#include "stages/stages.h"

/* [sky] keys into the fill options: the method, and the sun when the config fixes it (an
 * explicit direction first, else date, time and place: then the solar position, for the log). */
static int sky_fill_options(const rs_config *cfg, rs_irradiance_opts *opts, rs_err *err)
{
    rs_skyfill_opts *o = &opts->sky.fill;
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
    opts->solar_when = when;
    opts->solar_az_deg = az;
    opts->solar_el_deg = el;
    return 0;
}

/* Every key the stage reads, once. -1 with err when they contradict each other. */
static int read_opts(const rs_config *cfg, rs_irradiance_opts *o, rs_err *err)
{
    memset(o, 0, sizeof *o);
    o->config_file = rs_config_file(cfg);
    o->samples = (int)rs_config_int(cfg, "irradiance", "samples");
    o->sky_samples = (int)rs_config_int(cfg, "irradiance", "sky_samples");
    o->sun_samples = (int)rs_config_int(cfg, "irradiance", "sun_samples");
    o->seed = (uint32_t)rs_config_int(cfg, "irradiance", "seed");
    o->sun_target_error = rs_config_real(cfg, "irradiance", "sun_target_error");
    /* [irradiance] target_error: rounds of rays per facet until its E_sky + G is known that
     * well (gather.h); rays into K then count with the radiance of the facets they hit. */
    o->target_error = rs_config_real(cfg, "irradiance", "target_error");
    o->relay_share = rs_config_real(cfg, "irradiance", "relay_share");
    o->skip_convex = rs_config_bool(cfg, "irradiance", "skip_convex");
    o->skip_unseen = rs_config_bool(cfg, "irradiance", "skip_unseen");
    o->sh_max_error = rs_config_real(cfg, "irradiance", "sh_max_error");
    /* The sun set: the sky pixels above sun_threshold x the median, up to the cone's solid angle. */
    o->sky.sun_threshold = rs_config_real(cfg, "irradiance", "sun_threshold");
    double cone = rs_config_real(cfg, "irradiance", "sun_max_cone_deg") * M_PI / 180;
    o->sky.max_sr = 2 * M_PI * (1 - cos(cone));
    o->sky.explicit_sun = o->sun_samples > 0 || o->sky_samples > 0;
    o->fill_name = rs_config_string(cfg, "sky", "fill");
    o->sky_panorama = rs_config_has(cfg, "sky", "panorama");
    o->ground_from_scan = strcmp(rs_config_string(cfg, "sky", "ground_albedo_from"), "scan") == 0;
    const char *ff = rs_config_string(cfg, "sky", "fill_from_facets");
    o->fill_from_facets = strcmp(ff, "on") == 0 ? RS_FILL_FROM_FACETS_ON
        : strcmp(ff, "off") == 0                ? RS_FILL_FROM_FACETS_OFF
                                                : RS_FILL_FROM_FACETS_AUTO;
    o->fill_directional = strcmp(rs_config_string(cfg, "sky", "fill_from_facets_modes"), "directional") == 0;
    o->ncaptures = rs_config_sections(cfg, "capture", o->captures, RS_SKYENV_MAX_OTHERS + 1);
    if (sky_fill_options(cfg, o, err) != 0) return -1;
    return rs_irradiance_sun_options(cfg, &o->sun, err);
}

/* observe.ply's radiance and observed flag per facet. */
static int read_observe(const rs_config *cfg, rs_irradiance_state *s, rs_err *err)
{
    char path[4096];
    const char *obs_path = rs_work_path(cfg, "observe.ply", path, sizeof path);
    rs_ply *obs = rs_ply_read(obs_path, err);
    if (!obs) return -1;
    size_t nf = s->nf;
    double *observed = malloc(nf * sizeof *observed); /* as the file has it */
    s->radiance = malloc(3 * nf * sizeof *s->radiance);
    s->observed = malloc(nf);
    int rc = -1;
    if (!s->radiance || !observed || !s->observed) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory reading %s", obs_path);
    } else if (rs_faceprop_get_rgb(obs, obs_path, "radiance", nf, s->radiance, err) == 0 &&
               rs_faceprop_get(obs, obs_path, "observed", nf, observed, err) == 0) {
        for (size_t f = 0; f < nf; f++) s->observed[f] = observed[f] > 0;
        rc = 0;
    }
    free(observed);
    rs_ply_free(obs);
    return rc;
}

/* facet_id.exr, which must match the capture's panorama. */
static int read_facet_ids(const rs_config *cfg, rs_irradiance_state *s, rs_err *err)
{
    char path[4096];
    const char *id_path = rs_work_path(cfg, "facet_id.exr", path, sizeof path);
    if (!(s->ids = rs_image_read(id_path, err))) return -1;
    const rs_image *ids = s->ids, *pano = s->cap.pano;
    if (ids->width != pano->width || ids->height != pano->height || ids->channels != 1)
        return rs_err_set(err, RS_ERR_INPUT, id_path, 0,
                          "is %dx%d with %d channels: expected %dx%d, 1 channel "
                          "(rerun observe)",
                          ids->width, ids->height, ids->channels, pano->width, pano->height);
    return 0;
}

/* The earlier stages' files, the capture, and the model's BVH. */
static int load_inputs(const rs_config *cfg, rs_irradiance_state *s, rs_report *rep, rs_err *err)
{
    char path[4096];
    if (!(s->mesh = rs_mesh_read(rs_work_path(cfg, "mesh.ply", path, sizeof path), NULL, err))) return -1;
    s->nf = s->mesh->nfaces;
    if (read_observe(cfg, s, err) != 0 || rs_capture_load(cfg, "capture", &s->cap, err) != 0 ||
        read_facet_ids(cfg, s, err) != 0)
        return -1;
    double t0 = rs_now();
    if (!(s->scene = rs_scene_new(s->mesh, err))) return -1;
    rs_report_time(rep, "bvh", rs_now() - t0);
    return 0;
}

/* [sky] panorama, the explicit sun taken out of it, and its pixels that see sky. */
static int load_sky_panorama(const rs_config *cfg, const rs_irradiance_opts *o, rs_irradiance_state *s, rs_err *err)
{
    if (!o->sky_panorama) return 0;
    if (rs_capture_load(cfg, "sky", &s->sky, err) != 0) return -1;
    rs_sunsource_remove(&s->sun, &s->sky, NULL, 0);
    if (!(s->sky_mask = malloc((size_t)s->sky.pano->width * s->sky.pano->height)))
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the sky panorama's mask");
    rs_skyenv_sky_mask(s->scene, &s->sky, s->sky_mask);
    s->so.sky = &s->sky;
    s->so.sky_mask = s->sky_mask;
    return 0;
}

/* Further captures ([capture.NAME]), the explicit sun taken out: their sky fills what this
 * capture cannot see. */
static int load_other_captures(const rs_config *cfg, const rs_irradiance_opts *o, rs_irradiance_state *s, rs_err *err)
{
    for (int i = 0; i < o->ncaptures && i < RS_SKYENV_MAX_OTHERS + 1; i++) {
        if (strcmp(o->captures[i], "capture") == 0 || s->nothers == RS_SKYENV_MAX_OTHERS) continue;
        rs_capture *c = &s->others[s->nothers];
        if (rs_capture_load(cfg, o->captures[i], c, err) != 0) return -1;
        rs_sunsource_remove(&s->sun, c, NULL, 0);
        s->other_names[s->nothers] = o->captures[i];
        uint8_t **mask = &s->other_masks[s->nothers++];
        if (!(*mask = malloc((size_t)c->pano->width * c->pano->height)))
            return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for [%s]'s sky mask", o->captures[i]);
        rs_skyenv_sky_mask(s->scene, c, *mask);
    }
    if (o->ncaptures > RS_SKYENV_MAX_OTHERS + 1)
        rs_log_warn("irradiance: only the first %d further captures feed the sky map", RS_SKYENV_MAX_OTHERS);
    for (int i = 0; i < s->nothers; i++) {
        s->other_ptrs[i] = &s->others[i];
        s->other_mask_ptrs[i] = s->other_masks[i];
    }
    s->so.others = s->other_ptrs;
    s->so.other_masks = s->other_mask_ptrs;
    s->so.nothers = s->nothers;
    return 0;
}

/* What the sky map is made of, and what it lacks for the sun's rays. */
static void log_sky_map(const rs_irradiance_opts *o, const rs_irradiance_state *s, rs_report *rep)
{
    const rs_skyenv *env = &s->env;
    const rs_skyenv_info *info = &s->info;
    rs_log_info("irradiance: sky %zu pixels (median luminance %.4g), %zu filled (%s), %zu bright kept out of the fill",
                env->sky_pixels, env->sky_median, env->filled_pixels, o->fill_name, env->bright_pixels);
    if (s->sky.pano)
        rs_log_info("irradiance: sky panorama %s gave %zu map pixels; exposure factor %.4g %.4g %.4g from %.3g sr "
                    "of shared sky",
                    s->sky.path, info->sky_pano_pixels, info->sky_pano_scale[0], info->sky_pano_scale[1],
                    info->sky_pano_scale[2], info->sky_overlap_sr);
    if (info->fill.cv_folds)
        rs_log_info("irradiance: held-out sky blocks (%d): relative error of their light filled by rows %.3f, by the "
                    "model %.3f; the sun placed from: %s",
                    info->fill.cv_folds, info->fill.cv_rel_row, info->fill.cv_rel_model,
                    rs_irradiance_sun_source_name(info->fill.sun_source));
    if (s->so.fill.method == RS_SKYFILL_MODEL && !info->fill.fit_samples)
        rs_log_warn("irradiance: too little visible sky to fit the sky model: filled by rows");
    if (!o->sun_samples)
        rs_report_skip(rep, "sun sampling", "[irradiance] sun_samples = 0: cosine-weighted rays only");
    else if (!env->sun_cdf)
        rs_report_skip(rep, "sun sampling", "no sky pixel is brighter than %g x the median sky", o->sky.sun_threshold);
}

typedef struct {
    const rs_config *cfg; /* NULL: the sources are loaded already */
    const rs_irradiance_opts *o;
    rs_irradiance_state *s;
} sky_map_job;

/* The sky panorama and the further captures loaded (unless loaded already), the map built and
 * completed (skyenv.h): rank 0's alone under MPI (rs_irradiance_share_sky_map sends it). */
static int sky_map_build(void *ctx, rs_err *err)
{
    sky_map_job *j = ctx;
    rs_irradiance_state *s = j->s;
    if (j->cfg && (load_sky_panorama(j->cfg, j->o, s, err) != 0 || load_other_captures(j->cfg, j->o, s, err) != 0))
        return -1;
    return rs_skyenv_build_opts(&s->cap, s->ids->data, &s->so, &s->env, &s->info, err);
}

/* Collective: sky_map_build on rank 0, its map on every rank. */
static int sky_map_run(const rs_config *cfg, const rs_irradiance_opts *o, rs_irradiance_state *s, rs_err *err)
{
    sky_map_job job = {cfg, o, s};
    if (rs_par_root_run(sky_map_build, &job, err) != 0) return -1;
    return rs_irradiance_share_sky_map(&s->env, &s->info, &s->sun, err);
}

/* The sky map: the explicit sun set up (its disc leaves the capture; every rank's copy of the
 * capture needs that), the map built (sky_map_run), then the sun's last word
 * (rs_sunsource_auto). */
static int build_sky_map(const rs_config *cfg, const rs_irradiance_opts *o, rs_irradiance_state *s, rs_report *rep,
                         rs_err *err)
{
    double t0 = rs_now();
    s->so = o->sky;
    if (rs_irradiance_setup_sun(o, s, err) != 0 || sky_map_run(cfg, o, s, err) != 0) return -1;
    rs_irradiance_sun_auto(o, s);
    for (int i = 0; i < s->nothers; i++)
        rs_log_info("irradiance: capture %s: exposure factor %.4g %.4g %.4g from %.3g sr of shared sky",
                    s->others[i].path, s->info.other_scale[i][0], s->info.other_scale[i][1], s->info.other_scale[i][2],
                    s->info.other_overlap_sr[i]);
    if (s->nothers) rs_log_info("irradiance: further captures gave %zu map pixels", s->info.other_pixels);
    rs_report_time(rep, "sky_map", rs_now() - t0);
    log_sky_map(o, s, rep);
    return 0;
}

/* The gather's context over the sky map and the observed radiance. */
static void gather_context(const rs_irradiance_opts *o, rs_irradiance_state *s)
{
    s->g = (rs_gather_ctx){.scene = s->scene,
                           .env = &s->env,
                           .cap = &s->cap,
                           .facet_id = s->ids->data,
                           .samples = o->samples,
                           .sky_samples = o->sky_samples,
                           .sun_samples = o->sun_samples,
                           .seed = o->seed,
                           .sun_target_error = o->sun_target_error,
                           .skip_convex = o->skip_convex,
                           .relay_share = o->relay_share,
                           .target_error = o->target_error,
                           .radiance = s->radiance,
                           .observed = s->observed};
}

typedef struct {
    const rs_skyenv *env;
    rs_irradiance_pass *p;
} sky_sh_job;

/* The sky's harmonics and their test: rank 0's alone under MPI (a pass over the map). */
static int sky_sh_build(void *ctx, rs_err *err)
{
    sky_sh_job *j = ctx;
    return rs_skysh_build(j->env, j->p->sh_tol, 256, &j->p->sh, err);
}

/* One gather into s->fg (zeroed) and s->pass; s->g.sky_sh points into s->pass. suffix names its
 * timings. */
static int gather_pass_run(const rs_irradiance_opts *o, rs_irradiance_state *s, rs_report *rep, const char *suffix,
                           rs_err *err)
{
    rs_gather_ctx *g = &s->g;
    rs_irradiance_pass *p = &s->pass;
    const rs_image *ids = s->ids;
    size_t nf = s->nf;
    char key[64];
    memset(p, 0, sizeof *p);
    g->sky_sh = NULL;
    p->sh_tol = o->sh_max_error;
    p->sh_candidates = g->skip_convex && p->sh_tol > 0 ? rs_skysh_candidates(g->scene) : 0;
    double t0;
    if (p->sh_candidates) { /* the test costs a pass over the map: only when a facet can use it */
        t0 = rs_now();
        sky_sh_job job = {g->env, p};
        if (rs_par_root_run(sky_sh_build, &job, err) != 0) return -1;
        rs_irradiance_share_sky_sh(&p->sh);
        snprintf(key, sizeof key, "sky_sh%s", suffix);
        rs_report_time(rep, key, rs_now() - t0);
        if (p->sh.usable) g->sky_sh = &p->sh;
    }
    /* [irradiance] skip_unseen: only what a camera sees and what lights it (rs_gather_run). */
    uint8_t *needed = o->skip_unseen ? calloc(nf, 1) : NULL;
    if (needed) {
        for (size_t k = 0; k < (size_t)ids->width * ids->height; k++)
            if (ids->data[k] >= 0 && ids->data[k] < (float)nf) needed[(size_t)ids->data[k]] = 1;
        for (size_t f = 0; f < nf; f++) needed[f] |= g->observed[f];
    }
    t0 = rs_now();
    rs_progress *prog = rs_progress_start("irradiance: gather", nf);
    int failed = o->skip_unseen && !needed ? rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory during the gather")
                                           : rs_gather_run(g, nf, needed, s->fg, NULL, prog, &p->gs, err);
    free(needed);
    rs_progress_end(prog);
    p->seconds = rs_now() - t0;
    snprintf(key, sizeof key, "gather%s", suffix);
    rs_report_time(rep, key, p->seconds);
    if (failed) return -1;
    /* Before the explicit sun is added: the second gather has no sun term, and its difference
     * from the first must be noise alone (with the sun in one of them the factor was 12 to 24). */
    t0 = rs_now();
    if (rs_gather_mc_calibration(g, nf, s->fg, g->radiance, g->observed, 512, &p->mc_factor, &p->mc_facets, err) != 0)
        return -1;
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
static int ground_from_scan(const rs_irradiance_opts *o, rs_irradiance_state *s, rs_report *rep, rs_err *err)
{
    const rs_gather_ctx *g = &s->g;
    rs_skyenv *env = &s->env;
    const rs_skyenv_opts *so = &s->so;
    const rs_skyfill_report *fill = &s->info.fill;
    const rs_sunsource *sun = &s->sun;
    if (so->fill.method != RS_SKYFILL_MODEL || !fill->ground_model_pixels) return 0;
    rs_json_set_int(rep->metrics, "sky_ground_model_pixels", (long long)fill->ground_model_pixels);
    const char *from = "config", *why = NULL;
    char few[160];
    double albedo[3] = {so->fill.ground_albedo, so->fill.ground_albedo, so->fill.ground_albedo};
    rs_skyground gr = {0};
    if (!o->ground_from_scan) {
        /* as asked */
    } else if (sun->active) {
        why = "an explicit sun is added after the gather, so the ground's own E would miss it";
    } else if (sun->search && !(rs_irradiance_sky_glow(fill, so->fill.method) < RS_SUNSEARCH_MIN_GLOW)) {
        why = "a sun no camera saw may be found in the shadows after the gather, and the ground's own E would miss it";
    } else {
        double t0 = rs_now();
        if (rs_skyground_albedo(g, s->mesh, g->radiance, g->observed, &gr, err) != 0) return -1;
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
        if (rs_skyenv_set_ground(env, rgb, so->explicit_sun, err) < 0) return -1;
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
        long n = rs_skyenv_ground_from_bands(env, so->explicit_sun, err);
        if (n < 0) return -1;
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

/* The model fill placed its sun where the visible sky's glow put it, degrees from where the
 * shadows do: fitted again around the searched sun, the circumsolar sky and so the E that the
 * DNI estimate divides by move with it (street canyon: 12.6 % -> 10.8 % albedo error). So the
 * map is built again and the facets gathered again. */
static int regather_around_searched_sun(const rs_irradiance_opts *o, rs_irradiance_state *s, rs_report *rep,
                                        rs_err *err)
{
    rs_log_info("irradiance: the sky model fitted again around the searched sun (%.1f deg from its first "
                "direction), and the facets gathered again",
                s->sun.found_off_deg);
    s->so.fill.sun_given = 1;
    s->so.fill.sun_dir = s->sun.dir_world;
    rs_skyenv_release(&s->env);
    double t0 = rs_now();
    if (sky_map_run(NULL, o, s, err) != 0) return -1;
    rs_report_time(rep, "sky_map_searched_sun", rs_now() - t0);
    s->info.fill.sun_source = RS_SUN_SHADOWS;
    /* The sun is explicit now: the unseen ground copies the measured ground, as the first map's
     * did (ground_from_scan said why), unless the config asked for its albedo. */
    if (o->ground_from_scan && rs_skyenv_ground_from_bands(&s->env, s->so.explicit_sun, err) < 0) return -1;
    s->first_pass_rays = s->pass.gs.rays;
    for (size_t f = 0; f < s->nf; f++) free(s->fg[f].entries);
    memset(s->fg, 0, s->nf * sizeof *s->fg);
    return gather_pass_run(o, s, rep, "_searched_sun", err);
}

static void release_state(rs_irradiance_state *s)
{
    if (s->fg)
        for (size_t f = 0; f < s->nf; f++) free(s->fg[f].entries);
    free(s->fg);
    free(s->radiance);
    free(s->observed);
    rs_image_free(s->ids);
    rs_skyenv_release(&s->env);
    rs_scene_free(s->scene);
    rs_mesh_free(s->occ);
    free(s->occ_proxy);
    rs_capture_release(&s->cap);
    rs_capture_release(&s->sky);
    free(s->sky_mask);
    for (int i = 0; i < s->nothers; i++) {
        rs_capture_release(&s->others[i]);
        free(s->other_masks[i]);
    }
    rs_mesh_free(s->mesh);
}

typedef struct {
    const rs_config *cfg;
    const rs_irradiance_opts *o;
    rs_irradiance_state *s;
    rs_report *rep;
} finish_job;

/* The hidden sky's check against the facets, the report and the files: rank 0's alone (the
 * check's robust fits cost seconds at 10^5 facets and need no other rank). */
static int finish(void *ctx, rs_err *err)
{
    finish_job *j = ctx;
    if (rs_irradiance_skyscale(j->o, j->s, j->rep, err) != 0) return -1;
    double fill_rate = rs_skyfill_rate_used(&j->s->info.fill, j->s->so.fill.method);
    rs_irradiance_report(j->o, j->s, fill_rate, j->rep);
    return rs_irradiance_write(j->cfg, j->s, fill_rate, j->rep, err);
}

int rs_irradiance_run(const rs_config *cfg, rs_report *rep, rs_err *err)
{
    rs_irradiance_opts o;
    if (read_opts(cfg, &o, err) != 0) return -1;
    rs_irradiance_state s;
    memset(&s, 0, sizeof s);
    int rc = -1;
    if (load_inputs(cfg, &s, rep, err) != 0 || build_sky_map(cfg, &o, &s, rep, err) != 0 ||
        rs_irradiance_close(cfg, &s, rep, err) != 0)
        goto out;
    if (!(s.fg = calloc(s.nf, sizeof *s.fg))) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu facets", s.nf);
        goto out;
    }
    gather_context(&o, &s);
    if (ground_from_scan(&o, &s, rep, err) != 0 || gather_pass_run(&o, &s, rep, "", err) != 0) goto out;
    if (s.sun.search && rs_irradiance_search_sun(&o, &s, rep, err) != 0) goto out;
    if (s.sun.searched && s.so.fill.method == RS_SKYFILL_MODEL && s.info.fill.fit_samples &&
        regather_around_searched_sun(&o, &s, rep, err) != 0)
        goto out;
    if (s.sun.active && rs_irradiance_explicit_sun(&o, &s, rep, err) != 0) goto out;
    finish_job job = {cfg, &o, &s, rep};
    rc = rs_par_root_run(finish, &job, err); /* MPI: nothing after this is collective */
out:
    release_state(&s);
    return rc;
}
