/* ptx: the Leica PTX reader (docs/DESIGN.md, section Scan files): one or more organized scans back to back,
 * each registered by its 4x4 matrix. PTX has no magic bytes: common/cloud_format.c reads as
 * PTX whatever no other format claims. */
#ifndef RS_PTX_H
#define RS_PTX_H

#include <stddef.h>
#include "common/cloud.h"
#include "common/err.h"

/* The 4x4 matrix (row-vector form, may hold a scale) is applied to every point; the position
 * line is the scanner centre in the registered frame already and is kept as it is (not
 * transformed). Errors name the file, the line and what was expected (truncated files
 * included). */
rs_cloud *rs_ptx_read(const char *path, rs_err *err);
rs_cloud *rs_ptx_read_mem(const char *data, size_t size, const char *name, rs_err *err);

#endif
