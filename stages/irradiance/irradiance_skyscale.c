/* irradiance_skyscale: the filled sky's brightness checked against the observed facets that see
 * it ([sky] fill_from_facets, sky/skyscale.h): same-plane pairs of observed facets that see
 * different shares of the uncertain filled light say how bright it really is. The correction
 * t per channel (in units of the fill's own uncertainty) moves every gathered facet's E_sky by
 * t x fill_sigma_rgb, or the directional mode's t0 t1 t2 (skyscale_dir.h) by t0 fill_sigma_rgb
 * + t1 fill_sigma_dir x + t2 fill_sigma_dir y: linear in the filled radiance, so no ray is
 * traced again. */
#include <stdlib.h>
#include <string.h>
#include "common/log.h"
#include "sky/skyscale.h"
#include "sky/skyscale_dir.h"
#include "sky/sunshadow.h"
#include "stages/irradiance/irradiance_skyscale.h"

#define PAIR_RADIUS_M 3.0 /* same-plane partners within this distance */
#define PAIR_MAX      16  /* partners per facet at most */
#define BLOCK_M       2.0 /* the spatial blocks whose estimates' spread is the shared error */
#define APPLY_Z       2.0 /* auto: applied when |t| is at least this many of its sigmas */

typedef struct {
    uint64_t key;
    size_t pair;
} key_pair;

static int cmp_key_pair(const void *a, const void *b)
{
    const key_pair *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return (x->pair > y->pair) - (x->pair < y->pair);
}

/* Each pair's block: the BLOCK_M cell of its first facet's centroid, numbered 0.. in key order. */
static uint32_t *pair_blocks(const rs_mesh *mesh, const rs_sunshadow_pairs *pp)
{
    key_pair *kp = malloc((pp->n ? pp->n : 1) * sizeof *kp);
    uint32_t *block = malloc((pp->n ? pp->n : 1) * sizeof *block);
    if (!kp || !block) {
        free(kp);
        free(block);
        return NULL;
    }
    for (size_t q = 0; q < pp->n; q++) {
        rs_v3 c, n;
        double area;
        rs_mesh_face(mesh, pp->a[q], &c, &n, &area);
        double v[3] = {c.x, c.y, c.z};
        uint64_t key = 0;
        for (int k = 0; k < 3; k++) {
            double q2 = floor(v[k] / BLOCK_M);
            int64_t iq = isfinite(q2) ? (int64_t)fmax(-1e6, fmin(1e6, q2)) : 0;
            key = key << 21 | (uint64_t)((iq + (1 << 20)) & ((1 << 21) - 1));
        }
        kp[q] = (key_pair){key, q};
    }
    qsort(kp, pp->n, sizeof *kp, cmp_key_pair);
    uint32_t id = 0;
    for (size_t q = 0; q < pp->n; q++) {
        if (q && kp[q].key != kp[q - 1].key) id++;
        block[kp[q].pair] = id;
    }
    free(kp);
    return block;
}

/* The estimate's inputs: E = E_sky + G (observed facets' part), S, L per facet, and with
 * directional S's direction moments; the one mode into sc, the directional one into sd (its
 * return code in *rc_dir: 0 estimated, 1 too few pairs, 2 not asked for). */
static int estimate(const rs_irradiance_state *s, int directional, rs_skyscale *sc, rs_skyscale_dir *sd, int *rc_dir,
                    rs_err *err)
{
    size_t nf = s->nf, n3 = 3 * (nf ? nf : 1);
    double *E = malloc(n3 * sizeof *E), *S = malloc(n3 * sizeof *S);
    double *Sx = directional ? malloc(n3 * sizeof *Sx) : NULL, *Sy = directional ? malloc(n3 * sizeof *Sy) : NULL;
    uint8_t *use = calloc(nf ? nf : 1, 1);
    rs_sunshadow_pairs pp = {0};
    uint32_t *block = NULL;
    int rc = -1;
    *rc_dir = 2;
    if (!E || !S || !use || (directional && (!Sx || !Sy))) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory checking the hidden sky against the facets");
        goto out;
    }
    for (size_t f = 0; f < nf; f++) {
        const rs_facet_gather *fg = &s->fg[f];
        double g[3];
        rs_gather_inter_observed(fg, s->radiance, s->observed, g);
        for (int ch = 0; ch < 3; ch++) {
            E[3 * f + ch] = fg->esky[ch] + g[ch];
            S[3 * f + ch] = fg->fill_sigma_rgb[ch];
            if (directional) {
                Sx[3 * f + ch] = fg->fill_sigma_dir[0][ch];
                Sy[3 * f + ch] = fg->fill_sigma_dir[1][ch];
            }
        }
        use[f] = s->observed[f] && !fg->relay && (fg->rays > 0 || fg->sky_sh);
    }
    double t0 = rs_now();
    if (rs_sunshadow_pairs_build(s->mesh, use, 0, PAIR_RADIUS_M, PAIR_MAX, &pp, err) != 0) goto out;
    rs_log_debug("fill_from_facets: %zu pairs in %.2f s", pp.n, rs_now() - t0);
    if (!(block = pair_blocks(s->mesh, &pp))) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory checking the hidden sky against the facets");
        goto out;
    }
    rs_skyscale_input in = {.nf = nf,
                            .E = E,
                            .S = S,
                            .L = s->radiance,
                            .a = pp.a,
                            .b = pp.b,
                            .npairs = pp.n,
                            .block = block,
                            .max_per_facet = PAIR_MAX};
    rc = rs_skyscale_estimate(&in, sc, err);
    if (rc >= 0 && directional) {
        /* each filled direction's uncertainty bounds how dark the correction may make it */
        double *limits = NULL;
        size_t nlimits = 0;
        if (rs_skyscale_dir_limits(&s->env, &limits, &nlimits, err) != 0) {
            rc = -1;
            goto out;
        }
        rs_skyscale_dir_input din = {.base = in, .Sx = Sx, .Sy = Sy, .limits = limits, .nlimits = nlimits};
        *rc_dir = rs_skyscale_dir_estimate(&din, sd, err);
        free(limits);
        if (*rc_dir < 0) rc = -1;
    }
out:
    free(E);
    free(S);
    free(Sx);
    free(Sy);
    free(use);
    free(block);
    rs_sunshadow_pairs_free(&pp);
    return rc;
}

/* irradiance.json fill_from_facets.directional. */
static void report_directional(rs_json *j, const rs_skyscale_dir *sd, int applied)
{
    rs_json *d = rs_json_set_obj(j, "directional");
    rs_json_set_int(d, "pairs", (long long)sd->pairs);
    rs_json_set_int(d, "jackknife_groups", sd->groups);
    rs_json_set_num(d, "shared_error_ratio", sd->shared_ratio);
    rs_json *tl = rs_json_set_arr(d, "t_lum"), *sl = rs_json_set_arr(d, "sigma_lum");
    for (int k = 0; k < 3; k++) {
        rs_json_push_num(tl, sd->t[3][k]);
        rs_json_push_num(sl, sqrt(sd->cov[3][k][k]));
    }
    rs_json_set_num(d, "chi2_lum", sd->chi2[3]);
    rs_json_set_num(d, "residual_spread", sd->resid_mad[3]);
    rs_json_set_bool(d, "at_bound", sd->at_bound);
    static const char *const tkey[3] = {"t_r", "t_g", "t_b"}, *const skey[3] = {"sigma_r", "sigma_g", "sigma_b"};
    for (int ch = 0; ch < 3; ch++) { /* t0 t1 t2 per channel */
        rs_json *tc = rs_json_set_arr(d, tkey[ch]), *sc = rs_json_set_arr(d, skey[ch]);
        for (int k = 0; k < 3; k++) {
            rs_json_push_num(tc, sd->t[ch][k]);
            rs_json_push_num(sc, sqrt(sd->cov[ch][k][k]));
        }
    }
    rs_json_set_bool(d, "applied", applied);
}

/* Adds the correction to every gathered facet's E_sky (and its luminance to filled_lum): the
 * directional mode's when dir is given, else the one mode's. */
static void apply(rs_irradiance_state *s, const rs_skyscale *one, const rs_skyscale_dir *dir)
{
    for (size_t f = 0; f < s->nf; f++) {
        rs_facet_gather *fg = &s->fg[f];
        double d[3];
        for (int ch = 0; ch < 3; ch++) {
            d[ch] = dir ? rs_skyscale_dir_delta(dir, ch, fg->fill_sigma_rgb[ch], fg->fill_sigma_dir[0][ch],
                                                fg->fill_sigma_dir[1][ch])
                        : one->t[ch] * fg->fill_sigma_rgb[ch];
            fg->esky[ch] = fmax(0, fg->esky[ch] + d[ch]);
        }
        double dl = rs_skyenv_luminance3(d);
        fg->esky_lum = rs_skyenv_luminance3(fg->esky);
        fg->filled_lum = fmax(0, fg->filled_lum + dl);
    }
}

int rs_irradiance_skyscale(const rs_irradiance_opts *o, rs_irradiance_state *s, rs_report *rep, rs_err *err)
{
    if (o->fill_from_facets == RS_FILL_FROM_FACETS_OFF) return 0;
    if (s->sun.active && s->sun.from_shadows) {
        /* The shadows' DNI divides by the E that the fill gives and is read from the same
         * same-plane ratios: the evidence would count twice. A joint fit is not built. */
        rs_report_skip(rep, "hidden sky from the facets",
                       "a sun from the shadows was estimated from the same same-plane ratios");
        return 0;
    }
    double t0 = rs_now();
    rs_skyscale sc;
    rs_skyscale_dir sd;
    int rc_dir;
    int rc = estimate(s, o->fill_directional, &sc, &sd, &rc_dir, err);
    if (rc < 0) return -1;
    rs_report_time(rep, "fill_from_facets", rs_now() - t0);
    rs_json *j = rs_json_set_obj(rep->metrics, "fill_from_facets");
    rs_json_set_int(j, "pairs", (long long)sc.pairs);
    rs_json_set_int(j, "facets", (long long)sc.facets);
    rs_json_set_num(j, "t_lum", sc.t_lum);
    rs_json_set_num(j, "sigma_lum", sc.sigma_lum);
    rs_json_set_num(j, "residual_spread", sc.resid_mad);
    rs_json_set_bool(j, "at_bound", sc.at_bound);
    rs_json *jt = rs_json_set_arr(j, "t"), *js = rs_json_set_arr(j, "sigma");
    for (int ch = 0; ch < 3; ch++) {
        rs_json_push_num(jt, sc.t[ch]);
        rs_json_push_num(js, sc.sigma[ch]);
    }
    /* The directional mode, when its direction-dependent part is significant and every direction's
     * correction stays in range, replaces the one mode (under on and auto alike: it is applied on
     * evidence, the one mode is its fallback). */
    int use_dir = rc_dir == 0 && !sd.at_bound && sd.chi2[3] >= RS_SKYSCALE_DIR_CHI2;
    if (rc_dir != 2) report_directional(j, &sd, use_dir);
    if (use_dir) {
        rs_json_set_bool(j, "applied", 1);
        rs_json_set_str(j, "mode", "directional");
        apply(s, NULL, &sd);
        rs_log_info("irradiance: the hidden sky from %zu same-plane pairs, by direction: t0 t1 t2 (luminance) %+.3g "
                    "%+.3g %+.3g (+- %.2g %.2g %.2g; chi-square of t1 t2 %.3g) times the fill's uncertainty",
                    sd.pairs, sd.t[3][0], sd.t[3][1], sd.t[3][2], sqrt(sd.cov[3][0][0]), sqrt(sd.cov[3][1][1]),
                    sqrt(sd.cov[3][2][2]), sd.chi2[3]);
        return 0;
    }
    const char *why = NULL;
    if (rc == 1)
        why = "too few same-plane pairs of observed facets see different shares of the filled sky";
    else if (o->fill_from_facets == RS_FILL_FROM_FACETS_AUTO && sc.at_bound)
        why = "the one mode of the fill's error does not explain the facets (its fit lies at the edge of its range)";
    else if (o->fill_from_facets == RS_FILL_FROM_FACETS_AUTO && !(fabs(sc.t_lum) >= APPLY_Z * sc.sigma_lum))
        why = "the facets do not tell the hidden sky's brightness from the fill's (|t| below 2 sigma)";
    rs_json_set_bool(j, "applied", why == NULL);
    if (why) {
        rs_report_skip(rep, "hidden sky from the facets", "%s: t %.3g +- %.2g from %zu pairs", why, sc.t_lum,
                       sc.sigma_lum, sc.pairs);
        return 0;
    }
    rs_json_set_str(j, "mode", "one");
    apply(s, &sc, NULL);
    rs_log_info("irradiance: the hidden sky from %zu same-plane pairs of %zu observed facets: %+.3g %+.3g %+.3g "
                "(+- %.2g %.2g %.2g) times the fill's uncertainty (luminance %+.3g +- %.2g; residual spread %.3g)",
                sc.pairs, sc.facets, sc.t[0], sc.t[1], sc.t[2], sc.sigma[0], sc.sigma[1], sc.sigma[2], sc.t_lum,
                sc.sigma_lum, sc.resid_mad);
    return 0;
}
