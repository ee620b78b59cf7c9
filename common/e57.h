/* e57: the ASTM E57 (E2807) reader: scans (data3D) with their poses, grids, intensity, colour
 * and normals, and the images (images2D) with their poses, read from files other software wrote.
 * The XML section is parsed by libexpat; the binary part (1024-byte pages ending in a CRC-32C,
 * compressed-vector sections of data, index and empty packets, bit-packed bytestreams) by
 * common/e57_file.c and common/e57_points.c. docs/FORMATS.md lists the fields used.
 *
 * Streaming: rs_e57_open reads the header and the XML (small), rs_e57_scan_begin then
 * rs_e57_scan_next deliver a scan's points a chunk at a time in the world frame (the scan's
 * pose applied), so the reader's memory does not depend on the file's size. rs_e57_read builds
 * an rs_cloud from those chunks. Every error names the file, a byte offset or an XML path, and
 * what was expected. */
#ifndef RS_E57_H
#define RS_E57_H

#include <stddef.h>
#include <stdint.h>

#include "common/cloud.h"
#include "common/err.h"

typedef struct rs_e57 rs_e57;

/* One data3D entry as the XML describes it. */
typedef struct rs_e57_scan_info {
    char name[128], guid[128];
    uint64_t records;                           /* the points' recordCount */
    int has_pose;                               /* the XML had a pose (else identity) */
    double rotation[9];                         /* row-major, local to world (the unit quaternion's matrix) */
    double translation[3];                      /* the scanner's position in the world frame */
    int grid;                                   /* rowIndex and columnIndex present with usable bounds */
    int64_t row_min, row_max, col_min, col_max; /* the grid's index bounds when grid */
    int spherical;                              /* coordinates are sphericalRange/Azimuth/Elevation */
    int has_intensity, has_rgb, has_normals;
} rs_e57_scan_info;

/* A chunk of points (owned by the reader, valid until the next call). */
typedef struct rs_e57_points {
    size_t n;
    double *xyz;        /* 3n, world frame */
    uint8_t *valid;     /* n: 0 for an invalid state (no return, direction only) */
    float *intensity;   /* n, scaled to 0..1 by the intensity limits; NULL without intensity */
    uint8_t *rgb;       /* 3n, scaled to 0..255 by the colour limits; NULL without colour */
    float *normal;      /* 3n, world frame; NULL without nor:normalX/Y/Z */
    int64_t *row, *col; /* n, the grid indices; NULL unless the scan has a grid */
} rs_e57_points;

/* The projection of an images2D entry. */
typedef enum { RS_E57_VISUAL, RS_E57_SPHERICAL, RS_E57_PINHOLE, RS_E57_CYLINDRICAL } rs_e57_projection;

typedef struct rs_e57_image_info {
    char name[128], guid[128], associated_scan[128]; /* associatedData3DGuid, "" if none */
    rs_e57_projection projection;
    int width, height;    /* imageWidth / imageHeight */
    int png;              /* 1: pngImage, 0: jpegImage */
    uint64_t blob_offset; /* the image blob's physical offset (after its 16-byte section header) */
    uint64_t blob_length; /* its bytes */
    int has_pose;
    double rotation[9], translation[3]; /* row-major, camera to world */
    double pixel_width, pixel_height;   /* spherical: radians per pixel; pinhole/cylindrical: metres */
    double focal_length, principal_x, principal_y, radius; /* pinhole (and cylindrical radius), metres */
    int has_distortion;                                    /* the dist:distortion extension (Leica) */
    double k[6], p[2], cx, cy, fx, fy;                     /* its CV_K1..K6, CV_P1/P2, CV_CX/CY, CV_FX/FY */
} rs_e57_image_info;

/* Opens path: checks the header, the pages holding the XML (CRC-32C), parses the XML. */
rs_e57 *rs_e57_open(const char *path, rs_err *err);
/* The same over bytes in memory (not copied: they must outlive the reader); name for messages. */
rs_e57 *rs_e57_open_mem(const void *data, size_t size, const char *name, rs_err *err);
void rs_e57_close(rs_e57 *e); /* NULL is fine */

int rs_e57_scan_count(const rs_e57 *e);
const rs_e57_scan_info *rs_e57_scan(const rs_e57 *e, int i);
int rs_e57_image_count(const rs_e57 *e);
const rs_e57_image_info *rs_e57_image(const rs_e57 *e, int i);

/* Starts reading scan i's points (any scan, any number of times). */
int rs_e57_scan_begin(rs_e57 *e, int i, rs_err *err);
/* The next chunk of at most RS_E57_CHUNK points into *out; returns 1 with out->n > 0, 0 at the
 * end of the scan (every record read), -1 on error. */
#define RS_E57_CHUNK 16384
int rs_e57_scan_next(rs_e57 *e, rs_e57_points *out, rs_err *err);

/* Reads image i's blob (the encoded JPEG or PNG) into a malloc'd buffer. */
int rs_e57_image_blob(rs_e57 *e, int i, uint8_t **data, size_t *size, rs_err *err);

/* Every scan of path into one cloud: scans with a grid become rs_scan grids (cells no point
 * fills are invalid), the others unorganized points after them (their invalid points dropped).
 * A file without points is refused. Progress is reported on stderr. */
rs_cloud *rs_e57_read(const char *path, rs_err *err);
/* The same from memory (the fuzz harness). */
rs_cloud *rs_e57_read_mem(const void *data, size_t size, const char *name, rs_err *err);

/* CRC-32C (Castagnoli) of n bytes, as E57 pages carry it (exported for the test writer). */
uint32_t rs_e57_crc32c(const void *data, size_t n);

#endif
