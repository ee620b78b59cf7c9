/* report_html: the growing text of the run report (pipeline/report.h): appending with printf,
 * HTML escaping, base64 for data: URIs, and the inline SVG plots the report draws itself
 * (report_svg.c: bars, histograms, lines, a scatter with its Pareto front, colour bars). */
#ifndef RS_REPORT_HTML_H
#define RS_REPORT_HTML_H

#include <stddef.h>

/* A growing NUL-terminated text; failed is set (and further appends ignored) when memory ran out. */
typedef struct rs_html {
    char *s;
    size_t len, cap;
    int failed;
} rs_html;

void rs_html_printf(rs_html *h, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
void rs_html_put(rs_html *h, const char *text);
/* text with & < > " escaped. */
void rs_html_esc(rs_html *h, const char *text);
/* data as base64 (RFC 4648, padded). */
void rs_html_base64(rs_html *h, const unsigned char *data, size_t n);
void rs_html_release(rs_html *h);

/* ---- plots (report_svg.c), each an <svg> element of width x height pixels ---- */

/* One series of a plot. */
typedef struct rs_svg_series {
    const char *name;  /* legend */
    const char *color; /* CSS colour */
    const double *v;   /* values, one per category (bars) or point */
} rs_svg_series;

/* Grouped bars: ncat categories (labels), nseries bars each; unit names the value axis. */
void rs_svg_bars(rs_html *h, const char *title, const char *const *labels, int ncat, const rs_svg_series *series,
                 int nseries, const char *unit);
/* Histogram of the n finite values of v in [lo, hi] over nbins bins (values outside are
 * counted in the end bins and the caption says how many); xlabel names the quantity. */
void rs_svg_histogram(rs_html *h, const char *title, const double *v, size_t n, double lo, double hi, int nbins,
                      const char *xlabel);
/* y[0..n) against 1..n on a log10 axis (values <= 0 drawn at the axis' floor). */
void rs_svg_log_line(rs_html *h, const char *title, const double *y, int n, const char *xlabel, const char *ylabel);
/* Points (x[k], y[k]) labelled, on log10 x and linear y, with the Pareto front (lowest y for
 * any x no larger) drawn as a step line. */
void rs_svg_pareto(rs_html *h, const char *title, const double *x, const double *y, const char *const *labels, int n,
                   const char *xlabel, const char *ylabel);

/* A colour map: t in [0, 1] to sRGB 8-bit. */
typedef void (*rs_colormap_fn)(double t, unsigned char rgb[3]);
void rs_colormap_ramp(double t, unsigned char rgb[3]);      /* common/image.h's ramp, sRGB */
void rs_colormap_diverging(double t, unsigned char rgb[3]); /* blue - white (0.5) - red */
void rs_colormap_grey(double t, unsigned char rgb[3]);      /* black - white, sRGB-encoded linear ramp */
/* A horizontal colour bar of width pixels for values lo..hi with five numbered ticks and the
 * unit under it. */
void rs_svg_colorbar(rs_html *h, rs_colormap_fn map, double lo, double hi, const char *unit, int width);

#endif
