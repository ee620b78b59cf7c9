/* meshdist: distances from points to a triangle mesh (Embree point queries), for the mesh
 * report (scan points to the mesh) and the accuracy tests (mesh samples to the truth). */
#ifndef RS_MESHDIST_H
#define RS_MESHDIST_H

#include <stddef.h>
#include "common/err.h"
#include "common/mesh.h"

typedef struct rs_meshdist rs_meshdist;

/* Builds the BVH over m (copied: m may be freed afterwards). Caller frees with
 * rs_meshdist_free. */
rs_meshdist *rs_meshdist_new(const rs_mesh *m, rs_err *err);
void rs_meshdist_free(rs_meshdist *d);

/* Distance (m) from p (same frame as the mesh) to the nearest point of the mesh, or INFINITY
 * when none lies within max_m. Thread-safe. *face gets the nearest face when not NULL. */
double rs_meshdist_query(const rs_meshdist *d, const double p[3], double max_m, size_t *face);

/* Closest point to p on triangle (a, b, c) (Ericson, Real-Time Collision Detection, 5.1.5). */
void rs_closest_on_triangle(const double p[3], const double a[3], const double b[3], const double c[3], double out[3]);

#endif
