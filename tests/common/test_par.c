/* Tests of common/par.h as a single process (the default build, or a program not started by
 * mpirun): one rank, the work queue deals every item once to whichever thread asks, and the
 * exchanges leave the data as it is. The ranks themselves are tested by tests/mpi. */
#include <stdlib.h>
#include <string.h>
#include "common/par.h"
#ifdef _OPENMP
#include <omp.h>
#endif
#include "tests/testutil.h"

static void test_single_rank(void **state)
{
    (void)state;
    rs_err err;
    rs_err_clear(&err);
    assert_int_equal(rs_par_init(&err), 0);
    assert_int_equal(rs_par_size(), 1);
    assert_int_equal(rs_par_rank(), 0);
    assert_true(rs_par_is_root());
    assert_int_equal(rs_par_any(0), 0);
    assert_int_equal(rs_par_any(7), 1);
    assert_true(rs_par_max(-2.5) == -2.5);
    size_t lo = 1, hi = 0;
    rs_par_range(10, &lo, &hi);
    assert_int_equal(lo, 0);
    assert_int_equal(hi, 10);
    rs_par_solo_begin();
    assert_int_equal(rs_par_size(), 1);
    rs_par_solo_end();
}

/* Blocks of 16 over 1000 items on every thread: each item once, the last block short. */
static void test_queue_deals_each_item_once(void **state)
{
    (void)state;
    enum { N = 1000, BLOCK = 16 };
    int seen[N];
    memset(seen, 0, sizeof seen);
    rs_par_queue *q = rs_par_queue_new(N, BLOCK);
    assert_non_null(q);
    int bad_block = 0;
#pragma omp parallel
    {
        size_t b, e;
        while (rs_par_queue_take(q, &b, &e)) {
            if (!(b < e && e <= N && (e - b == BLOCK || e == N) && b % BLOCK == 0)) {
#pragma omp atomic write
                bad_block = 1;
            }
            for (size_t k = b; k < e && k < N; k++) {
#pragma omp atomic
                seen[k]++;
            }
        }
    }
    size_t b, e;
    assert_int_equal(rs_par_queue_take(q, &b, &e), 0); /* empty stays empty */
    rs_par_queue_free(q);
    assert_int_equal(bad_block, 0);
    for (int k = 0; k < N; k++) assert_int_equal(seen[k], 1);
    rs_par_queue *none = rs_par_queue_new(0, BLOCK);
    assert_int_equal(rs_par_queue_take(none, &b, &e), 0);
    rs_par_queue_free(none);
}

static void test_exchanges_keep_data(void **state)
{
    (void)state;
    rs_err err;
    rs_err_clear(&err);
    double v[6] = {1, 2, 3, 4, 5, 6};
    assert_int_equal(rs_par_allgather_range(v, 2, 3 * sizeof *v, &err), 0);
    for (int k = 0; k < 6; k++) assert_true(v[k] == k + 1);
    const char mine[] = "facets";
    unsigned char *all = NULL;
    size_t total = 0, starts[2] = {9, 9};
    assert_int_equal(rs_par_allgather_bytes(mine, sizeof mine, &all, &total, starts, &err), 0);
    assert_int_equal(total, sizeof mine);
    assert_int_equal(starts[0], 0);
    assert_int_equal(starts[1], sizeof mine);
    assert_memory_equal(all, mine, sizeof mine);
    free(all);
}

static int count_call(void *ctx, rs_err *err)
{
    int *calls = ctx;
    (*calls)++;
    return *calls > 1 ? rs_err_set(err, RS_ERR_INPUT, "x.ply", 3, "second call") : 0;
}

/* Rank 0 alone runs the step (once), its failure is the caller's, and what it made stays. */
static void test_root_run_and_bcast(void **state)
{
    (void)state;
    rs_err err;
    rs_err_clear(&err);
    int calls = 0;
    assert_int_equal(rs_par_root_run(count_call, &calls, &err), 0);
    assert_int_equal(calls, 1);
    assert_int_equal(rs_par_root_run(count_call, &calls, &err), -1);
    assert_int_equal(err.kind, RS_ERR_INPUT);
    char text[] = "occluders";
    void *buf = text;
    size_t n = sizeof text;
    assert_int_equal(rs_par_bcast_alloc(&buf, &n, &err), 0);
    assert_ptr_equal(buf, text);
    assert_int_equal(n, sizeof text);
}

/* Rank 0's solo sections take the thread count given, and give the rank's own back after. */
static void test_solo_threads(void **state)
{
    (void)state;
#ifdef _OPENMP
    omp_set_num_threads(1);
    rs_par_set_solo_threads(3);
    rs_par_solo_begin();
    assert_int_equal(omp_get_max_threads(), 3);
    rs_par_solo_begin(); /* nested: the outermost decides */
    assert_int_equal(omp_get_max_threads(), 3);
    rs_par_solo_end();
    rs_par_solo_end();
    assert_int_equal(omp_get_max_threads(), 1);
    rs_par_set_solo_threads(0);
    rs_par_solo_begin();
    assert_int_equal(omp_get_max_threads(), 1);
    rs_par_solo_end();
#else
    skip();
#endif
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_single_rank), cmocka_unit_test(test_queue_deals_each_item_once),
             cmocka_unit_test(test_exchanges_keep_data), cmocka_unit_test(test_root_run_and_bcast),
             cmocka_unit_test(test_solo_threads))
