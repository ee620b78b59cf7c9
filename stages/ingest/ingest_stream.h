/* ingest_stream: the ingest stage's streaming path (ingest_stream.c) and what it shares with the
 * whole-cloud path (ingest.c). Internal to stages/ingest. */
#ifndef RS_INGEST_STREAM_H
#define RS_INGEST_STREAM_H

#include <stddef.h>
#include <stdint.h>

#include "common/cloud.h"
#include "common/config.h"
#include "common/err.h"
#include "pipeline/stage.h"

/* Across a line, unorganized points spread less than this share of their length have no surface. */
#define RS_INGEST_MIN_SPREAD 1e-5

typedef struct rs_las rs_las;
typedef struct rs_e57 rs_e57;

/* The streaming path's reader over every [ingest] scan file (ingest_stream.c). */
typedef struct file_info {
    int las;              /* 1 LAS, 0 E57 */
    int wide;             /* LAS: 16-bit colour (some value above 255), the high byte kept */
    size_t records, kept; /* points in the file, points kept (valid, class kept, not withheld) */
    uint64_t withheld;    /* LAS: withheld points dropped */
    int has_int, has_rgb, has_nrm, has_viewpoint;
    double viewpoint[3];
} file_info;

typedef struct source {
    const rs_config *cfg;
    int nfiles, file, scan;
    char path[4096];
    file_info *info;
    const uint8_t *keep; /* LAS classes kept, NULL: all */
    int keep_withheld;
    rs_las *las;
    rs_e57 *e57;
    /* the current chunk of kept points, the cloud's attributes (zeros where a file has none) */
    size_t n, cap, raw_n; /* kept points in the chunk, room, records the chunk consumed */
    int survey;           /* pass 1: a LAS colour value above 255 marks the file's colour 16-bit */
    int xyz_only;         /* the checking passes: only the coordinates are needed */
    double *xyz;
    float *in, *nrm;
    uint8_t *rgb;
    int has_int, has_rgb, has_nrm;
    double shift[3];    /* subtracted from every coordinate (recentring) */
    uint64_t hist[256]; /* LAS classes of the current file (pass 1) */
} source;

typedef struct coincident {
    uint8_t *dropped; /* one bit per point kept, in stream order */
    size_t total, distinct;
} coincident;

/* The next chunk of kept points of any file into s (1; s->n may be 0), 0 after the last file,
 * -1 on error; rewind starts again at the first file's first point. */
int rs_ingest_source_next(source *s, rs_err *err);
void rs_ingest_source_rewind(source *s);

/* cloud.ply at path from the stream, the points co marks dropped skipped (count are left). */
int rs_ingest_write_points(source *s, const coincident *co, const rs_cloud *shape, size_t count, const char *path,
                           rs_err *err);

/* Outlier removal and voxel grid on the streamed points, in tiles (ingest_tiles.c), then
 * cloud.ply at path: the whole-cloud path's result (docs/FORMATS.md, The ingest's streaming
 * path). lo, hi: the box of the points (recentred). s is rewound as needed; co's bitmap gets
 * the outliers too. */
int rs_ingest_clean_stream(const rs_config *cfg, source *s, rs_report *rep, coincident *co, rs_cloud *shape,
                           const double lo[3], const double hi[3], const char *path, rs_err *err);

/* 1 when [ingest] streaming is on and every scan file is LAS (not LAZ) or an E57 whose scans
 * have no grid. */
int rs_ingest_can_stream(const rs_config *cfg);
/* 1 when outlier removal or the voxel grid is on. */
int rs_ingest_cleans(const rs_config *cfg);
/* The ingest from the files' chunks into cloud.ply at path (same bytes and report as the
 * whole-cloud path). */
int rs_ingest_stream(const rs_config *cfg, rs_report *rep, const char *path, rs_err *err);

/* The hash both paths find coincident points by. */
uint64_t rs_ingest_point_hash(const double *p);

/* The unorganized points must carry a surface: the whole-cloud path's refusals, for npoints
 * unorganized points of which distinct are distinct, collinear when they lie on a line. */
int rs_ingest_surface_check(const rs_config *cfg, size_t npoints, size_t distinct, int collinear, rs_err *err);

#endif
