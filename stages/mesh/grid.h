/* grid: triangulation of organized scans on their own angular grid (the mesh stage's first
 * step). Exports rs_grid_triangulate. */
#ifndef RS_GRID_H
#define RS_GRID_H

#include <stddef.h>
#include "cloud.h"
#include "err.h"
#include "mesh.h"

typedef struct rs_grid_opts {
    double max_depth_ratio;    /* drop triangles whose ranges differ by more than this fraction */
    double max_grazing_rad;    /* drop triangles seen at more than this angle from their normal */
    double max_gap_factor;     /* drop cells spanning more than this many angular grid steps */
} rs_grid_opts;

typedef struct rs_grid_stats {
    size_t cells;              /* grid cells, the wrap-around column included */
    size_t cells_no_return;    /* cells with fewer than 3 valid corners */
    size_t triangles;          /* triangles kept */
    size_t dropped_depth;      /* triangles across a depth discontinuity */
    size_t dropped_grazing;    /* triangles seen at a grazing angle (or degenerate) */
    size_t dropped_gap;        /* cells spanning an angular gap (e.g. the seam of a partial sweep) */
    size_t flipped;            /* triangles whose grid winding faced away and was turned */
} rs_grid_stats;

/* Triangulates every scan of c: each grid cell (its 4 corners, or 3 when one has no return)
 * gives up to two triangles, split along the diagonal that keeps more of them (then the
 * shorter one). A triangle is dropped when its ranges from the scanner differ by more than
 * max_depth_ratio of the smallest, or when the angle between its normal and the ray to the
 * scanner exceeds max_grazing_rad. Kept triangles wind counter-clockwise seen from the scanner.
 * Vertices are the valid points used, in point order. Needs c->nscans > 0. Caller frees. */
rs_mesh *rs_grid_triangulate(const rs_cloud *c, const rs_grid_opts *o, rs_grid_stats *st, rs_err *err);

#endif
