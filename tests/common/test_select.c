/* Tests of rs_select_kth and rs_select_kth_double: for every k, the value a full sort puts at index k, on random arrays,
 * arrays with many equal values, sorted and reversed ones, and a single element. */
#include <stdlib.h>
#include <string.h>
#include "common/select.h"
#include "tests/testutil.h"

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* For every k of vals[0..n): select returns what qsort puts at k. One per element type. */
#define DEFINE_CHECK_ALL_K(name, T, cmp, select)                                  \
    static void name(const T *vals, size_t n)                                     \
    {                                                                             \
        T *sorted = malloc(n * sizeof *sorted), *work = malloc(n * sizeof *work); \
        assert_non_null(sorted);                                                  \
        assert_non_null(work);                                                    \
        memcpy(sorted, vals, n * sizeof *sorted);                                 \
        qsort(sorted, n, sizeof *sorted, cmp);                                    \
        for (size_t k = 0; k < n; k++) {                                          \
            memcpy(work, vals, n * sizeof *work);                                 \
            assert_true(select(work, n, k) == sorted[k]);                         \
        }                                                                         \
        free(sorted);                                                             \
        free(work);                                                               \
    }

DEFINE_CHECK_ALL_K(check_all_k_float, float, cmp_float, rs_select_kth)
DEFINE_CHECK_ALL_K(check_all_k_double, double, cmp_double, rs_select_kth_double)

/* Both types on the same values; the doubles spread a little, so that some differ only past a
 * float's precision. */
static void check_all_k(const float *src, size_t n)
{
    double *vals = malloc(n * sizeof *vals);
    assert_non_null(vals);
    for (size_t k = 0; k < n; k++) vals[k] = src[k] + 1e-12 * (double)(k % 3);
    check_all_k_float(src, n);
    check_all_k_double(vals, n);
    free(vals);
}

static void test_select_matches_sort(void **state)
{
    (void)state;
    enum { N = 257 };
    float v[N];
    unsigned s = 12345;
    for (int trial = 0; trial < 20; trial++) {
        size_t n = 1 + (size_t)trial * 13 % N;
        for (size_t k = 0; k < n; k++) {
            s = s * 1103515245u + 12345u;
            /* trials alternate between spread values and a handful of repeated ones */
            v[k] = trial % 2 ? (float)((s >> 16) % 5) : (float)(s >> 8) / 16777216.0f;
        }
        check_all_k(v, n);
    }
    for (size_t k = 0; k < N; k++) v[k] = (float)k;
    check_all_k(v, N);
    for (size_t k = 0; k < N; k++) v[k] = (float)(N - k);
    check_all_k(v, N);
    for (size_t k = 0; k < N; k++) v[k] = 1.0f;
    check_all_k(v, N);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_select_matches_sort))
