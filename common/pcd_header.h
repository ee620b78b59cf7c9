/* pcd_header: rhoscan's own check of a PCD file's header and data size before PCL reads it: PCL
 * trusts the header (an empty file or a header whose sizes do not add up crashed its reader). */
#ifndef RS_PCD_HEADER_H
#define RS_PCD_HEADER_H

#ifdef __cplusplus
extern "C" { /* read from common/pcl_bridge.cpp */
#endif

#include <stddef.h>
#include "common/err.h"

/* Checks size bytes of a PCD file (name names it in errors): the header lines once each in the
 * format's order (VERSION FIELDS SIZE TYPE COUNT WIDTH HEIGHT VIEWPOINT POINTS DATA; VERSION,
 * COUNT and VIEWPOINT may be left out), FIELDS, SIZE, TYPE and COUNT agree
 * (one value each per field, at most 256 fields; SIZE 1, 2, 4 or 8; TYPE I, U or F, F of size 4
 * or 8; COUNT 1 to 10^6), WIDTH x HEIGHT = POINTS (integers, at most 2^31 - 1), DATA ascii,
 * binary or binary_compressed, and binary data at least POINTS x the point's bytes (compressed:
 * its two sizes consistent with the file and the points). Errors name the line and the field. */
int rs_pcd_check(const char *data, size_t size, const char *name, rs_err *err);
/* The same on a file. */
int rs_pcd_check_file(const char *path, rs_err *err);

#ifdef __cplusplus
}
#endif

#endif
