/* las: the ASPRS LAS reader (versions 1.0 to 1.4, point data record formats 0 to 10), streaming
 * a chunk of points at a time, and the cloud built from it; LAZ (compressed LAS) is refused. */
#ifndef RS_LAS_H
#define RS_LAS_H

#include <stddef.h>
#include <stdint.h>

#include "common/cloud.h"
#include "common/err.h"
#include "common/las_crs.h"

/* What the public header block says, checked against the file (rs_las_open). */
typedef struct rs_las_info {
    int version_major, version_minor;
    int format;                /* point data record format, 0..10 */
    unsigned record_length;    /* bytes per point record; beyond the format's fields: extra bytes */
    unsigned header_size;      /* bytes of the public header block */
    uint32_t offset_to_points; /* where the first point record starts */
    uint32_t nvlrs;
    uint64_t npoints; /* the 64-bit count of LAS 1.4 when it is set, else the legacy 32-bit one */
    uint16_t global_encoding;
    double scale[3], offset[3]; /* coordinate = integer * scale + offset */
    double min[3], max[3];      /* the header's bounding box */
    int has_rgb;                /* formats 2, 3, 5, 7, 8 and 10 */
    uint64_t file_size;
    rs_las_crs crs;   /* the coordinate system of the GeoTIFF keys or WKT, kind NONE without one */
    double unit_m[3]; /* metres per file unit (x, y, z): the decoded coordinates are in metres */
} rs_las_info;

/* One chunk of decoded points, owned by the reader (valid until the next call). */
typedef struct rs_las_chunk {
    size_t n;
    double *xyz;             /* 3 n: (integer * scale + offset) * unit_m, the file's frame, metres */
    uint16_t *intensity;     /* n */
    uint16_t *rgb;           /* 3 n as stored (16-bit fields), NULL without colour */
    uint8_t *classification; /* n: the class number (formats 0-5: the low 5 bits of the field) */
    uint8_t *withheld;       /* n: 1 when the withheld flag is set (formats 0-5: bit 7 of byte 15;
                                6-10: bit 2 of the classification flags, byte 15) */
} rs_las_chunk;

typedef struct rs_las rs_las;

/* Opens path and checks its header before anything the counts would size is allocated: the
 * signature, the version, the header size, the point offset, the format and its record
 * length, the scales and offsets, and that the points the header counts fit in the file from
 * the point offset on (the offset is used, never assumed to follow the header or the VLRs).
 * A LAZ file (bit 7 or 6 of the format byte, or a "laszip encoded" VLR) is refused with a
 * message saying how to decompress it. Errors are RS_ERR_INPUT naming the file, the byte
 * offset of the field and what was expected. Caller closes with rs_las_close. */
rs_las *rs_las_open(const char *path, rs_err *err);
const rs_las_info *rs_las_info_of(const rs_las *f); /* borrowed, valid while f is open */
/* Decodes the next chunk of at most about 4 MiB of records (a record length's extra bytes
 * skipped, waveform packets ignored); its n is 0 once every point was read. NULL on error: a
 * file that ends before its last point, or a coordinate beyond RS_CLOUD_MAX_M (the error names
 * the point and its offset). */
const rs_las_chunk *rs_las_next(rs_las *f, rs_err *err);
void rs_las_close(rs_las *f); /* NULL is fine */

/* "2 6" into keep[256] (1 for each class number listed, 0..255, space-separated); the text
 * names the key in messages. Returns 0, or -1 with err set (file: NULL, the caller names it). */
int rs_las_parse_classes(const char *text, uint8_t keep[256], rs_err *err);

/* Reads path into an unorganized cloud (nscans 0, every point valid) from its chunks, one copy:
 * coordinates in double as the file has them (no recentring here), intensity as the 16-bit
 * value, colour in 8 bits by the rule of docs/FORMATS.md (every R, G and B value of the kept
 * points <= 255: 8-bit values written into the 16-bit fields, taken as they are; otherwise
 * 16-bit colour, its high byte). keep: the classes kept (NULL: all); a file with points none of
 * which is kept is refused, naming the classes it has. The cloud's normals_up is set (no
 * scanner position is in a LAS file). Caller frees. */
rs_cloud *rs_las_read(const char *path, const uint8_t *keep, rs_err *err);
/* The same, keep_withheld 1 to keep the points flagged withheld (rs_las_read drops them, as the
 * specification asks: "should not be included in processing"); *withheld (may be NULL) gets the
 * count of withheld points dropped. */
rs_cloud *rs_las_read_with(const char *path, const uint8_t *keep, int keep_withheld, uint64_t *withheld, rs_err *err);

#endif
