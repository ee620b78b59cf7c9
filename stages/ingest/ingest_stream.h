/* ingest_stream: the ingest stage's streaming path (ingest_stream.c) and what it shares with the
 * whole-cloud path (ingest.c). Internal to stages/ingest. */
#ifndef RS_INGEST_STREAM_H
#define RS_INGEST_STREAM_H

#include <stddef.h>
#include <stdint.h>

#include "common/config.h"
#include "common/err.h"
#include "pipeline/stage.h"

/* Across a line, unorganized points spread less than this share of their length have no surface. */
#define RS_INGEST_MIN_SPREAD 1e-5

/* 1 when [ingest] streaming is on, outlier removal off, no voxel grid, and every scan file is
 * LAS (not LAZ) or an E57 whose scans have no grid. */
int rs_ingest_can_stream(const rs_config *cfg);
/* The ingest from the files' chunks into cloud.ply at path (same bytes and report as the
 * whole-cloud path). */
int rs_ingest_stream(const rs_config *cfg, rs_report *rep, const char *path, rs_err *err);

/* The hash both paths find coincident points by. */
uint64_t rs_ingest_point_hash(const double *p);

/* The unorganized points must carry a surface: the whole-cloud path's refusals, for npoints
 * unorganized points of which distinct are distinct, collinear when they lie on a line. */
int rs_ingest_surface_check(const rs_config *cfg, size_t npoints, size_t distinct, int collinear, rs_err *err);

#endif
