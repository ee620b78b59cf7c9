/* fuzz_io: for the harnesses whose reader takes a path (PCL's PCD reader, the XYZ reader, the
 * COLMAP model folder): the input written to a file of a per-process temporary folder. */
#ifndef RS_FUZZ_IO_H
#define RS_FUZZ_IO_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* The harness's temporary folder, made once (removed by the system's /tmp cleaning): in memory
 * (/dev/shm) when there is one, where a harness runs 70 times faster than on a busy disk. */
static inline const char *fuzz_dir(void)
{
    static char dir[256];
    if (!dir[0]) {
        struct stat st;
        const char *base = getenv("TMPDIR")                     ? getenv("TMPDIR")
            : stat("/dev/shm", &st) == 0 && S_ISDIR(st.st_mode) ? "/dev/shm"
                                                                : "/tmp";
        snprintf(dir, sizeof dir, "%s/rhoscan-fuzz-XXXXXX", base);
        if (!mkdtemp(dir)) abort();
    }
    return dir;
}

/* Writes n bytes to fuzz_dir()/name; returns the path (static buffer per name slot). */
static inline const char *fuzz_write(const char *name, const void *data, size_t n)
{
    static char paths[8][512];
    static int next;
    char *p = paths[next++ % 8];
    snprintf(p, sizeof paths[0], "%s/%s", fuzz_dir(), name);
    FILE *f = fopen(p, "wb");
    if (!f || (n && fwrite(data, 1, n, f) != n) || fclose(f) != 0) abort();
    return p;
}

#endif
