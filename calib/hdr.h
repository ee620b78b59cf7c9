/* hdr: bracketed 8-bit exposures of one view -> linear radiance (OpenCV's CalibrateDebevec and
 * MergeDebevec, or a given response curve), with clipped pixels counted and a clipped sun found. */
#ifndef RS_HDR_H
#define RS_HDR_H

#include "common/err.h"
#include "common/image.h"

typedef struct rs_hdr_report {
    size_t clipped_px;   /* pixels saturated even in the shortest exposure: radiance is a lower bound */
    int sun_clipped;     /* 1 when the largest clipped blob is small and compact: a clipped sun */
    double sun_x, sun_y; /* its centroid, image pixels (centres at integers) */
    size_t sun_px;       /* its area, pixels */
} rs_hdr_report;

/* Merges count >= 2 exposures (3 channels, values = 8-bit codes / 255 as stored in the files,
 * NOT linearised) taken with exposure times times_s into *out (linear radiance up to one global
 * scale, 3 channels). response: 256 x 3 linear exposure per code (R, G, B interleaved), or NULL
 * to calibrate it from the brackets. A code >= 250 counts as saturated. Caller frees *out. */
int rs_hdr_merge(const rs_image *const *brackets, const double *times_s, int count, const float *response,
                 rs_image **out, rs_hdr_report *report, rs_err *err);

#endif
