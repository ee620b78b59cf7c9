/* cloud_format: the one place that maps a point-cloud file to its reader (a table in
 * cloud_format.c, in the manner of libvips' foreign/), and refuses by their magic bytes the
 * formats rhoscan recognises but does not read. */
#ifndef RS_CLOUD_FORMAT_H
#define RS_CLOUD_FORMAT_H

#include <stdint.h>

#include "common/cloud.h"
#include "common/err.h"

/* What the formats that do not describe themselves need to be read. */
typedef struct rs_cloud_read_opts {
    const char *columns;     /* XYZ/CSV text: the column map of rs_cloud_read_text; NULL: "x y z" */
    const uint8_t *las_keep; /* LAS: 256 flags, the classes kept (rs_las_parse_classes); NULL: all */
    int las_keep_withheld;   /* LAS: 1 keeps the points flagged withheld (default 0: dropped) */
    uint64_t *las_withheld;  /* LAS, out (may be NULL): the withheld points dropped */
} rs_cloud_read_opts;

/* Reads a point-cloud file with the reader its magic bytes name, else its extension:
 *   PLY  "ply" magic                        rs_cloud_read_ply (cloud_ply.h)
 *   E57  "ASTM-E57"                          rs_e57_read (e57.h)
 *   LAZ  "LASF", compressed (bit 7 or 6 of the point format at byte 104): refused by rs_las_read
 *   LAS  "LASF"                              rs_las_read (las.h), opts->las_keep
 *   PCD  .pcd                                rs_pcl_read_pcd (pcl_bridge.h)
 *   text .xyz .txt .csv .pts                 rs_cloud_read_text (cloud_text.h), opts->columns
 *   PTX  anything else (PTX has no magic)    rs_ptx_read (ptx.h)
 * An extension counts only for the formats without magic bytes: a file that does not start
 * with "ply" is not read as PLY, whatever its name. A refusal is an RS_ERR_INPUT error naming
 * the file and the format. opts may be NULL (defaults). When format is not NULL, *format gets
 * the name of the format chosen (static text, as in the first column above), also when the
 * read fails. */
rs_cloud *rs_cloud_read_with(const char *path, const rs_cloud_read_opts *opts, const char **format, rs_err *err);
/* rs_cloud_read_with(path, NULL, NULL, err). */
rs_cloud *rs_cloud_read(const char *path, rs_err *err);

#endif
