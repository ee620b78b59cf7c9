/* sampling: Owen-scrambled Sobol points and the maps onto hemispheres and triangles. */
#include "sampling.h"

uint32_t rs_hash_u32(uint32_t x)
{
    /* lowbias32 (Chris Wellons' hash-prospector): cheap, good avalanche. */
    x ^= x >> 16;
    x *= 0x7feb352dU;
    x ^= x >> 15;
    x *= 0x846ca68bU;
    x ^= x >> 16;
    return x;
}

uint32_t rs_hash_combine(uint32_t seed, uint32_t v)
{
    return seed ^ (rs_hash_u32(v) + 0x9e3779b9U + (seed << 6) + (seed >> 2));
}

static uint32_t reverse_bits(uint32_t x)
{
    x = ((x >> 1) & 0x55555555U) | ((x & 0x55555555U) << 1);
    x = ((x >> 2) & 0x33333333U) | ((x & 0x33333333U) << 2);
    x = ((x >> 4) & 0x0F0F0F0FU) | ((x & 0x0F0F0F0FU) << 4);
    x = ((x >> 8) & 0x00FF00FFU) | ((x & 0x00FF00FFU) << 8);
    return (x >> 16) | (x << 16);
}

/* Laine-Karras style hash permutation; applied to bit-reversed values it is an Owen scramble. */
static uint32_t lk_permutation(uint32_t x, uint32_t seed)
{
    x += seed;
    x ^= x * 0x6c50b47cU;
    x ^= x * 0xb82f1e52U;
    x ^= x * 0xc7afe638U;
    x ^= x * 0x8d22f6e6U;
    return x;
}

static uint32_t nested_uniform_scramble(uint32_t x, uint32_t seed)
{
    return reverse_bits(lk_permutation(reverse_bits(x), seed));
}

/* Sobol dimension 1 (dimension 0 is the bit-reversed index). */
static uint32_t sobol_dim1(uint32_t i)
{
    uint32_t v = 1U << 31, r = 0;
    for (; i; i >>= 1, v ^= v >> 1)
        if (i & 1) r ^= v;
    return r;
}

void rs_sobol2_owen(uint32_t i, uint32_t seed, double *x, double *y)
{
    uint32_t idx = nested_uniform_scramble(i, seed);
    uint32_t sx = nested_uniform_scramble(reverse_bits(idx), rs_hash_combine(seed, 0));
    uint32_t sy = nested_uniform_scramble(sobol_dim1(idx), rs_hash_combine(seed, 1));
    *x = sx * (1.0 / 4294967296.0);
    *y = sy * (1.0 / 4294967296.0);
}

rs_v3 rs_cosine_hemisphere(rs_v3 n, double x, double y)
{
    double a = 2 * x - 1, b = 2 * y - 1, r, phi;
    if (a == 0 && b == 0) {
        r = 0;
        phi = 0;
    } else if (fabs(a) > fabs(b)) {
        r = a;
        phi = (M_PI / 4) * (b / a);
    } else {
        r = b;
        phi = M_PI / 2 - (M_PI / 4) * (a / b);
    }
    double dx = r * cos(phi), dy = r * sin(phi);
    double dz = sqrt(fmax(0.0, 1.0 - dx * dx - dy * dy));
    rs_v3 t, bt;
    rs_v3_basis(n, &t, &bt);
    return rs_v3_add(rs_v3_add(rs_v3_scale(t, dx), rs_v3_scale(bt, dy)), rs_v3_scale(n, dz));
}

rs_v3 rs_triangle_point(rs_v3 a, rs_v3 b, rs_v3 c, double x, double y)
{
    double b0, b1;
    if (y > x) {
        b0 = x / 2;
        b1 = y - b0;
    } else {
        b1 = y / 2;
        b0 = x - b1;
    }
    double b2 = 1 - b0 - b1;
    return rs_v3_make(b0 * a.x + b1 * b.x + b2 * c.x, b0 * a.y + b1 * b.y + b2 * c.y,
                      b0 * a.z + b1 * b.z + b2 * c.z);
}
