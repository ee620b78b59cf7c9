/* sampling: deterministic sample sequences. Owen-scrambled Sobol points (Burley 2020,
 * "Practical Hash-based Owen Scrambling"): low discrepancy in 2D, independent between seeds,
 * so that every facet gets its own well-stratified set whatever the thread count. */
#ifndef RS_SAMPLING_H
#define RS_SAMPLING_H

#include <stdint.h>
#include "common/vec.h"

/* The hashes and the Sobol points are inline: a gather calls them for every ray with seeds
 * that are the same for a whole facet, which the compiler then computes once. */
static inline uint32_t rs_hash_u32(uint32_t x)
{
    /* lowbias32 (Chris Wellons' hash-prospector): cheap, good avalanche. */
    x ^= x >> 16;
    x *= 0x7feb352dU;
    x ^= x >> 15;
    x *= 0x846ca68bU;
    x ^= x >> 16;
    return x;
}

static inline uint32_t rs_hash_combine(uint32_t seed, uint32_t v)
{
    return seed ^ (rs_hash_u32(v) + 0x9e3779b9U + (seed << 6) + (seed >> 2));
}

static inline uint32_t rs_reverse_bits(uint32_t x)
{
    x = ((x >> 1) & 0x55555555U) | ((x & 0x55555555U) << 1);
    x = ((x >> 2) & 0x33333333U) | ((x & 0x33333333U) << 2);
    x = ((x >> 4) & 0x0F0F0F0FU) | ((x & 0x0F0F0F0FU) << 4);
    x = ((x >> 8) & 0x00FF00FFU) | ((x & 0x00FF00FFU) << 8);
    return (x >> 16) | (x << 16);
}

/* Laine-Karras style hash permutation; applied to bit-reversed values it is an Owen scramble. */
static inline uint32_t rs_lk_permutation(uint32_t x, uint32_t seed)
{
    x += seed;
    x ^= x * 0x6c50b47cU;
    x ^= x * 0xb82f1e52U;
    x ^= x * 0xc7afe638U;
    x ^= x * 0x8d22f6e6U;
    return x;
}

/* Sobol dimension 1 (dimension 0 is the bit-reversed index), bit-reversed. Its direction
 * numbers are Pascal's triangle mod 2: output bit j (from the top) is the XOR of the index bits
 * k with C(k, j) odd, i.e. (Lucas) of the k whose bits include j's. That superset sum takes five
 * shift-and-mask steps; the bit loop it replaces ran over all 32 bits of a scrambled index with
 * a branch each (15 % of the irradiance stage). */
static inline uint32_t rs_sobol_dim1_reversed(uint32_t i)
{
    i ^= (i >> 1) & 0x55555555U;
    i ^= (i >> 2) & 0x33333333U;
    i ^= (i >> 4) & 0x0F0F0F0FU;
    i ^= (i >> 8) & 0x00FF00FFU;
    i ^= (i >> 16) & 0x0000FFFFU;
    return i;
}

/* Point i of a 2D Owen-scrambled Sobol sequence with the given seed, in [0, 1)^2.
 * The first 2^k points of any seed are stratified in every elementary interval.
 * (Nested uniform scramble of v: reverse(lk(reverse(v))); the reversals that cancel are left out.) */
static inline void rs_sobol2_owen(uint32_t i, uint32_t seed, double *x, double *y)
{
    uint32_t idx = rs_reverse_bits(rs_lk_permutation(rs_reverse_bits(i), seed));
    uint32_t sx = rs_reverse_bits(rs_lk_permutation(idx, rs_hash_combine(seed, 0)));
    uint32_t sy = rs_reverse_bits(rs_lk_permutation(rs_sobol_dim1_reversed(idx), rs_hash_combine(seed, 1)));
    *x = sx * (1.0 / 4294967296.0);
    *y = sy * (1.0 / 4294967296.0);
}

/* Cosine-weighted direction on the hemisphere around unit n from (x, y) in [0,1)^2
 * (concentric disc mapping, Shirley & Chiu 1997, keeps the stratification). pdf = cos / pi. */
rs_v3 rs_cosine_hemisphere(rs_v3 n, double x, double y);

/* Uniform point on triangle (a, b, c) from (x, y) in [0,1)^2 (Heitz 2019 low-distortion map,
 * which keeps low-discrepancy points well spread). */
rs_v3 rs_triangle_point(rs_v3 a, rs_v3 b, rs_v3 c, double x, double y);

#endif
