/* par: the ranks of an MPI run (see par.h). The one file that includes mpi.h: compiled with
 * RHOSCAN_MPI (cmake -DRHOSCAN_MPI=ON) it talks to MPI, without it every team has one rank. */
#include "common/par.h"

#include <limits.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#ifdef RHOSCAN_MPI
#include <mpi.h>
#endif

static int world_rank, world_size = 1, local_size = 1, solo_depth;
static int solo_threads, saved_threads; /* rs_par_set_solo_threads; the rank's own count meanwhile */
static rs_par_traffic traffic;

/* The rank count a launcher gave this process in its environment (Open MPI's mpirun, PMIx as
 * Slurm's srun --mpi=pmix sets it, MPICH's PMI), 0 when none did. */
static long launcher_size(void)
{
    static const char *const vars[] = {"OMPI_COMM_WORLD_SIZE", "PMIX_SIZE", "PMI_SIZE", NULL};
    for (int k = 0; vars[k]; k++) {
        const char *v = getenv(vars[k]);
        if (v && atol(v) > 0) return atol(v);
    }
    return getenv("PMIX_RANK") ? 2 : 0; /* PMIx names the rank but not always the size */
}

static void count_traffic(double bytes, double messages)
{
#pragma omp atomic
    traffic.bytes += bytes;
#pragma omp atomic
    traffic.messages += messages;
}

rs_par_traffic rs_par_traffic_now(void)
{
    return traffic;
}

#ifdef RHOSCAN_MPI
/* Waits for req without spinning on a core (every collective here is started non-blocking and
 * waited for so): the ranks other than 0 wait through every stage that rank 0 runs alone, and
 * a blocking MPI call polls (Open MPI's mpi_yield_when_idle only
 * yields the core, it still burns it when nothing else runs). Sleeps from 50 us up to 10 ms
 * between tests: at most 10 ms late at the end of a long wait. */
static void wait_gently(MPI_Request *req)
{
    long ns = 50000;
    for (;;) {
        int done = 0;
        MPI_Test(req, &done, MPI_STATUS_IGNORE);
        if (done) return;
        struct timespec ts = {0, ns};
        nanosleep(&ts, NULL);
        if (ns < 10000000) ns *= 2;
    }
}

static void gentle_barrier(void)
{
    MPI_Request req;
    MPI_Ibarrier(MPI_COMM_WORLD, &req);
    wait_gently(&req);
}

static void finalize_at_exit(void)
{
    int done = 0;
    MPI_Finalized(&done);
    if (done) return;
    gentle_barrier(); /* rank 0 may still be writing the run's metrics and report */
    MPI_Finalize();
}
#endif

int rs_par_init(rs_err *err)
{
    long launched = launcher_size();
#ifdef RHOSCAN_MPI
    int started = 0;
    MPI_Initialized(&started);
    if (started || launched == 0) return 0;
    int provided = 0;
    if (MPI_Init_thread(NULL, NULL, MPI_THREAD_SERIALIZED, &provided) != MPI_SUCCESS)
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "MPI did not start (MPI_Init_thread)");
    atexit(finalize_at_exit);
    MPI_Comm_rank(MPI_COMM_WORLD, &world_rank);
    MPI_Comm_size(MPI_COMM_WORLD, &world_size);
    MPI_Comm host;
    MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &host);
    MPI_Comm_size(host, &local_size);
    MPI_Comm_free(&host);
    /* The work queue is advanced from whichever OpenMP thread runs dry, one at a time. */
    if (provided < MPI_THREAD_SERIALIZED && world_size > 1)
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0,
                          "MPI provides thread level %d: expected MPI_THREAD_SERIALIZED or better", provided);
    return 0;
#else
    if (launched > 1)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                          "started as one of %ld MPI ranks, but this rhoscan was built without MPI: every rank would "
                          "do the whole work and write the same files (build with cmake -DRHOSCAN_MPI=ON, or run "
                          "without mpirun)",
                          launched);
    return 0;
#endif
}

int rs_par_built_with_mpi(void)
{
#ifdef RHOSCAN_MPI
    return 1;
#else
    return 0;
#endif
}

int rs_par_rank(void)
{
    return solo_depth ? 0 : world_rank;
}

int rs_par_size(void)
{
    return solo_depth ? 1 : world_size;
}

int rs_par_is_root(void)
{
    return rs_par_rank() == 0;
}

int rs_par_world_rank(void)
{
    return world_rank;
}

int rs_par_world_size(void)
{
    return world_size;
}

int rs_par_local_size(void)
{
    return local_size;
}

void rs_par_set_solo_threads(int threads)
{
    solo_threads = threads > 0 ? threads : 0;
}

void rs_par_solo_begin(void)
{
#ifdef _OPENMP
    if (solo_depth == 0 && world_rank == 0 && solo_threads > 0) {
        saved_threads = omp_get_max_threads();
        omp_set_num_threads(solo_threads);
    }
#endif
    solo_depth++;
}

void rs_par_solo_end(void)
{
    if (solo_depth > 0) solo_depth--;
#ifdef _OPENMP
    if (solo_depth == 0 && world_rank == 0 && solo_threads > 0 && saved_threads > 0) {
        omp_set_num_threads(saved_threads);
        saved_threads = 0;
    }
#endif
}

int rs_par_root_run(int (*fn)(void *ctx, rs_err *err), void *ctx, rs_err *err)
{
    int rc = 0;
    if (rs_par_is_root()) {
        rs_par_solo_begin();
        rc = fn(ctx, err);
        rs_par_solo_end();
    }
    if (rs_par_any(rc != 0) && rc == 0)
        rc = rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "a step failed on MPI rank 0 (rank 0 says why)");
    return rc;
}

int rs_par_bcast_alloc(void **buf, size_t *n, rs_err *err)
{
    if (rs_par_size() <= 1) return 0;
    uint64_t len = *n;
    rs_par_bcast(&len, sizeof len);
    int failed = 0;
    if (!rs_par_is_root()) {
        *n = (size_t)len;
        failed = !(*buf = malloc(len ? (size_t)len : 1));
    }
    if (rs_par_any(failed)) {
        if (!rs_par_is_root()) free(*buf), *buf = NULL;
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %llu bytes from MPI rank 0",
                          (unsigned long long)len);
    }
    rs_par_bcast(*buf, (size_t)len);
    return 0;
}

int rs_par_any(int flag)
{
    flag = flag != 0;
#ifdef RHOSCAN_MPI
    if (rs_par_size() > 1) {
        MPI_Request req;
        MPI_Iallreduce(MPI_IN_PLACE, &flag, 1, MPI_INT, MPI_LOR, MPI_COMM_WORLD, &req);
        wait_gently(&req);
        count_traffic(2.0 * sizeof flag * (world_size - 1), world_size - 1);
    }
#endif
    return flag;
}

double rs_par_max(double v)
{
#ifdef RHOSCAN_MPI
    if (rs_par_size() > 1) {
        MPI_Request req;
        MPI_Iallreduce(MPI_IN_PLACE, &v, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD, &req);
        wait_gently(&req);
        count_traffic(2.0 * sizeof v * (world_size - 1), world_size - 1);
    }
#endif
    return v;
}

/* MPI counts are ints: long buffers go in pieces of at most 1 GiB. */
#define RS_PAR_PIECE ((size_t)1 << 30)

#ifdef RHOSCAN_MPI
static void bcast_from(void *buf, size_t n, int root)
{
    for (size_t at = 0; at < n; at += RS_PAR_PIECE) {
        size_t piece = n - at < RS_PAR_PIECE ? n - at : RS_PAR_PIECE;
        MPI_Request req;
        MPI_Ibcast((unsigned char *)buf + at, (int)piece, MPI_BYTE, root, MPI_COMM_WORLD, &req);
        wait_gently(&req);
    }
}
#endif

void rs_par_bcast(void *buf, size_t n)
{
#ifdef RHOSCAN_MPI
    if (rs_par_size() > 1) {
        bcast_from(buf, n, 0);
        count_traffic((double)n * (world_rank == 0 ? world_size - 1 : 1), world_rank == 0 ? world_size - 1 : 1);
    }
#else
    (void)buf;
    (void)n;
#endif
}

void rs_par_range(size_t n, size_t *lo, size_t *hi)
{
    size_t size = (size_t)rs_par_size(), rank = (size_t)rs_par_rank();
    *lo = n / size * rank + (rank < n % size ? rank : n % size);
    *hi = *lo + n / size + (rank < n % size);
}

#ifdef RHOSCAN_MPI
/* Each rank's share of n items as rs_par_range deals them, as MPI counts and displacements
 * (counts[0..size), displs after them; malloc'd, caller frees). NULL when out of memory. */
static int *range_counts(size_t n, int size)
{
    int *counts = malloc(2 * (size_t)size * sizeof *counts);
    if (!counts) return NULL;
    int *displs = counts + size;
    for (int r = 0; r < size; r++) {
        size_t part = n / (size_t)size, extra = n % (size_t)size;
        displs[r] = (int)(part * (size_t)r + ((size_t)r < extra ? (size_t)r : extra));
        counts[r] = (int)(part + ((size_t)r < extra));
    }
    return counts;
}
#endif

int rs_par_gather_range(void *v, size_t n, size_t item_bytes, rs_err *err)
{
#ifdef RHOSCAN_MPI
    int size = rs_par_size();
    if (size <= 1) return 0;
    if (n > INT_MAX || item_bytes > INT_MAX)
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "%zu items of %zu bytes: too many for one MPI exchange", n,
                          item_bytes);
    int *counts = range_counts(n, size);
    if (!counts) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    int *displs = counts + size;
    MPI_Datatype item;
    MPI_Type_contiguous((int)item_bytes, MPI_BYTE, &item);
    MPI_Type_commit(&item);
    MPI_Request req;
    if (world_rank == 0)
        MPI_Igatherv(MPI_IN_PLACE, 0, MPI_DATATYPE_NULL, v, counts, displs, item, 0, MPI_COMM_WORLD, &req);
    else
        MPI_Igatherv((unsigned char *)v + (size_t)displs[world_rank] * item_bytes, counts[world_rank], item, NULL,
                     NULL, NULL, item, 0, MPI_COMM_WORLD, &req);
    wait_gently(&req);
    MPI_Type_free(&item);
    double mine = (double)counts[world_rank] * (double)item_bytes;
    if (world_rank == 0)
        count_traffic((double)(n * item_bytes) - mine, size - 1);
    else
        count_traffic(mine, 1);
    free(counts);
#else
    (void)v;
    (void)n;
    (void)item_bytes;
    (void)err;
#endif
    return 0;
}

static size_t rows_done;

void rs_par_rows_done(size_t rows)
{
    rows_done += rows;
}

size_t rs_par_rows_total(void)
{
    return rows_done;
}

int rs_par_allgather_range(void *v, size_t n, size_t item_bytes, rs_err *err)
{
#ifdef RHOSCAN_MPI
    int size = rs_par_size();
    if (size <= 1) return 0;
    if (n > INT_MAX || item_bytes > INT_MAX)
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "%zu items of %zu bytes: too many for one MPI exchange", n,
                          item_bytes);
    int *counts = range_counts(n, size);
    if (!counts) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    int *displs = counts + size;
    MPI_Datatype item;
    MPI_Type_contiguous((int)item_bytes, MPI_BYTE, &item);
    MPI_Type_commit(&item);
    MPI_Request req;
    MPI_Iallgatherv(MPI_IN_PLACE, 0, MPI_DATATYPE_NULL, v, counts, displs, item, MPI_COMM_WORLD, &req);
    wait_gently(&req);
    MPI_Type_free(&item);
    double mine = (double)counts[world_rank] * (double)item_bytes;
    count_traffic((double)(n * item_bytes) - mine + mine * (size - 1), 2.0 * (size - 1));
    free(counts);
#else
    (void)v;
    (void)n;
    (void)item_bytes;
    (void)err;
#endif
    return 0;
}

int rs_par_allgather_bytes(const void *mine, size_t n, unsigned char **all, size_t *total, size_t *starts, rs_err *err)
{
    int size = rs_par_size();
    uint64_t *len = malloc((size_t)size * sizeof *len);
    if (!len) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    len[0] = n;
#ifdef RHOSCAN_MPI
    if (size > 1) {
        uint64_t me = n;
        MPI_Request req;
        MPI_Iallgather(&me, 1, MPI_UINT64_T, len, 1, MPI_UINT64_T, MPI_COMM_WORLD, &req);
        wait_gently(&req);
    }
#endif
    size_t sum = 0;
    for (int r = 0; r < size; r++) {
        if (starts) starts[r] = sum;
        sum += (size_t)len[r];
    }
    if (starts) starts[size] = sum;
    *total = sum;
    *all = malloc(sum ? sum : 1);
    /* Every rank fails here alike or not at all only if memory is alike: say so to all. */
    int failed = rs_par_any(!*all);
    if (failed) {
        free(len);
        free(*all);
        *all = NULL;
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu bytes of results from the ranks", sum);
    }
    size_t at = 0;
    for (int r = 0; r < size; r++) {
        if (r == rs_par_rank() && len[r]) memcpy(*all + at, mine, (size_t)len[r]);
#ifdef RHOSCAN_MPI
        /* One broadcast per rank, in pieces: no int count overflows however large a part is. */
        if (size > 1) bcast_from(*all + at, (size_t)len[r], r);
#endif
        at += (size_t)len[r];
    }
    if (size > 1) count_traffic((double)(sum - n) + (double)n * (size - 1), 2.0 * (size - 1));
    free(len);
    return 0;
}

struct rs_par_queue {
    size_t n, block, next; /* next: the single-process counter */
#ifdef RHOSCAN_MPI
    int shared;  /* dealt through the window on rank 0 */
    MPI_Win win; /* one int64 on rank 0: the next block's first item */
#endif
};

rs_par_queue *rs_par_queue_new(size_t n, size_t block)
{
    rs_par_queue *q = calloc(1, sizeof *q);
    if (!q) return NULL;
    q->n = n;
    q->block = block ? block : 1;
#ifdef RHOSCAN_MPI
    if (rs_par_size() > 1) {
        int64_t *counter = NULL;
        gentle_barrier(); /* ranks arrive apart: none polls in the window's creation */
        MPI_Win_allocate(world_rank == 0 ? (MPI_Aint)sizeof *counter : 0, sizeof *counter, MPI_INFO_NULL,
                         MPI_COMM_WORLD, &counter, &q->win);
        if (world_rank == 0) {
            MPI_Win_lock(MPI_LOCK_EXCLUSIVE, 0, 0, q->win);
            *counter = 0;
            MPI_Win_unlock(0, q->win);
        }
        gentle_barrier(); /* nobody takes before the counter is 0 */
        MPI_Win_lock_all(MPI_MODE_NOCHECK, q->win);
        q->shared = 1;
    }
#endif
    return q;
}

int rs_par_queue_take(rs_par_queue *q, size_t *begin, size_t *end)
{
    size_t first;
#ifdef RHOSCAN_MPI
    if (q->shared) {
        int64_t add = (int64_t)q->block, old = 0;
#pragma omp critical(rs_par_mpi)
        {
            MPI_Fetch_and_op(&add, &old, MPI_INT64_T, 0, 0, MPI_SUM, q->win);
            MPI_Win_flush(0, q->win);
        }
        count_traffic(2.0 * sizeof old, 1);
        first = (size_t)old;
    } else
#endif
    {
#pragma omp atomic capture
        {
            first = q->next;
            q->next += q->block;
        }
    }
    if (first >= q->n) return 0;
    *begin = first;
    *end = q->n - first < q->block ? q->n : first + q->block;
    return 1;
}

void rs_par_queue_free(rs_par_queue *q)
{
    if (!q) return;
#ifdef RHOSCAN_MPI
    if (q->shared) {
        MPI_Win_unlock_all(q->win);
        gentle_barrier(); /* the other ranks may still gather their last blocks */
        MPI_Win_free(&q->win);
    }
#endif
    free(q);
}
