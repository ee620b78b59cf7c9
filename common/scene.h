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

/* Distance to push a ray origin off a surface at point p: scaled to the scene's size and to
 * the float precision at p, so that the ray does not hit the facet it starts on. */
double rs_scene_offset(const rs_scene *s, rs_v3 p);

#endif
