/* cloud: point clouds from range scanners in memory, keeping each scan's angular grid when
 * there is one (PTX), and their basic operations. The files are the format modules':
 * common/cloud_format.h reads any cloud file (its table maps a file to its reader: PLY in
 * cloud_ply.h, PTX in ptx.h, XYZ/CSV text in cloud_text.h, PCD in pcl_bridge.h, LAS in las.h). */
#ifndef RS_CLOUD_H
#define RS_CLOUD_H

#include <stddef.h>
#include <stdint.h>
#include "common/err.h"

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
    float *normal;    /* 3 * npoints, unit normals the file gave (E57 nor:, PLY nx ny nz), world frame;
                         NULL if none. The mesh stage uses them as they are, orientation included */
    uint8_t *valid;   /* npoints: 0 for no-return points (0 0 0 in PTX) */
    int nscans;       /* 0 for an unorganized cloud */
    rs_scan *scans;
    double origin[3];    /* world = xyz + origin (m): non-zero once georeferenced
                                  coordinates were recentred (rs_cloud_recentre) */
    int has_viewpoint;   /* the unorganized points' scanner centre is known */
    double viewpoint[3]; /* it, in the frame of xyz (normals are turned toward it) */
    int normals_up;      /* without a viewpoint: the unorganized points' normals are turned up (+Z),
                            as for LAS (airborne and mobile clouds carry no scanner position) */
} rs_cloud;

void rs_cloud_free(rs_cloud *c); /* NULL is fine */

/* Appends src's points and scans to dst (scan offsets shifted). Intensity and colour arrays
 * are created when only one side has them (zeros for the points that had none); normals are
 * kept only when both sides have them (or dst is empty). */
int rs_cloud_append(rs_cloud *dst, const rs_cloud *src, rs_err *err);
/* Points that belong to no scan (an unorganized part of the cloud). */
size_t rs_cloud_unorganized(const rs_cloud *c);

/* For the readers: grows c's arrays to hold total points (c->npoints unchanged). Intensity
 * and colour arrays are grown when they exist and created when wanted, normals grown when they
 * exist; their entries from c->npoints on are zero. */
int rs_cloud_resize(rs_cloud *c, size_t total, int want_intensity, int want_rgb, rs_err *err);

/* Georeferenced coordinates (some |coordinate| of a valid point or scanner above limit_m,
 * e.g. 1e4 m) lose millimetres in float: moves points and scanner positions by the whole
 * metres of their bounding box centre, adding that to c->origin. Returns 1 when moved, 0 when
 * not needed. Done in double before any float geometry (PCL, Embree, mesh.ply). */
int rs_cloud_recentre(rs_cloud *c, double limit_m);

/* Coordinates read from text and PCD clouds beyond this (m) are refused: no scan reaches that far,
 * and the float geometry after recentring could not hold it. */
#define RS_CLOUD_MAX_M 1e9

#endif
