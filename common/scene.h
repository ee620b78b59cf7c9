/* scene: the mesh in an Embree 3 BVH, built once, queried in batches from OpenMP loops.
 * Embree traces float geometry and does no self-intersection handling: callers offset ray
 * origins with rs_scene_offset(). Rays are validated (finite) before tracing. */
#ifndef RS_SCENE_H
#define RS_SCENE_H

#include <stddef.h>
#include <stdint.h>
#include "common/err.h"
#include "common/mesh.h"

#define RS_NO_HIT UINT32_MAX

typedef struct rs_scene rs_scene;

typedef struct rs_ray {
    rs_v3 org, dir; /* dir need not be unit; t is in units of |dir| */
    double tnear, tfar;
} rs_ray;

typedef struct rs_hit {
    uint32_t face;    /* RS_NO_HIT when the ray escapes */
    float t;          /* hit distance in units of |dir| */
    float u, v;       /* barycentrics of vertices 1 and 2 */
    uint8_t backface; /* the ray hit the side opposite to the face's normal */
    uint8_t occluder; /* the ray escaped the mesh and hit an occluder (rs_scene_set_occluders):
                         face is then that occluder's proxy facet, backface 1, u = v = 0 */
} rs_hit;

/* Builds the BVH. The mesh is borrowed: it must outlive the scene. */
rs_scene *rs_scene_new(const rs_mesh *mesh, rs_err *err);
void rs_scene_free(rs_scene *s);
const rs_mesh *rs_scene_mesh(const rs_scene *s);
/* Unit normal of face f (precomputed; zero for degenerate faces). */
rs_v3 rs_scene_normal(const rs_scene *s, uint32_t f);

/* Closest hits of n rays. Rays with non-finite values get face = RS_NO_HIT. Thread-safe. */
void rs_scene_intersect(const rs_scene *s, const rs_ray *rays, rs_hit *hits, size_t n);
/* The same for rays that are coherent (a camera's neighbouring pixels, in order): Embree may then
 * trace them as packets (the closest hits are the same, up to ties between triangles). */
void rs_scene_intersect_coherent(const rs_scene *s, const rs_ray *rays, rs_hit *hits, size_t n);
/* occluded[k] = 1 when something lies on ray k within (tnear, tfar). Thread-safe. */
void rs_scene_occluded(const rs_scene *s, const rs_ray *rays, uint8_t *occluded, size_t n);

/* Attaches occluders (faces between known and unknown space, each facing the known side,
 * meshing/freespace.h) to the scene: a ray that escapes the mesh is traced against them and is
 * blocked at the first face it crosses into unknown space farther than near (m) from its origin,
 * or at near when it is inside unknown space there (it crossed into it nearer and not out
 * again): reported as a hit on proxy[occluder face] with occluder = 1 (intersect) or as occluded
 * (occluded). The near limit keeps a facet from being shadowed by the faces of its own cell.
 * occ and proxy are borrowed (they must outlive the scene); an occ with no face detaches them.
 * Not thread-safe against queries running at the same time. */
int rs_scene_set_occluders(rs_scene *s, const rs_mesh *occ, const uint32_t *proxy, double near, rs_err *err);
/* The occluders' face count (0 without). */
size_t rs_scene_occluder_faces(const rs_scene *s);

/* Distance to push a ray origin off a surface at point p: scaled to the scene's size and to
 * the float precision at p, so that the ray does not hit the facet it starts on. */
double rs_scene_offset(const rs_scene *s, rs_v3 p);

#endif
