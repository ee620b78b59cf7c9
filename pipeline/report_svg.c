/* report_svg: the report's plots as inline SVG, drawn here (no plotting library): grouped bars,
 * histograms, a log-scale line, a scatter with its Pareto front, and colour bars. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/image.h"
#include "pipeline/report_html.h"

#define W  560
#define H  260
#define ML 64 /* margins: left, right, top, bottom */
#define MR 16
#define MT 28
#define MB 48

/* A "nice" tick step for a range span split in about n steps. */
static double nice_step(double span, int n)
{
    double raw = span / n, mag = pow(10, floor(log10(raw))), r = raw / mag;
    return (r < 1.5 ? 1 : r < 3 ? 2 : r < 7 ? 5 : 10) * mag;
}

static void fmt_num(char *out, size_t n, double v)
{
    double a = fabs(v);
    if (v == 0)
        snprintf(out, n, "0");
    else if (a >= 1e5 || a < 1e-3)
        snprintf(out, n, "%.2g", v);
    else
        snprintf(out, n, "%.4g", v);
}

static void open_svg(rs_html *h, const char *title, int w, int hgt)
{
    rs_html_printf(h,
                   "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%d\" height=\"%d\" viewBox=\"0 0 %d %d\" "
                   "class=\"plot\" role=\"img\"><title>",
                   w, hgt, w, hgt);
    rs_html_esc(h, title);
    rs_html_printf(h, "</title><rect width=\"%d\" height=\"%d\" fill=\"#fff\"/>", w, hgt);
    rs_html_printf(h, "<text x=\"%d\" y=\"18\" font-size=\"13\" font-weight=\"bold\">", ML);
    rs_html_esc(h, title);
    rs_html_put(h, "</text>");
}

/* The y axis over [lo, hi] (linear) with gridlines and the label; returns nothing. */
static void y_axis(rs_html *h, double lo, double hi, const char *label)
{
    double step = nice_step(hi - lo, 5);
    for (double t = ceil(lo / step) * step; t <= hi + 1e-9 * step; t += step) {
        double y = MT + (H - MT - MB) * (1 - (t - lo) / (hi - lo));
        char s[32];
        fmt_num(s, sizeof s, t);
        rs_html_printf(h,
                       "<line x1=\"%d\" x2=\"%d\" y1=\"%.1f\" y2=\"%.1f\" stroke=\"#ddd\"/>"
                       "<text x=\"%d\" y=\"%.1f\" font-size=\"11\" text-anchor=\"end\">%s</text>",
                       ML, W - MR, y, y, ML - 4, y + 4, s);
    }
    rs_html_printf(h, "<text transform=\"translate(14 %d) rotate(-90)\" font-size=\"11\" text-anchor=\"middle\">",
                   (MT + H - MB) / 2);
    rs_html_esc(h, label);
    rs_html_printf(h, "</text><line x1=\"%d\" x2=\"%d\" y1=\"%d\" y2=\"%d\" stroke=\"#000\"/>", ML, ML, MT, H - MB);
}

static void x_label(rs_html *h, const char *label)
{
    rs_html_printf(h, "<text x=\"%d\" y=\"%d\" font-size=\"11\" text-anchor=\"middle\">", (ML + W - MR) / 2, H - 6);
    rs_html_esc(h, label);
    rs_html_printf(h, "</text><line x1=\"%d\" x2=\"%d\" y1=\"%d\" y2=\"%d\" stroke=\"#000\"/>", ML, W - MR, H - MB,
                   H - MB);
}

void rs_svg_bars(rs_html *h, const char *title, const char *const *labels, int ncat, const rs_svg_series *series,
                 int nseries, const char *unit)
{
    double top = 0;
    for (int s = 0; s < nseries; s++)
        for (int c = 0; c < ncat; c++)
            if (isfinite(series[s].v[c]) && series[s].v[c] > top) top = series[s].v[c];
    if (!(top > 0)) top = 1;
    top = ceil(top / nice_step(top, 5)) * nice_step(top, 5);
    open_svg(h, title, W, H);
    y_axis(h, 0, top, unit);
    double slot = (double)(W - ML - MR) / (ncat ? ncat : 1), bw = slot * 0.8 / (nseries ? nseries : 1);
    for (int c = 0; c < ncat; c++) {
        for (int s = 0; s < nseries; s++) {
            double v = isfinite(series[s].v[c]) && series[s].v[c] > 0 ? series[s].v[c] : 0;
            double bh = (H - MT - MB) * v / top, x = ML + c * slot + slot * 0.1 + s * bw;
            rs_html_printf(h, "<rect x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"%s\"><title>", x,
                           H - MB - bh, bw, bh, series[s].color);
            rs_html_esc(h, labels[c]);
            rs_html_printf(h, " %s: %.4g %s</title></rect>", series[s].name, v, unit);
        }
        rs_html_printf(h, "<text x=\"%.1f\" y=\"%d\" font-size=\"11\" text-anchor=\"middle\">", ML + (c + 0.5) * slot,
                       H - MB + 14);
        rs_html_esc(h, labels[c]);
        rs_html_put(h, "</text>");
    }
    for (int s = 0; s < nseries; s++)
        rs_html_printf(h,
                       "<rect x=\"%d\" y=\"%d\" width=\"10\" height=\"10\" fill=\"%s\"/>"
                       "<text x=\"%d\" y=\"%d\" font-size=\"11\">%s</text>",
                       W - MR - 150 + 75 * s, 8, series[s].color, W - MR - 136 + 75 * s, 17, series[s].name);
    x_label(h, "stage");
    rs_html_put(h, "</svg>");
}

void rs_svg_histogram(rs_html *h, const char *title, const double *v, size_t n, double lo, double hi, int nbins,
                      const char *xlabel)
{
    size_t *count = calloc((size_t)nbins, sizeof *count), below = 0, above = 0, used = 0, top = 1;
    if (!count) return;
    for (size_t k = 0; k < n; k++) {
        if (!isfinite(v[k])) continue;
        double t = (v[k] - lo) / (hi - lo) * nbins;
        int b = t < 0 ? 0 : t >= nbins ? nbins - 1 : (int)t;
        below += v[k] < lo;
        above += v[k] > hi;
        count[b]++;
        used++;
    }
    for (int b = 0; b < nbins; b++)
        if (count[b] > top) top = count[b];
    char t[256];
    snprintf(t, sizeof t, "%s (%zu facets)", title, used);
    open_svg(h, t, W, H);
    y_axis(h, 0, (double)top, "facets");
    double bw = (double)(W - ML - MR) / nbins;
    for (int b = 0; b < nbins; b++) {
        double bh = (H - MT - MB) * (double)count[b] / (double)top;
        rs_html_printf(h,
                       "<rect x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"#4878a8\">"
                       "<title>%.4g to %.4g: %zu</title></rect>",
                       ML + b * bw, H - MB - bh, bw * 0.95, bh, lo + (hi - lo) * b / nbins,
                       lo + (hi - lo) * (b + 1) / nbins, count[b]);
    }
    for (int k = 0; k <= 4; k++) {
        char s[32];
        fmt_num(s, sizeof s, lo + (hi - lo) * k / 4);
        rs_html_printf(h, "<text x=\"%.1f\" y=\"%d\" font-size=\"11\" text-anchor=\"middle\">%s</text>",
                       ML + (W - ML - MR) * k / 4.0, H - MB + 14, s);
    }
    char xl[256];
    if (below || above)
        snprintf(xl, sizeof xl, "%s (%zu below and %zu above the range counted in the end bins)", xlabel, below, above);
    else
        snprintf(xl, sizeof xl, "%s", xlabel);
    x_label(h, xl);
    rs_html_put(h, "</svg>");
    free(count);
}

/* log10 range of the positive values, widened to whole decades. */
static void log_range(const double *v, int n, double *lo, double *hi)
{
    *lo = INFINITY;
    *hi = -INFINITY;
    for (int k = 0; k < n; k++)
        if (v[k] > 0 && isfinite(v[k])) {
            *lo = fmin(*lo, floor(log10(v[k])));
            *hi = fmax(*hi, ceil(log10(v[k])));
        }
    if (!isfinite(*lo)) *lo = -8, *hi = 0;
    if (*hi <= *lo) *hi = *lo + 1;
}

void rs_svg_log_line(rs_html *h, const char *title, const double *y, int n, const char *xlabel, const char *ylabel)
{
    double lo, hi;
    log_range(y, n, &lo, &hi);
    open_svg(h, title, W, H);
    for (double d = lo; d <= hi; d++) {
        double py = MT + (H - MT - MB) * (1 - (d - lo) / (hi - lo));
        rs_html_printf(h,
                       "<line x1=\"%d\" x2=\"%d\" y1=\"%.1f\" y2=\"%.1f\" stroke=\"#ddd\"/>"
                       "<text x=\"%d\" y=\"%.1f\" font-size=\"11\" text-anchor=\"end\">1e%+d</text>",
                       ML, W - MR, py, py, ML - 4, py + 4, (int)d);
    }
    rs_html_printf(h, "<text transform=\"translate(14 %d) rotate(-90)\" font-size=\"11\" text-anchor=\"middle\">",
                   (MT + H - MB) / 2);
    rs_html_esc(h, ylabel);
    rs_html_printf(h, "</text><line x1=\"%d\" x2=\"%d\" y1=\"%d\" y2=\"%d\" stroke=\"#000\"/>", ML, ML, MT, H - MB);
    rs_html_put(h, "<polyline fill=\"none\" stroke=\"#c03030\" stroke-width=\"1.5\" points=\"");
    for (int k = 0; k < n; k++) {
        double l = y[k] > 0 && isfinite(y[k]) ? log10(y[k]) : lo;
        double px = ML + (W - ML - MR) * (n > 1 ? (double)k / (n - 1) : 0.5);
        rs_html_printf(h, "%.1f,%.1f ", px, MT + (H - MT - MB) * (1 - (l - lo) / (hi - lo)));
    }
    rs_html_put(h, "\"/>");
    for (int k = 0; k < n; k++) {
        if (n > 12 && k % (n / 6) != 0 && k != n - 1) continue;
        rs_html_printf(h, "<text x=\"%.1f\" y=\"%d\" font-size=\"11\" text-anchor=\"middle\">%d</text>",
                       ML + (W - ML - MR) * (n > 1 ? (double)k / (n - 1) : 0.5), H - MB + 14, k + 1);
    }
    x_label(h, xlabel);
    rs_html_put(h, "</svg>");
}

static int cmp_by_x(const void *a, const void *b, const double *x)
{
    double u = x[*(const int *)a], v = x[*(const int *)b];
    return (u > v) - (u < v);
}

static const double *sort_key;
static int cmp_idx(const void *a, const void *b)
{
    return cmp_by_x(a, b, sort_key);
}

void rs_svg_pareto(rs_html *h, const char *title, const double *x, const double *y, const char *const *labels, int n,
                   const char *xlabel, const char *ylabel)
{
    double lx, hx, ty = 0;
    log_range(x, n, &lx, &hx);
    for (int k = 0; k < n; k++)
        if (isfinite(y[k]) && y[k] > ty) ty = y[k];
    if (!(ty > 0)) ty = 1;
    ty = ceil(ty / nice_step(ty, 5)) * nice_step(ty, 5);
    open_svg(h, title, W, H);
    y_axis(h, 0, ty, ylabel);
    for (double d = lx; d <= hx; d++)
        rs_html_printf(h, "<text x=\"%.1f\" y=\"%d\" font-size=\"11\" text-anchor=\"middle\">1e%+d</text>",
                       ML + (W - ML - MR) * (d - lx) / (hx - lx), H - MB + 14, (int)d);
#define PX(v) (ML + (W - ML - MR) * ((v) > 0 ? log10(v) - lx : 0) / (hx - lx))
#define PY(v) (MT + (H - MT - MB) * (1 - (v) / ty))
    int *idx = malloc((size_t)(n ? n : 1) * sizeof *idx);
    if (!idx) return;
    for (int k = 0; k < n; k++) idx[k] = k;
    sort_key = x;
    qsort(idx, (size_t)n, sizeof *idx, cmp_idx);
    rs_html_put(h, "<polyline fill=\"none\" stroke=\"#c03030\" stroke-width=\"1.5\" points=\"");
    double best = INFINITY;
    for (int j = 0; j < n; j++) {
        int k = idx[j];
        if (!(isfinite(x[k]) && isfinite(y[k]) && y[k] < best)) continue;
        if (isfinite(best)) rs_html_printf(h, "%.1f,%.1f ", PX(x[k]), PY(best));
        best = y[k];
        rs_html_printf(h, "%.1f,%.1f ", PX(x[k]), PY(best));
    }
    rs_html_put(h, "\"/>");
    for (int k = 0; k < n; k++) {
        if (!isfinite(x[k]) || !isfinite(y[k])) continue;
        rs_html_printf(h, "<circle cx=\"%.1f\" cy=\"%.1f\" r=\"3.5\" fill=\"#4878a8\"><title>", PX(x[k]), PY(y[k]));
        rs_html_esc(h, labels[k]);
        rs_html_printf(h, ": %.4g, %.4g</title></circle>", x[k], y[k]);
    }
#undef PX
#undef PY
    free(idx);
    x_label(h, xlabel);
    rs_html_put(h, "</svg>");
}

void rs_colormap_ramp(double t, unsigned char rgb[3])
{
    float lin[3];
    rs_image_ramp(t, lin);
    for (int c = 0; c < 3; c++) rgb[c] = (unsigned char)lrintf(255 * rs_linear_to_srgb(lin[c]));
}

void rs_colormap_diverging(double t, unsigned char rgb[3])
{
    /* blue (0.23 0.30 0.75) - white - red (0.71 0.02 0.15), straight lines in sRGB */
    static const double lo[3] = {59, 76, 192}, mid[3] = {247, 247, 247}, hi[3] = {180, 4, 38};
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    for (int c = 0; c < 3; c++) {
        double v = t < 0.5 ? lo[c] + (mid[c] - lo[c]) * t * 2 : mid[c] + (hi[c] - mid[c]) * (t - 0.5) * 2;
        rgb[c] = (unsigned char)lrint(v);
    }
}

void rs_colormap_grey(double t, unsigned char rgb[3])
{
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    rgb[0] = rgb[1] = rgb[2] = (unsigned char)lrintf(255 * rs_linear_to_srgb((float)t));
}

void rs_svg_colorbar(rs_html *h, rs_colormap_fn map, double lo, double hi, const char *unit, int width)
{
    int id = (int)h->len; /* unique within the page */
    rs_html_printf(h,
                   "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%d\" height=\"44\" class=\"colorbar\">"
                   "<defs><linearGradient id=\"cb%d\">",
                   width, id);
    for (int k = 0; k <= 16; k++) {
        unsigned char c[3];
        map(k / 16.0, c);
        rs_html_printf(h, "<stop offset=\"%.4f\" stop-color=\"#%02x%02x%02x\"/>", k / 16.0, c[0], c[1], c[2]);
    }
    rs_html_printf(h,
                   "</linearGradient></defs><rect x=\"8\" y=\"2\" width=\"%d\" height=\"12\" fill=\"url(#cb%d)\" "
                   "stroke=\"#444\"/>",
                   width - 16, id);
    for (int k = 0; k <= 4; k++) {
        char s[32];
        fmt_num(s, sizeof s, lo + (hi - lo) * k / 4);
        double x = 8 + (width - 16) * k / 4.0;
        rs_html_printf(h,
                       "<line x1=\"%.1f\" x2=\"%.1f\" y1=\"14\" y2=\"18\" stroke=\"#444\"/>"
                       "<text x=\"%.1f\" y=\"28\" font-size=\"10\" text-anchor=\"%s\">%s</text>",
                       x, x, x,
                       k == 0       ? "start"
                           : k == 4 ? "end"
                                    : "middle",
                       s);
    }
    rs_html_printf(h, "<text x=\"%d\" y=\"41\" font-size=\"10\" text-anchor=\"middle\">", width / 2);
    rs_html_esc(h, unit);
    rs_html_put(h, "</text></svg>");
}
