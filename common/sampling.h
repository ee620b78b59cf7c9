/* sampling: deterministic sample sequences. Owen-scrambled Sobol points (Burley 2020,
 * "Practical Hash-based Owen Scrambling"): low discrepancy in 2D, independent between seeds,
 * so that every facet gets its own well-stratified set whatever the thread count. */
#ifndef RS_SAMPLING_H
#define RS_SAMPLING_H

#include <stdint.h>
#include "vec.h"

uint32_t rs_hash_u32(uint32_t x);
uint32_t rs_hash_combine(uint32_t seed, uint32_t v);

/* Point i of a 2D Owen-scrambled Sobol sequence with the given seed, in [0, 1)^2.
 * The first 2^k points of any seed are stratified in every elementary interval. */
void rs_sobol2_owen(uint32_t i, uint32_t seed, double *x, double *y);

/* Cosine-weighted direction on the hemisphere around unit n from (x, y) in [0,1)^2
 * (concentric disc mapping, Shirley & Chiu 1997, keeps the stratification). pdf = cos / pi. */
rs_v3 rs_cosine_hemisphere(rs_v3 n, double x, double y);

/* Uniform point on triangle (a, b, c) from (x, y) in [0,1)^2 (Heitz 2019 low-distortion map,
 * which keeps low-discrepancy points well spread). */
rs_v3 rs_triangle_point(rs_v3 a, rs_v3 b, rs_v3 c, double x, double y);

#endif
