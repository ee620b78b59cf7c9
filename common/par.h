/* par: the ranks of a run spread over processes with MPI (rhoscan built with
 * cmake -DRHOSCAN_MPI=ON and started by mpirun or a scheduler's launcher). Every rank runs the
 * same program on the same inputs and holds the same state; the loops that cost split their
 * work over the ranks through this file and exchange the results, so that every rank ends a
 * collective step with the same bytes. Without MPI (the default build, or a program not started
 * by a launcher) this is a single process of one rank: every call is a no-op or a plain loop,
 * and no code outside common/par.c needs to know which.
 *
 * Collective calls (marked so) must be made by every rank of the current team, in the same
 * order. The team is every rank, or this rank alone between rs_par_solo_begin and _end (a
 * stage that runs on rank 0 only: its library calls then see a team of one). All calls but
 * rs_par_queue_take come from one thread, outside OpenMP parallel regions. */
#ifndef RS_PAR_H
#define RS_PAR_H

#include <stddef.h>
#include "common/err.h"

/* Starts MPI when a launcher started this process (its environment says so; a plain start of
 * the program never touches MPI). Safe to call more than once; MPI ends at exit. 0, or -1 with
 * err set when MPI would not start or lacks the thread support the work queue needs. */
int rs_par_init(rs_err *err);

/* 1 in a build with MPI (-DRHOSCAN_MPI=ON), else 0. */
int rs_par_built_with_mpi(void);

/* This rank and the team's size (0 and 1 without MPI, and inside a solo section). */
int rs_par_rank(void);
int rs_par_size(void);
int rs_par_is_root(void);
/* The whole run's rank and size, whatever the team; ranks on this host (for threads per rank). */
int rs_par_world_rank(void);
int rs_par_world_size(void);
int rs_par_local_size(void);

/* This rank alone until the matching end (nested pairs allowed). On world rank 0, when
 * rs_par_set_solo_threads gave a count, the outermost section runs with that many OpenMP
 * threads: the other ranks on the host sleep meanwhile, so their cores are free. */
void rs_par_solo_begin(void);
void rs_par_solo_end(void);
/* The thread count for rank 0's solo sections (0: keep the rank's own); set by the program
 * when it shares the host's cores out between its ranks itself. */
void rs_par_set_solo_threads(int threads);

/* Collective: fn(ctx, err) on rank 0 alone, in a solo section, while the other ranks wait
 * asleep: for a step whose result is cheap to send and dear to compute again, which rank 0
 * then sends with rs_par_bcast. Returns fn's code on rank 0; on the others 0, or -1 with err
 * saying that rank 0 failed (rank 0's err says why). */
int rs_par_root_run(int (*fn)(void *ctx, rs_err *err), void *ctx, rs_err *err);
/* Collective: *n bytes at *buf on rank 0 to every rank; on the others *buf is malloc'd here
 * (caller frees) and *n set. -1 with err set when out of memory on any rank. */
int rs_par_bcast_alloc(void **buf, size_t *n, rs_err *err);

/* Collective: 1 when flag is non-zero on any rank (also the team's barrier; a rank waiting
 * in it sleeps between tests instead of polling a core). */
int rs_par_any(int flag);
/* Collective: the largest of the ranks' v. */
double rs_par_max(double v);
/* Collective: n bytes of buf from rank 0 to every rank. */
void rs_par_bcast(void *buf, size_t n);

/* This rank's even share [*lo, *hi) of n items (rank order, contiguous). */
void rs_par_range(size_t n, size_t *lo, size_t *hi);
/* Collective: v holds n items of item_bytes each; every rank computed its rs_par_range share,
 * and after the call every rank holds every share. -1 with err set when n is too large for
 * one exchange (2^31 items). */
int rs_par_allgather_range(void *v, size_t n, size_t item_bytes, rs_err *err);
/* Collective: the concatenation, in rank order, of every rank's n bytes at mine, into *all
 * (malloc'd, caller frees; *total its bytes; starts[r] where rank r's part begins when starts
 * is not NULL, rs_par_size() + 1 entries). -1 with err set when out of memory. */
int rs_par_allgather_bytes(const void *mine, size_t n, unsigned char **all, size_t *total, size_t *starts, rs_err *err);

/* Collective: like rs_par_allgather_range, but only rank 0 ends with every share (the other
 * ranks' v beyond their own share is left as it was): for results that rank 0 alone writes,
 * at 1 / N of the allgather's traffic. -1 with err set when n is too large (2^31 items). */
int rs_par_gather_range(void *v, size_t n, size_t item_bytes, rs_err *err);

/* Image rows this rank computed since the start (the stages that split by pixel rows add
 * theirs), for the stages' `mpi` record: a rank that skipped its rows shows there. */
void rs_par_rows_done(size_t rows);
size_t rs_par_rows_total(void);

/* A work queue over n items dealt in blocks of block items, to whichever rank and thread asks
 * first (dynamic load balancing across ranks: costs per item may differ by orders of
 * magnitude). With MPI the next block's index is a counter on rank 0 that the ranks advance
 * with one atomic fetch-and-add each (MPI_Fetch_and_op); without, an atomic counter. */
typedef struct rs_par_queue rs_par_queue;
/* Collective. NULL when out of memory (every rank then gets NULL only if its own allocation
 * failed: callers combine with rs_par_any). */
rs_par_queue *rs_par_queue_new(size_t n, size_t block);
/* Any thread: the next block [*begin, *end), 1; 0 when the queue is empty. */
int rs_par_queue_take(rs_par_queue *q, size_t *begin, size_t *end);
/* Collective (waits for every rank to have emptied the queue). q may be NULL. */
void rs_par_queue_free(rs_par_queue *q);

/* What this rank sent and received through this file since the start, for the stages' metrics
 * and docs/BENCHMARKS.md: bytes (payload, both ways) and messages (queue requests, and one per
 * peer for each exchange). */
typedef struct rs_par_traffic {
    double bytes;
    double messages;
} rs_par_traffic;
rs_par_traffic rs_par_traffic_now(void);

#endif
