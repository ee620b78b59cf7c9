/* unorganized: meshing of point clouds without a scan grid (PLY, PCD, XYZ from other tools)
 * through PCL: normals turned toward the scanner, then greedy projection or Poisson. */
#ifndef RS_UNORGANIZED_H
#define RS_UNORGANIZED_H

#include <stddef.h>
#include "common/cloud.h"
#include "common/err.h"
#include "common/mesh.h"

typedef struct rs_unorg_opts {
    int poisson; /* 0: greedy projection triangulation, 1: Poisson */
    int normal_neighbours;
    double max_edge_m; /* greedy: search radius; <= 0: 8 x the 90th percentile spacing */
    int poisson_depth;
    int threads; /* 0: all cores */
} rs_unorg_opts;

typedef struct rs_unorg_stats {
    size_t points;
    double spacing_median_m, spacing_p90_m; /* nearest-neighbour distances */
    double max_edge_m;                      /* greedy: the search radius used */
    size_t faces_raw;                       /* from PCL, before trimming */
    size_t faces_trimmed;                   /* Poisson: faces far from every point, removed */
    size_t faces_pieces;                    /* Poisson: faces of small pieces left by the trim, removed */
    double cell_m;                          /* Poisson: the octree's finest cell */
    size_t points_no_normal;                /* too few neighbours for a normal */
    int normals_given;                      /* the cloud's own normals were used (not estimated) */
} rs_unorg_stats;

/* Meshes the valid points of c outside its scan grids, seen from c->viewpoint, or from above
 * when c has none but normals_up (LAS); one of the two is required: it orients the normals,
 * hence the triangles. Triangles wind counter-clockwise seen from the scanner's side (from
 * above). Caller frees. */
rs_mesh *rs_unorg_mesh(const rs_cloud *c, const rs_unorg_opts *o, rs_unorg_stats *st, rs_err *err);

#endif
