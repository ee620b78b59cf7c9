/* reflectance: albedo per facet, rho_i = pi L_i / E_i, with
 *   direct:          E_i = E_sky,i                       (Okura et al. 2008 baseline)
 *   interreflection: E_i = E_sky,i + G_i, G from the gather (panorama readings where the camera
 *                    sees the hit point, else K_ij times facet j's radiance)
 *   paper:           E_i = E_sky,i + sum_j K_ij L_j with the paper's dense point-to-point K.
 * With [reflectance] pool_accuracy > 0 (not paper), an observed facet's E is its sun's part plus
 * the weighted mean of the rest over its neighbours of the same plane (pool.h): less Monte Carlo
 * noise, and albedo.ply carries that E. With [reflectance] albedo_pool_sigmas > 0 (not paper), the
 * albedo itself is then pooled with same-plane neighbours that agree within their noise (albpool.h):
 * the radiance's noise falls, steps and resolved textures stay, albedo_sigma_rel says by how much.
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
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/faceprop.h"
#include "stages/reflectance/greycard.h"
#include "common/image.h"
#include "common/log.h"
#include "stages/reflectance/albpool.h"
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

/* [reflectance] method: what E is (the header above). */
typedef enum { RS_REFL_INTERREFLECTION, RS_REFL_DIRECT, RS_REFL_PAPER, RS_REFL_METHODS } rs_refl_method;
static const char *const refl_method_name[RS_REFL_METHODS] = {"interreflection", "direct", "paper"};

/* The [reflectance] keys, read once. */
typedef struct {
    rs_refl_method method;
    double pool_accuracy;    /* > 0: pool the irradiance within the plane (pool.h; not paper) */
    double albedo_pool;      /* > 0: pool the albedo within same-material planes, this test (albpool.h) */
    long paper_max_facets;   /* paper: larger meshes are refused */
    double sigma_floor;      /* albedo_sigma_floor */
    double min_irradiance;   /* share of the median E below which a facet is not estimable */
    int fill_given;          /* unobserved_albedo is set ... */
    double fill_given_value; /* ... to this */
    int fill_by_orientation; /* unobserved_albedo_by is not "all" */
} refl_opts;

static int refl_opts_read(const rs_config *cfg, refl_opts *o, rs_err *err)
{
    const char *method = rs_config_string(cfg, "reflectance", "method");
    int m = 0;
    while (m < RS_REFL_METHODS && strcmp(method, refl_method_name[m]) != 0) m++;
    if (m == RS_REFL_METHODS)
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[reflectance] method = %s: expected interreflection, direct or paper", method);
    o->method = (rs_refl_method)m;
    o->pool_accuracy = rs_config_real(cfg, "reflectance", "pool_accuracy");
    o->albedo_pool = rs_config_real(cfg, "reflectance", "albedo_pool_sigmas");
    o->paper_max_facets = rs_config_int(cfg, "reflectance", "paper_max_facets");
    o->sigma_floor = rs_config_real(cfg, "reflectance", "albedo_sigma_floor");
    o->min_irradiance = rs_config_real(cfg, "reflectance", "min_irradiance");
    o->fill_given = rs_config_has(cfg, "reflectance", "unobserved_albedo");
    o->fill_given_value = o->fill_given ? rs_config_real(cfg, "reflectance", "unobserved_albedo") : 0;
    o->fill_by_orientation = strcmp(rs_config_string(cfg, "reflectance", "unobserved_albedo_by"), "all") != 0;
    return 0;
}

typedef struct {
    size_t nf;
    const double *area, *L, *esky, *gseen;
    const double *sky_filled, *esky_sigma, *mc_sigma; /* from irradiance.ply */
    const double *L_sigma_rel;                        /* from observe.ply */
    double sigma_floor;
    const uint8_t *observed;
    const rs_transport *K; /* gather kernel (interreflection) */
    const float *dense;    /* paper kernel, m * m (paper) */
    rs_refl_method method;
    double min_irradiance;
    int fill_given;
    double fill_given_value;
    const uint8_t *orient; /* fill class per facet (fill_class_of); NULL: one fill for all */
    const double *esun;    /* the sun's part of esky, never pooled (irradiance.ply) */
    const rs_pool *pool;   /* NULL: each facet's own gather (pool.h) */
} refl_in;

typedef struct {
    double *rho, *G, *Lfill;
    const double *rho_own; /* each facet's own albedo before pooling (rho when not pooled) */
    double *E, *scratch;   /* E_sky + G as divided by (pooled), and room for 3 per facet */
    uint8_t *estimable;
    double fill[3];                        /* the mean of all estimable facets */
    double fill_class[RS_FILL_CLASSES][3]; /* what unobserved facets of each orientation take */
    int iterations;
    const char *origin;    /* rhoscan_origin "OX OY OZ", "" when none */
    double residuals[200]; /* the largest relative change of each sweep (solve_residuals) */
    int nresiduals;
    /* the albedo pooled within planes (albpool.h): its uncertainty's parts, NULL when not */
    const double *pool_s_rad, *pool_s_mc, *pool_s_bias, *pool_neff;
    double pool_sigmas; /* its test */
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
        if (in->method == RS_REFL_INTERREFLECTION) {
            for (int ch = 0; ch < 3; ch++) g[ch] = in->gseen[3 * i + ch];
            for (size_t e = in->K->row_start[i]; e < in->K->row_start[i + 1]; e++) {
                uint32_t j = in->K->col[e];
                const double *Lj = in->observed[j] ? in->L + 3 * j : Lfill + 3 * j;
                for (int ch = 0; ch < 3; ch++) g[ch] += in->K->k_unseen[e] * Lj[ch];
            }
        } else if (in->method == RS_REFL_PAPER) {
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

/* Paper: row i's sum of the dense kernel; past pi the point-to-point form factor diverged. */
static double paper_row_sum(const refl_in *in, size_t i)
{
    double rs = 0;
    for (size_t j = 0; j < in->nf; j++) rs += in->dense[i * in->nf + j];
    return rs;
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
        if (in->method == RS_REFL_PAPER && in->dense && paper_row_sum(in, i) > M_PI)
            ok = 0; /* point-to-point form factor blew up: not written out */
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
    out->nresiduals = 0;
    double prev[RS_FILL_CLASSES][3];
    for (int c = 0; c < RS_FILL_CLASSES; c++) prev[c][0] = prev[c][1] = prev[c][2] = -1;
    for (out->iterations = 1; out->iterations <= 200; out->iterations++) {
        compute_G(in, out->Lfill, out->G);
        total_irradiance(in, out);
        estimate(in, out, Emin);
        if (in->method == RS_REFL_DIRECT) break; /* no G, nothing to iterate */
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
        out->residuals[out->nresiduals++] = change;
        if (change < 1e-7) break;
    }
    if (in->method == RS_REFL_DIRECT) memset(out->G, 0, 3 * nf * sizeof *out->G);
    return 0;
}

/* A diffuse surface reflects at most what reaches it: an albedo above 1 says the light was
 * underestimated there (a wrong sky, exposure or pose), not that the wall is that bright. */
static int above_one(const refl_out *out, size_t f)
{
    /* Judged on the facet's own albedo: pooling with its neighbours would hide the evidence. */
    const double *r = out->rho_own ? out->rho_own : out->rho;
    return r[3 * f] > 1 || r[3 * f + 1] > 1 || r[3 * f + 2] > 1;
}

/* Relative uncertainty of rho = pi L / E, for estimable facets: L's observation noise, E's fill
 * and Monte Carlo errors, and the floor, in quadrature (independent sources). With the albedo
 * pooled: the pooled radiance noise, the Monte Carlo part taken as correlated, and the pooling's
 * bias over a resolved texture (albpool.h) instead of the facet's own L and Monte Carlo terms. */
static void albedo_sigma_rel(const refl_in *in, const refl_out *out, double *sig)
{
    for (size_t i = 0; i < in->nf; i++) {
        double E = lum3(in->esky + 3 * i) + lum3(out->G + 3 * i);
        if (!(out->estimable[i] && E > 0)) {
            sig[i] = 0;
            continue;
        }
        double fill = in->esky_sigma[i] / E, v = in->sigma_floor * in->sigma_floor + fill * fill;
        if (out->pool_neff) {
            double r = out->pool_s_rad[i], m = out->pool_s_mc[i], b = out->pool_s_bias[i];
            v += r * r + m * m + b * b;
        } else {
            double r = in->L_sigma_rel[i], m = in->mc_sigma[i] / E;
            v += r * r + m * m;
        }
        sig[i] = sqrt(v);
    }
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
    albedo_sigma_rel(in, out, tmp);
    if (!rs_ply_add_scalar(faces, "albedo_sigma_rel", RS_PLY_FLOAT32, tmp)) goto oom;
    if (out->pool_neff &&
        (!rs_ply_add_scalar(faces, "albedo_pool_facets", RS_PLY_FLOAT32, out->pool_neff) ||
         !rs_ply_add_scalar(faces, "albedo_pool_bias_rel", RS_PLY_FLOAT32, out->pool_s_bias)))
        goto oom;
    for (size_t i = 0; i < nf; i++) tmp[i] *= RS_NORMAL_Z80;
    if (!rs_ply_add_scalar(faces, "albedo_bound80_rel", RS_PLY_FLOAT32, tmp)) goto oom;
    for (size_t i = 0; i < nf; i++) tmp[i] /= RS_NORMAL_Z80;
    for (size_t i = 0; i < nf; i++) tmp[i] *= (alb[3 * i] + alb[3 * i + 1] + alb[3 * i + 2]) / 3;
    if (!rs_ply_add_scalar(faces, "albedo_sigma", RS_PLY_FLOAT32, tmp)) goto oom;
    for (size_t i = 0; i < nf; i++) tmp[i] = in->observed[i];
    if (!rs_ply_add_scalar(faces, "observed", RS_PLY_UINT8, tmp)) goto oom;
    for (size_t i = 0; i < nf; i++) tmp[i] = out->estimable[i];
    if (!rs_ply_add_scalar(faces, "estimable", RS_PLY_UINT8, tmp)) goto oom;
    for (size_t i = 0; i < nf; i++) tmp[i] = out->estimable[i] && above_one(out, i);
    if (!rs_ply_add_scalar(faces, "albedo_above_one", RS_PLY_UINT8, tmp)) goto oom;
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
                       RHOSCAN_VERSION, refl_method_name[in->method], out->fill_class[0][0], out->fill_class[0][1],
                       out->fill_class[0][2], out->fill_class[1][0], out->fill_class[1][1], out->fill_class[1][2],
                       out->fill_class[2][0], out->fill_class[2][1], out->fill_class[2][2]);
    rs_ply_add_comment(ply, "rhoscan_fill_albedo %.9g %.9g %.9g", out->fill[0], out->fill[1], out->fill[2]);
    if (out->origin && out->origin[0]) rs_ply_add_comment(ply, "rhoscan_origin %s", out->origin);
    rs_ply_add_comment(ply,
                       "red green blue: the albedo clipped to [0, 1] and sRGB-encoded, 8 bit, for viewers; "
                       "albedo_r/g/b and every other float property are linear");
    rs_ply_add_comment(ply,
                       "albedo_sigma_rel: standard (1 sigma) relative uncertainty of the albedo = sqrt(%.4g^2 + "
                       "radiance_sigma_rel^2 + (irradiance_sky_sigma^2 + irradiance_mc_sigma^2) / (E_sky + G)^2); "
                       "albedo_bound80_rel = %.4f x albedo_sigma_rel: |relative error| below it with 80 %% "
                       "probability (two-sided, normal); albedo_sigma = albedo_sigma_rel x mean albedo",
                       in->sigma_floor, RS_NORMAL_Z80);
    if (out->pool_neff)
        rs_ply_add_comment(ply,
                           "albedo pooled within planes (albedo_pool_sigmas %g): albedo_sigma_rel's radiance term is "
                           "the pooled one, its Monte Carlo term is taken as correlated, and albedo_pool_bias_rel is "
                           "added; pi L / (E_sky + G) is the facet's own, unpooled albedo",
                           out->pool_sigmas);
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

/* The stage's per-facet arrays, one allocation each (3 per facet where RGB). */
typedef struct {
    size_t nf;
    double *area;    /* m^2 (mesh.ply) */
    uint8_t *orient; /* fill class (fill_class_of) */
    /* observe.ply */
    double *L, *L_sigma_rel;
    uint8_t *observed;
    /* irradiance.ply; esun, inv_dist and gathered only when pooling */
    double *esky, *gseen, *sky_filled, *esky_sigma, *mc_sigma, *esun, *inv_dist;
    uint8_t *gathered;
    /* the solve's */
    double *rho, *G, *Lfill, *E, *scratch;
    uint8_t *estimable;
    /* pooled, what albedo.ply carries (pool_outputs) */
    double *esky_pooled, *G_pooled, *mc_pooled;
    /* the albedo pooled within planes (albedo_pool) */
    double *rho_pooled, *ap_s_rad, *ap_s_mc, *ap_s_bias, *ap_neff, *ap_in_mc;
    char origin[256]; /* mesh.ply's rhoscan_origin comment ("" when not georeferenced) */
} refl_facets;

static double *facet_doubles(size_t n)
{
    return calloc(n ? n : 1, sizeof(double));
}

static uint8_t *facet_flags(size_t n)
{
    return calloc(n ? n : 1, 1);
}

static int refl_facets_alloc(refl_facets *fb, size_t nf)
{
    fb->nf = nf;
    double **d3[] = {&fb->L, &fb->esky, &fb->gseen, &fb->esun, &fb->rho, &fb->G, &fb->Lfill, &fb->E, &fb->scratch};
    double **d1[] = {&fb->area, &fb->L_sigma_rel, &fb->sky_filled, &fb->esky_sigma, &fb->mc_sigma, &fb->inv_dist};
    uint8_t **f1[] = {&fb->orient, &fb->observed, &fb->gathered, &fb->estimable};
    int ok = 1;
    for (size_t k = 0; k < sizeof d3 / sizeof *d3; k++) ok &= (*d3[k] = facet_doubles(3 * nf)) != NULL;
    for (size_t k = 0; k < sizeof d1 / sizeof *d1; k++) ok &= (*d1[k] = facet_doubles(nf)) != NULL;
    for (size_t k = 0; k < sizeof f1 / sizeof *f1; k++) ok &= (*f1[k] = facet_flags(nf)) != NULL;
    return ok ? 0 : -1;
}

static void refl_facets_free(refl_facets *fb)
{
    double *d[] = {fb->area,       fb->L,        fb->L_sigma_rel, fb->esky,        fb->gseen,    fb->sky_filled,
                   fb->esky_sigma, fb->mc_sigma, fb->esun,        fb->inv_dist,    fb->rho,      fb->G,
                   fb->Lfill,      fb->E,        fb->scratch,     fb->esky_pooled, fb->G_pooled, fb->mc_pooled,
                   fb->rho_pooled, fb->ap_s_rad, fb->ap_s_mc,     fb->ap_s_bias,   fb->ap_neff,  fb->ap_in_mc};
    for (size_t k = 0; k < sizeof d / sizeof *d; k++) free(d[k]);
    free(fb->orient);
    free(fb->observed);
    free(fb->gathered);
    free(fb->estimable);
}

static void facet_geometry(const rs_mesh *mesh, refl_facets *fb)
{
    for (size_t f = 0; f < fb->nf; f++) {
        rs_v3 c, n;
        rs_mesh_face(mesh, f, &c, &n, &fb->area[f]);
        fb->orient[f] = fill_class_of(n);
    }
}

/* observe.ply: radiance, observed flags, radiance_sigma_rel. */
static int read_observe(const rs_config *cfg, refl_facets *fb, rs_err *err)
{
    char path[4096];
    size_t nf = fb->nf;
    double *observed = fb->scratch; /* as doubles; the solve has not started */
    const char *op = rs_work_path(cfg, "observe.ply", path, sizeof path);
    rs_ply *obs = rs_ply_read(op, err);
    int rc = -1;
    if (obs && rs_faceprop_get_rgb(obs, op, "radiance", nf, fb->L, err) == 0 &&
        rs_faceprop_get(obs, op, "observed", nf, observed, err) == 0 &&
        optional_prop(obs, op, "radiance_sigma_rel", nf, fb->L_sigma_rel, err) == 0) {
        for (size_t f = 0; f < nf; f++) fb->observed[f] = observed[f] > 0;
        rc = 0;
    }
    rs_ply_free(obs);
    return rc;
}

/* irradiance.ply: E_sky, the gather's seen part, the uncertainty terms and, when pooling is
 * asked for, its inputs. Returns 1 when pooling can go ahead, 0 when not, -1 on error. */
static int read_irradiance(const rs_config *cfg, const refl_opts *o, refl_facets *fb, rs_report *rep, rs_err *err)
{
    char path[4096];
    size_t nf = fb->nf;
    const char *ip = rs_work_path(cfg, "irradiance.ply", path, sizeof path);
    rs_ply *irr = rs_ply_read(ip, err);
    int rc = -1;
    if (!irr || rs_faceprop_get_rgb(irr, ip, "irradiance_sky", nf, fb->esky, err) != 0 ||
        rs_faceprop_get_rgb(irr, ip, "irradiance_inter_seen", nf, fb->gseen, err) != 0 ||
        rs_faceprop_get(irr, ip, "sky_filled", nf, fb->sky_filled, err) != 0 ||
        rs_faceprop_get(irr, ip, "irradiance_sky_sigma", nf, fb->esky_sigma, err) != 0 ||
        optional_prop(irr, ip, "irradiance_mc_sigma", nf, fb->mc_sigma, err) != 0)
        goto out;
    rc = o->pool_accuracy > 0 && o->method != RS_REFL_PAPER
        ? pool_inputs(irr, ip, nf, fb->esun, fb->inv_dist, fb->gathered, fb->scratch, rep, err)
        : 0;
out:
    rs_ply_free(irr);
    return rc;
}

/* The figures of reflectance.json. */
typedef struct {
    int albedo_pooled;                    /* the albedo was pooled (albpool.h): */
    rs_albpool_out ap;                    /*   its summary */
    int pooled;                           /* the irradiance was pooled: */
    double pool_mean;                     /*   mean facets per pooled mean */
    size_t pool_pooled, pool_asked;       /*   facets pooled with others, of the observed ones */
    int paper;                            /* the paper's kernel was built: */
    double paper_pairs;                   /*   segment tests run */
    size_t observed, estimable, diverged; /* facets; diverged: paper rows past pi */
    size_t above_one;                     /* estimable facets with a channel's albedo above 1 */
} refl_counts;

/* Each observed facet's pool of plane neighbours (pool.h). */
static int build_pool(const rs_mesh *mesh, const refl_opts *o, const refl_facets *fb, rs_pool *pool, refl_counts *n,
                      rs_err *err)
{
    if (rs_pool_build(mesh, fb->inv_dist, fb->gathered, fb->observed, o->pool_accuracy, pool) != 0)
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory pooling the irradiance of %zu facets", fb->nf);
    n->pooled = 1;
    rs_pool_stats(pool, fb->observed, &n->pool_mean, &n->pool_pooled, &n->pool_asked);
    rs_log_info("reflectance: irradiance pooled within the plane (accuracy %g): %zu of the %zu observed facets, "
                "%.1f facets per mean",
                o->pool_accuracy, n->pool_pooled, n->pool_asked, n->pool_mean);
    return 0;
}

/* The method's kernel: transport.ply's (interreflection), the paper's dense one (which reads no
 * panorama at hit points: gseen becomes 0), none (direct). */
static int load_kernel(const rs_config *cfg, const refl_opts *o, const rs_mesh *mesh, refl_facets *fb, rs_transport **K,
                       float **dense, refl_counts *n, rs_report *rep, rs_err *err)
{
    char path[4096];
    size_t nf = fb->nf;
    switch (o->method) {
    case RS_REFL_INTERREFLECTION:
        *K = rs_transport_read(rs_work_path(cfg, "transport.ply", path, sizeof path), nf, err);
        return *K ? 0 : -1;
    case RS_REFL_PAPER:
        if ((long)nf > o->paper_max_facets)
            return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                              "[reflectance] method = paper on %zu facets: its O(m^3) visibility would not finish "
                              "in minutes; expected at most [reflectance] paper_max_facets = %ld facets",
                              nf, o->paper_max_facets);
        if (rs_paper_kernel(mesh, dense, &n->paper_pairs, err) != 0) return -1;
        n->paper = 1;
        memset(fb->gseen, 0, 3 * nf * sizeof *fb->gseen);
        return 0;
    default: rs_report_skip(rep, "interreflection", "method = direct ignores light from other facets"); return 0;
    }
}

static refl_in solve_inputs(const refl_opts *o, const refl_facets *fb, const rs_transport *K, const float *dense,
                            const rs_pool *pool)
{
    return (refl_in){.nf = fb->nf,
                     .area = fb->area,
                     .L = fb->L,
                     .esky = fb->esky,
                     .gseen = fb->gseen,
                     .sky_filled = fb->sky_filled,
                     .esky_sigma = fb->esky_sigma,
                     .mc_sigma = fb->mc_sigma,
                     .L_sigma_rel = fb->L_sigma_rel,
                     .sigma_floor = o->sigma_floor,
                     .observed = fb->observed,
                     .K = K,
                     .dense = dense,
                     .method = o->method,
                     .min_irradiance = o->min_irradiance,
                     .fill_given = o->fill_given,
                     .fill_given_value = o->fill_given_value,
                     .orient = o->fill_by_orientation ? fb->orient : NULL,
                     .esun = fb->esun,
                     .pool = pool->start ? pool : NULL};
}

/* Pooled, the files carry what the albedo divided by: E_sky = sun + pooled rest, G pooled,
 * and the Monte Carlo noise of that mean; in and out point at those afterwards. */
static int pool_outputs(const rs_pool *pool, refl_facets *fb, refl_in *in, refl_out *out, rs_err *err)
{
    size_t nf = fb->nf;
    double *rest = fb->scratch; /* the solve is done with it */
    if (!(fb->esky_pooled = facet_doubles(3 * nf)) || !(fb->G_pooled = facet_doubles(3 * nf)) ||
        !(fb->mc_pooled = facet_doubles(nf)))
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the pooled irradiance of %zu facets", nf);
    for (size_t k = 0; k < 3 * nf; k++) rest[k] = fb->esky[k] - fb->esun[k];
    rs_pool_apply3(pool, rest, fb->esky_pooled);
    for (size_t k = 0; k < 3 * nf; k++) fb->esky_pooled[k] += fb->esun[k];
    rs_pool_apply3(pool, out->G, fb->G_pooled);
    rs_pool_sigma(pool, in->mc_sigma, fb->mc_pooled);
    in->esky = fb->esky_pooled;
    in->mc_sigma = fb->mc_pooled;
    out->G = fb->G_pooled;
    return 0;
}

/* The albedo pooled within same-material planes (albpool.h); out->rho then is the pooled one. */
static int albedo_pool(const rs_mesh *mesh, const refl_opts *o, refl_facets *fb, const refl_in *in, refl_out *out,
                       refl_counts *n, rs_err *err)
{
    size_t nf = fb->nf;
    if (!(fb->rho_pooled = facet_doubles(3 * nf)) || !(fb->ap_s_rad = facet_doubles(nf)) ||
        !(fb->ap_s_mc = facet_doubles(nf)) || !(fb->ap_s_bias = facet_doubles(nf)) ||
        !(fb->ap_neff = facet_doubles(nf)) || !(fb->ap_in_mc = facet_doubles(nf)))
        goto oom;
    for (size_t i = 0; i < nf; i++) {
        double E = lum3(in->esky + 3 * i) + lum3(out->G + 3 * i);
        fb->ap_in_mc[i] = E > 0 ? in->mc_sigma[i] / E : 0;
    }
    rs_albpool_in ai = {.nf = nf,
                        .rho = out->rho,
                        .usable = out->estimable,
                        .s_rad = in->L_sigma_rel,
                        .s_mc = fb->ap_in_mc,
                        .floor = o->sigma_floor,
                        .sigmas = o->albedo_pool};
    n->ap = (rs_albpool_out){.rho = fb->rho_pooled,
                             .s_rad = fb->ap_s_rad,
                             .s_mc = fb->ap_s_mc,
                             .s_bias = fb->ap_s_bias,
                             .neff = fb->ap_neff};
    if (rs_albpool_run(mesh, &ai, &n->ap) != 0) goto oom;
    out->rho_own = out->rho;
    out->rho = fb->rho_pooled;
    out->pool_s_rad = fb->ap_s_rad, out->pool_s_mc = fb->ap_s_mc, out->pool_s_bias = fb->ap_s_bias;
    out->pool_neff = fb->ap_neff, out->pool_sigmas = o->albedo_pool;
    n->albedo_pooled = 1;
    rs_log_info("reflectance: albedo pooled within planes (test %g sigmas): %zu facets pooled, %.1f effective facets "
                "per albedo, %.0f %% of the candidates kept, shrinkage %.2f",
                o->albedo_pool, n->ap.pooled, n->ap.mean_neff, 100 * n->ap.mean_kept_share, n->ap.mean_shrink);
    return 0;
oom:
    return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory pooling the albedo of %zu facets", nf);
}

static void count_facets(const refl_in *in, const refl_out *out, refl_counts *n)
{
    for (size_t f = 0; f < in->nf; f++) {
        n->observed += in->observed[f];
        n->estimable += out->estimable[f];
        if (in->method == RS_REFL_PAPER && in->observed[f] && !out->estimable[f] && paper_row_sum(in, f) > M_PI)
            n->diverged++;
        n->above_one += out->estimable[f] && above_one(out, f);
    }
}

static void report_reflectance(rs_report *rep, const refl_in *in, const refl_out *out, const refl_counts *n)
{
    if (n->pooled) {
        rs_json_set_num(rep->metrics, "pool_mean_facets", n->pool_mean);
        rs_json_set_int(rep->metrics, "pool_facets_pooled", (long long)n->pool_pooled);
    }
    if (n->albedo_pooled) {
        rs_json_set_int(rep->metrics, "albedo_pool_facets_pooled", (long long)n->ap.pooled);
        rs_json_set_num(rep->metrics, "albedo_pool_mean_facets", n->ap.mean_neff);
        rs_json_set_num(rep->metrics, "albedo_pool_kept_share", n->ap.mean_kept_share);
        rs_json_set_num(rep->metrics, "albedo_pool_mean_shrinkage", n->ap.mean_shrink);
    }
    if (n->paper) rs_json_set_num(rep->metrics, "paper_pairs_tested", n->paper_pairs);
    rs_json_set_str(rep->metrics, "method", refl_method_name[in->method]);
    rs_json_set_int(rep->metrics, "facets", (long long)in->nf);
    rs_json_set_int(rep->metrics, "observed", (long long)n->observed);
    rs_json_set_int(rep->metrics, "estimable", (long long)n->estimable);
    rs_json_set_int(rep->metrics, "paper_rows_diverged", (long long)n->diverged);
    rs_json_set_int(rep->metrics, "albedo_above_one", (long long)n->above_one);
    if (n->above_one)
        rs_log_warn("reflectance: %zu estimable facets have an albedo above 1, impossible for a diffuse surface: "
                    "the light there is underestimated (check the sky, the exposure and the pose); albedo.ply flags "
                    "them (albedo_above_one = 1)",
                    n->above_one);
    rs_json_set_int(rep->metrics, "fill_iterations", out->iterations);
    rs_json *res = rs_json_set_arr(rep->metrics, "solve_residuals"); /* per sweep, for the report's plot */
    for (int k = 0; k < out->nresiduals; k++) rs_json_push_num(res, out->residuals[k]);
    rs_json *fill = rs_json_set_arr(rep->metrics, "fill_albedo");
    for (int ch = 0; ch < 3; ch++) rs_json_push_num(fill, out->fill[ch]);
    rs_json *by = rs_json_set_obj(rep->metrics, "fill_albedo_by_orientation");
    for (int c = 0; c < RS_FILL_CLASSES; c++) {
        rs_json *a = rs_json_set_arr(by, fill_class_name[c]);
        for (int ch = 0; ch < 3; ch++) rs_json_push_num(a, out->fill_class[c][ch]);
    }
}

int rs_reflectance_run(const rs_config *cfg, rs_report *rep, rs_err *err)
{
    refl_opts o = {0};
    if (refl_opts_read(cfg, &o, err) != 0) return -1;
    char path[4096];
    int rc = -1;
    rs_transport *K = NULL;
    float *dense = NULL;
    rs_pool pool = {0};
    refl_facets fb = {0};
    refl_counts n = {0};
    rs_ply *mesh_ply = NULL;
    rs_mesh *mesh = rs_mesh_read(rs_work_path(cfg, "mesh.ply", path, sizeof path), &mesh_ply, err);
    if (!mesh) return -1;
    /* A georeferenced model's shift (docs/DESIGN.md, section Frames) goes on into albedo.ply, the
     * file users take away; the mesh's property tables are not kept. */
    const char *origin = rs_ply_find_comment(mesh_ply, "rhoscan_origin");
    snprintf(fb.origin, sizeof fb.origin, "%s", origin ? origin : "");
    rs_ply_free(mesh_ply);
    size_t nf = mesh->nfaces;
    if (refl_facets_alloc(&fb, nf) != 0) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu facets", nf);
        goto out;
    }
    facet_geometry(mesh, &fb);
    int can_pool = read_observe(cfg, &fb, err) != 0 ? -1 : read_irradiance(cfg, &o, &fb, rep, err);
    if (can_pool < 0) goto out;
    double t0 = rs_now();
    if (can_pool) {
        if (build_pool(mesh, &o, &fb, &pool, &n, err) != 0) goto out;
        rs_report_time(rep, "pool", rs_now() - t0);
    }
    t0 = rs_now();
    if (load_kernel(cfg, &o, mesh, &fb, &K, &dense, &n, rep, err) != 0) goto out;
    rs_report_time(rep, "kernel", rs_now() - t0);

    refl_in in = solve_inputs(&o, &fb, K, dense, &pool);
    refl_out ro = {.rho = fb.rho,
                   .G = fb.G,
                   .Lfill = fb.Lfill,
                   .E = fb.E,
                   .scratch = fb.scratch,
                   .estimable = fb.estimable,
                   .origin = fb.origin};
    t0 = rs_now();
    if (solve(&in, &ro) != 0) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    rs_report_time(rep, "solve", rs_now() - t0);
    if (in.pool && pool_outputs(&pool, &fb, &in, &ro, err) != 0) goto out;
    if (o.albedo_pool > 0 && o.method != RS_REFL_PAPER) {
        t0 = rs_now();
        if (albedo_pool(mesh, &o, &fb, &in, &ro, &n, err) != 0) goto out;
        rs_report_time(rep, "albedo_pool", rs_now() - t0);
    }
    if (rs_greycard_report(cfg, nf, in.esky, ro.G, ro.rho, ro.estimable, rep->metrics, err) != 0) goto out;
    count_facets(&in, &ro, &n);
    if (n.diverged)
        rs_log_warn("paper: %zu facets have kernel row sums above pi (the point-to-point form factor "
                    "diverges for close neighbours); they are flagged not estimable",
                    n.diverged);
    report_reflectance(rep, &in, &ro, &n);
    if (n.observed > n.estimable)
        rs_report_skip(rep, "albedo of observed facets",
                       "%zu observed facets receive too little light "
                       "or are degenerate: flagged estimable = 0",
                       n.observed - n.estimable);
    rs_log_info("reflectance (%s): %zu facets, %zu observed, %zu estimable; fill albedo up %.3f, side %.3f, "
                "down %.3f (luminance)",
                refl_method_name[o.method], nf, n.observed, n.estimable, lum3(ro.fill_class[RS_FILL_UP]),
                lum3(ro.fill_class[RS_FILL_SIDE]), lum3(ro.fill_class[RS_FILL_DOWN]));
    rc = write_albedo(cfg, mesh, &in, &ro, err);
out:
    refl_facets_free(&fb);
    rs_pool_free(&pool);
    free(dense);
    rs_transport_free(K);
    rs_mesh_free(mesh);
    return rc;
}
