/* axes: the one place where rhoscan's world frame (Z up, right-handed, metres; docs/DESIGN.md,
 * section Frames) becomes the Y-up frame of glTF 2.0 and of OBJ as importers read it (Blender's
 * OBJ importer assumes Y up): x stays, up (z) becomes y, and y becomes -z, a rotation of -90
 * degrees about x, so the frame stays right-handed and nothing is mirrored. */
#ifndef RS_AXES_H
#define RS_AXES_H

#include "common/vec.h"

static inline rs_v3 rs_axes_yup_from_zup(rs_v3 p)
{
    return rs_v3_make(p.x, p.z, -p.y);
}
static inline rs_v3 rs_axes_zup_from_yup(rs_v3 p)
{
    return rs_v3_make(p.x, -p.z, p.y);
}

#endif
