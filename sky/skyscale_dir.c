/* skyscale_dir: the hidden sky's direction-dependent error from same-plane facets (see
 * skyscale_dir.h). */
#include "sky/skyscale_dir.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/pano.h"
#include "common/select.h"
#include "sky/skyenv.h"

#define HUBER_K    1.345 /* Huber's constant, in units of the residuals' robust spread */
#define LIGHT_KEPT 0.1   /* every filled direction keeps at least this share of its light: the
                            multiplier t0 + t1 x + t2 y stays at or above -(1 - it) / sigma_max */
#define T_HI       12.0  /* ... and at or below this (skyscale.c's range for the one mode) */
#define BOUND_TOL  0.05  /* a fit this close to the range's edge is at it */
#define FIT_MAX    20000 /* the pairs a fit reads at most (every stride-th) */
#define MAX_ITER   40
#define MIN_GROUPS 8     /* non-empty jackknife groups for a spread; fewer: no evidence */

typedef struct {
    double lr; /* log(L_i / L_j) */
    double ei, ej;
    double si[3], sj[3]; /* (S, Sx, Sy) of each facet */
    uint32_t group;
} dpair;

static double lum(const double *rgb)
{
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

static double median(double *v, size_t n)
{
    double hi = rs_select_kth_double(v, n, n / 2);
    return n % 2 ? hi : 0.5 * (hi + rs_select_kth_double(v, n, n / 2 - 1));
}

static double dot3(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* The residual at t and, with J, its gradient dr/dt. */
static double resid(const dpair *p, const double *t, double *J)
{
    double a = p->ei + dot3(t, p->si), b = p->ej + dot3(t, p->sj);
    if (!(a > 0) || !(b > 0)) {
        if (J) J[0] = J[1] = J[2] = 0;
        return 1e3;
    }
    if (J)
        for (int k = 0; k < 3; k++) J[k] = -(p->si[k] / a - p->sj[k] / b);
    return p->lr - log(a / b);
}

static double huber(double z)
{
    double a = fabs(z);
    return a <= HUBER_K ? 0.5 * z * z : HUBER_K * (a - 0.5 * HUBER_K);
}

/* Every direction's multiplier within the range (the moments' directions have |(x, y)| <= 1). */
typedef struct {
    double lo;           /* without limits: the lowest multiplier anywhere */
    const double *limit; /* x, y, lowest per filled direction */
    size_t n;
} range;

static int feasible(const double *t, const range *rg, double margin)
{
    double h = hypot(t[1], t[2]);
    if (t[0] + h > T_HI - margin) return 0;
    if (!rg->limit) return t[0] - h >= rg->lo + margin;
    for (size_t k = 0; k < rg->n; k++) {
        const double *l = rg->limit + 3 * k;
        if (t[0] + t[1] * l[0] + t[2] * l[1] < l[2] + margin) return 0;
    }
    return 1;
}

/* Inverse of a symmetric 3 x 3 matrix; 0 when singular. */
static int inv3(const double m[3][3], double out[3][3])
{
    double c00 = m[1][1] * m[2][2] - m[1][2] * m[2][1], c01 = m[1][2] * m[2][0] - m[1][0] * m[2][2],
           c02 = m[1][0] * m[2][1] - m[1][1] * m[2][0];
    double det = m[0][0] * c00 + m[0][1] * c01 + m[0][2] * c02;
    double scale = fabs(m[0][0]) + fabs(m[1][1]) + fabs(m[2][2]);
    if (!(fabs(det) > 1e-15 * scale * scale * scale) || !isfinite(det)) return 0;
    out[0][0] = c00 / det;
    out[1][0] = c01 / det;
    out[2][0] = c02 / det;
    out[0][1] = (m[0][2] * m[2][1] - m[0][1] * m[2][2]) / det;
    out[1][1] = (m[0][0] * m[2][2] - m[0][2] * m[2][0]) / det;
    out[2][1] = (m[0][1] * m[2][0] - m[0][0] * m[2][1]) / det;
    out[0][2] = (m[0][1] * m[1][2] - m[0][2] * m[1][1]) / det;
    out[1][2] = (m[0][2] * m[1][0] - m[0][0] * m[1][2]) / det;
    out[2][2] = (m[0][0] * m[1][1] - m[0][1] * m[1][0]) / det;
    return 1;
}

/* The Huber cost of the pairs taken every stride-th, group `skip` left out (-1: none). */
static double cost(const dpair *p, size_t n, size_t stride, long skip, double scale, const double *t)
{
    double c = 0;
    for (size_t k = 0; k < n; k += stride)
        if ((long)p[k].group != skip) c += huber(resid(&p[k], t, NULL) / scale);
    return c;
}

/* t minimising that cost from t (in place), by Gauss-Newton on the reweighted squares (Huber's
 * weights min(1, k / |r / scale|)), each step halved until it lowers the cost within range. */
static void fit(const dpair *p, size_t n, size_t stride, long skip, double scale, const range *lo, double *t)
{
    double c = cost(p, n, stride, skip, scale, t);
    for (int it = 0; it < MAX_ITER; it++) {
        double H[3][3] = {{0}}, g[3] = {0}, J[3];
        for (size_t k = 0; k < n; k += stride) {
            if ((long)p[k].group == skip) continue;
            double r = resid(&p[k], t, J), z = fabs(r / scale), w = z <= HUBER_K ? 1 : HUBER_K / z;
            for (int a = 0; a < 3; a++) {
                g[a] += w * J[a] * r;
                for (int b = 0; b < 3; b++) H[a][b] += w * J[a] * J[b];
            }
        }
        /* a tiny ridge: a moment that no pair varies (one wall alone) leaves H singular */
        double tr = H[0][0] + H[1][1] + H[2][2], Hi[3][3];
        for (int a = 0; a < 3; a++) H[a][a] += 1e-6 * tr + 1e-300;
        if (!inv3(H, Hi)) return;
        double step[3];
        for (int a = 0; a < 3; a++) step[a] = -(Hi[a][0] * g[0] + Hi[a][1] * g[1] + Hi[a][2] * g[2]);
        double f = 1, tn[3], cn = INFINITY;
        for (int h = 0; h < 30; h++, f *= 0.5) {
            for (int a = 0; a < 3; a++) tn[a] = t[a] + f * step[a];
            if (!feasible(tn, lo, 0)) continue;
            cn = cost(p, n, stride, skip, scale, tn);
            if (cn <= c) break;
        }
        if (!(cn <= c)) return;
        double moved = fabs(tn[0] - t[0]) + fabs(tn[1] - t[1]) + fabs(tn[2] - t[2]);
        memcpy(t, tn, sizeof tn);
        c = cn;
        if (moved < 1e-7) return;
    }
}

/* The robust spread (1.4826 MAD about 0) of the residuals at t. */
static double spread(const dpair *p, size_t n, const double *t, double *scratch)
{
    for (size_t k = 0; k < n; k++) scratch[k] = fabs(resid(&p[k], t, NULL));
    return 1.4826 * median(scratch, n);
}

/* The pairs of channel ch (0..2, 3 luminance) that inform some term: the facets' shares of one
 * of the moments differ by RS_SKYSCALE_MIN_CONTRAST. */
static size_t collect(const rs_skyscale_dir_input *in, int ch, dpair *p)
{
    const rs_skyscale_input *b = &in->base;
    size_t n = 0;
    for (size_t q = 0; q < b->npairs; q++) {
        uint32_t ij[2] = {b->a[q], b->b[q]};
        double e[2], l[2], s[2][3];
        for (int u = 0; u < 2; u++) {
            size_t f = ij[u];
            const double *m[3] = {b->S + 3 * f, in->Sx + 3 * f, in->Sy + 3 * f};
            e[u] = ch < 3 ? b->E[3 * f + ch] : lum(b->E + 3 * f);
            l[u] = ch < 3 ? b->L[3 * f + ch] : lum(b->L + 3 * f);
            for (int k = 0; k < 3; k++) s[u][k] = ch < 3 ? m[k][ch] : lum(m[k]);
        }
        if (!(e[0] > 0 && e[1] > 0 && l[0] > 0 && l[1] > 0 && s[0][0] >= 0 && s[1][0] >= 0)) continue;
        double contrast = 0, sum = e[0] + e[1] + l[0] + l[1];
        for (int k = 0; k < 3; k++) {
            contrast = fmax(contrast, fabs(s[0][k] / e[0] - s[1][k] / e[1]));
            sum += s[0][k] + s[1][k];
        }
        if (!isfinite(sum) || contrast < RS_SKYSCALE_MIN_CONTRAST) continue;
        dpair *d = &p[n++];
        d->lr = log(l[0] / l[1]);
        d->ei = e[0], d->ej = e[1];
        memcpy(d->si, s[0], sizeof d->si);
        memcpy(d->sj, s[1], sizeof d->sj);
        d->group = b->block ? b->block[q] % RS_SKYSCALE_DIR_GROUPS : 0;
    }
    return n;
}

/* One channel: the data's t and covariance, then the prior N(0, I) folded in. */
static size_t channel(const rs_skyscale_dir_input *in, int ch, dpair *p, double *scratch, double t_out[3],
                      double cov_out[3][3], double *chi2, double *mad, int *at_bound, int *groups_out, double *lambda_out)
{
    memset(t_out, 0, 3 * sizeof *t_out);
    memset(cov_out, 0, 9 * sizeof(double));
    for (int a = 0; a < 3; a++) cov_out[a][a] = 1;
    *chi2 = 0, *mad = 0;
    size_t n = collect(in, ch, p);
    if (n < RS_SKYSCALE_MIN_PAIRS) return n;
    size_t stride = (n + FIT_MAX - 1) / FIT_MAX;
    range rg = {rs_skyscale_dir_lowest(in->sigma_max), in->limits, in->nlimits}, *lo = &rg;
    double t[3] = {0, 0, 0};
    double scale = fmax(spread(p, n, t, scratch), 1e-6);
    fit(p, n, stride, -1, scale, lo, t);
    scale = fmax(spread(p, n, t, scratch), 1e-6);
    fit(p, n, stride, -1, scale, lo, t);
    *mad = scale;
    if (at_bound) *at_bound = !feasible(t, lo, BOUND_TOL);
    /* Curvature over every pair inside Huber's core, each facet counted once (skyscale.c): the
     * information Hc = sum J J^T / (scale^2 dep). A term no pair tells from the others leaves it
     * singular; the prior then holds that combination. */
    double Hc[3][3] = {{0}}, J[3], Cc[3][3], R[3][3];
    for (size_t k = 0; k < n; k++) {
        double r = resid(&p[k], t, J);
        if (fabs(r / scale) > HUBER_K) continue;
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) Hc[a][b] += J[a] * J[b];
    }
    double dep = in->base.max_per_facet > 1 ? in->base.max_per_facet / 2 : 1, tr = 0;
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++) Hc[a][b] /= scale * scale * dep;
    for (int a = 0; a < 3; a++) tr += Hc[a][a];
    memcpy(R, Hc, sizeof R);
    for (int a = 0; a < 3; a++) R[a][a] += 1e-6 * tr + 1e-300;
    int have_cc = inv3(R, Cc);
    /* Jackknife over groups of blocks, each left out in turn: where its variance of a term
     * exceeds the curvature's, errors a wall's facets share are at work, and the information is
     * deflated by the largest such ratio (the one mode's rule, skyscale.c, in three terms). */
    double lambda = 1;
    int m = 0;
    if (in->base.block) {
        double tg[RS_SKYSCALE_DIR_GROUPS][3], mean[3] = {0, 0, 0};
        size_t count[RS_SKYSCALE_DIR_GROUPS] = {0};
        for (size_t k = 0; k < n; k += stride) count[p[k].group]++;
        for (int g = 0; g < RS_SKYSCALE_DIR_GROUPS; g++) {
            if (!count[g]) continue;
            memcpy(tg[m], t, sizeof t);
            fit(p, n, stride, g, scale, lo, tg[m]);
            for (int a = 0; a < 3; a++) mean[a] += tg[m][a];
            m++;
        }
        if (m < MIN_GROUPS) {
            if (groups_out) *groups_out = m;
            return n; /* too few groups to know the shared errors: no evidence, the prior */
        }
        for (int a = 0; a < 3; a++) mean[a] /= m;
        for (int a = 0; a < 3; a++) {
            double v = 0;
            for (int g = 0; g < m; g++) v += (tg[g][a] - mean[a]) * (tg[g][a] - mean[a]);
            v *= (m - 1.0) / m;
            if (have_cc && Cc[a][a] > 0) lambda = fmax(lambda, v / Cc[a][a]);
        }
    }
    if (groups_out) *groups_out = m;
    if (lambda_out) *lambda_out = lambda;
    /* The prior N(0, I): precision P = Hc / lambda + I, mode P^-1 (Hc / lambda) t. */
    double P[3][3], Pi[3][3], Ht[3];
    for (int a = 0; a < 3; a++) {
        Ht[a] = (Hc[a][0] * t[0] + Hc[a][1] * t[1] + Hc[a][2] * t[2]) / lambda;
        for (int b = 0; b < 3; b++) P[a][b] = Hc[a][b] / lambda + (a == b);
    }
    if (!inv3(P, Pi)) return n;
    for (int a = 0; a < 3; a++) {
        t_out[a] = Pi[a][0] * Ht[0] + Pi[a][1] * Ht[1] + Pi[a][2] * Ht[2];
        for (int b = 0; b < 3; b++) cov_out[a][b] = Pi[a][b];
    }
    /* (t1, t2) against 0 under its 2 x 2 block */
    double a11 = Pi[1][1], a12 = Pi[1][2], a22 = Pi[2][2], det = a11 * a22 - a12 * a12;
    if (det > 0)
        *chi2 = (a22 * t_out[1] * t_out[1] - 2 * a12 * t_out[1] * t_out[2] + a11 * t_out[2] * t_out[2]) / det;
    return n;
}

int rs_skyscale_dir_estimate(const rs_skyscale_dir_input *in, rs_skyscale_dir *out, rs_err *err)
{
    memset(out, 0, sizeof *out);
    out->lowest = rs_skyscale_dir_lowest(in->sigma_max);
    for (int c = 0; c < 4; c++)
        for (int a = 0; a < 3; a++) out->cov[c][a][a] = 1;
    size_t np = in->base.npairs ? in->base.npairs : 1;
    dpair *p = malloc(np * sizeof *p);
    double *scratch = malloc(np * sizeof *scratch);
    if (!p || !scratch) {
        free(p);
        free(scratch);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0,
                          "out of memory checking the hidden sky's directions against the facets");
    }
    out->pairs = channel(in, 3, p, scratch, out->t[3], out->cov[3], &out->chi2[3], &out->resid_mad[3], &out->at_bound,
                         &out->groups, &out->shared_ratio);
    int rc = out->pairs >= RS_SKYSCALE_MIN_PAIRS ? 0 : 1;
    for (int c = 0; rc == 0 && c < 3; c++)
        channel(in, c, p, scratch, out->t[c], out->cov[c], &out->chi2[c], &out->resid_mad[c], NULL, NULL, NULL);
    free(p);
    free(scratch);
    return rc;
}

int rs_skyscale_dir_limits(const rs_skyenv *env, double **limits, size_t *n, rs_err *err)
{
    enum { AZ = 72, EL = 36 }; /* 5 degree cells over the sphere (elevation -90 to 90) */
    double *cell = malloc((size_t)AZ * EL * 3 * sizeof *cell), *best = calloc((size_t)AZ * EL, sizeof *best);
    *limits = NULL, *n = 0;
    if (!cell || !best) {
        free(cell);
        free(best);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory bounding the hidden sky's correction");
    }
    for (int r = 0; env->fill_sigma_px && r < env->height; r++)
        for (int c = 0; c < env->width; c++) {
            size_t p = (size_t)r * env->width + c;
            double sg = env->fill_sigma_px[p];
            if (!env->filled[p] || !(sg > 0)) continue;
            rs_v3 d = rs_pose_dir_to_world(&env->pose, rs_pano_pixel_dir(env->width, env->height, c, r));
            double az = atan2(d.y, d.x), el = asin(fmax(-1, fmin(1, d.z)));
            int ia = (int)floor((az + M_PI) / (2 * M_PI) * AZ), ie = (int)floor((el + M_PI / 2) / M_PI * EL);
            ia = ia < 0 ? 0 : ia >= AZ ? AZ - 1 : ia;
            ie = ie < 0 ? 0 : ie >= EL ? EL - 1 : ie;
            size_t k = (size_t)ie * AZ + ia;
            if (sg > best[k]) best[k] = sg, cell[3 * k] = d.x, cell[3 * k + 1] = d.y;
        }
    size_t m = 0;
    for (size_t k = 0; k < (size_t)AZ * EL; k++)
        if (best[k] > 0) {
            cell[3 * m] = cell[3 * k], cell[3 * m + 1] = cell[3 * k + 1];
            cell[3 * m + 2] = -(1 - LIGHT_KEPT) / fmin(1, best[k]);
            m++;
        }
    free(best);
    if (!m) {
        free(cell);
        return 0;
    }
    *limits = cell, *n = m;
    return 0;
}

double rs_skyscale_dir_lowest(double sigma_max)
{
    if (!(sigma_max > 0) || sigma_max > 1) sigma_max = 1;
    return -(1 - LIGHT_KEPT) / sigma_max;
}

double rs_skyscale_dir_delta(const rs_skyscale_dir *d, int ch, double S, double Sx, double Sy)
{
    return d->t[ch][0] * S + d->t[ch][1] * Sx + d->t[ch][2] * Sy;
}
