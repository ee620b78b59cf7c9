/* eval_priv: what eval.c and eval_view.c share: one evaluation's inputs and per-facet results.
 * Not installed; tools/eval only. */
#ifndef RS_EVAL_PRIV_H
#define RS_EVAL_PRIV_H

#include "tools/eval/eval.h"
#include "common/image.h"
#include "common/ply.h"

/* Everything one evaluation holds; freed by eval_free. */
typedef struct ev {
    rs_truth tr; /* owns truth, truth_ply, tpart, trgb */
    rs_mesh *truth, *res;
    rs_ply *truth_ply, *res_ply;
    size_t nt, nf;
    int nparts;
    int *tpart;
    double *trgb;           /* 3 per truth triangle */
    double *alb, *esky, *g; /* 3 per facet */
    double *obs, *est, *area, *encl;
    double *rel, *sgn; /* per facet: mean over R,G,B of |rho - t| / t, (rho - t) / t */
    uint8_t *sel;      /* observed, estimable, finite, matched */
    rs_eval_match m;
    rs_image *ids, *pano, *dc, *dd, *di, *synth;
} ev;

/* The camera-view measures into doc: "coverage", "irradiance", "synth"; writes eval_error.exr
 * and eval_error.png into out_dir. good[f]: observed and estimable. part_gshare[nparts]: the
 * truth's interreflection share diffind / (diffdir + diffind) over each part's pixels. */
int rs_eval_camera(const ev *e, const uint8_t *good, rs_json *doc, const char *out_dir, double *part_gshare,
                   rs_err *err);

#endif
