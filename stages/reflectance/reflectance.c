/* reflectance: albedo per facet, rho_i = pi L_i / E_i, with
 *   direct:          E_i = E_sky,i                       (Okura et al. 2008 baseline)
 *   interreflection: E_i = E_sky,i + G_i, G from the gather (panorama readings where the camera
 *                    sees the hit point, else K_ij times facet j's radiance)
 *   paper:           E_i = E_sky,i + sum_j K_ij L_j with the paper's dense point-to-point K.
 * With [reflectance] pool_accuracy > 0 (not paper), an observed facet's E is its sun's part plus
 * the weighted mean of the rest over its neighbours of the same plane (pool.h): less Monte Carlo
 * noise, and albedo.ply carries that E.
 * Facets the camera does not see still light their neighbours: their radiance is modelled as
 * rho_fill (E_sky + G) / pi, rho_fill being [reflectance] unobserved_albedo or the
 * area-weighted mean albedo of the estimable facets facing the same way (up, down or sideways),
 * solved together by fixed-point iteration.
 * Writes albedo.ply with the face properties of docs/DESIGN.md, section File contract, plus the sky completion's
 * share (sky_filled), E_sky's fill uncertainty (irradiance_sky_sigma) and the albedo's standard
 * uncertainty, independent sources in quadrature:
 *   albedo_sigma_rel = sqrt(floor^2 + radiance_sigma_rel^2
 *                           + (irradiance_sky_sigma^2 + irradiance_mc_sigma^2) / E^2),
 * E = E_sky + G in luminance; radiance_sigma_rel is the observation noise of L (observe.ply),
 * irradiance_mc_sigma the gather's Monte Carlo noise, floor = [reflectance] albedo_sigma_floor
 * (what is not modelled: mesh, calibration). albedo_bound80_rel = 1.2816 albedo_sigma_rel
 * bounds the error with 80 % probability (two-sided, normal error); albedo_sigma is
 * albedo_sigma_rel times the facet's mean albedo over the channels. */
#include <stdlib.h>
#include <string.h>
#include "common/faceprop.h"
#include "stages/reflectance/greycard.h"
#include "common/image.h"
#include "common/log.h"
#include "stages/reflectance/paper.h"
#include "stages/reflectance/pool.h"
#include "stages/stages.h"
#include "light/transport.h"

/* Unobserved facets take the albedo measured on facets facing the same way: ground and roofs,
 * walls, ceilings and soffits differ in material far more often than walls among themselves.
 * A class's mean is shrunk toward the mean of all by a prior worth RS_FILL_PRIOR_SHARE of the
 * estimable area, so a class seen on a few facets does not take their noise. */
enum { RS_FILL_UP, RS_FILL_SIDE, RS_FILL_DOWN, RS_FILL_CLASSES };
static const char *const fill_class_name[RS_FILL_CLASSES] = {"up", "side", "down"};
#define RS_FILL_CLASS_COS   0.70710678 /* normal within 45 degrees of straight up or down */
#define RS_FILL_PRIOR_SHARE 0.01

typedef struct {
    size_t nf;
    const double *area, *L, *esky, *gseen;
    const double *sky_filled, *esky_sigma, *mc_sigma; /* from irradiance.ply */
    const double *L_sigma_rel;                        /* from observe.ply */
    double sigma_floor;
    const uint8_t *observed;
    const rs_transport *K; /* gather kernel (interreflection) */
    const float *dense;    /* paper kernel, m * m (paper) */
    int method;            /* 0 interreflection, 1 direct, 2 paper */
    double min_irradiance;
    int fill_given;
    double fill_given_value;
    const uint8_t *orient; /* fill class per facet (fill_class_of); NULL: one fill for all */
    const double *esun;    /* the sun's part of esky, never pooled (irradiance.ply) */
    const rs_pool *pool;   /* NULL: each facet's own gather (pool.h) */
} refl_in;

typedef struct {
    double *rho, *G, *Lfill;
    double *E, *scratch; /* E_sky + G as divided by (pooled), and room for 3 per facet */
    uint8_t *estimable;
    double fill[3];                        /* the mean of all estimable facets */
    double fill_class[RS_FILL_CLASSES][3]; /* what unobserved facets of each orientation take */
    int iterations;
    size_t blowups; /* paper: rows whose kernel sums past pi */
} refl_out;

static uint8_t fill_class_of(rs_v3 n)
{
    return n.z > RS_FILL_CLASS_COS ? RS_FILL_UP : (n.z < -RS_FILL_CLASS_COS ? RS_FILL_DOWN : RS_FILL_SIDE);
}

static const double *fill_of(const refl_in *in, const refl_out *out, size_t i)
{
    return out->fill_class[in->orient ? in->orient[i] : RS_FILL_SIDE];
}

/* P(|N(0, 1)| <= 1.2816) = 0.80: the two-sided 80 % bound of a normal error, in sigmas. */
#define RS_NORMAL_Z80 1.2816

static double lum3(const double *v)
{
    return 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2];
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* G_i with the current radiance model (observed L, else Lfill). */
static void compute_G(const refl_in *in, const double *Lfill, double *G)
{
#pragma omp parallel for schedule(static)
    for (size_t i = 0; i < in->nf; i++) {
        double g[3] = {0, 0, 0};
        if (in->method == 0) {
            for (int ch = 0; ch < 3; ch++) g[ch] = in->gseen[3 * i + ch];
            for (size_t e = in->K->row_start[i]; e < in->K->row_start[i + 1]; e++) {
                uint32_t j = in->K->col[e];
                const double *Lj = in->observed[j] ? in->L + 3 * j : Lfill + 3 * j;
                for (int ch = 0; ch < 3; ch++) g[ch] += in->K->k_unseen[e] * Lj[ch];
            }
        } else if (in->method == 2) {
            const float *row = in->dense + i * in->nf;
            for (size_t j = 0; j < in->nf; j++) {
                if (row[j] == 0) continue;
                const double *Lj = in->observed[j] ? in->L + 3 * j : Lfill + 3 * j;
                for (int ch = 0; ch < 3; ch++) g[ch] += row[j] * Lj[ch];
            }
        }
        for (int ch = 0; ch < 3; ch++) G[3 * i + ch] = g[ch];
    }
}

/* out->E = E_sky + G; with a pool, the sun's part plus the neighbours' mean of the rest. */
static void total_irradiance(const refl_in *in, refl_out *out)
{
    size_t n3 = 3 * in->nf;
    if (!in->pool) {
        for (size_t k = 0; k < n3; k++) out->E[k] = in->esky[k] + out->G[k];
        return;
    }
    for (size_t k = 0; k < n3; k++) out->scratch[k] = in->esky[k] - in->esun[k] + out->G[k];
    rs_pool_apply3(in->pool, out->scratch, out->E);
    for (size_t k = 0; k < n3; k++) out->E[k] += in->esun[k];
}

/* One pass: albedo and estimable flags from out->E, then the fill albedos. */
static void estimate(const refl_in *in, refl_out *out, double Emin)
{
    double sum[RS_FILL_CLASSES][3] = {{0}}, wsum[RS_FILL_CLASSES] = {0};
    for (size_t i = 0; i < in->nf; i++) {
        const double *E = out->E + 3 * i;
        int ok = in->observed[i];
        for (int ch = 0; ch < 3; ch++) {
            if (!(isfinite(E[ch]) && E[ch] > Emin && isfinite(in->L[3 * i + ch]))) ok = 0;
        }
        if (in->method == 2 && in->dense) {
            double rs = 0;
            for (size_t j = 0; j < in->nf; j++) rs += in->dense[i * in->nf + j];
            if (rs > M_PI) ok = 0; /* point-to-point form factor blew up: not written out */
        }
        out->estimable[i] = (uint8_t)ok;
        for (int ch = 0; ch < 3; ch++) out->rho[3 * i + ch] = ok ? M_PI * in->L[3 * i + ch] / E[ch] : 0;
        if (ok) {
            int c = in->orient ? in->orient[i] : RS_FILL_SIDE;
            for (int ch = 0; ch < 3; ch++) sum[c][ch] += in->area[i] * out->rho[3 * i + ch];
            wsum[c] += in->area[i];
        }
    }
    double all = wsum[0] + wsum[1] + wsum[2], prior = RS_FILL_PRIOR_SHARE * all;
    for (int ch = 0; ch < 3; ch++) {
        double s = sum[0][ch] + sum[1][ch] + sum[2][ch];
        out->fill[ch] = in->fill_given ? in->fill_given_value : (all > 0 ? s / all : 0.5);
        for (int c = 0; c < RS_FILL_CLASSES; c++)
            out->fill_class[c][ch] =
                in->fill_given || !(all > 0) ? out->fill[ch] : (sum[c][ch] + prior * out->fill[ch]) / (wsum[c] + prior);
    }
}

static int solve(const refl_in *in, refl_out *out)
{
    size_t nf = in->nf;
    /* Threshold for "receives enough light": a share of the median over observed facets. */
    double *e = malloc((nf ? nf : 1) * sizeof *e);
    if (!e) return -1;
    size_t ne = 0;
    for (size_t i = 0; i < nf; i++)
        if (in->observed[i]) e[ne++] = lum3(in->esky + 3 * i) + lum3(in->gseen + 3 * i);
    qsort(e, ne, sizeof *e, cmp_double);
    double Emin = ne ? in->min_irradiance * e[ne / 2] : 0;
    if (!(Emin > 0)) Emin = 1e-30;
    free(e);

    memset(out->Lfill, 0, 3 * nf * sizeof *out->Lfill);
    double prev[RS_FILL_CLASSES][3];
    for (int c = 0; c < RS_FILL_CLASSES; c++) prev[c][0] = prev[c][1] = prev[c][2] = -1;
    for (out->iterations = 1; out->iterations <= 200; out->iterations++) {
        compute_G(in, out->Lfill, out->G);
        total_irradiance(in, out);
        estimate(in, out, Emin);
        if (in->method == 1) break; /* direct: no G, nothing to iterate */
        double change = 0;
        for (size_t i = 0; i < nf; i++) {
            if (in->observed[i]) continue;
            const double *fill = fill_of(in, out, i);
            for (int ch = 0; ch < 3; ch++) {
                double Lnew = fill[ch] * out->E[3 * i + ch] / M_PI;
                double d = fabs(Lnew - out->Lfill[3 * i + ch]) / fmax(fabs(Lnew), 1e-30);
                if (d > change) change = d;
                out->Lfill[3 * i + ch] = Lnew;
            }
        }
        for (int c = 0; c < RS_FILL_CLASSES; c++)
            for (int ch = 0; ch < 3; ch++) {
                double d = fabs(out->fill_class[c][ch] - prev[c][ch]);
                if (d > change) change = d;
                prev[c][ch] = out->fill_class[c][ch];
            }
        if (change < 1e-7) break;
    }
    if (in->method == 1) memset(out->G, 0, 3 * nf * sizeof *out->G);
    return 0;
}

static int write_albedo(const rs_config *cfg, const rs_mesh *mesh, const refl_in *in, const refl_out *out, rs_err *err)
{
    size_t nf = in->nf;
    rs_ply *ply = rs_ply_new();
    double *alb = malloc(3 * nf * sizeof *alb), *tmp = malloc(nf * sizeof *tmp);
    int rc = -1;
    rs_ply_element *faces = ply ? rs_mesh_to_ply(mesh, ply) : NULL;
    if (!faces || !alb || !tmp) goto oom;
    /* Facets with no estimate carry the fill albedo, so the model is complete for relighting;
     * estimable = 0 says it is assumed, not measured. */
    for (size_t i = 0; i < nf; i++)
        for (int ch = 0; ch < 3; ch++)
            alb[3 * i + ch] = out->estimable[i] ? out->rho[3 * i + ch] : fill_of(in, out, i)[ch];
    if (rs_faceprop_add_rgb(faces, "albedo", alb) != 0 || rs_faceprop_add_rgb(faces, "radiance", in->L) != 0 ||
        rs_faceprop_add_rgb(faces, "irradiance_sky", in->esky) != 0 ||
        rs_faceprop_add_rgb(faces, "irradiance_inter", out->G) != 0)
        goto oom;
    if (!rs_ply_add_scalar(faces, "sky_filled", RS_PLY_FLOAT32, in->sky_filled) ||
        !rs_ply_add_scalar(faces, "irradiance_sky_sigma", RS_PLY_FLOAT32, in->esky_sigma) ||
        !rs_ply_add_scalar(faces, "irradiance_mc_sigma", RS_PLY_FLOAT32, in->mc_sigma) ||
        !rs_ply_add_scalar(faces, "radiance_sigma_rel", RS_PLY_FLOAT32, in->L_sigma_rel))
        goto oom;
    /* Relative uncertainty of rho = pi L / E, for estimable facets: L's observation noise, E's
     * fill and Monte Carlo errors, and the floor, in quadrature (independent sources). */
    for (size_t i = 0; i < nf; i++) {
        double E = lum3(in->esky + 3 * i) + lum3(out->G + 3 * i);
        double rE2 = (in->esky_sigma[i] * in->esky_sigma[i] + in->mc_sigma[i] * in->mc_sigma[i]) / (E * E);
        tmp[i] = out->estimable[i] && E > 0
            ? sqrt(in->sigma_floor * in->sigma_floor + in->L_sigma_rel[i] * in->L_sigma_rel[i] + rE2)
            : 0;
    }
    if (!rs_ply_add_scalar(faces, "albedo_sigma_rel", RS_PLY_FLOAT32, tmp)) goto oom;
    for (size_t i = 0; i < nf; i++) tmp[i] *= RS_NORMAL_Z80;
    if (!rs_ply_add_scalar(faces, "albedo_bound80_rel", RS_PLY_FLOAT32, tmp)) goto oom;
    for (size_t i = 0; i < nf; i++) tmp[i] /= RS_NORMAL_Z80;
    for (size_t i = 0; i < nf; i++) tmp[i] *= (alb[3 * i] + alb[3 * i + 1] + alb[3 * i + 2]) / 3;
    if (!rs_ply_add_scalar(faces, "albedo_sigma", RS_PLY_FLOAT32, tmp)) goto oom;
    for (size_t i = 0; i < nf; i++) tmp[i] = in->observed[i];
    if (!rs_ply_add_scalar(faces, "observed", RS_PLY_UINT8, tmp)) goto oom;
    for (size_t i = 0; i < nf; i++) tmp[i] = out->estimable[i];
    if (!rs_ply_add_scalar(faces, "estimable", RS_PLY_UINT8, tmp)) goto oom;
    static const char *const rgbnames[3] = {"red", "green", "blue"};
    for (int ch = 0; ch < 3; ch++) {
        for (size_t i = 0; i < nf; i++) {
            double a = alb[3 * i + ch];
            tmp[i] = floor(255.0 * rs_linear_to_srgb((float)(a < 0 ? 0 : (a > 1 ? 1 : a))) + 0.5);
        }
        if (!rs_ply_add_scalar(faces, rgbnames[ch], RS_PLY_UINT8, tmp)) goto oom;
    }
    rs_ply_add_comment(ply,
                       "rhoscan %s reflectance: method %s; albedo of non-estimable facets is the fill of "
                       "their orientation: up %.4f %.4f %.4f, side %.4f %.4f %.4f, down %.4f %.4f %.4f",
                       RHOSCAN_VERSION, rs_config_string(cfg, "reflectance", "method"), out->fill_class[0][0],
                       out->fill_class[0][1], out->fill_class[0][2], out->fill_class[1][0], out->fill_class[1][1],
                       out->fill_class[1][2], out->fill_class[2][0], out->fill_class[2][1], out->fill_class[2][2]);
    rs_ply_add_comment(ply, "rhoscan_fill_albedo %.9g %.9g %.9g", out->fill[0], out->fill[1], out->fill[2]);
    rs_ply_add_comment(ply,
                       "albedo_sigma_rel: standard (1 sigma) relative uncertainty of the albedo = sqrt(%.4g^2 + "
                       "radiance_sigma_rel^2 + (irradiance_sky_sigma^2 + irradiance_mc_sigma^2) / (E_sky + G)^2); "
                       "albedo_bound80_rel = %.4f x albedo_sigma_rel: |relative error| below it with 80 %% "
                       "probability (two-sided, normal); albedo_sigma = albedo_sigma_rel x mean albedo",
                       in->sigma_floor, RS_NORMAL_Z80);
    char path[4096];
    rc = rs_ply_write(ply, rs_work_path(cfg, "albedo.ply", path, sizeof path), 1, err);
    goto done;
oom:
    rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory building albedo.ply");
done:
    rs_ply_free(ply);
    free(alb);
    free(tmp);
    return rc;
}

/* An uncertainty term from an earlier stage's file; files written without it (other tools,
 * older runs) give 0 for that term, and the log says the uncertainty lacks it. */
static int optional_prop(const rs_ply *ply, const char *file, const char *name, size_t nf, double *out, rs_err *err)
{
    const rs_ply_element *faces = rs_ply_find_element(ply, "face");
    if (faces && rs_ply_find_prop(faces, name)) return rs_faceprop_get(ply, file, name, nf, out, err);
    memset(out, 0, nf * sizeof *out);
    rs_log_warn("reflectance: %s has no face property %s: albedo_sigma_rel leaves that term out", file, name);
    return 0;
}

/* What pooling needs from irradiance.ply: 1 read, 0 absent (a file from before pooling: the
 * summary says so), -1 error. */
static int pool_inputs(const rs_ply *irr, const char *ip, size_t nf, double *esun, double *inv_dist, uint8_t *gathered,
                       double *tmp, rs_report *rep, rs_err *err)
{
    const rs_ply_element *faces = rs_ply_find_element(irr, "face");
    if (!faces || !rs_ply_find_prop(faces, "hit_distance_inv") || !rs_ply_find_prop(faces, "gathered") ||
        !rs_ply_find_prop(faces, "irradiance_sun_r")) {
        rs_report_skip(rep, "pooling",
                       "%s has no hit_distance_inv, gathered or irradiance_sun (written before "
                       "pooling): each facet keeps its own gather",
                       ip);
        return 0;
    }
    if (rs_faceprop_get_rgb(irr, ip, "irradiance_sun", nf, esun, err) != 0 ||
        rs_faceprop_get(irr, ip, "hit_distance_inv", nf, inv_dist, err) != 0 ||
        rs_faceprop_get(irr, ip, "gathered", nf, tmp, err) != 0)
        return -1;
    for (size_t f = 0; f < nf; f++) gathered[f] = tmp[f] > 0;
    return 1;
}

int rs_reflectance_run(const rs_config *cfg, rs_report *rep, rs_err *err)
{
    char path[4096];
    int rc = -1;
    rs_ply *obs = NULL, *irr = NULL;
    rs_transport *K = NULL;
    float *dense = NULL;
    rs_mesh *mesh = rs_mesh_read(rs_work_path(cfg, "mesh.ply", path, sizeof path), NULL, err);
    if (!mesh) return -1;
    size_t nf = mesh->nfaces;
    double *buf = calloc(24 * nf + 1, sizeof *buf);
    uint8_t *flags = calloc(4 * nf + 1, 1);
    double *pbuf = calloc(10 * nf + 1, sizeof *pbuf); /* E, scratch, esun, inv_dist */
    rs_pool pool = {0};
    if (!buf || !flags || !pbuf) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu facets", nf);
        goto out;
    }
    double *area = buf, *L = buf + nf, *esky = buf + 4 * nf, *gseen = buf + 7 * nf, *obsd = buf + 10 * nf;
    double *esun = pbuf + 6 * nf, *inv_dist = pbuf + 9 * nf;
    uint8_t *gathered = flags + 2 * nf, *orient = flags + 3 * nf;
    refl_out ro = {.rho = buf + 11 * nf,
                   .G = buf + 14 * nf,
                   .Lfill = buf + 17 * nf,
                   .E = pbuf,
                   .scratch = pbuf + 3 * nf,
                   .estimable = flags + nf};
    for (size_t f = 0; f < nf; f++) {
        rs_v3 c, n;
        rs_mesh_face(mesh, f, &c, &n, &area[f]);
        orient[f] = fill_class_of(n);
    }
    const char *method = rs_config_string(cfg, "reflectance", "method");
    int m = strcmp(method, "direct") == 0 ? 1 : (strcmp(method, "paper") == 0 ? 2 : 0);
    const char *op = rs_work_path(cfg, "observe.ply", path, sizeof path);
    if (!(obs = rs_ply_read(op, err)) || rs_faceprop_get_rgb(obs, op, "radiance", nf, L, err) != 0 ||
        rs_faceprop_get(obs, op, "observed", nf, obsd, err) != 0 ||
        optional_prop(obs, op, "radiance_sigma_rel", nf, buf + 22 * nf, err) != 0)
        goto out;
    for (size_t f = 0; f < nf; f++) flags[f] = obsd[f] > 0;
    const char *ip = rs_work_path(cfg, "irradiance.ply", path, sizeof path);
    if (!(irr = rs_ply_read(ip, err)) || rs_faceprop_get_rgb(irr, ip, "irradiance_sky", nf, esky, err) != 0 ||
        rs_faceprop_get_rgb(irr, ip, "irradiance_inter_seen", nf, gseen, err) != 0 ||
        rs_faceprop_get(irr, ip, "sky_filled", nf, buf + 20 * nf, err) != 0 ||
        rs_faceprop_get(irr, ip, "irradiance_sky_sigma", nf, buf + 21 * nf, err) != 0 ||
        optional_prop(irr, ip, "irradiance_mc_sigma", nf, buf + 23 * nf, err) != 0)
        goto out;
    double t0 = rs_now(), accuracy = rs_config_real(cfg, "reflectance", "pool_accuracy");
    int can_pool =
        accuracy > 0 && m != 2 ? pool_inputs(irr, ip, nf, esun, inv_dist, gathered, ro.scratch, rep, err) : 0;
    if (can_pool < 0) goto out;
    if (can_pool) {
        if (rs_pool_build(mesh, inv_dist, gathered, flags, accuracy, &pool) != 0) {
            rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory pooling the irradiance of %zu facets", nf);
            goto out;
        }
        double mean;
        size_t pooled, asked;
        rs_pool_stats(&pool, flags, &mean, &pooled, &asked);
        rs_json_set_num(rep->metrics, "pool_mean_facets", mean);
        rs_json_set_int(rep->metrics, "pool_facets_pooled", (long long)pooled);
        rs_report_time(rep, "pool", rs_now() - t0);
        rs_log_info("reflectance: irradiance pooled within the plane (accuracy %g): %zu of the %zu observed facets, "
                    "%.1f facets per mean",
                    accuracy, pooled, asked, mean);
    }
    t0 = rs_now();
    if (m == 0) {
        if (!(K = rs_transport_read(rs_work_path(cfg, "transport.ply", path, sizeof path), nf, err))) goto out;
    } else if (m == 2) {
        long maxf = rs_config_int(cfg, "reflectance", "paper_max_facets");
        if ((long)nf > maxf) {
            rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                       "[reflectance] method = paper on %zu facets: its O(m^3) visibility would not finish "
                       "in minutes; expected at most [reflectance] paper_max_facets = %ld facets",
                       nf, maxf);
            goto out;
        }
        double pairs;
        if (rs_paper_kernel(mesh, &dense, &pairs, err) != 0) goto out;
        rs_json_set_num(rep->metrics, "paper_pairs_tested", pairs);
        memset(gseen, 0, 3 * nf * sizeof *gseen); /* the paper reads no panorama at hit points */
    } else {
        rs_report_skip(rep, "interreflection", "method = direct ignores light from other facets");
    }
    rs_report_time(rep, "kernel", rs_now() - t0);
    refl_in in = {nf,
                  area,
                  L,
                  esky,
                  gseen,
                  buf + 20 * nf,
                  buf + 21 * nf,
                  buf + 23 * nf,
                  buf + 22 * nf,
                  rs_config_real(cfg, "reflectance", "albedo_sigma_floor"),
                  flags,
                  K,
                  dense,
                  m,
                  rs_config_real(cfg, "reflectance", "min_irradiance"),
                  rs_config_has(cfg, "reflectance", "unobserved_albedo"),
                  0,
                  strcmp(rs_config_string(cfg, "reflectance", "unobserved_albedo_by"), "all") == 0 ? NULL : orient,
                  esun,
                  pool.start ? &pool : NULL};
    if (in.fill_given) in.fill_given_value = rs_config_real(cfg, "reflectance", "unobserved_albedo");
    t0 = rs_now();
    if (solve(&in, &ro) != 0) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    rs_report_time(rep, "solve", rs_now() - t0);
    /* Pooled, the files carry what the albedo divided by: E_sky = sun + pooled rest, G pooled,
     * and the Monte Carlo noise of that mean. */
    if (in.pool) { /* into buffers the solve is done with: E, scratch, inv_dist */
        double *esky_p = ro.E, *G_p = ro.scratch, *mc_p = inv_dist;
        for (size_t k = 0; k < 3 * nf; k++) G_p[k] = esky[k] - esun[k];
        rs_pool_apply3(&pool, G_p, esky_p);
        for (size_t k = 0; k < 3 * nf; k++) esky_p[k] += esun[k];
        rs_pool_apply3(&pool, ro.G, G_p);
        rs_pool_sigma(&pool, in.mc_sigma, mc_p);
        in.esky = esky_p;
        in.mc_sigma = mc_p;
        ro.G = G_p;
    }
    if (rs_greycard_report(cfg, nf, in.esky, ro.G, ro.rho, ro.estimable, rep->metrics, err) != 0) goto out;
    size_t nobs = 0, nest = 0, blow = 0;
    for (size_t f = 0; f < nf; f++) {
        nobs += flags[f];
        nest += ro.estimable[f];
        if (m == 2 && flags[f] && !ro.estimable[f]) {
            double rs = 0;
            for (size_t j = 0; j < nf; j++) rs += dense[f * nf + j];
            if (rs > M_PI) blow++;
        }
    }
    if (blow)
        rs_log_warn("paper: %zu facets have kernel row sums above pi (the point-to-point form factor "
                    "diverges for close neighbours); they are flagged not estimable",
                    blow);
    rs_json_set_str(rep->metrics, "method", method);
    rs_json_set_int(rep->metrics, "facets", (long long)nf);
    rs_json_set_int(rep->metrics, "observed", (long long)nobs);
    rs_json_set_int(rep->metrics, "estimable", (long long)nest);
    rs_json_set_int(rep->metrics, "paper_rows_diverged", (long long)blow);
    rs_json_set_int(rep->metrics, "fill_iterations", ro.iterations);
    rs_json *fill = rs_json_set_arr(rep->metrics, "fill_albedo");
    for (int ch = 0; ch < 3; ch++) rs_json_push_num(fill, ro.fill[ch]);
    rs_json *by = rs_json_set_obj(rep->metrics, "fill_albedo_by_orientation");
    for (int c = 0; c < RS_FILL_CLASSES; c++) {
        rs_json *a = rs_json_set_arr(by, fill_class_name[c]);
        for (int ch = 0; ch < 3; ch++) rs_json_push_num(a, ro.fill_class[c][ch]);
    }
    if (nobs > nest)
        rs_report_skip(rep, "albedo of observed facets",
                       "%zu observed facets receive too little light "
                       "or are degenerate: flagged estimable = 0",
                       nobs - nest);
    rs_log_info("reflectance (%s): %zu facets, %zu observed, %zu estimable; fill albedo up %.3f, side %.3f, "
                "down %.3f (luminance)",
                method, nf, nobs, nest, lum3(ro.fill_class[RS_FILL_UP]), lum3(ro.fill_class[RS_FILL_SIDE]),
                lum3(ro.fill_class[RS_FILL_DOWN]));
    rc = write_albedo(cfg, mesh, &in, &ro, err);
out:
    free(buf);
    free(flags);
    free(pbuf);
    rs_pool_free(&pool);
    free(dense);
    rs_transport_free(K);
    rs_ply_free(obs);
    rs_ply_free(irr);
    rs_mesh_free(mesh);
    return rc;
}
