/* gains: robust per-camera gains from the overlaps' log ratios (see gains.h). */
#include "calib/gains.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/linsolve.h"

#define TUKEY_C     4.685 /* 95 % efficiency at the normal distribution */
#define SPREAD_MIN  0.005 /* a pair's spread is never taken as smaller: noise-free pairs would rule the solve */
#define SIGMA_MIN   1e-4  /* the biweight's scale floor (identical frames have MAD 0) */
#define TUKEY_ITERS 20

int rs_gain_samples_add(rs_gain_samples *s, float log_ratio, float weight)
{
    if (s->count == s->cap) {
        size_t cap = s->cap ? 2 * s->cap : 256;
        float *lr = realloc(s->log_ratio, cap * sizeof *lr);
        if (!lr) return -1;
        s->log_ratio = lr;
        float *w = realloc(s->weight, cap * sizeof *w);
        if (!w) return -1;
        s->weight = w;
        s->cap = cap;
    }
    s->log_ratio[s->count] = log_ratio;
    s->weight[s->count] = weight;
    s->count++;
    return 0;
}

void rs_gain_samples_free(rs_gain_samples *s)
{
    free(s->log_ratio);
    free(s->weight);
    memset(s, 0, sizeof *s);
}

void rs_gain_report_free(rs_gain_report *r)
{
    if (!r) return;
    free(r->pairs);
    memset(r, 0, sizeof *r);
}

typedef struct {
    float v, w;
} value_weight;

/* By value, then weight: equal elements are identical, so the sorted order (and every sum over
 * it) does not depend on the order the samples came in. */
static int by_value(const void *a, const void *b)
{
    const value_weight *x = a, *y = b;
    if (x->v != y->v) return x->v < y->v ? -1 : 1;
    return x->w < y->w ? -1 : x->w > y->w;
}

/* The weighted median of sorted vw[0..n): the first value at which the cumulative weight
 * reaches half the total. */
static double weighted_median(const value_weight *vw, size_t n, double total)
{
    double acc = 0;
    for (size_t k = 0; k < n; k++) {
        acc += vw[k].w;
        if (acc >= 0.5 * total) return vw[k].v;
    }
    return n ? vw[n - 1].v : 0;
}

int rs_gain_pair_estimate(const rs_gain_samples *s, double *log_ratio, double *spread, double *inlier)
{
    size_t n = 0;
    value_weight *vw = malloc((s->count ? s->count : 1) * sizeof *vw);
    if (!vw) return -1;
    double total = 0;
    for (size_t k = 0; k < s->count; k++)
        if (s->weight[k] > 0 && isfinite(s->log_ratio[k])) {
            vw[n].v = s->log_ratio[k], vw[n].w = s->weight[k];
            total += vw[n++].w;
        }
    if (n == 0 || !(total > 0)) {
        free(vw);
        return -1;
    }
    qsort(vw, n, sizeof *vw, by_value);
    double mu = weighted_median(vw, n, total);
    /* The scale: the weighted median of the absolute deviations. */
    value_weight *dev = malloc(n * sizeof *dev);
    if (!dev) {
        free(vw);
        return -1;
    }
    for (size_t k = 0; k < n; k++) dev[k].v = fabsf(vw[k].v - (float)mu), dev[k].w = vw[k].w;
    qsort(dev, n, sizeof *dev, by_value);
    double sigma = 1.4826 * weighted_median(dev, n, total);
    free(dev);
    double c = TUKEY_C * fmax(sigma, SIGMA_MIN), kept = total;
    for (int it = 0; it < TUKEY_ITERS; it++) {
        double sw = 0, swr = 0;
        kept = 0;
        for (size_t k = 0; k < n; k++) {
            double u = (vw[k].v - mu) / c;
            if (fabs(u) >= 1) continue;
            double t = 1 - u * u, w = vw[k].w * t * t;
            sw += w, swr += w * vw[k].v, kept += vw[k].w;
        }
        if (!(sw > 0)) break;
        double next = swr / sw;
        int done = fabs(next - mu) < 1e-9;
        mu = next;
        if (done) break;
    }
    free(vw);
    *log_ratio = mu;
    if (spread) *spread = sigma;
    if (inlier) *inlier = kept / total;
    return 0;
}

/* The normal equations of ln g_i - ln g_j = r_ij over the pairs, known gains substituted, and
 * (without any known gain) the geometric mean 1 as a penalty. x gets ln g. */
static int solve_logs(int n, const rs_gain_pair *pairs, const double *pair_w, int npairs, const double *known,
                      double *x)
{
    double *a = calloc((size_t)n * n, sizeof *a);
    if (!a) return -1;
    double wsum = 0;
    memset(x, 0, (size_t)n * sizeof *x);
    for (int p = 0; p < npairs; p++) {
        int i = pairs[p].i, j = pairs[p].j;
        double w = pair_w[p], r = pairs[p].log_ratio;
        a[i * n + i] += w, a[j * n + j] += w;
        a[i * n + j] -= w, a[j * n + i] -= w;
        x[i] += w * r, x[j] -= w * r;
        wsum += w;
    }
    double lam = wsum > 0 ? wsum / n : 1;
    int any_known = 0;
    for (int k = 0; k < n; k++) any_known |= known && known[k] > 0;
    for (int k = 0; k < n; k++) {
        if (!(known && known[k] > 0)) continue;
        double lk = log(known[k]);
        for (int i = 0; i < n; i++) {
            if (i == k) continue;
            x[i] -= a[i * n + k] * lk;
            a[i * n + k] = 0;
            a[k * n + i] = 0;
        }
        a[k * n + k] = 1;
        x[k] = lk;
    }
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            int fixed = known && (known[i] > 0 || known[j] > 0);
            if (!any_known) a[i * n + j] += lam / n;
            /* A camera in no pair (or a part of the rig linked to nothing known) stays at 1. */
            if (i == j && !fixed) a[i * n + i] += 1e-9 * lam;
        }
    int rc = rs_solve_dense(a, x, (size_t)n);
    free(a);
    if (rc != 0)
        for (int i = 0; i < n; i++) x[i] = known && known[i] > 0 ? log(known[i]) : 0;
    return 0;
}

int rs_gains_solve(int n, const rs_gain_samples *samples, const double *known, double *gains, rs_gain_report *report)
{
    rs_gain_pair *pairs = calloc((size_t)n * n + 1, sizeof *pairs);
    double *pair_w = calloc((size_t)n * n + 1, sizeof *pair_w), *x = calloc((size_t)n + 1, sizeof *x);
    double *pair_n = calloc((size_t)n * n + 1, sizeof *pair_n);
    if (!pairs || !pair_w || !x || !pair_n) goto oom;
    int np = 0;
    for (int i = 0; i < n; i++)
        for (int j = i + 1; j < n; j++) {
            const rs_gain_samples *s = &samples[i * n + j];
            if (s->count < RS_GAIN_MIN_SAMPLES) continue;
            rs_gain_pair *p = &pairs[np];
            if (rs_gain_pair_estimate(s, &p->log_ratio, &p->spread, &p->inlier) != 0) continue;
            p->i = i, p->j = j, p->samples = s->count;
            double wsum = 0;
            for (size_t k = 0; k < s->count; k++) wsum += s->weight[k];
            double sp = fmax(p->spread, SPREAD_MIN);
            pair_n[np] = wsum * p->inlier;
            pair_w[np++] = wsum * p->inlier / (sp * sp);
        }
    if (solve_logs(n, pairs, pair_w, np, known, x) != 0) goto oom;
    double rw = 0, rr = 0;
    for (int p = 0; p < np; p++) {
        pairs[p].residual = x[pairs[p].i] - x[pairs[p].j] - pairs[p].log_ratio;
        rw += pair_n[p], rr += pair_n[p] * pairs[p].residual * pairs[p].residual;
    }
    for (int i = 0; i < n; i++) gains[i] = exp(x[i]);
    if (report) {
        report->npairs = np;
        report->pairs = pairs;
        report->residual_rms = rw > 0 ? sqrt(rr / rw) : 0;
        report->fixed = 0;
        for (int i = 0; i < n; i++) report->fixed += known && known[i] > 0;
        pairs = NULL;
    }
    free(pairs);
    free(pair_w);
    free(pair_n);
    free(x);
    return 0;
oom:
    free(pairs);
    free(pair_w);
    free(pair_n);
    free(x);
    return -1;
}
