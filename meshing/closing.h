/* closing: faces that close the scanned model where its geometry makes them certain (issue 28,
 * part 1; docs/PIPELINE.md, irradiance: "Unknown space blocks light"). Pure geometry: a mesh, its
 * BVH and the points it was seen from (the scanners' positions, the camera's), no config, no file.
 *
 * Planar regions are the texture atlas's charts (meshing/atlas.h: connected facets whose normals
 * lie within 10 degrees of the chart's first one), kept when their area is at least min_area and
 * their facets' corners lie within max_rms (RMS) of the area-weighted plane. Each is rasterised in
 * its plane's coordinates (s, t) at `cell` (0.1 m: a tenth of a storey's height, finer than the
 * 0.25 m free-space grid, so that a column's shadow keeps its shape), a cell belonging to the
 * region when its centre lies in one of the region's facets. A cell is *shadowed* when every
 * viewpoint in front of the plane has a surface on its line of sight nearer than 0.75 cell short
 * of the cell's centre (the scanner could not have seen it), and at least one is in front.
 *   - Holes: empty cells not connected (4-neighbours) to the raster's border through empty cells,
 *     and shadowed: covered in the region's plane, facing its normal (RS_CLOSE_HOLE). An opening
 *     a viewpoint saw through (a window, a door) is not shadowed and stays open.
 *   - Extension (walls, |n_z| < 0.34, and ceilings, n_z < -0.7): from the region and its filled
 *     holes outward over empty shadowed cells, at most extend_max (2 m) from them, never into a
 *     cell another surface of the mesh crosses (the plane's intersection with the others), never
 *     above the mesh's top nor below its bottom: a boundary that is a scan shadow's edge is
 *     continued, a real end of the building is not (nothing nearer hides what lies past it), and
 *     above the walls' tops the sky stays open (RS_CLOSE_EXTEND).
 *   - Slabs (ceilings): a region seen only from below, where fewer than half of its cells have a
 *     surface of the mesh within slab_probe (1.5 m) straight above them, gets its top face,
 *     slab_thickness (0.2 m, a concrete slab or a roof's build-up) above its underside, facing up,
 *     over the region, its filled holes and its extension, and its edges: vertical faces around
 *     that outline, facing outward (RS_CLOSE_SLAB).
 * Every face carries a proxy whose radiance stands for the unseen surface's: for holes and
 * extensions the region's facet nearest to it over the raster (they lie in its plane and face its
 * way), for a slab's top and edges the mesh's facet nearest to the face among those facing its way
 * (normal within 60 degrees; the region's own when none does): the underside faces the other way. Faces are wound counter-clockwise seen from the side they
 * face (the side the scanner saw: an occluder's known side). */
#ifndef RS_CLOSING_H
#define RS_CLOSING_H

#include <stddef.h>
#include <stdint.h>
#include "common/err.h"
#include "common/mesh.h"
#include "common/scene.h"
#include "common/vec.h"

enum { RS_CLOSE_HOLE = 2, RS_CLOSE_EXTEND = 3, RS_CLOSE_SLAB = 4 }; /* occluders.ply's `source` (1: free space) */

typedef struct rs_closing_opts {
    double cell;           /* raster cell, m (grown per region until it has at most max_cells) */
    double min_area;       /* smallest region, m^2 */
    double max_rms;        /* the region's corners' RMS distance from its plane, at most, m */
    double extend_max;     /* extension's reach beyond the region, m */
    double slab_thickness; /* a slab's top above its underside, m */
    double slab_probe;     /* a surface this far above a ceiling's cell is its top (scanned), m */
    size_t max_cells;      /* per region raster */
} rs_closing_opts;

#define RS_CLOSING_OPTS_DEFAULT                \
    {                                          \
        0.1, 2.0, 0.05, 2.0, 0.2, 1.5, 4000000 \
    }

typedef struct rs_closing_stats {
    size_t regions;                           /* planar regions examined */
    size_t walls, ceilings, slabs;            /* of them */
    double hole_area, extend_area, slab_area; /* m^2 of faces added (slab: top only) */
    size_t faces;                             /* triangles */
    double rays;                              /* visibility rays traced */
} rs_closing_stats;

/* The closing faces of mesh m (traced by scene, which must be m's, without occluders), seen from
 * views[0 .. nviews). *occ (NULL when no face), *proxy and *source (RS_CLOSE_*) per triangle are
 * the caller's to free. -1 with err when out of memory. */
int rs_closing_build(const rs_mesh *m, const rs_scene *scene, const rs_v3 *views, size_t nviews,
                     const rs_closing_opts *o, rs_mesh **occ, uint32_t **proxy, uint8_t **source, rs_closing_stats *st,
                     rs_err *err);

#endif
