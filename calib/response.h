/* response: a camera's response curve from a text file ([rig] response_file), used instead of
 * calibrating one from the brackets (Debevec). Exports rs_response_read. */
#ifndef RS_RESPONSE_H
#define RS_RESPONSE_H

#include <stddef.h>
#include "common/err.h"

/* The file: 256 data lines, line i for 8-bit code i, each with one number (all channels) or three
 * (R G B), separated by spaces, tabs or commas; blank lines and lines starting with '#' are
 * skipped. A number is the linear exposure (radiance x time, any common scale) that gives code
 * i: from RS_RESPONSE_MIN to RS_RESPONSE_MAX (MergeDebevec takes its logarithm, in float) and
 * non-decreasing with the code. out: 256 x 3, R G B interleaved (rs_hdr_merge's response). Errors
 * name the file, the line and the value. */
#define RS_RESPONSE_MIN 1e-30
#define RS_RESPONSE_MAX 1e30
int rs_response_read(const char *path, float *out, rs_err *err);
/* The same from size bytes of text (a NUL byte is an error); path names it in errors. */
int rs_response_parse(const char *data, size_t size, const char *path, float *out, rs_err *err);

#endif
