/* cloud: point clouds from range scanners, keeping each scan's angular grid when there is one
 * (PTX), and cloud.ply, the ingest stage's output. */
#ifndef RS_CLOUD_H
#define RS_CLOUD_H

#include <stddef.h>
#include <stdint.h>
#include "err.h"
#include "ply.h"

/* One scan of an organized cloud: cols x rows points stored column by column (as in PTX),
 * point (col, row) at index first + col * rows + row. */
typedef struct rs_scan {
    int cols, rows;
    double position[3];        /* scanner centre, world frame (the registered frame) */
    size_t first;
} rs_scan;

typedef struct rs_cloud {
    size_t npoints;
    double *xyz;               /* 3 * npoints, world frame, metres */
    float *intensity;          /* npoints, NULL if none */
    uint8_t *rgb;              /* 3 * npoints, NULL if none */
    uint8_t *valid;            /* npoints: 0 for no-return points (0 0 0 in PTX) */
    int nscans;                /* 0 for an unorganized cloud */
    rs_scan *scans;
} rs_cloud;

void rs_cloud_free(rs_cloud *c);          /* NULL is fine */

/* Reads a point-cloud file told apart by content: PLY ("ply" magic) or else PTX. */
rs_cloud *rs_cloud_read(const char *path, rs_err *err);
/* Appends src's points and scans to dst (scan offsets shifted). Intensity and colour arrays
 * are created when only one side has them (zeros for the points that had none). */
int rs_cloud_append(rs_cloud *dst, const rs_cloud *src, rs_err *err);
/* Points that belong to no scan (an unorganized part of the cloud). */
size_t rs_cloud_unorganized(const rs_cloud *c);

/* Leica PTX with one or more scans (DESIGN.md section 3): the 4x4 matrix (row-vector form,
 * may hold a scale) is applied to every point; the position line is the scanner centre in the
 * registered frame already and is kept as it is (not transformed).
 * Errors name the file, the line and what was expected (truncated files included). */
rs_cloud *rs_ptx_read(const char *path, rs_err *err);
rs_cloud *rs_ptx_read_mem(const char *data, size_t size, const char *name, rs_err *err);

/* cloud.ply: valid points only, vertex properties x y z (double), intensity, red green blue
 * (when present), and for organized scans scan, row, col (int); each scan's grid and scanner
 * position in a comment "rhoscan_scan INDEX COLS ROWS PX PY PZ". Reading a PLY written by
 * other software gives an unorganized cloud. */
int rs_cloud_write_ply(const rs_cloud *c, const char *path, rs_err *err);
rs_cloud *rs_cloud_read_ply(const char *path, rs_err *err);
/* The same from a PLY in memory (its "vertex" element); name is used in messages.
 * Grid cells not in the file come back as no-return points (valid 0, at the scanner). */
rs_cloud *rs_cloud_from_ply(const rs_ply *ply, const char *name, rs_err *err);

#endif
