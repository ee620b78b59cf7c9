/* ply_internal: what ply.c (model, builders, writer) and ply_read.c (reader) share.
 * Not part of the public API: include ply.h elsewhere. */
#ifndef RS_PLY_INTERNAL_H
#define RS_PLY_INTERNAL_H

#include <stddef.h>
#include "common/ply.h"

#define RS_PLY_NTYPES 8

/* Bytes per value in binary files, and the names written in headers (the original PLY names,
 * which every reader knows). Indexed by rs_ply_type. */
extern const size_t rs_ply_type_size[RS_PLY_NTYPES];
extern const char *const rs_ply_type_name[RS_PLY_NTYPES];
/* Range of each type (floats: +-FLT_MAX, +-DBL_MAX). */
extern const double rs_ply_type_min[RS_PLY_NTYPES];
extern const double rs_ply_type_max[RS_PLY_NTYPES];

int rs_ply_type_valid(int type);
int rs_ply_type_is_int(rs_ply_type type);

/* Makes room for item n in arr, which holds n items and was only ever grown by this
 * function: capacity doubles at powers of two, so appending one at a time stays linear.
 * Returns the (possibly moved) array, or NULL with arr untouched when memory runs out. */
void *rs_ply_grow(void *arr, size_t n, size_t item_size);

#endif
