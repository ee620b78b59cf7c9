/* report: the page a person reads after a run, WORKDIR/report.html, with its images in
 * WORKDIR/report/ (docs/PIPELINE.md, section The report). Built from the work folder's files
 * only (metrics.json, every <stage>.json, albedo.ply, facet_id.exr, synth.exr, diff.exr, the
 * panorama, albedo.glb, bench.csv), so that `rhoscan report WORKDIR` rebuilds it without
 * running anything; the driver and every stage program rebuild it after a stage ran. No
 * network: images are files beside it, plots inline SVG, the 3D view's scripts copied beside it
 * and its model embedded as a data: URI. Written atomically. */
#ifndef RS_REPORT_H
#define RS_REPORT_H

#include "common/err.h"

typedef struct rs_report_opts {
    const char *workdir;
    const char *const *stages; /* stage names in pipeline order, NULL-terminated; NULL: metrics.json's */
    const char *truth;         /* truth PLY ([report] truth); NULL: the one metrics.json's configuration names */
    const char *three_dir;     /* where three.min.js and examples/js live; NULL: Debian's /usr/share/javascript/three */
} rs_report_opts;

/* Writes workdir/report.html and its images. -1 with *err on a system error (cannot write) or
 * a malformed input (a truth PLY that does not read); missing inputs only leave sections out. */
int rs_report_write(const rs_report_opts *o, rs_err *err);

#endif
