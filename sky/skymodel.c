/* skymodel: Perez all-weather sky with a spherical-harmonic residual, fitted to measured sky
 * patches (see skymodel.h). Perez, Seals, Michalsky 1993, "All-weather model for sky luminance
 * distribution", Solar Energy 50(3); starts from CIE S 011/E:2003 standard skies. */
#include "sky/skymodel.h"

#include "common/linsolve.h"

#include <float.h>
#include <stdlib.h>
#include <string.h>

#define NPAR      6 /* a b c d e, log scale */
#define NSH       ((RS_SKYMODEL_MAX_SH + 1) * (RS_SKYMODEL_MAX_SH + 1))
#define HUBER_LOG 0.25 /* log-radiance residual beyond which a sample is down-weighted */
/* Weak prior toward the CIE standard sky the fit started from: a deviation of one prior_scale
 * costs PRIOR_WEIGHT x the total sample weight (a log residual of 0.1 on every sample). A visible
 * sky that constrains a parameter moves it anyway; one that does not (the anti-solar sky near
 * the horizon hidden in a courtyard) leaves it near a real sky's value instead of wherever the
 * fit wanders (e = 2.8 brightened a hidden anti-solar sky 1.5-2x on a rendered courtyard). */
#define PRIOR_WEIGHT 0.01
static const double prior_scale[5] = {1, 0.3, 10, 1.5, 0.3};

/* Parameter box: keeps the model positive and finite (b, d < 0 so nothing blows up at the
 * horizon or away from the sun); wider than every CIE standard sky. */
static const double lo[5] = {-1.5, -20, 0, -20, -1.5}, hi[5] = {30, -0.01, 100, 0, 30};

double rs_skymodel_perez(const double p[5], double cos_theta, double gamma)
{
    double ct = cos_theta < 0.01 ? 0.01 : cos_theta, cg = cos(gamma);
    return (1 + p[0] * exp(p[1] / ct)) * (1 + p[2] * exp(p[3] * gamma) + p[4] * cg * cg);
}

static double angle_between(rs_v3 a, rs_v3 b)
{
    /* atan2 of |a x b| and a.b: accurate near 0 where acos is not. */
    return atan2(rs_v3_len(rs_v3_cross(a, b)), rs_v3_dot(a, b));
}

/* Real spherical harmonics Y_lm (l <= order) of unit direction d into y[(order+1)^2], index
 * l^2 + l + m, from the associated Legendre recursion (no Condon-Shortley phase). */
static void sh_eval(int order, rs_v3 d, double *y)
{
    double x = d.z, s = sqrt(fmax(0, 1 - x * x)), phi = atan2(d.y, d.x);
    double P[RS_SKYMODEL_MAX_SH + 1][RS_SKYMODEL_MAX_SH + 1];
    P[0][0] = 1;
    for (int m = 1; m <= order; m++) P[m][m] = (2 * m - 1) * s * P[m - 1][m - 1];
    for (int m = 0; m < order; m++) P[m + 1][m] = (2 * m + 1) * x * P[m][m];
    for (int m = 0; m <= order; m++)
        for (int l = m + 2; l <= order; l++)
            P[l][m] = ((2 * l - 1) * x * P[l - 1][m] - (l + m - 1) * P[l - 2][m]) / (l - m);
    for (int l = 0; l <= order; l++)
        for (int m = 0; m <= l; m++) {
            double f = 1;
            for (int k = l - m + 1; k <= l + m; k++) f *= k; /* (l + m)! / (l - m)! */
            double K = sqrt((2 * l + 1) / (4 * M_PI) / f);
            if (m == 0)
                y[l * l + l] = K * P[l][0];
            else {
                y[l * l + l + m] = 1.4142135623730951 * K * P[l][m] * cos(m * phi);
                y[l * l + l - m] = 1.4142135623730951 * K * P[l][m] * sin(m * phi);
            }
        }
}

/* Per-sample data of one channel's fit. */
typedef struct {
    double cos_theta, gamma, cos2_gamma, logL, w; /* cos_theta clamped as in rs_skymodel_perez */
} fitpt;

/* log of the Perez factor at a fitting point, and (when grad) its derivatives by a b c d e. */
static double log_perez_pt(const double *q, const fitpt *p, double *grad)
{
    double e1 = exp(q[1] / p->cos_theta), A = 1 + q[0] * e1;
    double e2 = exp(q[3] * p->gamma), B = 1 + q[2] * e2 + q[4] * p->cos2_gamma;
    if (!(A > 1e-9) || !(B > 1e-9) || !isfinite(A) || !isfinite(B)) return NAN;
    if (grad) {
        grad[0] = e1 / A;
        grad[1] = q[0] * e1 / (p->cos_theta * A);
        grad[2] = e2 / B;
        grad[3] = q[2] * p->gamma * e2 / B;
        grad[4] = p->cos2_gamma / B;
    }
    return log(A * B);
}

typedef struct {
    const double *q0; /* prior centre (a..e) */
    double weight;    /* PRIOR_WEIGHT x total sample weight */
} prior;

static double prior_cost(const prior *pr, const double *q)
{
    double c = 0;
    for (int k = 0; k < 5; k++) {
        double z = (q[k] - pr->q0[k]) / prior_scale[k];
        c += pr->weight * z * z;
    }
    return c;
}

/* Weighted sum of squared log residuals plus the prior; DBL_MAX if the model is not positive
 * somewhere. */
static double cost(const fitpt *pt, size_t n, const double *q, double *res, const prior *pr)
{
    double c = prior_cost(pr, q);
    for (size_t i = 0; i < n; i++) {
        double lf = log_perez_pt(q, &pt[i], NULL);
        if (!isfinite(lf)) return DBL_MAX;
        double r = pt[i].logL - q[5] - lf;
        if (res) res[i] = r;
        c += pt[i].w * r * r;
    }
    return c;
}

static void clamp_params(double *q)
{
    for (int k = 0; k < 5; k++) q[k] = q[k] < lo[k] ? lo[k] : (q[k] > hi[k] ? hi[k] : q[k]);
}

/* Levenberg-Marquardt from q (in/out), analytic Jacobian, box-projected steps. */
static double lm_fit(const fitpt *pt, size_t n, double *q, double *res, double *jac, const prior *pr)
{
    double c = cost(pt, n, q, res, pr), lambda = 1e-3;
    if (c == DBL_MAX) return c;
    for (int it = 0; it < 100; it++) {
        for (size_t i = 0; i < n; i++) {
            double g[5] = {0, 0, 0, 0, 0}; /* set: q passed cost(), so finite here */
            log_perez_pt(q, &pt[i], g);
            for (int k = 0; k < 5; k++) jac[i * NPAR + k] = -g[k];
            jac[i * NPAR + 5] = -1;
        }
        double JtJ[NPAR * NPAR] = {0}, Jtr[NPAR] = {0};
        for (size_t i = 0; i < n; i++)
            for (int a = 0; a < NPAR; a++) {
                Jtr[a] -= pt[i].w * jac[i * NPAR + a] * res[i];
                for (int b = 0; b <= a; b++) JtJ[a * NPAR + b] += pt[i].w * jac[i * NPAR + a] * jac[i * NPAR + b];
            }
        for (int a = 0; a < 5; a++) { /* the prior's residuals */
            double sc = pr->weight / (prior_scale[a] * prior_scale[a]);
            JtJ[a * NPAR + a] += sc;
            Jtr[a] -= sc * (q[a] - pr->q0[a]);
        }
        for (int a = 0; a < NPAR; a++)
            for (int b = 0; b < a; b++) JtJ[b * NPAR + a] = JtJ[a * NPAR + b];
        int improved = 0;
        while (lambda < 1e10) {
            double A[NPAR * NPAR], step[NPAR], qn[NPAR];
            memcpy(A, JtJ, sizeof A);
            memcpy(step, Jtr, sizeof step);
            for (int a = 0; a < NPAR; a++) A[a * NPAR + a] += lambda * (JtJ[a * NPAR + a] + 1e-12);
            if (rs_solve_dense(A, step, NPAR) == 0) {
                for (int a = 0; a < NPAR; a++) qn[a] = q[a] + step[a];
                clamp_params(qn);
                double cn = cost(pt, n, qn, NULL, pr);
                if (cn < c) {
                    double rel = (c - cn) / fmax(c, 1e-300);
                    memcpy(q, qn, sizeof qn);
                    c = cost(pt, n, q, res, pr);
                    lambda = fmax(lambda * 0.3, 1e-9);
                    improved = rel > 1e-10;
                    break;
                }
            }
            lambda *= 10;
        }
        if (!improved) break;
    }
    return c;
}

/* Fits one channel: three CIE starts (clear type 12, intermediate type 8, overcast type 1),
 * each refined by LM with a weak prior toward itself, then two Huber reweightings from the best. */
static void fit_channel(fitpt *pt, size_t n, double *w0, double *res, double *jac, double out[NPAR])
{
    static const double starts[3][5] = {{-1, -0.32, 10, -3, 0.45}, {-1, -0.55, 5, -2.5, 0.3}, {4, -0.7, 0.1, -1, 0}};
    double best = DBL_MAX, wsum = 0;
    for (size_t i = 0; i < n; i++) wsum += w0[i];
    prior pr = {starts[0], PRIOR_WEIGHT * wsum};
    for (int s = 0; s < 3; s++) {
        double q[NPAR];
        prior ps = {starts[s], PRIOR_WEIGHT * wsum};
        memcpy(q, starts[s], 5 * sizeof *q);
        /* log scale start: weighted mean of logL - log f */
        double sw = 0, sr = 0;
        for (size_t i = 0; i < n; i++) {
            sw += pt[i].w;
            sr += pt[i].w * (pt[i].logL - log_perez_pt(q, &pt[i], NULL));
        }
        q[5] = sw > 0 ? sr / sw : 0;
        double c = lm_fit(pt, n, q, res, jac, &ps);
        if (c < best) {
            best = c;
            pr = ps;
            memcpy(out, q, NPAR * sizeof *q);
        }
    }
    for (int round = 0; round < 2; round++) {
        cost(pt, n, out, res, &pr);
        for (size_t i = 0; i < n; i++) {
            double a = fabs(res[i]);
            pt[i].w = w0[i] * (a > HUBER_LOG ? HUBER_LOG / a : 1);
        }
        lm_fit(pt, n, out, res, jac, &pr);
    }
}

static void sh_fit_channel(const rs_skysample *s, size_t n, const double *res, const double *w, int order, double ridge,
                           double *coef)
{
    int nc = (order + 1) * (order + 1);
    double A[NSH * NSH] = {0}, b[NSH] = {0}, y[NSH], sw = 0;
    for (size_t i = 0; i < n; i++) {
        sh_eval(order, s[i].dir, y);
        sw += w[i];
        for (int a = 0; a < nc; a++) {
            b[a] += w[i] * y[a] * res[i];
            for (int c = 0; c < nc; c++) A[a * nc + c] += w[i] * y[a] * y[c];
        }
    }
    for (int l = 0; l <= order; l++)
        for (int m = -l; m <= l; m++) {
            double pen = l == 0 ? 1e-9 : ridge * (l * (l + 1.0)) * (l * (l + 1.0));
            A[(l * l + l + m) * nc + l * l + l + m] += pen * sw;
        }
    memset(coef, 0, NSH * sizeof *coef);
    if (rs_solve_dense(A, b, (size_t)nc) == 0)
        for (int a = 0; a < nc; a++) coef[a] = b[a];
}

/* Per-channel residual of the Perez part at the samples (log), and the robust weights. */
static void perez_residuals(const rs_skysample *s, size_t n, const rs_skymodel *m, int ch, double *res, double *w)
{
    for (size_t i = 0; i < n; i++) {
        double f = rs_skymodel_perez(m->perez[ch], s[i].dir.z, angle_between(s[i].dir, m->sun));
        res[i] = log(fmax(s[i].rgb[ch], 1e-30)) - m->log_scale[ch] - log(f);
        double a = fabs(res[i]);
        w[i] = s[i].rgb[ch] > 0 ? s[i].weight * (a > HUBER_LOG ? HUBER_LOG / a : 1) : 0;
    }
}

void rs_skymodel_refit_sh(const rs_skysample *s, size_t n, int sh_order, double sh_ridge, rs_skymodel *m)
{
    memset(m->sh, 0, sizeof m->sh);
    m->sh_order = sh_order;
    if (sh_order < 0) return;
    double *res = malloc(2 * n * sizeof *res);
    if (!res) {
        m->sh_order = -1;
        return;
    }
    for (int ch = 0; ch < 3; ch++) {
        perez_residuals(s, n, m, ch, res, res + n);
        sh_fit_channel(s, n, res, res + n, sh_order, sh_ridge, m->sh[ch]);
    }
    free(res);
}

int rs_skymodel_fit(const rs_skysample *s, size_t n, rs_v3 sun, int sh_order, double sh_ridge, rs_skymodel *m)
{
    memset(m, 0, sizeof *m);
    m->sun = rs_v3_norm(sun);
    m->sh_order = -1;
    if (n < 12) return -1;
    fitpt *pt = malloc(n * sizeof *pt);
    double *w0 = malloc(n * sizeof *w0), *res = malloc(n * sizeof *res), *jac = malloc(n * NPAR * sizeof *jac);
    if (!pt || !w0 || !res || !jac) {
        free(pt);
        free(w0);
        free(res);
        free(jac);
        return -1;
    }
    for (int ch = 0; ch < 3; ch++) {
        size_t k = 0;
        for (size_t i = 0; i < n; i++) {
            if (!(s[i].rgb[ch] > 0)) continue; /* log of black: no information on the shape */
            pt[k].cos_theta = s[i].dir.z < 0.01 ? 0.01 : s[i].dir.z;
            pt[k].gamma = angle_between(s[i].dir, m->sun);
            pt[k].cos2_gamma = cos(pt[k].gamma) * cos(pt[k].gamma);
            pt[k].logL = log(s[i].rgb[ch]);
            pt[k].w = w0[k] = s[i].weight;
            k++;
        }
        double q[NPAR] = {0, -1, 0, -1, 0, log(1e-30)};
        if (k >= 12) fit_channel(pt, k, w0, res, jac, q);
        memcpy(m->perez[ch], q, 5 * sizeof *q);
        m->log_scale[ch] = q[5];
    }
    free(pt);
    free(w0);
    free(res);
    free(jac);
    rs_skymodel_refit_sh(s, n, sh_order, sh_ridge, m);
    /* Fit quality on luminance, for the log. */
    double sw = 0, sr = 0;
    for (size_t i = 0; i < n; i++) {
        double rgb[3];
        rs_skymodel_eval(m, s[i].dir, rgb);
        double ym = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
        double yo = 0.2126 * s[i].rgb[0] + 0.7152 * s[i].rgb[1] + 0.0722 * s[i].rgb[2];
        if (ym > 0 && yo > 0) {
            double r = log(yo / ym);
            sw += s[i].weight;
            sr += s[i].weight * r * r;
        }
    }
    m->fit_rms_log = sw > 0 ? sqrt(sr / sw) : 0;
    return 0;
}

void rs_skymodel_eval(const rs_skymodel *m, rs_v3 dir, double rgb[3])
{
    double y[NSH];
    if (m->sh_order >= 0) sh_eval(m->sh_order, dir, y);
    int nc = (m->sh_order + 1) * (m->sh_order + 1);
    double gamma = angle_between(dir, m->sun);
    for (int ch = 0; ch < 3; ch++) {
        double lg = m->log_scale[ch] + log(rs_skymodel_perez(m->perez[ch], dir.z, gamma));
        for (int a = 0; a < nc; a++) lg += m->sh[ch][a] * y[a];
        rgb[ch] = exp(lg < 700 ? lg : 700);
    }
}

rs_v3 rs_skymodel_find_sun(const rs_skysample *s, size_t n)
{
    static const double clear[5] = {-1, -0.32, 10, -3, 0.45};
    rs_v3 best_dir = rs_v3_make(0, 0, 1);
    double best = DBL_MAX;
    for (double el = -5; el <= 90; el += 2.5)
        for (double az = 0; az < 360; az += (el >= 89 ? 360 : 2.5)) {
            double er = el * M_PI / 180, ar = az * M_PI / 180;
            rs_v3 sun = rs_v3_make(cos(er) * cos(ar), cos(er) * sin(ar), sin(er));
            /* Cost: weighted variance of log(Y / f); the scale drops out. */
            double sw = 0, s1 = 0, s2 = 0;
            for (size_t i = 0; i < n; i++) {
                double yo = 0.2126 * s[i].rgb[0] + 0.7152 * s[i].rgb[1] + 0.0722 * s[i].rgb[2];
                if (!(yo > 0)) continue;
                double r = log(yo / rs_skymodel_perez(clear, s[i].dir.z, angle_between(s[i].dir, sun)));
                sw += s[i].weight;
                s1 += s[i].weight * r;
                s2 += s[i].weight * r * r;
            }
            double c = sw > 0 ? s2 / sw - (s1 / sw) * (s1 / sw) : DBL_MAX;
            if (c < best) {
                best = c;
                best_dir = sun;
            }
        }
    return best_dir;
}
