/* nadir: closing the hole a terrestrial scanner leaves below itself (below its lowest elevation,
 * where the tripod stands). A camera on a tripod beside it sees that ground, so a model without
 * it leaves the pixels there unexplained and the ground's light missing from every gather. */
#ifndef RS_NADIR_H
#define RS_NADIR_H

#include <stddef.h>
#include "common/cloud.h"
#include "common/mesh.h"

typedef struct rs_nadir_stats {
    size_t ring_points; /* lowest valid point of each column used as the cap's rim */
    double rms_m;       /* RMS distance of the rim from the fitted plane */
    size_t triangles;   /* triangles added */
    char why_not[160];  /* when nothing was added: the reason */
} rs_nadir_stats;

/* The cap for scan s of c: the plane fitted to the lowest ring of points, meshed from the ring
 * down to the point below the scanner along the scanner's own grid directions. Returns NULL
 * (with st->why_not set, err untouched) when there is no ring below the scanner or the ground
 * there is not flat within max_rms_m; NULL with err set when out of memory. */
rs_mesh *rs_nadir_cap(const rs_cloud *c, int s, double max_rms_m, rs_nadir_stats *st, rs_err *err);

/* The same on the lattice of a grid triangulated at stride (rs_grid_lattice: the rim is the
 * lowest valid point of each used column among the used rows, so that it welds), and, when
 * spacing_m > 0, meshed coarsely inside the rim: rings about spacing_m apart (never more than
 * the lattice's), every m-th column with m rim gaps about spacing_m. rs_nadir_cap is stride 1,
 * spacing 0 (the grid's own steps). */
rs_mesh *rs_nadir_cap_coarse(const rs_cloud *c, int s, double max_rms_m, int stride, double spacing_m,
                             rs_nadir_stats *st, rs_err *err);

/* a + b with b's vertices that equal one of a's (bit for bit) merged into it. Caller frees. */
rs_mesh *rs_mesh_merge_welded(const rs_mesh *a, const rs_mesh *b);

#endif
