/* atlas: a UV atlas of a mesh for a per-texel texture (issue 22). Charts are connected facets
 * whose normals lie within max_angle of the chart's first facet (buildings are mostly planes);
 * each chart is projected orthographically onto the plane of that first facet, so a texel is
 * texel x texel metres everywhere (uniform within 1 / cos(max_angle) of the projection), and the
 * charts' rectangles are packed, with a gutter of empty texels around each, into square pages
 * of a power-of-two side of at most max_side. Pure geometry: no config, no file. */
#ifndef RS_ATLAS_H
#define RS_ATLAS_H

#include <stddef.h>
#include <stdint.h>
#include "common/err.h"
#include "common/mesh.h"

typedef struct rs_atlas_opts {
    double texel;         /* metres per texel (> 0); raised when needed (max_texels, max_side) */
    double max_angle_deg; /* normals within this of the chart's first facet join it (0: 10) */
    int gutter;           /* empty texels around each chart's content (0: 2) */
    int max_side;         /* largest page side, a power of two (0: 8192) */
    double max_texels;    /* the pages' texels (all of them) at most this many (0: no bound) */
} rs_atlas_opts;

/* A chart: its plane frame and its place in a page. A point p of the chart's plane has
 * s = (p - origin).eu, t = (p - origin).ev; page pixel coordinates (x right, y down, pixel c
 * covering [c, c + 1)) X = x0 + 0.5 + (s - smin) / texel, Y = y0 + 0.5 + (tmax - t) / texel. */
typedef struct rs_atlas_chart {
    rs_v3 origin, eu, ev, normal; /* right-handed: eu x ev = normal */
    double smin, tmax;            /* of the chart's corners */
    int page;
    int x0, y0;          /* first content texel (the gutter lies outside x0 .. x0 + w - 1) */
    int w, h;            /* content texels */
    size_t first, count; /* its faces: faces[first .. first + count) */
} rs_atlas_chart;

typedef struct rs_atlas {
    double texel; /* metres per texel, as used */
    int gutter;
    int npages;
    int side;           /* every page's side, texels */
    double rect_texels; /* the charts' rectangles with their gutters, texels (packing: / pages' texels) */
    size_t nfaces, ncharts;
    rs_atlas_chart *charts;
    uint32_t *face_chart; /* nfaces: the chart of each face */
    uint32_t *faces;      /* nfaces: faces grouped by chart, each chart's in face order */
    float *uv;            /* 6 per face: (u, v) of each corner, page coordinates / side, v down */
} rs_atlas;

/* Builds the atlas of m. -1 (NULL) with err: out of memory, a texel that is not positive, or a
 * mesh with no face. */
rs_atlas *rs_atlas_build(const rs_mesh *m, const rs_atlas_opts *o, rs_err *err);
void rs_atlas_free(rs_atlas *a);

/* Page pixel coordinates of world point p projected onto chart c. */
void rs_atlas_project(const rs_atlas *a, const rs_atlas_chart *c, rs_v3 p, double *X, double *Y);

#endif
