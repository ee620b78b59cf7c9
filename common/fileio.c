/* fileio: atomic outputs, whole-file reads, checksums, paths (see fileio.h). */
#include "common/fileio.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* Writes left until the one that fails as a full disk would; -1: none fails (see fileio.h). */
static long fault_countdown = -1;

void rs_fault_inject_enospc(long nth)
{
    fault_countdown = nth > 0 ? nth : -1;
}

/* 1 when the current write is the one rs_fault_inject_enospc asked to fail. */
static int fault_should_fail(void)
{
    if (fault_countdown < 0) return 0;
    int fail;
#pragma omp critical(rs_fault)
    fail = (--fault_countdown == 0);
    return fail;
}

/* An output that cannot be written is the system's trouble (exit 2, README), whatever errno
 * says: EACCES on a read-only work folder is not a bad input. */
static int output_failed(rs_err *err, const char *path, const char *what)
{
    rs_err_errno(err, path, "%s", what);
    if (err) err->kind = RS_ERR_SYSTEM;
    return -1;
}

int rs_atomic_open(rs_atomic_file *f, const char *path, rs_err *err)
{
    memset(f, 0, sizeof *f);
    if (strlen(path) >= sizeof f->path) return rs_err_set(err, RS_ERR_INPUT, path, 0, "path too long");
    snprintf(f->path, sizeof f->path, "%s", path);
    snprintf(f->tmp_path, sizeof f->tmp_path, "%s.tmp.%ld", path, (long)getpid());
    f->fp = fopen(f->tmp_path, "wb");
    if (!f->fp) return output_failed(err, path, "cannot create a temporary file beside the output");
    return 0;
}

int rs_atomic_write(rs_atomic_file *f, const void *data, size_t n, rs_err *err)
{
    if (f->failed) return -1;
    if (fault_should_fail()) {
        f->failed = 1;
        errno = ENOSPC;
        return rs_err_errno(err, f->path, "write failed (fault injected); previous output kept");
    }
    if (n && fwrite(data, 1, n, f->fp) != n) {
        f->failed = 1;
        return output_failed(err, f->path, "write failed; previous output kept");
    }
    return 0;
}

int rs_atomic_commit(rs_atomic_file *f, rs_err *err)
{
    if (!f->fp) return rs_err_set(err, RS_ERR_INTERNAL, f->path, 0, "commit without open");
    if (f->failed) {
        rs_atomic_abort(f);
        return -1;
    }
    int bad = fflush(f->fp) != 0 || fsync(fileno(f->fp)) != 0;
    int saved = errno;
    if (fclose(f->fp) != 0 && !bad) {
        bad = 1;
        saved = errno;
    }
    f->fp = NULL;
    if (bad) {
        errno = saved;
        output_failed(err, f->path, "write failed; previous output kept");
        unlink(f->tmp_path);
        return -1;
    }
    if (rename(f->tmp_path, f->path) != 0) {
        output_failed(err, f->path, "cannot rename the temporary file over the output");
        unlink(f->tmp_path);
        return -1;
    }
    return 0;
}

void rs_atomic_abort(rs_atomic_file *f)
{
    if (f->fp) {
        fclose(f->fp);
        f->fp = NULL;
    }
    if (f->tmp_path[0]) unlink(f->tmp_path);
    f->tmp_path[0] = 0;
}

int rs_write_file_atomic(const char *path, const void *data, size_t n, rs_err *err)
{
    rs_atomic_file f;
    if (rs_atomic_open(&f, path, err) != 0) return -1;
    if (rs_atomic_write(&f, data, n, err) != 0) {
        rs_atomic_abort(&f);
        return -1;
    }
    return rs_atomic_commit(&f, err);
}

int rs_read_file(const char *path, char **data, size_t *size, rs_err *err)
{
    *data = NULL;
    *size = 0;
    FILE *fp = fopen(path, "rb");
    if (!fp) return rs_err_errno(err, path, "cannot open");
    struct stat st;
    if (fstat(fileno(fp), &st) != 0 || !S_ISREG(st.st_mode)) {
        fclose(fp);
        return rs_err_set(err, RS_ERR_INPUT, path, 0, "not a regular file");
    }
    size_t n = (size_t)st.st_size;
    char *buf = malloc(n + 1);
    if (!buf) {
        fclose(fp);
        return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory reading %zu bytes", n);
    }
    if (n && fread(buf, 1, n, fp) != n) {
        rs_err_errno(err, path, "read failed");
        free(buf);
        fclose(fp);
        return -1;
    }
    fclose(fp);
    buf[n] = 0;
    *data = buf;
    *size = n;
    return 0;
}

uint64_t rs_hash_bytes(const void *data, size_t n, uint64_t seed)
{
    const unsigned char *p = data;
    uint64_t h = seed;
    for (size_t i = 0; i < n; i++) {
        h ^= p[i];
        h *= 0x100000001b3ULL;
    }
    return h;
}

/* splitmix64's finalizer: every input bit reaches every output bit. */
static uint64_t mix64(uint64_t x)
{
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ULL;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
}

/* File hashes take 8-byte words in four independent lanes, mixed at the end: byte-wise FNV-1a
 * is one multiply chain per byte, and hashing the inputs and outputs (transport.ply is 43 MB at
 * 1e5 facets) was 4 to 9 % of the reflectance and render stages (perf). Change detection only:
 * the values differ from rs_hash_bytes', so state files written before rerun their stage once. */
int rs_hash_file(const char *path, uint64_t *hash, rs_err *err)
{
    FILE *fp = fopen(path, "rb");
    if (!fp) return rs_err_errno(err, path, "cannot open");
    uint64_t lane[4] = {RS_HASH_SEED, RS_HASH_SEED ^ 1, RS_HASH_SEED ^ 2, RS_HASH_SEED ^ 3}, total = 0;
    uint64_t buf[1 << 13];
    size_t n;
    uint64_t tail = RS_HASH_SEED;
    while ((n = fread(buf, 1, sizeof buf, fp)) > 0) {
        size_t words = n / 32 * 4;
        for (size_t k = 0; k < words; k += 4)
            for (int q = 0; q < 4; q++) {
                uint64_t x = (lane[q] ^ buf[k + q]) * 0x100000001b3ULL;
                lane[q] = x ^ (x >> 29);
            }
        tail =
            rs_hash_bytes((const unsigned char *)buf + 8 * words, n - 8 * words, tail); /* only the last read has one */
        total += n;
    }
    int bad = ferror(fp);
    fclose(fp);
    if (bad) return rs_err_errno(err, path, "read failed");
    uint64_t h = mix64(total ^ tail);
    for (int q = 0; q < 4; q++) h = mix64(h ^ lane[q]);
    *hash = h;
    return 0;
}

int rs_file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

/* A file in the way (ENOTDIR) or a missing parent is the config's mistake (exit 1); a folder that
 * may not be written (EACCES, EROFS) or a full disk is an output that cannot be written (exit 2). */
static int mkdir_failed(rs_err *err, const char *path)
{
    int e = errno;
    rs_err_errno(err, path, "cannot create folder");
    if (err && e != ENOTDIR && e != ENOENT && e != ENAMETOOLONG) err->kind = RS_ERR_SYSTEM;
    return -1;
}

int rs_mkdir_p(const char *path, rs_err *err)
{
    char buf[4096];
    if (strlen(path) >= sizeof buf) return rs_err_set(err, RS_ERR_INPUT, path, 0, "path too long");
    snprintf(buf, sizeof buf, "%s", path);
    for (char *p = buf + 1; *p; p++) {
        if (*p != '/') continue;
        *p = 0;
        if (mkdir(buf, 0777) != 0 && errno != EEXIST) return mkdir_failed(err, buf);
        *p = '/';
    }
    if (mkdir(buf, 0777) != 0 && errno != EEXIST) return mkdir_failed(err, buf);
    struct stat st;
    if (stat(buf, &st) != 0 || !S_ISDIR(st.st_mode))
        return rs_err_set(err, RS_ERR_INPUT, buf, 0, "exists but is not a folder");
    return 0;
}

char *rs_path_join(char *out, size_t n, const char *dir, const char *name)
{
    if (!dir || !*dir || name[0] == '/')
        snprintf(out, n, "%s", name);
    else
        snprintf(out, n, "%s%s%s", dir, dir[strlen(dir) - 1] == '/' ? "" : "/", name);
    return out;
}
