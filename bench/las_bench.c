/* las_bench: the LAS reader's speed and memory (docs/BENCHMARKS.md, LAS reading). Writes a
 * large LAS file of random points a chunk at a time, then reads it either streaming (rs_las_next:
 * the chunk is all the reader holds) or into an rs_cloud (rs_las_read, what the ingest does);
 * prints one CSV line: mode, points, bytes, CPU s, wall s, points per CPU-second (the reader is
 * one thread), peak RSS of the process (MB).
 *   rhoscan-bench-las generate FILE POINTS [FORMAT]   (FORMAT 0-10, default 3)
 *   rhoscan-bench-las stream FILE
 *   rhoscan-bench-las cloud FILE
 * Run each read in a process of its own so that the peak RSS is that read's alone. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#include "common/las.h"
#include "common/log.h"

static const unsigned min_record[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
static const unsigned rgb_at[11] = {0, 0, 20, 28, 0, 28, 0, 30, 30, 0, 30};

static void put32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(v >> (8 * i));
}
static void putd(unsigned char *p, double d)
{
    memcpy(p, &d, 8);
} /* little-endian hosts */

/* xorshift64*: the points' integers, reproducible. */
static uint64_t next_random(uint64_t *s)
{
    *s ^= *s >> 12, *s ^= *s << 25, *s ^= *s >> 27;
    return *s * 0x2545f4914f6cdd1dULL;
}

static int generate(const char *path, uint64_t n, int format)
{
    unsigned hsize = format >= 6 ? 375 : 227, rec = min_record[format];
    unsigned char h[375] = "LASF";
    h[24] = 1, h[25] = format >= 6 ? 4 : 2;
    h[94] = (unsigned char)hsize, h[95] = (unsigned char)(hsize >> 8);
    put32(h + 96, hsize);
    h[104] = (unsigned char)format;
    h[105] = (unsigned char)rec;
    put32(h + 107, format >= 6 || n > 0xffffffffu ? 0 : (uint32_t)n);
    const double scale = 0.001, offset[3] = {500000, 5400000, 0}, extent = 1000; /* a 1 km square, 1 mm grid */
    for (int j = 0; j < 3; j++) {
        putd(h + 131 + 8 * j, scale);
        putd(h + 155 + 8 * j, offset[j]);
        putd(h + 179 + 16 * j, offset[j] + extent);
        putd(h + 187 + 16 * j, offset[j]);
    }
    if (format >= 6) memcpy(h + 247, &n, 8);
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(h, 1, hsize, f) != hsize) return -1;
    enum { BATCH = 65536 };
    unsigned char *buf = calloc(BATCH, rec);
    if (!buf) return -1;
    uint64_t s = 88172645463325252ULL;
    for (uint64_t done = 0; done < n;) {
        size_t m = n - done < BATCH ? (size_t)(n - done) : BATCH;
        for (size_t i = 0; i < m; i++) {
            unsigned char *p = buf + i * rec;
            for (int j = 0; j < 3; j++) put32(p + 4 * j, (uint32_t)(next_random(&s) % (uint64_t)(extent / scale)));
            uint64_t r = next_random(&s);
            p[12] = (unsigned char)r, p[13] = (unsigned char)(r >> 8);
            p[format >= 6 ? 16 : 15] = (unsigned char)(r >> 16) % 10;
            if (rgb_at[format])
                for (int j = 0; j < 6; j++) p[rgb_at[format] + j] = (unsigned char)(r >> (24 + 5 * j));
        }
        if (fwrite(buf, rec, m, f) != m) return -1;
        done += m;
    }
    free(buf);
    return fclose(f);
}

static double cpu_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static void report(const char *mode, const char *path, uint64_t n, uint64_t bytes, double cpu, double wall)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    printf("%s,%s,%llu,%llu,%.3f,%.3f,%.3g,%.1f\n", mode, path, (unsigned long long)n, (unsigned long long)bytes, cpu,
           wall, (double)n / cpu, ru.ru_maxrss / 1024.0);
}

int main(int argc, char **argv)
{
    rs_log_init("rhoscan-bench-las");
    if (argc >= 4 && strcmp(argv[1], "generate") == 0) {
        int format = argc >= 5 ? atoi(argv[4]) : 3;
        if (format < 0 || format > 10) return 1;
        return generate(argv[2], strtoull(argv[3], NULL, 10), format) == 0 ? 0 : 2;
    }
    if (argc != 3 || (strcmp(argv[1], "stream") != 0 && strcmp(argv[1], "cloud") != 0)) {
        fprintf(stderr, "usage: rhoscan-bench-las generate FILE POINTS [FORMAT] | stream FILE | cloud FILE\n");
        return 1;
    }
    rs_err err = {0};
    double c0 = cpu_s(), w0 = rs_now();
    uint64_t n = 0, bytes = 0;
    volatile double sum = 0;
    if (strcmp(argv[1], "stream") == 0) {
        rs_las *f = rs_las_open(argv[2], &err);
        if (!f) goto fail;
        bytes = rs_las_info_of(f)->file_size;
        for (const rs_las_chunk *ch; (ch = rs_las_next(f, &err)) && ch->n;) {
            n += ch->n;
            sum += ch->xyz[3 * ch->n - 1];
        }
        rs_las_close(f);
        if (err.msg[0]) goto fail;
    } else {
        rs_las *f = rs_las_open(argv[2], &err);
        if (!f) goto fail;
        bytes = rs_las_info_of(f)->file_size;
        rs_las_close(f);
        rs_cloud *c = rs_las_read(argv[2], NULL, &err);
        if (!c) goto fail;
        n = c->npoints;
        sum += c->xyz[3 * n - 1];
        rs_cloud_free(c);
    }
    report(argv[1], argv[2], n, bytes, cpu_s() - c0, rs_now() - w0);
    return 0;
fail : {
    char buf[2048];
    rs_err_format(&err, buf, sizeof buf);
    fprintf(stderr, "rhoscan-bench-las: %s\n", buf);
    return err.kind ? (int)err.kind : 2;
}
}
