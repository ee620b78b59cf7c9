/* err: filling and formatting error records (see err.h). */
#include "common/err.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

/* Room kept for the start of a shortened path (its root: which tree the file is in). */
#define PATH_HEAD_MIN 48

/* path into out (cap bytes with the NUL). A path that does not fit keeps its start, "...", and
 * its end from a '/' on, so that the file's name (the last component) always survives whole. */
static void shorten_path(const char *path, char *out, size_t cap)
{
    size_t n = strlen(path);
    if (cap == 0 || path == out) return; /* rs_err_set(err, ..., err->file, ...) keeps it */
    if (n < cap) {
        memcpy(out, path, n + 1);
        return;
    }
    const char *base = strrchr(path, '/');
    base = base ? base : path;
    size_t room = cap - 1, base_len = strlen(base);
    if (base_len + 3 >= room) { /* only the name's end fits */
        size_t keep = room > 3 ? room - 3 : 0;
        snprintf(out, cap, "...%s", path + n - keep);
        return;
    }
    /* As much of the end as leaves PATH_HEAD_MIN characters of the start, cut at a '/'. */
    size_t tail_max = room - 3 > PATH_HEAD_MIN + base_len ? room - 3 - PATH_HEAD_MIN : base_len;
    const char *tail = path + n - tail_max;
    const char *slash = strchr(tail, '/');
    tail = slash && slash <= base ? slash : base;
    size_t tail_len = strlen(tail), head = room - 3 - tail_len;
    snprintf(out, cap, "%.*s...%s", (int)head, path, tail);
}

void rs_err_set_file(rs_err *err, const char *file)
{
    if (!err) return;
    shorten_path(file ? file : "", err->file, sizeof err->file);
}

static void err_fill(rs_err *err, rs_err_kind kind, const char *file, long line, const char *fmt, va_list ap)
{
    err->kind = kind;
    rs_err_set_file(err, file);
    err->line = line;
    vsnprintf(err->msg, sizeof err->msg, fmt, ap);
}

int rs_err_set(rs_err *err, rs_err_kind kind, const char *file, long line, const char *fmt, ...)
{
    if (!err) return -1;
    va_list ap;
    va_start(ap, fmt);
    err_fill(err, kind, file, line, fmt, ap);
    va_end(ap);
    return -1;
}

int rs_err_errno(rs_err *err, const char *file, const char *fmt, ...)
{
    int saved = errno;
    if (!err) return -1;
    va_list ap;
    va_start(ap, fmt);
    /* A path that is missing, unreadable or a folder is the user's input, not the system's. */
    int input = saved == ENOENT || saved == EACCES || saved == EISDIR || saved == ENOTDIR;
    err_fill(err, input ? RS_ERR_INPUT : RS_ERR_SYSTEM, file, 0, fmt, ap);
    va_end(ap);
    size_t len = strlen(err->msg);
    snprintf(err->msg + len, sizeof err->msg - len, ": %s", strerror(saved));
    return -1;
}

void rs_err_format(const rs_err *err, char *buf, size_t size)
{
    if (size == 0) return;
    char line[32] = "";
    if (err->file[0] && err->line > 0) snprintf(line, sizeof line, ":%ld", err->line);
    if (!err->file[0]) {
        snprintf(buf, size, "%s", err->msg);
        return;
    }
    /* A small buffer shortens the path, never its file name, before it cuts the message. */
    size_t fixed = strlen(line) + 2 + strlen(err->msg), cap = size > fixed ? size - fixed : 1;
    char file[sizeof err->file];
    shorten_path(err->file, file, cap < sizeof file ? cap : sizeof file);
    if (!file[0] && size > 1) shorten_path(err->file, file, size / 2 < sizeof file ? size / 2 : sizeof file);
    snprintf(buf, size, "%s%s: %s", file, line, err->msg);
}

void rs_err_clear(rs_err *err)
{
    if (!err) return;
    memset(err, 0, sizeof *err);
}
