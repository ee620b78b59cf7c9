/* cloud: point clouds from range scanners, keeping each scan's angular grid when there is one
 * (PTX), and cloud.ply, the ingest stage's output. */
#ifndef RS_CLOUD_H
#define RS_CLOUD_H

#include <stddef.h>
#include <stdint.h>
#include "common/err.h"
#include "common/ply.h"

/* One scan of an organized cloud: cols x rows points stored column by column (as in PTX),
 * point (col, row) at index first + col * rows + row. */
typedef struct rs_scan {
    int cols, rows;
    double position[3]; /* scanner centre, world frame (the registered frame) */
    size_t first;
} rs_scan;

typedef struct rs_cloud {
    size_t npoints;
    double *xyz;      /* 3 * npoints, world frame, metres */
    float *intensity; /* npoints, NULL if none */
    uint8_t *rgb;     /* 3 * npoints, NULL if none */
    uint8_t *valid;   /* npoints: 0 for no-return points (0 0 0 in PTX) */
    int nscans;       /* 0 for an unorganized cloud */
    rs_scan *scans;
    double origin[3];    /* world = xyz + origin (m): non-zero once georeferenced
                                  coordinates were recentred (rs_cloud_recentre) */
    int has_viewpoint;   /* the unorganized points' scanner centre is known */
    double viewpoint[3]; /* it, in the frame of xyz (normals are turned toward it) */
} rs_cloud;

void rs_cloud_free(rs_cloud *c); /* NULL is fine */

/* Reads a point-cloud file told apart by content: PLY ("ply" magic) or else PTX. */
rs_cloud *rs_cloud_read(const char *path, rs_err *err);
/* Appends src's points and scans to dst (scan offsets shifted). Intensity and colour arrays
 * are created when only one side has them (zeros for the points that had none). */
int rs_cloud_append(rs_cloud *dst, const rs_cloud *src, rs_err *err);
/* Points that belong to no scan (an unorganized part of the cloud). */
size_t rs_cloud_unorganized(const rs_cloud *c);

/* Georeferenced coordinates (some |coordinate| of a valid point or scanner above limit_m,
 * e.g. 1e4 m) lose millimetres in float: moves points and scanner positions by the whole
 * metres of their bounding box centre, adding that to c->origin. Returns 1 when moved, 0 when
 * not needed. Done in double before any float geometry (PCL, Embree, mesh.ply). */
int rs_cloud_recentre(rs_cloud *c, double limit_m);

/* Coordinates read from text and PCD clouds beyond this (m) are refused: no scan reaches that far,
 * and the float geometry after recentring could not hold it. */
#define RS_CLOUD_MAX_M 1e9

/* Reads an XYZ/CSV text cloud: one point per line, numbers separated by white space, commas
 * or semicolons; lines starting with # or // and a first line that is not numeric (a header)
 * are skipped. columns names each column in order: x y z intensity r g b (or red green blue),
 * nx ny nz and "-" (ignored); NULL means "x y z". Colours above 1 anywhere are 0..255, else
 * 0..1 (above 255 is an error); coordinates up to RS_CLOUD_MAX_M, intensities within the float
 * range. Errors name the file, line and column. Gives an unorganized cloud. */
rs_cloud *rs_cloud_read_text(const char *path, const char *columns, rs_err *err);

/* Leica PTX with one or more scans (DESIGN.md section 3): the 4x4 matrix (row-vector form,
 * may hold a scale) is applied to every point; the position line is the scanner centre in the
 * registered frame already and is kept as it is (not transformed).
 * Errors name the file, the line and what was expected (truncated files included). */
rs_cloud *rs_ptx_read(const char *path, rs_err *err);
rs_cloud *rs_ptx_read_mem(const char *data, size_t size, const char *name, rs_err *err);

/* cloud.ply: valid points only, vertex properties x y z (double), intensity, red green blue
 * (when present), and for organized scans scan, row, col (int); each scan's grid and scanner
 * position in a comment "rhoscan_scan INDEX COLS ROWS PX PY PZ", and a non-zero origin in
 * "rhoscan_origin OX OY OZ" (world = x + OX, ...; positions are in the same local frame), and
 * the unorganized points' scanner in "rhoscan_viewpoint X Y Z". Reading a PLY written by
 * other software gives an unorganized cloud. */
int rs_cloud_write_ply(const rs_cloud *c, const char *path, rs_err *err);
rs_cloud *rs_cloud_read_ply(const char *path, rs_err *err);
/* The same from a PLY in memory (its "vertex" element); name is used in messages.
 * Grid cells not in the file come back as no-return points (valid 0, at the scanner). */
rs_cloud *rs_cloud_from_ply(const rs_ply *ply, const char *name, rs_err *err);

#endif
