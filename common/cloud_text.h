/* cloud_text: XYZ/CSV text point clouds (exports of CloudCompare, scanners' office software,
 * Leica PTS), read with a column map from the config. Text has no magic bytes:
 * common/cloud_format.c knows it by extension (.xyz, .txt, .csv, .pts). */
#ifndef RS_CLOUD_TEXT_H
#define RS_CLOUD_TEXT_H

#include "common/cloud.h"
#include "common/err.h"

/* One point per line, numbers separated by white space, commas or semicolons; lines starting
 * with # or // and a first line that is not numeric (a header) are skipped. columns names
 * each column in order: x y z intensity r g b (or red green blue), nx ny nz and "-"
 * (ignored); NULL means "x y z". Colours above 1 anywhere are 0..255, else 0..1. Errors name
 * the file, line and column. Gives an unorganized cloud. */
rs_cloud *rs_cloud_read_text(const char *path, const char *columns, rs_err *err);

#endif
