/* e57_read: the E57 reader's speed and memory (docs/BENCHMARKS.md, section E57 reading).
 *   rhoscan-e57-bench FILE.e57 [--cloud]
 * Streams every scan's points through rs_e57_scan_next (default), or builds the whole cloud
 * with rs_e57_read (--cloud), and prints points, wall and CPU seconds, million points per CPU
 * second, and the peak resident memory (getrusage). Single-threaded: CPU seconds are one core's. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#include "common/e57.h"
#include "common/log.h"

static double cpu_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: rhoscan-e57-bench FILE.e57 [--cloud]\n");
        return 1;
    }
    rs_log_init("rhoscan-e57-bench");
    rs_log_set_level(RS_LOG_WARN);
    int cloud = argc > 2 && strcmp(argv[2], "--cloud") == 0;
    rs_err err = {0};
    double t0 = rs_now(), c0 = cpu_s(), check = 0;
    size_t points = 0;
    if (cloud) {
        rs_cloud *c = rs_e57_read(argv[1], &err);
        if (!c) goto fail;
        points = c->npoints;
        check = c->xyz[3 * points - 1];
        rs_cloud_free(c);
    } else {
        rs_e57 *e = rs_e57_open(argv[1], &err);
        if (!e) goto fail;
        for (int s = 0; s < rs_e57_scan_count(e); s++) {
            if (rs_e57_scan_begin(e, s, &err) != 0) goto fail;
            rs_e57_points p;
            int r;
            while ((r = rs_e57_scan_next(e, &p, &err)) > 0) {
                points += p.n;
                check += p.xyz[3 * p.n - 1];
            }
            if (r < 0) goto fail;
        }
        rs_e57_close(e);
    }
    double wall = rs_now() - t0, cpu = cpu_s() - c0;
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    printf("%s: %s, %zu points, %.3f s wall, %.3f s CPU, %.1f Mpoints/s per core, peak RSS %.1f MB (check %g)\n",
           argv[1], cloud ? "cloud" : "stream", points, wall, cpu, points / cpu / 1e6, ru.ru_maxrss / 1024.0, check);
    return 0;
fail:
    rs_log_error(&err);
    return 1;
}
