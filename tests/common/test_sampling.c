/* Tests of the sample sequences and maps. */
#include <math.h>
#include "common/sampling.h"
#include "tests/testutil.h"

/* Owen-scrambled Sobol is a (0,2)-sequence: the first 2^k points put exactly one point in
 * each of the 2^k intervals of every elementary shape (here columns, rows and squares). */
static void test_sobol_stratified(void **state)
{
    (void)state;
    for (uint32_t seed = 1; seed < 50; seed++) {
        int cols[16] = {0}, rows[16] = {0}, squares[16] = {0};
        for (uint32_t i = 0; i < 16; i++) {
            double x, y;
            rs_sobol2_owen(i, seed, &x, &y);
            assert_true(x >= 0 && x < 1 && y >= 0 && y < 1);
            cols[(int)(x * 16)]++;
            rows[(int)(y * 16)]++;
            squares[(int)(x * 4) * 4 + (int)(y * 4)]++;
        }
        for (int k = 0; k < 16; k++) {
            assert_int_equal(cols[k], 1);
            assert_int_equal(rows[k], 1);
            assert_int_equal(squares[k], 1);
        }
    }
}

static void test_sobol_seeds_differ(void **state)
{
    (void)state;
    double x1, y1, x2, y2;
    rs_sobol2_owen(5, 1, &x1, &y1);
    rs_sobol2_owen(5, 2, &x2, &y2);
    assert_true(x1 != x2 || y1 != y2);
}

/* Cosine-weighted directions: unit, in the hemisphere, E[cos] = 2/3. */
static void test_cosine_hemisphere(void **state)
{
    (void)state;
    rs_v3 n = rs_v3_norm(rs_v3_make(0.3, -0.5, 0.8));
    double sum = 0;
    int N = 4096;
    for (int i = 0; i < N; i++) {
        double x, y;
        rs_sobol2_owen((uint32_t)i, 7, &x, &y);
        rs_v3 d = rs_cosine_hemisphere(n, x, y);
        assert_true(fabs(rs_v3_len(d) - 1) < 1e-9);
        double c = rs_v3_dot(d, n);
        assert_true(c >= -1e-12);
        sum += c;
    }
    assert_true(fabs(sum / N - 2.0 / 3.0) < 1e-3);
}

static void test_triangle_points(void **state)
{
    (void)state;
    rs_v3 a = {0, 0, 0}, b = {2, 0, 0}, c = {0, 1, 0};
    rs_v3 mean = {0, 0, 0};
    int N = 1024;
    for (int i = 0; i < N; i++) {
        double x, y;
        rs_sobol2_owen((uint32_t)i, 9, &x, &y);
        rs_v3 p = rs_triangle_point(a, b, c, x, y);
        assert_true(p.x >= -1e-12 && p.y >= -1e-12 && p.x / 2 + p.y <= 1 + 1e-12);
        mean = rs_v3_add(mean, rs_v3_scale(p, 1.0 / N));
    }
    assert_true(fabs(mean.x - 2.0 / 3) < 2e-3 && fabs(mean.y - 1.0 / 3) < 2e-3);
}

/* The inline Sobol points (five shift-and-mask steps for dimension 1) are the values of the
 * textbook construction: nested uniform scrambles around the direction-number loop. */
static uint32_t ref_reverse(uint32_t x)
{
    uint32_t r = 0;
    for (int b = 0; b < 32; b++) r |= ((x >> b) & 1u) << (31 - b);
    return r;
}

static uint32_t ref_scramble(uint32_t x, uint32_t seed)
{
    return ref_reverse(rs_lk_permutation(ref_reverse(x), seed));
}

static void test_sobol_reference(void **state)
{
    (void)state;
    for (uint32_t s = 0; s < 2000; s++) {
        uint32_t seed = rs_hash_u32(s * 7919u + 1);
        for (uint32_t i = 0; i < 300; i++) {
            uint32_t k = i < 256 ? i : rs_hash_u32(i + s);
            uint32_t idx = ref_scramble(k, seed), v = 1u << 31, d1 = 0;
            for (uint32_t j = idx; j; j >>= 1, v ^= v >> 1)
                if (j & 1) d1 ^= v;
            double x, y;
            rs_sobol2_owen(k, seed, &x, &y);
            assert_true(x == ref_scramble(ref_reverse(idx), rs_hash_combine(seed, 0)) * (1.0 / 4294967296.0));
            assert_true(y == ref_scramble(d1, rs_hash_combine(seed, 1)) * (1.0 / 4294967296.0));
        }
    }
}

/* rs_sincos_pi against libm over [-1, 1], quadrant edges included. */
static void test_sincos_pi(void **state)
{
    (void)state;
    for (int i = -400000; i <= 400000; i++) {
        double w = i / 400000.0, s, c;
        rs_sincos_pi(w, &s, &c);
        assert_true(fabs(s - sin(M_PI * w)) < 1e-15 && fabs(c - cos(M_PI * w)) < 1e-15);
    }
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_sobol_stratified), cmocka_unit_test(test_sobol_seeds_differ),
             cmocka_unit_test(test_cosine_hemisphere), cmocka_unit_test(test_triangle_points),
             cmocka_unit_test(test_sobol_reference), cmocka_unit_test(test_sincos_pi))
