/* simplify: quadric edge-collapse simplification (Garland & Heckbert 1997) to a target mean
 * edge length or face count, keeping sharp edges, boundaries and manifoldness. */
#ifndef RS_SIMPLIFY_H
#define RS_SIMPLIFY_H

#include <stddef.h>
#include "common/err.h"
#include "common/mesh.h"

typedef struct rs_simplify_opts {
    double target_edge_m;       /* stop once the mean edge length reaches this (m); 0: no limit */
    size_t target_faces;        /* stop once at most this many faces remain; 0: no limit */
    double max_normal_turn_rad; /* refuse a collapse that turns a face's normal more than this */
    double min_quality;         /* refuse a collapse whose worst triangle around the edge falls
                                    below this and below the worst one there before: quality
                                    4 sqrt(3) area / sum of squared edges, 1 when equilateral */
    double boundary_weight;     /* weight of the planes that hold boundary edges in place, per
                                    squared edge length (face planes weigh their area) */
    double length_weight;       /* cost added per squared edge length and unit of quadric area:
                                    on flat parts the shortest edges go first */
    double edge_per_metre;      /* > 0: refuse a collapse that makes an edge longer than this
                                    times its distance from view_point (a size that grows with
                                    distance, as a panorama's pixel footprint does); 0: off */
    double view_point[3];       /* m, world frame */
} rs_simplify_opts;

/* 60 degrees, 0.2, 10, 0.01; no targets, no size limit. */
void rs_simplify_defaults(rs_simplify_opts *o);

typedef struct rs_simplify_stats {
    size_t faces_in, faces_out, verts_in, verts_out;
    size_t collapses;
    size_t rejected_topology;           /* link condition, non-manifold edge, pinched boundary */
    size_t rejected_flip;               /* a face's normal would turn too far */
    size_t rejected_quality;            /* a face would become a needle (or a worse one) */
    size_t rejected_size;               /* an edge would outgrow edge_per_metre */
    double mean_edge_in, mean_edge_out; /* m */
} rs_simplify_stats;

/* Collapses edges cheapest first (quadric error plus the length term, ties broken by vertex
 * index) until a target is met or nothing more may collapse, and returns the new mesh
 * (unused vertices dropped, order kept). Faces whose corners repeat are dropped. The result
 * does not depend on thread count or memory layout. Caller frees with rs_mesh_free. */
rs_mesh *rs_simplify_apply(const rs_mesh *in, const rs_simplify_opts *o, rs_simplify_stats *st, rs_err *err);

#endif
