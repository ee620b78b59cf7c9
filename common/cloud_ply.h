/* cloud_ply: point clouds as PLY files. cloud.ply, the ingest stage's output: valid points
 * only, vertex properties x y z (double), intensity, red green blue, nx ny nz (when present), and for
 * organized scans scan, row, col (int); each scan's grid and scanner position in a comment
 * "rhoscan_scan INDEX COLS ROWS PX PY PZ", a non-zero origin in "rhoscan_origin OX OY OZ"
 * (world = x + OX, ...; positions are in the same local frame), and the unorganized points'
 * scanner in "rhoscan_viewpoint X Y Z", or without one "rhoscan_normals_up" when their normals
 * are to point up (LAS clouds, rs_cloud's normals_up). Reading a PLY written by other software gives an
 * unorganized cloud. */
#ifndef RS_CLOUD_PLY_H
#define RS_CLOUD_PLY_H

#include "common/cloud.h"
#include "common/err.h"
#include "common/ply.h"

int rs_cloud_write_ply(const rs_cloud *c, const char *path, rs_err *err);
/* cloud.ply of count points that are not in memory (the ingest's streaming path): the header is
 * the one rs_cloud_write_ply would write for shape (its scans, origin, viewpoint, normals_up, and
 * which of intensity, rgb and normal are non-NULL; its points are not read), the records come
 * from fn in order, one value per property: x y z [intensity] [red green blue] [nx ny nz]
 * [scan row col]. The same bytes as rs_cloud_write_ply for the same points. */
int rs_cloud_write_ply_stream(const rs_cloud *shape, size_t count, rs_ply_record_fn fn, void *ctx, const char *path,
                              rs_err *err);
rs_cloud *rs_cloud_read_ply(const char *path, rs_err *err);
/* The same from a PLY in memory (its "vertex" element); name is used in messages.
 * Grid cells not in the file come back as no-return points (valid 0, at the scanner). */
rs_cloud *rs_cloud_from_ply(const rs_ply *ply, const char *name, rs_err *err);

#endif
