/* occluders_ply: reads an occluder PLY (vertex x y z, face vertex_indices, face int proxy), as the
 * irradiance stage writes occluders.ply and takes [irradiance] occluders_file: the faces that close
 * the scanned shell for the light (freespace.h, closing.h), each with the mesh facet whose radiance
 * stands for its unseen surface. The irradiance stage attaches them to its scene for every ray; the
 * texture stage to its shadow rays toward the sun, so that both see the same closed model. */
#ifndef RS_OCCLUDERS_PLY_H
#define RS_OCCLUDERS_PLY_H

#include <stddef.h>
#include <stdint.h>
#include "common/err.h"
#include "common/mesh.h"

/* The occluders of a mesh of nf facets into *occ and *proxy (freed by the caller): 0, or -1 with
 * err naming the file, the element and what was expected (nothing is returned then). */
int rs_occluders_read(const char *path, size_t nf, rs_mesh **occ, uint32_t **proxy, rs_err *err);

#endif
