/* skyscale: the hidden sky's brightness from same-plane facets (see skyscale.h). */
#include "sky/skyscale.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/select.h"

#define HUBER_K   1.345 /* Huber's constant, in units of the residuals' robust spread */
#define T_LO      -0.9  /* t's range: E + t S stays positive for sigma <= 1 */
#define T_HI      12.0
#define T_STEPS   96
#define MIN_BLOCK 10    /* informative pairs for a block's own estimate */
#define BLOCK_MAX 256   /* the pairs a block's own fit reads at most */
#define FIT_MAX   20000 /* the pairs a fit reads at most (every stride-th): the grid costs T_STEPS passes */

typedef struct {
    double lr; /* log(L_i / L_j) */
    double ei, si, ej, sj;
    uint32_t block;
    size_t order; /* index among the pairs: a total order for the sort */
} pair_pt;

/* The median of v[0..n) (n > 0; v reordered). */
static double median(double *v, size_t n)
{
    double hi = rs_select_kth_double(v, n, n / 2);
    return n % 2 ? hi : 0.5 * (hi + rs_select_kth_double(v, n, n / 2 - 1));
}

static double lum(const double *rgb)
{
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

static double resid(const pair_pt *p, double t)
{
    double a = p->ei + t * p->si, b = p->ej + t * p->sj;
    if (!(a > 0) || !(b > 0)) return 1e3;
    return p->lr - log(a / b);
}

static double huber(double z)
{
    double a = fabs(z);
    return a <= HUBER_K ? 0.5 * z * z : HUBER_K * (a - 0.5 * HUBER_K);
}

/* The robust spread (1.4826 MAD about 0) of the residuals at t. scratch: n doubles. */
static double spread(const pair_pt *p, size_t n, double t, double *scratch)
{
    for (size_t k = 0; k < n; k++) scratch[k] = fabs(resid(&p[k], t));
    return 1.4826 * median(scratch, n);
}

/* t minimising the Huber cost of the pairs p[0..n) taken every stride-th, on a grid then by
 * golden section around its best. */
static double fit_t(const pair_pt *p, size_t n, size_t stride, double scale)
{
    double best = 0, bc = INFINITY, step = (T_HI - T_LO) / T_STEPS;
    for (int s = 0; s <= T_STEPS; s++) {
        double t = T_LO + s * step, c = 0;
        for (size_t k = 0; k < n; k += stride) c += huber(resid(&p[k], t) / scale);
        if (c < bc) bc = c, best = t;
    }
    double lo = fmax(T_LO, best - step), hi = fmin(T_HI, best + step);
    const double gr = 0.6180339887498949;
    for (int it = 0; it < 30; it++) {
        double x1 = hi - gr * (hi - lo), x2 = lo + gr * (hi - lo), c1 = 0, c2 = 0;
        for (size_t k = 0; k < n; k += stride) {
            c1 += huber(resid(&p[k], x1) / scale);
            c2 += huber(resid(&p[k], x2) / scale);
        }
        if (c1 < c2)
            hi = x2;
        else
            lo = x1;
    }
    return 0.5 * (lo + hi);
}

static int cmp_block(const void *a, const void *b)
{
    const pair_pt *x = a, *y = b;
    if (x->block != y->block) return x->block < y->block ? -1 : 1;
    return (x->order > y->order) - (x->order < y->order);
}

/* One channel (ch 0..2, or 3 for luminance): the data's t, its standard error (the larger of the
 * curvature's, counted over independent facets, and the spread between blocks), then the prior
 * N(0, 1) folded in. Returns the informative pairs. */
static size_t channel(const rs_skyscale_input *in, const uint32_t *block, int ch, pair_pt *p, double *scratch,
                      double *t_out, double *sigma_out, double *mad_out, int *at_bound)
{
    size_t n = 0;
    for (size_t q = 0; q < in->npairs; q++) {
        uint32_t i = in->a[q], j = in->b[q];
        double ei, ej, si, sj, li, lj;
        if (ch < 3) {
            ei = in->E[3 * i + ch], ej = in->E[3 * j + ch], si = in->S[3 * i + ch], sj = in->S[3 * j + ch];
            li = in->L[3 * i + ch], lj = in->L[3 * j + ch];
        } else {
            ei = lum(in->E + 3 * i), ej = lum(in->E + 3 * j), si = lum(in->S + 3 * i), sj = lum(in->S + 3 * j);
            li = lum(in->L + 3 * i), lj = lum(in->L + 3 * j);
        }
        if (!(ei > 0 && ej > 0 && li > 0 && lj > 0 && si >= 0 && sj >= 0) || !isfinite(si + sj + li + lj + ei + ej))
            continue;
        if (fabs(si / ei - sj / ej) < RS_SKYSCALE_MIN_CONTRAST) continue;
        /* order each pair so that i sees more of the uncertain light: a block's pairs then pull
         * the same way, and the sign of a residual means the same thing in every pair */
        if (si / ei < sj / ej) {
            double tmp;
            tmp = ei, ei = ej, ej = tmp;
            tmp = si, si = sj, sj = tmp;
            tmp = li, li = lj, lj = tmp;
        }
        p[n] = (pair_pt){log(li / lj), ei, si, ej, sj, block ? block[q] : 0, n};
        n++;
    }
    *t_out = 0, *sigma_out = 1, *mad_out = 0;
    if (n < RS_SKYSCALE_MIN_PAIRS) return n;
    size_t stride = (n + FIT_MAX - 1) / FIT_MAX;
    double scale = fmax(spread(p, n, 0, scratch), 1e-6);
    double t = fit_t(p, n, stride, scale);
    scale = fmax(spread(p, n, t, scratch), 1e-6);
    t = fit_t(p, n, stride, scale);
    *mad_out = scale;
    /* Curvature: the sum of (dr/dt)^2 over the pairs inside Huber's core, over scale^2, counted
     * as if each facet entered one pair (a facet shares its noise among max_per_facet pairs). */
    double info = 0;
    size_t core = 0;
    for (size_t k = 0; k < n; k++) {
        double r = resid(&p[k], t);
        if (fabs(r / scale) > HUBER_K) continue;
        double d = p[k].si / (p[k].ei + t * p[k].si) - p[k].sj / (p[k].ej + t * p[k].sj);
        info += d * d;
        core++;
    }
    double dep = in->max_per_facet > 1 ? in->max_per_facet / 2 : 1;
    double sig_curv = info > 0 ? scale * sqrt(dep / info) : 1e3;
    /* Blocks: each one's own t; the spread of those says what shared errors within a wall do. */
    double sig_blocks = 0;
    if (block) {
        qsort(p, n, sizeof *p, cmp_block);
        size_t m = 0;
        for (size_t lo = 0, hi; lo < n; lo = hi) {
            for (hi = lo; hi < n && p[hi].block == p[lo].block;) hi++;
            if (hi - lo >= MIN_BLOCK)
                scratch[m++] = fit_t(p + lo, hi - lo, (hi - lo + BLOCK_MAX - 1) / BLOCK_MAX, scale);
        }
        if (m >= 4) {
            double med = median(scratch, m);
            for (size_t k = 0; k < m; k++) scratch[k] = fabs(scratch[k] - med);
            sig_blocks = 1.2533 * 1.4826 * median(scratch, m) / sqrt((double)m);
        } else
            sig_blocks = 1e3; /* too few blocks to know the shared errors: no evidence */
    }
    double sd = fmax(sig_curv, sig_blocks), v = sd * sd;
    (void)core;
    if (at_bound) *at_bound = t < T_LO + (T_HI - T_LO) / T_STEPS || t > T_HI - (T_HI - T_LO) / T_STEPS;
    *t_out = t / (1 + v); /* the prior N(0, 1) and the data N(t, sd^2) */
    *sigma_out = sd / sqrt(1 + v);
    return n;
}

int rs_skyscale_estimate(const rs_skyscale_input *in, rs_skyscale *out, rs_err *err)
{
    memset(out, 0, sizeof *out);
    for (int c = 0; c < 3; c++) out->sigma[c] = 1;
    out->sigma_lum = 1;
    size_t np = in->npairs ? in->npairs : 1;
    pair_pt *p = malloc(np * sizeof *p);
    double *scratch = malloc(np * sizeof *scratch);
    uint8_t *seen = calloc(in->nf ? in->nf : 1, 1);
    if (!p || !scratch || !seen) {
        free(p);
        free(scratch);
        free(seen);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory checking the hidden sky against the facets");
    }
    double mad;
    out->pairs = channel(in, in->block, 3, p, scratch, &out->t_lum, &out->sigma_lum, &out->resid_mad, &out->at_bound);
    for (size_t q = 0; q < in->npairs; q++) {
        uint32_t i = in->a[q], j = in->b[q];
        double gi = lum(in->E + 3 * i) > 0 ? lum(in->S + 3 * i) / lum(in->E + 3 * i) : 0;
        double gj = lum(in->E + 3 * j) > 0 ? lum(in->S + 3 * j) / lum(in->E + 3 * j) : 0;
        if (fabs(gi - gj) >= RS_SKYSCALE_MIN_CONTRAST) seen[i] = seen[j] = 1;
    }
    for (size_t f = 0; f < in->nf; f++) out->facets += seen[f];
    int rc = out->pairs >= RS_SKYSCALE_MIN_PAIRS ? 0 : 1;
    for (int c = 0; rc == 0 && c < 3; c++)
        channel(in, in->block, c, p, scratch, &out->t[c], &out->sigma[c], &mad, NULL);
    free(p);
    free(scratch);
    free(seen);
    return rc;
}
