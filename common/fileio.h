/* fileio: atomic output files (write a temporary file beside the target, then rename),
 * checksums for provenance and rerun decisions, and path helpers.
 * A fault-injection switch (rs_fault_inject_enospc: fail the N-th write) lets tests
 * simulate a full disk. */
#ifndef RS_FILEIO_H
#define RS_FILEIO_H

#include <stdint.h>
#include <stdio.h>
#include "common/err.h"

/* An output being written: a FILE* on "<path>.tmp.<pid>" that becomes <path> on commit. */
typedef struct rs_atomic_file {
    FILE *fp;
    char path[4096];
    char tmp_path[4200];
    int failed;
} rs_atomic_file;

/* Failures to create, write or rename an output are RS_ERR_SYSTEM (exit 2) with the target's path
 * and strerror, whatever the errno (EACCES on a read-only folder too). */
int rs_atomic_open(rs_atomic_file *f, const char *path, rs_err *err);
/* Writes n bytes; returns 0 or -1 (ENOSPC and friends reported with the target path). */
int rs_atomic_write(rs_atomic_file *f, const void *data, size_t n, rs_err *err);
/* Flushes, fsyncs and renames over the target. On failure the target is left untouched. */
int rs_atomic_commit(rs_atomic_file *f, rs_err *err);
/* Drops the temporary file; safe to call after a failed commit or twice. */
void rs_atomic_abort(rs_atomic_file *f);
/* Whole buffer to path, atomically. */
int rs_write_file_atomic(const char *path, const void *data, size_t n, rs_err *err);

/* Reads a whole file (NUL-terminated for convenience); caller frees *data. */
int rs_read_file(const char *path, char **data, size_t *size, rs_err *err);

/* 64-bit FNV-1a over bytes, chainable through seed (use RS_HASH_SEED to start). */
#define RS_HASH_SEED 0xcbf29ce484222325ULL
uint64_t rs_hash_bytes(const void *data, size_t n, uint64_t seed);
/* 64-bit hash of a file's contents (word-wise, not rs_hash_bytes' value; for change
 * detection); 0 with *err set when unreadable. */
int rs_hash_file(const char *path, uint64_t *hash, rs_err *err);

int rs_file_exists(const char *path);
/* Creates a folder and its parents (mkdir -p). A file in the way is RS_ERR_INPUT; a folder that
 * may not be written (EACCES, EROFS) or a full disk RS_ERR_SYSTEM. */
int rs_mkdir_p(const char *path, rs_err *err);
/* dir/name into out (size n); returns out. */
char *rs_path_join(char *out, size_t n, const char *dir, const char *name);

/* Fault injection for tests, which run as root where permissions cannot fail: the nth atomic
 * write from now (1: the next) fails with ENOSPC as on a full disk, so that a test can check
 * that earlier outputs survive; nth <= 0 turns it off. The programs set it from
 * RHOSCAN_FAULT=enospc:N at start (pipeline/options.h: rs_program_start). Not thread-safe
 * against writes in progress: call it before any. */
void rs_fault_inject_enospc(long nth);

#endif
