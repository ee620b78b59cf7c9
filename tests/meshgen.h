/* meshgen: small procedural meshes for tests: subdivided rectangles, boxes (outward or inward),
 * and what a camera sees in a scene of a ground and a wall. */
#ifndef RS_MESHGEN_H
#define RS_MESHGEN_H

#include "common/mesh.h"

/* A mesh with room for nverts / nfaces that rs_meshgen_rect appends to. */
typedef struct {
    rs_mesh *m;
    size_t nv, nf;
} rs_meshgen;

rs_meshgen rs_meshgen_new(size_t max_verts, size_t max_faces);
/* Rectangle origin + s*e1 + t*e2, s,t in [0,1], split into nu x nv cells of two triangles,
 * normal along e1 x e2. Returns the index of its first face. */
size_t rs_meshgen_rect(rs_meshgen *g, rs_v3 origin, rs_v3 e1, rs_v3 e2, int nu, int nv);
/* Axis-aligned box [lo, hi] with n x n cells per side; inward: normals point inside. */
void rs_meshgen_box(rs_meshgen *g, rs_v3 lo, rs_v3 hi, int n, int inward);
rs_mesh *rs_meshgen_done(rs_meshgen *g);
/* Writes m as a binary PLY mesh at path; fails the test when it cannot. */
void rs_meshgen_write(const rs_mesh *m, const char *path);

/* A ground rectangle (z = 0, x in [gx0, gx1], y in [gy0, gy1]) and a wall in the plane x = wall_x
 * (y in [wy0, wy1], z in [0, wall_h]). */
typedef struct {
    double gx0, gx1, gy0, gy1;
    double wall_x, wy0, wy1, wall_h;
} rs_meshgen_wall_ground;

/* What a camera at o (x < wall_x) sees along d: 2 the wall, 1 the ground, 0 neither (the sky, or
 * ground beyond the model). */
int rs_meshgen_wall_ground_sees(const rs_meshgen_wall_ground *s, rs_v3 o, rs_v3 d);

#endif
