/* truth: a truth mesh with per-face albedo and parts (a reference scene's truth.ply, or
 * [report] truth), which part each result facet lies on, and the albedo error per facet and
 * over a set of facets, as the shared evaluator (eval_albedo.py of the shared reference set)
 * defines them. One implementation for rhoscan-eval (tools/eval) and the run report
 * (pipeline/report.h). */
#ifndef RS_TRUTH_H
#define RS_TRUTH_H

#include <stddef.h>
#include <stdint.h>
#include "common/err.h"
#include "common/mesh.h"
#include "common/ply.h"

/* A truth PLY: faces with float red, green, blue in (0, 1] (linear albedo) and an integer part. */
typedef struct rs_truth {
    rs_mesh *mesh;
    rs_ply *ply;
    size_t nt;
    int nparts;  /* largest part + 1 */
    int *part;   /* per truth face */
    double *rgb; /* 3 per truth face */
} rs_truth;

/* Reads path; errors name the file, the face and the property. Free with rs_truth_free. */
int rs_truth_read(const char *path, rs_truth *t, rs_err *err);
void rs_truth_free(rs_truth *t);

/* The truth part each result facet lies on. Seven points per facet (the centroid, and the
 * corners and edge midpoints pulled 15 % toward it, as the shared evaluator eval_albedo.py does)
 * each take the part of their nearest truth triangle if it lies within tol_m. */
typedef struct rs_eval_match {
    int *part;         /* majority part per facet (ties: the lower id), -1 unmatched */
    double *truth_rgb; /* 3 per facet: the albedo of the first agreeing point's triangle */
    uint8_t *interior; /* all seven points matched and on one part */
} rs_eval_match;

/* A facet is matched when its centroid lies within tol_m of the truth. truth_part and
 * truth_rgb hold one (three) value(s) per truth triangle. Caller frees with rs_eval_match_free. */
/* A georeferenced run was recentred (docs/DESIGN.md, section Frames): moves res's vertices back
 * by the rhoscan_origin comment of its PLY header (none: unchanged), into the truth's frame. */
void rs_truth_unshift(rs_mesh *res, const rs_ply *res_ply);

int rs_eval_match_facets(const rs_mesh *res, const rs_mesh *truth, const int *truth_part, const double *truth_rgb,
                         double tol_m, rs_eval_match *out, rs_err *err);
void rs_eval_match_free(rs_eval_match *m);

/* Enclosure of each facet of mesh: the cosine-weighted share of its hemisphere that hits the
 * mesh itself (64 stratified directions from the centroid), i.e. how much of its light can be
 * interreflection. out[nfaces]. */
int rs_eval_enclosure(const rs_mesh *mesh, double *out, rs_err *err);

/* Closest distance from p to triangle (a, b, c) (Ericson, Real-Time Collision Detection 5.1.5). */
double rs_eval_point_tri_dist(rs_v3 p, rs_v3 a, rs_v3 b, rs_v3 c);

/* The errors of one facet against its truth albedo t (3 channels, each floored at 1e-6):
 * *rel the mean over R, G, B of |rho - t| / t, *sgn of (rho - t) / t. */
void rs_truth_facet_error(const double *rho, const double *t, double *rel, double *sgn);

/* Area-weighted statistics of rel (and sgn) over the facets in mask: the evaluator's
 * mean, median and 95th percentile (the first sorted value whose cumulative weight reaches q),
 * bias (area-weighted mean of sgn). facets = 0 when mask is empty or has no area. idx: room
 * for nf indices. */
typedef struct rs_truth_stats {
    size_t facets;
    double area, mean_rel, median_rel, p95_rel, bias_rel;
} rs_truth_stats;
void rs_truth_stats_of(const double *rel, const double *sgn, const double *area, const uint8_t *mask, size_t nf,
                       size_t *idx, rs_truth_stats *out);

#endif
