/* irradiance: per facet, one hemisphere gather with Embree gives
 *   E_sky,i = integral of L_env(w) V_i(w) cos dw   (rays that escape read the sky map), and
 *   G_i     = sum_j K_ij L_j                        (rays that hit facet j),
 * with cosine-weighted Owen-scrambled Sobol directions from Sobol points spread over the facet,
 * plus shadow rays toward the bright sky pixels (the sun), which cosine rays would miss.
 * Where the camera sees a hit point, G reads the panorama there (sub-facet detail); elsewhere
 * it goes through K and the hit facet's mean radiance. Writes irradiance.ply (mesh + E_sky, G,
 * G from panorama readings, sky_filled) and transport.ply (the sparse K: per (i, j) the total
 * weight and the weight not read from the panorama). */
#include <stdlib.h>
#include <string.h>
#include "capture.h"
#include "faceprop.h"
#include "log.h"
#include "sampling.h"
#include "scene.h"
#include "gather.h"
#include "skyenv.h"
#include "stages.h"

static int write_outputs(const rs_config *cfg, const rs_mesh *mesh, const rs_facet_gather *fg,
                         const double *radiance, const uint8_t *observed, rs_report *rep, rs_err *err)
{
    size_t nf = mesh->nfaces, ne = 0;
    for (size_t f = 0; f < nf; f++) ne += fg[f].nentries;
    double *esky = malloc(3 * nf * sizeof *esky), *g = malloc(3 * nf * sizeof *g),
           *gseen = malloc(3 * nf * sizeof *gseen), *filled = malloc(nf * sizeof *filled);
    double *row = malloc((ne ? ne : 1) * sizeof *row), *col = malloc((ne ? ne : 1) * sizeof *col),
           *kt = malloc((ne ? ne : 1) * sizeof *kt), *ku = malloc((ne ? ne : 1) * sizeof *ku);
    rs_ply *ply = rs_ply_new(), *tp = rs_ply_new();
    int rc = -1;
    char path[4096];
    if (!esky || !g || !gseen || !filled || !row || !col || !kt || !ku || !ply || !tp) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory writing the irradiance outputs");
        goto out;
    }
    size_t e = 0;
    for (size_t f = 0; f < nf; f++) {
        for (int ch = 0; ch < 3; ch++) {
            esky[3 * f + ch] = fg[f].esky[ch];
            gseen[3 * f + ch] = fg[f].gseen[ch];
            g[3 * f + ch] = fg[f].gseen[ch];
        }
        filled[f] = fg[f].esky_lum > 0 ? fg[f].filled_lum / fg[f].esky_lum : 0;
        for (uint32_t q = 0; q < fg[f].nentries; q++, e++) {
            const rs_kentry *en = &fg[f].entries[q];
            row[e] = (double)f;
            col[e] = en->col;
            kt[e] = en->k;
            ku[e] = en->k_unseen;
            if (observed[en->col])      /* unobserved facets are the reflectance stage's job */
                for (int ch = 0; ch < 3; ch++) g[3 * f + ch] += en->k_unseen * radiance[3 * en->col + ch];
        }
    }
    rs_ply_element *faces = rs_mesh_to_ply(mesh, ply);
    if (!faces || rs_faceprop_add_rgb(faces, "irradiance_sky", esky) != 0 ||
        rs_faceprop_add_rgb(faces, "irradiance_inter", g) != 0 ||
        rs_faceprop_add_rgb(faces, "irradiance_inter_seen", gseen) != 0 ||
        !rs_ply_add_scalar(faces, "sky_filled", RS_PLY_FLOAT32, filled)) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory building irradiance.ply");
        goto out;
    }
    rs_ply_add_comment(ply, "rhoscan %s irradiance: E_sky and G (W m^-2 per unit radiance scale); "
                            "irradiance_inter counts observed facets only", RHOSCAN_VERSION);
    if (rs_ply_write(ply, rs_work_path(cfg, "irradiance.ply", path, sizeof path), 1, err) != 0) goto out;

    rs_ply_element *tr = rs_ply_add_element(tp, "transport", ne);
    if (!tr || !rs_ply_add_scalar(tr, "row", RS_PLY_UINT32, row) ||
        !rs_ply_add_scalar(tr, "col", RS_PLY_UINT32, col) || !rs_ply_add_scalar(tr, "k", RS_PLY_FLOAT32, kt) ||
        !rs_ply_add_scalar(tr, "k_unseen", RS_PLY_FLOAT32, ku)) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory building transport.ply");
        goto out;
    }
    rs_ply_add_comment(tp, "rhoscan %s sparse interreflection kernel: G_i = sum_j k L_j (k in sr)", RHOSCAN_VERSION);
    rs_ply_add_comment(tp, "rhoscan_facets %zu", nf);
    if (rs_ply_write(tp, rs_work_path(cfg, "transport.ply", path, sizeof path), 1, err) != 0) goto out;
    rs_json_set_int(rep->metrics, "kernel_entries", (long long)ne);
    rc = 0;
out:
    rs_ply_free(ply);
    rs_ply_free(tp);
    free(esky);
    free(g);
    free(gseen);
    free(filled);
    free(row);
    free(col);
    free(kt);
    free(ku);
    return rc;
}

int rs_irradiance_run(const rs_config *cfg, rs_report *rep, rs_err *err)
{
    char path[4096];
    int rc = -1;
    rs_capture cap = {0};
    rs_skyenv env = {0};
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
        rs_err_set(err, RS_ERR_INPUT, id_path, 0, "is %dx%d with %d channels: expected %dx%d, 1 channel "
                   "(rerun observe)", ids->width, ids->height, ids->channels, cap.pano->width, cap.pano->height);
        goto out;
    }
    int sun_samples = (int)rs_config_int(cfg, "irradiance", "sun_samples");
    double t0 = rs_now();
    double cone = rs_config_real(cfg, "irradiance", "sun_max_cone_deg") * M_PI / 180;
    if (rs_skyenv_build(&cap, ids->data, rs_config_real(cfg, "irradiance", "sun_threshold"),
                        2 * M_PI * (1 - cos(cone)), sun_samples > 0 || rs_config_int(cfg, "irradiance", "sky_samples") > 0,
                        &env, err) != 0)
        goto out;
    rs_report_time(rep, "sky_map", rs_now() - t0);
    rs_log_info("irradiance: sky %zu pixels (median luminance %.4g), %zu filled, %zu bright kept out of the fill",
                env.sky_pixels, env.sky_median, env.filled_pixels, env.bright_pixels);
    if (!sun_samples)
        rs_report_skip(rep, "sun sampling", "[irradiance] sun_samples = 0: cosine-weighted rays only");
    else if (!env.sun_cdf)
        rs_report_skip(rep, "sun sampling", "no sky pixel is brighter than %g x the median sky",
                       rs_config_real(cfg, "irradiance", "sun_threshold"));

    t0 = rs_now();
    if (!(scene = rs_scene_new(mesh, err))) goto out;
    rs_report_time(rep, "bvh", rs_now() - t0);
    rs_gather_ctx g = {scene, &env, &cap, ids->data, (int)rs_config_int(cfg, "irradiance", "samples"),
                    (int)rs_config_int(cfg, "irradiance", "sky_samples"), sun_samples, (uint32_t)rs_config_int(cfg, "irradiance", "seed"),
                    rs_config_real(cfg, "irradiance", "sun_target_error"), rs_config_bool(cfg, "irradiance", "skip_convex")};
    fg = calloc(nf, sizeof *fg);
    if (!fg) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu facets", nf);
        goto out;
    }
    /* [irradiance] skip_unseen: only what a camera sees and what lights it (rs_gather_run). */
    uint8_t *needed = rs_config_bool(cfg, "irradiance", "skip_unseen") ? calloc(nf, 1) : NULL;
    if (needed) {
        for (size_t k = 0; k < (size_t)ids->width * ids->height; k++)
            if (ids->data[k] >= 0 && ids->data[k] < (float)nf) needed[(size_t)ids->data[k]] = 1;
        for (size_t f = 0; f < nf; f++) needed[f] |= observed[f];
    }
    rs_gather_stats gs;
    t0 = rs_now();
    rs_progress *prog = rs_progress_start("irradiance: gather", nf);
    int failed = (rs_config_bool(cfg, "irradiance", "skip_unseen") && !needed) ||
                 rs_gather_run(&g, nf, needed, fg, NULL, prog, &gs) != 0;
    free(needed);
    rs_progress_end(prog);
    double gather_s = rs_now() - t0;
    rs_report_time(rep, "gather", gather_s);
    if (failed) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory during the gather");
        goto out;
    }
    if (gs.gathered < nf)
        rs_report_skip(rep, "gather of unseen facets", "%zu facets that no camera sees light no facet it sees "
                       "(closure of the light paths in %d waves)", nf - gs.gathered, gs.waves);
    if (gs.sees_nothing)
        rs_report_skip(rep, "tracing of convex facets", "%zu facets have the whole model below their plane: "
                       "their rays escape without tracing", gs.sees_nothing);
    rs_json_set_int(rep->metrics, "facets_gathered", (long long)gs.gathered);
    rs_json_set_int(rep->metrics, "facets_seeing_nothing", (long long)gs.sees_nothing);
    double rays = gs.rays;
    rs_json_set_num(rep->metrics, "rays", rays);
    rs_json_set_num(rep->metrics, "rays_per_second", gather_s > 0 ? rays / gather_s : 0);
    rs_json_set_int(rep->metrics, "sky_pixels", (long long)env.sky_pixels);
    rs_json_set_int(rep->metrics, "filled_pixels", (long long)env.filled_pixels);
    rs_json_set_int(rep->metrics, "bright_pixels", (long long)env.bright_pixels);
    rs_json_set_num(rep->metrics, "bright_solid_angle_sr", env.bright_sr);
    rs_json_set_num(rep->metrics, "sky_median_luminance", env.sky_median);
    double fl = 0, el = 0;
    for (size_t f = 0; f < nf; f++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(mesh, f, &c, &n, &a);
        fl += a * fg[f].filled_lum;
        el += a * fg[f].esky_lum;
    }
    rs_json_set_num(rep->metrics, "sky_filled_share", el > 0 ? fl / el : 0);
    rc = write_outputs(cfg, mesh, fg, radiance, observed, rep, err);
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
    rs_mesh_free(mesh);
    return rc;
}
