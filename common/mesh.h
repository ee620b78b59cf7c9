/* mesh: an indexed triangle mesh in world coordinates (metres, Z up), the unknowns of the
 * method. Triangles wind counter-clockwise seen from outside (the side the scanner saw).
 * Vertices are float because Embree traces float geometry; callers recentre georeferenced
 * coordinates before building one. */
#ifndef RS_MESH_H
#define RS_MESH_H

#include <stddef.h>
#include <stdint.h>
#include "common/err.h"
#include "common/log.h"
#include "common/ply.h"
#include "common/vec.h"

typedef struct rs_mesh {
    size_t nverts, nfaces;
    float *verts;   /* 3 * nverts */
    uint32_t *tris; /* 3 * nfaces */
} rs_mesh;

rs_mesh *rs_mesh_new(size_t nverts, size_t nfaces);
void rs_mesh_free(rs_mesh *m);

/* From a PLY's vertex (x y z) and face (vertex_indices or vertex_index) elements.
 * Polygons are split into fans; faces with an index out of range, or coordinates that are
 * not finite, are errors naming the file (name) and the element index. */
rs_mesh *rs_mesh_from_ply(const rs_ply *ply, const char *name, rs_err *err);
/* Adds "vertex" (x y z float) and "face" (vertex_indices uchar/int) elements to ply; returns
 * the face element so that callers can add per-facet properties. */
rs_ply_element *rs_mesh_to_ply(const rs_mesh *m, rs_ply *ply);
/* Reads a mesh PLY file, keeping the PLY (for face properties) in *ply_out if not NULL. */
rs_mesh *rs_mesh_read(const char *path, rs_ply **ply_out, rs_err *err);

/* Per-face geometry: centroid, unit normal (from the winding; zero for degenerate faces),
 * area in m^2. */
void rs_mesh_face(const rs_mesh *m, size_t f, rs_v3 *centroid, rs_v3 *normal, double *area);
static inline rs_v3 rs_mesh_vert(const rs_mesh *m, uint32_t v)
{
    return rs_v3_from_f(m->verts + 3 * (size_t)v);
}

/* 1 when face f's corners may be on one line: each component of the cross product of its edges
 * is within twice what rounding the corners to float can change it by (a collinear triangle
 * written in decimal and read into float keeps a tiny area that is only rounding). A sliver
 * whose thin side is resolved by its coordinates is not collinear. */
int rs_mesh_face_collinear(const rs_mesh *m, size_t f);

typedef struct rs_mesh_degenerate {
    size_t zero_area;  /* a repeated corner, or an area of at most min_area */
    size_t collinear;  /* rs_mesh_face_collinear */
    size_t coincident; /* the corners of an earlier kept face, in the same winding */
} rs_mesh_degenerate;

/* Sets drop[f] = 1 (drop: nfaces bytes, zeroed by the caller) for every face with nothing to
 * measure on: zero area, collinear corners, or coincident with an earlier face (every ray meets
 * coincident copies together: two million of them made tracing take hours). Counts each kind in
 * *count. progress (may be NULL) advances by 2 x nfaces. Returns -1 when out of memory or when
 * there are 2^32 - 1 faces or more. */
int rs_mesh_mark_degenerate(const rs_mesh *m, double min_area, uint8_t *drop, rs_mesh_degenerate *count,
                            rs_progress *progress);

/* Diagonal of the bounding box (m): scales ray offsets and tolerances. */
double rs_mesh_extent(const rs_mesh *m);

/* Lengths (m) of the distinct edges, each counted once, into a new array of *n values
 * (caller frees). NULL when out of memory, or when there is no edge (*n = 0). */
double *rs_mesh_edge_lengths(const rs_mesh *m, size_t *n);

#endif
