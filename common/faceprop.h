/* faceprop: per-facet values carried between stages as PLY face properties
 * (names of docs/DESIGN.md, section File contract: albedo_r/_g/_b, radiance_*, irradiance_sky_*, ...). */
#ifndef RS_FACEPROP_H
#define RS_FACEPROP_H

#include <stddef.h>
#include "common/err.h"
#include "common/ply.h"

/* Copies face property `name` of ply (file: for messages) into out[nfaces]; error when the
 * face element or the property is missing, or the face count differs from nfaces. */
int rs_faceprop_get(const rs_ply *ply, const char *file, const char *name, size_t nfaces, double *out, rs_err *err);
/* The three properties prefix_r, prefix_g, prefix_b into out[3 * nfaces] (interleaved). */
int rs_faceprop_get_rgb(const rs_ply *ply, const char *file, const char *prefix, size_t nfaces, double *out,
                        rs_err *err);
/* Adds prefix_r/_g/_b float properties from interleaved rgb[3 * count]. */
int rs_faceprop_add_rgb(rs_ply_element *faces, const char *prefix, const double *rgb);

#endif
