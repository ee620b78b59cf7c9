/* freespace_libs: the few OctoMap (liboctomap-dev) and OpenVDB (libopenvdb-dev) calls, both C++,
 * that freespace_bench needs to carve the same rays into their maps as into rhoscan's grid, for the
 * comparison in docs/BENCHMARKS.md ("Free-space map against OctoMap and OpenVDB"). Bench only:
 * rhoscan itself uses neither. States: 0 unknown, 1 free, 2 occupied, as meshing/freespace.h's. */
#ifndef RS_BENCH_FREESPACE_LIBS_H
#define RS_BENCH_FREESPACE_LIBS_H
#include <stddef.h>
#ifdef __cplusplus
extern "C" {
#endif

typedef struct rs_octo rs_octo;

rs_octo *rs_octo_new(double resolution_m);
void rs_octo_free(rs_octo *t);
/* Free along a -> b; b itself occupied when hit is 1 (OctoMap's ray update, lazily: inner nodes are
 * brought up to date by rs_octo_finish). */
void rs_octo_carve(rs_octo *t, const double a[3], const double b[3], int hit);
void rs_octo_finish(rs_octo *t);
int rs_octo_state(const rs_octo *t, const double p[3]);
size_t rs_octo_bytes(const rs_octo *t);
size_t rs_octo_leaves(const rs_octo *t);

/* An OpenVDB map of two MaskGrids (free, occupied) whose voxel (i, j, k) is the grid cell with
 * lower corner lo + (i, j, k) cell, carved by OpenVDB's own DDA. */
typedef struct rs_vdb rs_vdb;
rs_vdb *rs_vdb_new(double cell_m, const double lo[3]);
void rs_vdb_free(rs_vdb *v);
void rs_vdb_carve(rs_vdb *v, const double a[3], const double b[3], int hit);
int rs_vdb_state(const rs_vdb *v, const double p[3]);
size_t rs_vdb_bytes(const rs_vdb *v);
size_t rs_vdb_voxels(const rs_vdb *v);

#ifdef __cplusplus
}
#endif
#endif
