/* paper: the seed paper's dense interreflection kernel, as written (Zhao et al., Eq. 9, with
 * the emitting facet's area S_j): K_ij = cos_i cos_j V_ij S_j / r^2 between facet centroids,
 * V_ij by testing the segment between the centroids against every other facet. O(m^2) memory,
 * O(m^3) time, no acceleration structure: the baseline the gather is measured against. */
#ifndef RS_PAPER_H
#define RS_PAPER_H

#include <stddef.h>
#include "common/err.h"
#include "common/mesh.h"

/* K: m * m floats, row-major, caller frees. pairs_tested: segment tests run. */
int rs_paper_kernel(const rs_mesh *mesh, float **K, double *pairs_tested, rs_err *err);

#endif
