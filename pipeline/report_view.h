/* report_view: the camera-view images of the run report (pipeline/report.h), made from the work
 * folder's linear files (albedo.ply's per-facet values through facet_id.exr, synth.exr,
 * diff.exr, the panorama) and written as PNGs into WORKDIR/report/, each with the range and
 * colour map its colour bar shows and a sentence on how it was mapped. */
#ifndef RS_REPORT_VIEW_H
#define RS_REPORT_VIEW_H

#include <stddef.h>
#include <stdint.h>
#include "common/err.h"
#include "pipeline/report_html.h"

/* albedo.ply's per-facet values (linear). */
typedef struct rs_report_facets {
    size_t nf;
    double *alb, *rad, *esky, *g; /* 3 per facet: albedo, observed radiance, E_sky, interreflected G */
    double *sigma;                /* albedo_sigma_rel; NULL when the file has none */
    uint8_t *observed, *estimable;
} rs_report_facets;

/* Reads path (an albedo.ply). -1 with *err naming the file and the property when it lacks one. */
int rs_report_facets_read(const char *path, rs_report_facets *f, rs_err *err);
void rs_report_facets_free(rs_report_facets *f);

#define RS_REPORT_MAX_IMAGES 10

typedef struct rs_report_image {
    char file[64]; /* relative to the work folder: report/NAME.png */
    char title[96];
    char unit[96];  /* under the colour bar */
    char tone[400]; /* how the values became colours */
    double lo, hi;  /* the colour bar's range */
    rs_colormap_fn map;
} rs_report_image;

typedef struct rs_report_views {
    rs_report_image img[RS_REPORT_MAX_IMAGES];
    int n;
    int width, height; /* of every image */
    char missing[512]; /* why images are absent ("" when none is) */
} rs_report_views;

/* Writes the camera-view images of workdir into workdir/report/. pano: the capture's
 * panorama. f: albedo.ply's values (NULL when it does not exist yet). truth_err: per facet
 * the signed relative albedo error against the truth (NAN where not matched), or NULL. Images
 * whose inputs are missing are left out and said so in v->missing. -1 only on a system error
 * or a malformed input file. */
int rs_report_views_write(const char *workdir, const char *pano, const rs_report_facets *f, const double *truth_err,
                          rs_report_views *v, rs_err *err);

#endif
