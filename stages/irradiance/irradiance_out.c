/* irradiance_out: the irradiance stage's report and files (see irradiance_out.h). */
#include "stages/irradiance/irradiance_out.h"

#include <stdlib.h>
#include "common/faceprop.h"
#include "common/log.h"
#include "common/ply.h"
#include "light/kernel_out.h"
#include "stages/irradiance/irradiance_sun.h"

/* The gather's figures: what it left out and why, its harmonics, its rays. */
static void report_gather(const rs_irradiance_state *s, rs_report *rep)
{
    const rs_irradiance_pass *p = &s->pass;
    const rs_gather_ctx *g = &s->g;
    const rs_facet_gather *fg = s->fg;
    size_t nf = s->nf;
    if (p->gs.gathered < nf)
        rs_report_skip(rep, "gather of unseen facets",
                       "%zu facets that no camera sees light no facet it sees "
                       "(closure of the light paths in %d waves)",
                       nf - p->gs.gathered, p->gs.waves);
    if (p->gs.sees_nothing)
        rs_report_skip(rep, "tracing of convex facets",
                       "%zu facets have the whole model below their plane: "
                       "their rays escape without tracing",
                       p->gs.sees_nothing);
    if (p->gs.relays)
        rs_report_skip(rep, "full ray counts for relays",
                       "%zu facets that no camera sees, gathered for their light on "
                       "seen ones, traced %g of the rays ([irradiance] relay_share)",
                       p->gs.relays, g->relay_share);
    rs_json_set_int(rep->metrics, "facets_gathered", (long long)p->gs.gathered);
    rs_json_set_int(rep->metrics, "facets_relays", (long long)p->gs.relays);
    rs_json_set_int(rep->metrics, "facets_seeing_nothing", (long long)p->gs.sees_nothing);
    size_t nsh = 0;
    for (size_t f = 0; f < nf; f++) nsh += fg[f].sky_sh;
    rs_json_set_int(rep->metrics, "facets_sky_sh", (long long)nsh);
    rs_json_set_num(rep->metrics, "sky_sh_max_error", p->sh.max_error);
    rs_json_set_num(rep->metrics, "sky_sh_max_error_filled", p->sh.max_error_filled);
    rs_json_set_num(rep->metrics, "sky_sh_passed_share", p->sh.passed_share);
    if (!g->skip_convex || !(p->sh_tol > 0))
        rs_report_skip(rep, "sky harmonics", "[irradiance] %s: every facet gathers with rays",
                       g->skip_convex ? "sh_max_error = 0" : "skip_convex = false");
    else if (!p->sh_candidates)
        rs_report_skip(rep, "sky harmonics", "no facet has the whole model below its plane");
    else if (!p->sh.usable)
        rs_report_skip(rep, "sky harmonics",
                       "the sky map's order-2 irradiance is off by more than [irradiance] "
                       "sh_max_error = %g at every one of %d normals (up to %.2f %%, at %.2f %.2f %.2f): facets that "
                       "see only sky gather with rays",
                       p->sh.tol, p->sh.normals, 100 * p->sh.max_error, p->sh.worst_normal.x, p->sh.worst_normal.y,
                       p->sh.worst_normal.z);
    else
        rs_log_info("irradiance: %zu of %zu facets that see only sky took E_sky from the sky's order-2 harmonics, "
                    "no rays (error within %g on %.0f %% of the normals, up to %.2f %% at %.2f %.2f %.2f); the other "
                    "%zu face a normal above that or cut the sun set's cone, and gathered",
                    nsh, p->gs.sees_nothing, p->sh.tol, 100 * p->sh.passed_share, 100 * p->sh.max_error,
                    p->sh.worst_normal.x, p->sh.worst_normal.y, p->sh.worst_normal.z, p->gs.sees_nothing - nsh);
    double rays = p->gs.rays + s->first_pass_rays;
    rs_json_set_num(rep->metrics, "rays", rays);
    rs_json_set_num(rep->metrics, "rays_per_second", p->seconds > 0 ? p->gs.rays / p->seconds : 0);
    if (g->target_error > 0) {
        size_t refined = 0, capped = 0;
        for (size_t f = 0; f < nf; f++) {
            refined += fg[f].rounds > 0;
            capped += fg[f].rounds == RS_GATHER_MAX_ROUNDS;
        }
        rs_json_set_int(rep->metrics, "facets_refined", (long long)refined);
        rs_json_set_int(rep->metrics, "facets_refined_to_cap", (long long)capped);
        rs_log_info("irradiance: target_error %g: %zu facets took more rays than the base counts, %zu of them "
                    "%d x (the cap)",
                    g->target_error, refined, capped, 1 << RS_GATHER_MAX_ROUNDS);
    }
}

/* The sky map's figures, what completed it, and the sun's. */
static void report_sky(const rs_irradiance_opts *o, const rs_irradiance_state *s, rs_report *rep)
{
    const rs_skyenv *env = &s->env;
    const rs_skyenv_info *info = &s->info;
    const rs_skyenv_opts *so = &s->so;
    int nothers = s->nothers;
    rs_json_set_int(rep->metrics, "sky_pixels", (long long)env->sky_pixels);
    rs_json_set_int(rep->metrics, "filled_pixels", (long long)env->filled_pixels);
    rs_json_set_int(rep->metrics, "bright_pixels", (long long)env->bright_pixels);
    rs_json_set_num(rep->metrics, "bright_solid_angle_sr", env->bright_sr);
    rs_json_set_num(rep->metrics, "sky_median_luminance", env->sky_median);
    rs_json_set_str(rep->metrics, "sky_fill", o->fill_name);
    rs_json_set_num(rep->metrics, "sky_fill_sigma", env->fill_sigma);
    rs_json_set_num(rep->metrics, "sky_cv_rel_row", info->fill.cv_rel_row);
    rs_json_set_num(rep->metrics, "sky_cv_rel_model", info->fill.cv_rel_model);
    rs_json_set_int(rep->metrics, "sky_cv_blocks", info->fill.cv_folds);
    rs_json_set_str(rep->metrics, "sun_source", rs_irradiance_sun_source_name(info->fill.sun_source));
    rs_irradiance_report_sun(&s->sun, rep->metrics);
    rs_json *sd = rs_json_set_arr(rep->metrics, "sun_direction");
    rs_json_push_num(sd, info->fill.sun_dir.x);
    rs_json_push_num(sd, info->fill.sun_dir.y);
    rs_json_push_num(sd, info->fill.sun_dir.z);
    if (so->fill.method == RS_SKYFILL_MODEL) {
        rs_json_set_int(rep->metrics, "sky_model_sh_order", info->fill.model.sh_order);
        rs_json_set_num(rep->metrics, "sky_model_fit_rms_log", info->fill.model.fit_rms_log);
        rs_json *pz = rs_json_set_arr(rep->metrics, "sky_model_perez_green"); /* a b c d e */
        for (int k = 0; k < 5; k++) rs_json_push_num(pz, info->fill.model.perez[1][k]);
        rs_json_set_int(rep->metrics, "sky_ground_from_albedo", info->fill.ground_from_albedo);
    }
    if (nothers) {
        rs_json_set_int(rep->metrics, "sky_other_capture_pixels", (long long)info->other_pixels);
        /* Each further capture's exposure factor (capture / it, per channel) under its section's
         * name: the texture stage brings their radiance to the capture's exposure with them. */
        rs_json *ce = rs_json_set_obj(rep->metrics, "capture_exposure");
        for (int i = 0; i < nothers; i++) {
            rs_json *a = rs_json_set_arr(ce, s->other_names[i]);
            for (int ch = 0; ch < 3; ch++) rs_json_push_num(a, info->other_scale[i][ch]);
        }
    }
    if (s->sky.pano) {
        rs_json_set_int(rep->metrics, "sky_panorama_pixels", (long long)info->sky_pano_pixels);
        rs_json_set_num(rep->metrics, "sky_panorama_overlap_sr", info->sky_overlap_sr);
        rs_json *sc = rs_json_set_arr(rep->metrics, "sky_panorama_exposure");
        for (int ch = 0; ch < 3; ch++) rs_json_push_num(sc, info->sky_pano_scale[ch]);
    }
}

/* The share of E_sky filled in, over the model's area, and the fill's uncertainty: as a flat
 * figure, per square root of radian from the measured sky (fill_rate), and as the facets used it. */
static void report_fill(const rs_irradiance_state *s, double fill_rate, rs_report *rep)
{
    const rs_skyenv_info *info = &s->info;
    const rs_skyenv_opts *so = &s->so;
    const rs_facet_gather *fg = s->fg;
    const rs_mesh *mesh = s->mesh;
    size_t nf = s->nf;
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
     * their RMS (env->fill_sigma), stay in the metrics for comparison. */
    int use_model = so->fill.method == RS_SKYFILL_MODEL && info->fill.fit_samples;
    double fill_unc =
        rs_skyfill_sigma_from_blocks(info->fill.cv_folds, use_model ? info->fill.cv_max_model : info->fill.cv_max_row);
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
    rs_json_set_num(rep->metrics, "sky_cv_max_row", info->fill.cv_max_row);
    rs_json_set_num(rep->metrics, "sky_cv_max_model", info->fill.cv_max_model);
}

void rs_irradiance_report(const rs_irradiance_opts *o, const rs_irradiance_state *s, double fill_rate, rs_report *rep)
{
    report_gather(s, rep);
    report_sky(o, s, rep);
    report_fill(s, fill_rate, rep);
}

/* irradiance.ply's facet columns beside the mesh: colours 3 per facet, the others 1. */
typedef struct facet_columns {
    double *esky, *g, *gseen, *esun; /* E_sky, G from observed facets, G read from the panorama, E_sun */
    double *filled, *sigma, *mc;     /* sky_filled, irradiance_sky_sigma, irradiance_mc_sigma */
    double *inv_dist, *gathered;     /* hit_distance_inv, gathered */
} facet_columns;

static void columns_free(facet_columns *c)
{
    free(c->esky);
    free(c->g);
    free(c->gseen);
    free(c->filled);
    free(c->sigma);
    free(c->mc);
    free(c->esun);
    free(c->inv_dist);
    free(c->gathered);
}

/* 0, or -1 when out of memory (c then holds what it got, for columns_free). */
static int columns_alloc(facet_columns *c, size_t nf)
{
    c->esky = malloc(3 * nf * sizeof *c->esky);
    c->g = malloc(3 * nf * sizeof *c->g);
    c->gseen = malloc(3 * nf * sizeof *c->gseen);
    c->filled = malloc(nf * sizeof *c->filled);
    c->sigma = malloc(nf * sizeof *c->sigma);
    c->mc = malloc(nf * sizeof *c->mc);
    c->esun = malloc(3 * nf * sizeof *c->esun);
    c->inv_dist = malloc(nf * sizeof *c->inv_dist);
    c->gathered = malloc(nf * sizeof *c->gathered);
    return c->esky && c->g && c->gseen && c->filled && c->sigma && c->mc && c->esun && c->inv_dist && c->gathered ? 0
                                                                                                                  : -1;
}

static void columns_fill(facet_columns *c, const rs_irradiance_state *s)
{
    const rs_facet_gather *fg = s->fg;
    const double *radiance = s->radiance;
    double mc_factor = s->pass.mc_factor;
    const uint8_t *observed = s->observed;
    for (size_t f = 0; f < s->nf; f++) {
        for (int ch = 0; ch < 3; ch++) {
            c->esky[3 * f + ch] = fg[f].esky[ch];
            c->esun[3 * f + ch] = fg[f].esun[ch];
            c->gseen[3 * f + ch] = fg[f].gseen[ch];
        }
        c->inv_dist[f] = fg[f].inv_dist;
        c->gathered[f] = fg[f].rays > 0 || fg[f].sky_sh;
        rs_gather_inter_observed(&fg[f], radiance, observed, c->g + 3 * f);
        c->filled[f] = fg[f].esky_lum > 0 ? fg[f].filled_lum / fg[f].esky_lum : 0;
        c->sigma[f] = fg[f].fill_sigma_lum; /* rs_facet_gather: summed, not in quadrature */
        /* Monte Carlo noise of E_sky + G (rays toward unobserved facets count 0 here), the
         * independent-sample formula scaled by what a second seed showed (rs_gather_mc_calibration). */
        c->mc[f] = mc_factor * rs_gather_mc_sigma(&fg[f], radiance, observed);
        if (fg[f].sky_sh) c->mc[f] = fg[f].sh_sigma; /* no rays: the projection's measured error bound */
    }
}

/* The columns onto the mesh's faces; 0, or -1 when out of memory. */
static int columns_add(rs_ply_element *faces, const facet_columns *c)
{
    if (!faces || rs_faceprop_add_rgb(faces, "irradiance_sky", c->esky) != 0 ||
        rs_faceprop_add_rgb(faces, "irradiance_inter", c->g) != 0 ||
        rs_faceprop_add_rgb(faces, "irradiance_inter_seen", c->gseen) != 0 ||
        !rs_ply_add_scalar(faces, "sky_filled", RS_PLY_FLOAT32, c->filled) ||
        !rs_ply_add_scalar(faces, "irradiance_sky_sigma", RS_PLY_FLOAT32, c->sigma) ||
        !rs_ply_add_scalar(faces, "irradiance_mc_sigma", RS_PLY_FLOAT32, c->mc) ||
        rs_faceprop_add_rgb(faces, "irradiance_sun", c->esun) != 0 ||
        !rs_ply_add_scalar(faces, "hit_distance_inv", RS_PLY_FLOAT32, c->inv_dist) ||
        !rs_ply_add_scalar(faces, "gathered", RS_PLY_UINT8, c->gathered))
        return -1;
    return 0;
}

/* What the columns mean, in the file. */
static void add_comments(rs_ply *ply, double fill_rate, double mc_factor)
{
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
}

int rs_irradiance_write(const rs_config *cfg, const rs_irradiance_state *s, double fill_rate, rs_report *rep,
                        rs_err *err)
{
    size_t ne = 0;
    facet_columns cols = {0};
    rs_ply *ply = rs_ply_new();
    int rc = -1;
    char path[4096];
    if (columns_alloc(&cols, s->nf) != 0 || !ply) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory writing the irradiance outputs");
        goto out;
    }
    columns_fill(&cols, s);
    if (columns_add(rs_mesh_to_ply(s->mesh, ply), &cols) != 0) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory building irradiance.ply");
        goto out;
    }
    add_comments(ply, fill_rate, s->pass.mc_factor);
    if (rs_ply_write(ply, rs_work_path(cfg, "irradiance.ply", path, sizeof path), 1, err) != 0) goto out;

    rs_ply_free(ply); /* before the kernel's file, streamed from the rows (kernel_out.c) */
    ply = NULL;
    if (rs_kernel_write(rs_work_path(cfg, "transport.ply", path, sizeof path), s->fg, s->nf, &ne, err) != 0) goto out;
    rs_json_set_int(rep->metrics, "kernel_entries", (long long)ne);
    rc = 0;
out:
    rs_ply_free(ply);
    columns_free(&cols);
    return rc;
}
