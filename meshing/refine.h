/* refine: splits the long edges of a mesh (a CAD or BIM model, a closed truth mesh) until every
 * edge is at most a target length, a constant or one that grows with the distance from a view
 * point as a panorama's pixel footprint does: the facets are the method's unknowns, and a model
 * of a few large triangles per wall would give one albedo per wall. Red-green refinement
 * (Bank, Sherman and Weiser 1983): the edges to split are chosen per edge, so that both faces of
 * a shared edge split it at the same midpoint and the mesh stays conforming (no T-junctions);
 * a face with one, two or three split edges becomes two, three or four faces in its own winding. */
#ifndef RS_REFINE_H
#define RS_REFINE_H

#include <stddef.h>
#include "common/err.h"
#include "common/mesh.h"

typedef struct rs_refine_opts {
    double edge_m;         /* split edges longer than this (m); 0: only edge_per_metre */
    double edge_per_metre; /* > 0: also allow edge_per_metre x the distance of the edge's
                              midpoint from view_point, whichever of the two is longer */
    double view_point[3];  /* m, world frame */
    size_t max_faces;      /* refuse (RS_ERR_INPUT) to grow past this many faces; 0: 50 million */
} rs_refine_opts;

typedef struct rs_refine_stats {
    size_t faces_in, faces_out, edges_split;
    int passes;
} rs_refine_stats;

/* A new mesh whose edges all meet the target (the vertices of m first, in their order; the
 * midpoints after). NULL with err set: out of memory, or the refinement would pass max_faces
 * (the message gives the target and the count it would reach). stats may be NULL. */
rs_mesh *rs_mesh_refine(const rs_mesh *m, const rs_refine_opts *o, rs_refine_stats *stats, rs_err *err);

#endif
