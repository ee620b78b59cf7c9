/* gains: per-camera gains of a rig from the pixels that camera pairs share, robustly. Each shared
 * pixel gives a log ratio ln(L_i / L_j) of the two cameras' luminances with a weight (both
 * cameras' blending weights). Overlaps sit at frame edges, where real content is least reliable
 * (vignetting, flare, the lens model near its field limit, roof lines against the sky), so a
 * sum of luminances, ruled by the brightest pixels, is not used: per pair, a weighted median of
 * the log ratios, refined by Tukey's biweight, gives a ratio that a few tens of per cent of bad
 * pixels cannot move; then one least-squares solve over the pairs. */
#ifndef RS_GAINS_H
#define RS_GAINS_H

#include <stddef.h>

/* One pair's samples, grown by rs_gain_samples_add. */
typedef struct rs_gain_samples {
    size_t count, cap;
    float *log_ratio; /* ln(L_i / L_j) */
    float *weight;
} rs_gain_samples;

int rs_gain_samples_add(rs_gain_samples *s, float log_ratio, float weight);
void rs_gain_samples_free(rs_gain_samples *s);

#define RS_GAIN_MIN_SAMPLES 64 /* fewer shared pixels say too little about a ratio */

/* What the estimate says about itself, per pair and as a whole. */
typedef struct rs_gain_pair {
    int i, j;
    size_t samples;   /* pixels used (after the caller's exclusions) */
    double log_ratio; /* the pair's robust ln(gain_i / gain_j) */
    double spread;    /* robust standard deviation of the samples' log ratios (1.4826 x MAD) */
    double inlier;    /* share of the weight Tukey's biweight kept */
    double residual;  /* the solved ln(gain_i / gain_j) minus log_ratio */
} rs_gain_pair;

typedef struct rs_gain_report {
    int npairs;          /* pairs with at least RS_GAIN_MIN_SAMPLES samples */
    rs_gain_pair *pairs; /* npairs of them; free with rs_gain_report_free */
    double residual_rms; /* RMS of the pairs' residuals, weighted by their samples: how consistent they are */
    int fixed;           /* cameras whose gain was given */
} rs_gain_report;

void rs_gain_report_free(rs_gain_report *r);

/* A pair's robust ln(gain_i / gain_j) from its samples: the weighted median, then Tukey's
 * biweight (c = 4.685 robust sigmas) iterated from it. Returns -1 without samples of positive
 * weight. spread and inlier may be NULL. */
int rs_gain_pair_estimate(const rs_gain_samples *s, double *log_ratio, double *spread, double *inlier);

/* Gains of n cameras (observed = gain x true) from pairs[i * n + j] (i < j; the others unused).
 * known[i] > 0 fixes camera i's gain (NULL: none known). Without a known gain the geometric
 * mean over the cameras is 1; a camera in no usable pair keeps its known gain or 1. The system
 * per pair is ln g_i - ln g_j = r_ij, each weighted by its samples' weight over the square of
 * its spread (floored), so a noisy pair counts less. report may be NULL. Returns -1 when out of
 * memory. */
int rs_gains_solve(int n, const rs_gain_samples *pairs, const double *known, double *gains, rs_gain_report *report);

#endif
