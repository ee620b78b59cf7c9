/* meshreport: the mesh stage's quality report (mesh.json, merged into metrics.json): size,
 * edge lengths, boundary loops, non-manifold edges and the distance from scan points. */
#ifndef RS_MESHREPORT_H
#define RS_MESHREPORT_H

#include <stddef.h>
#include "common/err.h"
#include "common/json.h"
#include "common/mesh.h"

typedef struct rs_mesh_quality {
    size_t faces, verts, edges;
    double edge_mean_m, edge_median_m, edge_p5_m, edge_p95_m, edge_min_m, edge_max_m;
    size_t boundary_edges;          /* edges with one face */
    size_t boundary_loops;          /* connected chains of boundary edges: holes and outer borders */
    size_t nonmanifold_edges;       /* edges with three or more faces */
    size_t points_tested;           /* scan points measured (evenly spread over the cloud) */
    double dist_mean_m, dist_p95_m; /* their distance to the mesh (capped at max_dist_m) */
    double within_2cm;              /* share of them within 2 cm of the mesh */
} rs_mesh_quality;

/* Measures m; pts (3 doubles per point, the mesh's frame) may be NULL. At most max_points of
 * them are measured, taken at an even stride; distances beyond max_dist_m count as that. */
int rs_mesh_quality_measure(const rs_mesh *m, const double *pts, size_t npts, size_t max_points, double max_dist_m,
                            rs_mesh_quality *q, rs_err *err);
/* Adds the figures to obj under their names (faces, edge_mean_m, ..., dist_p95_m). */
void rs_mesh_quality_json(const rs_mesh_quality *q, rs_json *obj);

/* The edges of m with their face counts: boundary (1), manifold (2), non-manifold (3+). */
int rs_mesh_edge_census(const rs_mesh *m, size_t *edges, size_t *boundary, size_t *nonmanifold, size_t *loops);

#endif
