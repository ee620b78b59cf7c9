/* denoise: feature-preserving mesh denoising: bilateral filtering of the face normals (Zheng,
 * Fu, Au, Tai 2011) then vertex updates that follow them (Sun et al. 2007), movement bounded. */
#ifndef RS_DENOISE_H
#define RS_DENOISE_H

#include <stddef.h>
#include "common/err.h"
#include "common/mesh.h"

typedef struct rs_denoise_opts {
    int normal_iterations; /* passes of the bilateral normal filter */
    int vertex_iterations; /* steps of the least-squares vertex update */
    double sigma_r_deg;    /* range weight's sigma on the angle between two normals: a crease
                                  several times larger gets no weight, so it is kept */
    double sigma_s_edges;  /* spatial weight's sigma on centroid distance, in mean edge lengths */
    double max_move_m;     /* no vertex moves farther than this from where it was (m) */
} rs_denoise_opts;

/* 3 normal passes, 10 vertex steps, 10 degrees, 1 edge, 5 mm. */
void rs_denoise_defaults(rs_denoise_opts *o);

typedef struct rs_denoise_stats {
    size_t moved;                  /* vertices that moved at all */
    size_t clamped;                /* vertices held at max_move_m */
    double rms_move_m, max_move_m; /* over all vertices */
    double sigma_s_m;              /* the spatial sigma used */
} rs_denoise_stats;

/* Moves m's vertices in place (topology unchanged). Options out of range are errors that name
 * the [mesh] key; a mesh without faces is left as it is. */
int rs_denoise_apply(rs_mesh *m, const rs_denoise_opts *o, rs_denoise_stats *st, rs_err *err);

#endif
