/* Tests of common/par.h as a single process (the default build, or a program not started by
 * mpirun): one rank, the work queue deals every item once to whichever thread asks, and the
 * exchanges leave the data as it is. In an MPI build the ctest mpi_test_par runs this program
 * under mpirun -np 3 too: the single-process tests skip there, the row exchanges' tests
 * (which hold for any number of ranks) check what each rank ends with. The stages' runs on
 * ranks are tested by tests/mpi. */
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
    if (rs_par_world_size() > 1) skip(); /* under mpirun: the row tests below */
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
    if (rs_par_world_size() > 1) skip(); /* each rank sees only the blocks it took */
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
    if (rs_par_world_size() > 1) skip();
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

enum { ROWS = 7, COLS = 3 };

/* Row r, column c of the test image: what the rank whose band holds r writes there. */
static int cell(int r, int c)
{
    return 100 * r + c;
}

/* Each rank fills its band of rows (rs_par_range) and marks every other row -1: what a stage
 * that splits an image by rows holds before the exchange. */
static size_t fill_my_rows(int img[ROWS][COLS])
{
    size_t lo, hi;
    rs_par_range(ROWS, &lo, &hi);
    for (int r = 0; r < ROWS; r++)
        for (int c = 0; c < COLS; c++) img[r][c] = (size_t)r >= lo && (size_t)r < hi ? cell(r, c) : -1;
    return hi - lo;
}

/* To rank 0: every row there, in place; the other ranks keep what they had. 7 rows over 1 to 3
 * ranks leaves the bands uneven (3, 2, 2). */
static void test_gather_range_rows_to_root(void **state)
{
    (void)state;
    rs_err err;
    rs_err_clear(&err);
    assert_int_equal(rs_par_init(&err), 0);
    int img[ROWS][COLS];
    size_t mine = fill_my_rows(img);
    int before[ROWS][COLS];
    memcpy(before, img, sizeof img);
    assert_int_equal(rs_par_gather_range(img, ROWS, sizeof img[0], &err), 0);
    for (int r = 0; r < ROWS; r++)
        for (int c = 0; c < COLS; c++) assert_int_equal(img[r][c], rs_par_is_root() ? cell(r, c) : before[r][c]);
    assert_true(mine > 0 || rs_par_size() > ROWS);
    /* The same bands to every rank. */
    fill_my_rows(img);
    assert_int_equal(rs_par_allgather_range(img, ROWS, sizeof img[0], &err), 0);
    for (int r = 0; r < ROWS; r++)
        for (int c = 0; c < COLS; c++) assert_int_equal(img[r][c], cell(r, c));
}

/* A deliberately wrong split: a rank that exchanges rows it did not fill hands on its -1s,
 * which the gathered image shows (what the check above would catch in a stage). */
static void test_gather_range_shows_a_skipped_band(void **state)
{
    (void)state;
    rs_err err;
    rs_err_clear(&err);
    int img[ROWS][COLS];
    for (int r = 0; r < ROWS; r++)
        for (int c = 0; c < COLS; c++) img[r][c] = -1; /* this rank skipped its rows */
    if (rs_par_size() > 1 && !rs_par_is_root()) fill_my_rows(img);
    assert_int_equal(rs_par_gather_range(img, ROWS, sizeof img[0], &err), 0);
    if (!rs_par_is_root()) return;
    size_t lo, hi;
    rs_par_range(ROWS, &lo, &hi); /* rank 0's own band: still -1, the others' filled */
    for (int r = 0; r < ROWS; r++) assert_int_equal(img[r][0], (size_t)r < hi ? -1 : cell(r, 0));
}

/* The rows counter the stages' mpi record reports: what each rank adds, nothing else. */
static void test_rows_counter_adds(void **state)
{
    (void)state;
    size_t t0 = rs_par_rows_total();
    rs_par_rows_done(5);
    rs_par_rows_done(0);
    rs_par_rows_done(2);
    assert_int_equal(rs_par_rows_total() - t0, 7);
}

static int count_call(void *ctx, rs_err *err)
{
    int *calls = ctx;
    (*calls)++;
    return *calls > 1 ? rs_err_set(err, RS_ERR_INPUT, "x.ply", 3, "second call") : 0;
}

/* Rank 0 alone runs the step (once), every rank learns its failure, and rank 0's bytes reach
 * every rank (any number of ranks). */
static void test_root_run_and_bcast(void **state)
{
    (void)state;
    rs_err err;
    rs_err_clear(&err);
    int calls = 0;
    assert_int_equal(rs_par_root_run(count_call, &calls, &err), 0);
    assert_int_equal(calls, rs_par_is_root() ? 1 : 0);
    assert_int_equal(rs_par_root_run(count_call, &calls, &err), -1);
    assert_int_equal(err.kind, rs_par_is_root() ? RS_ERR_INPUT : RS_ERR_SYSTEM);
    char text[] = "occluders";
    void *buf = rs_par_is_root() ? text : NULL;
    size_t n = rs_par_is_root() ? sizeof text : 0;
    assert_int_equal(rs_par_bcast_alloc(&buf, &n, &err), 0);
    assert_int_equal(n, sizeof text);
    assert_memory_equal(buf, "occluders", sizeof text);
    if (rs_par_is_root())
        assert_ptr_equal(buf, text);
    else
        free(buf);
}

/* Rank 0's solo sections take the thread count given, and give the rank's own back after. */
static void test_solo_threads(void **state)
{
    (void)state;
#ifdef _OPENMP
    omp_set_num_threads(1);
    int want = rs_par_world_rank() == 0 ? 3 : 1; /* the other ranks keep theirs */
    rs_par_set_solo_threads(3);
    rs_par_solo_begin();
    assert_int_equal(omp_get_max_threads(), want);
    rs_par_solo_begin(); /* nested: the outermost decides */
    assert_int_equal(omp_get_max_threads(), want);
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
             cmocka_unit_test(test_exchanges_keep_data), cmocka_unit_test(test_gather_range_rows_to_root),
             cmocka_unit_test(test_gather_range_shows_a_skipped_band), cmocka_unit_test(test_rows_counter_adds),
             cmocka_unit_test(test_root_run_and_bcast), cmocka_unit_test(test_solo_threads))
