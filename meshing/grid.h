/* grid: triangulation of organized scans on their own angular grid (the mesh stage's first
 * step). Exports rs_grid_triangulate. */
#ifndef RS_GRID_H
#define RS_GRID_H

#include <stddef.h>
#include "common/cloud.h"
#include "common/err.h"
#include "common/mesh.h"

typedef struct rs_grid_opts {
    double max_depth_ratio; /* drop triangles whose ranges differ by more than this fraction */
    double max_grazing_rad; /* drop triangles seen at more than this angle from their normal */
    double max_gap_factor;  /* drop cells spanning more than this many angular grid steps */
    size_t target_faces;    /* the facet budget ([mesh] facets), 0: none */
    double target_edge_m;   /* or the facet size ([mesh] facet_size), 0: none */
} rs_grid_opts;

/* The grid mesh at stride k keeps at least this many times the budget's triangles, so that the
 * simplifier still chooses where the edges go (sharp edges, concave corners). */
#define RS_GRID_MARGIN 16.0
/* Nor below this many: a grid that small costs the simplifier seconds, and stride k widens the
 * strips cut out at depth discontinuities k times (on a 720 x 360 room scan at a 3000-facet
 * budget, stride 3 left 94 % of the points within 2 cm, stride 1 over 97 %). */
#define RS_GRID_MIN_TRIANGLES 1e6

typedef struct rs_grid_stats {
    size_t cells;           /* grid cells, the wrap-around column included */
    size_t cells_no_return; /* cells with fewer than 3 valid corners */
    size_t triangles;       /* triangles kept */
    size_t dropped_depth;   /* triangles across a depth discontinuity */
    size_t dropped_grazing; /* triangles seen at a grazing angle (or degenerate) */
    size_t dropped_gap;     /* cells spanning an angular gap (e.g. the seam of a partial sweep) */
    size_t flipped;         /* triangles whose grid winding faced away and was turned */
    int stride;             /* rows and columns used: every stride-th (of the last scan) */
} rs_grid_stats;

/* The stride k for scan s of c: 1 without a budget, or when the full grid has fewer than
 * RS_GRID_MIN_TRIANGLES triangles or RS_GRID_MARGIN times the budget; else the largest k
 * whose grid of every k-th row and column (PCL's OrganizedFastMesh "triangle pixel size")
 * keeps both: 2 x valid points / k^2 triangles against target_faces, or k x median range x
 * angular step against target_edge_m / sqrt(RS_GRID_MARGIN). Steps in rad, range in m. */
int rs_grid_stride(const rs_cloud *c, int s, const rs_grid_opts *o, double col_step, double row_step,
                   double median_range_m);

/* Indices 0, k, 2k, ... and n - 1 (the grid lines used at stride k) into out (n + 1 ints);
 * returns their count. */
int rs_grid_lattice(int n, int k, int *out);

/* Triangulates every scan of c at its stride (rs_grid_stride): each cell of the lattice
 * (rs_grid_lattice; its 4 corners, or 3 when one has no return) gives up to two triangles,
 * split along the diagonal that keeps more of them (then the shorter one); a cell spanning
 * more than max_gap_factor times its own number of grid steps is dropped. A triangle is dropped when its ranges from the scanner differ by more than
 * max_depth_ratio of the smallest, or when the angle between its normal and the ray to the
 * scanner exceeds max_grazing_rad. Kept triangles wind counter-clockwise seen from the scanner.
 * Vertices are the valid points used, in point order. Needs c->nscans > 0. Caller frees. */
rs_mesh *rs_grid_triangulate(const rs_cloud *c, const rs_grid_opts *o, rs_grid_stats *st, rs_err *err);

#endif
