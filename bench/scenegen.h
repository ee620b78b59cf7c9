/* scenegen: procedural building scenes for the benchmark: a grid of blocks, courtyards,
 * facades with niches (fins) and overhangs (slabs) on a ground plane, with a known albedo per part. */
#ifndef RS_BENCH_SCENEGEN_H
#define RS_BENCH_SCENEGEN_H

#include <stddef.h>
#include <stdint.h>
#include "common/mesh.h"

typedef struct rs_bench_scene {
    rs_mesh *mesh;
    uint32_t *part; /* per facet: the part (box, ring, ground) it belongs to */
    double *albedo; /* 3 per part: the true albedo, linear */
    size_t nparts;
    rs_v3 camera; /* a street-level camera position (m, world) */
} rs_bench_scene;

/* Builds a scene of about target_facets facets (within a few percent; at least a few hundred).
 * The layout depends on seed only, the subdivision on the facet count. NULL when out of memory. */
rs_bench_scene *rs_bench_scene_new(size_t target_facets, uint32_t seed);
void rs_bench_scene_free(rs_bench_scene *s);

#endif
