/* eval: rhoscan-eval, the comparison of a run (its work folder) with a Cycles truth folder
 * (docs/DESIGN.md, section Reference scenes): albedo error per facet and per truth part, coverage,
 * irradiance, re-render. */
#ifndef RS_EVAL_H
#define RS_EVAL_H

#include <stddef.h>
#include <stdint.h>
#include "common/err.h"
#include "common/json.h"
#include "common/mesh.h"
#include "pipeline/truth.h"

typedef struct rs_eval_opts {
    const char *truth_dir;    /* truth.ply, pano.exr, pano_diffcol/diffdir/diffind.exr */
    const char *work_dir;     /* albedo.ply, facet_id.exr, synth.exr */
    const char *out_dir;      /* eval.json and eval_error.exr/.png go here; NULL = work_dir */
    const char *json_path;    /* eval.json elsewhere; NULL = out_dir/eval.json */
    double tol_m;             /* a sample point further than this from every truth triangle is unmatched */
    double concave_threshold; /* a part is concave when its mean enclosure reaches this */
    /* Thresholds; NAN = not checked. */
    double max_error;     /* area-weighted mean relative error, interior facets */
    double max_error_all; /* the same over all matched facets */
    double min_coverage;  /* observed and estimable share of the model pixels */
} rs_eval_opts;

void rs_eval_opts_default(rs_eval_opts *o);

/* Runs the comparison and writes eval.json and the error images. Returns 0 when the
 * evaluation ran (then *passed = 1 when every threshold was met and no observed, estimable
 * facet has a non-finite albedo; the reasons for a failure are in the JSON's "failures"),
 * -1 with *err set when an input is missing or malformed. *result (if not NULL) receives
 * the JSON document; caller frees with rs_json_free. */
int rs_eval_run(const rs_eval_opts *o, rs_json **result, int *passed, rs_err *err);

/* A number of the result by dotted path ("albedo.interior.mean_rel", "parts.0.concave");
 * true/false read as 1/0; NAN when absent or null. */
double rs_eval_get(const rs_json *doc, const char *path);

#endif
