/* err: filling and formatting error records (see err.h). */
#include "common/err.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

static void err_fill(rs_err *err, rs_err_kind kind, const char *file, long line, const char *fmt, va_list ap)
{
    err->kind = kind;
    snprintf(err->file, sizeof err->file, "%s", file ? file : "");
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
    if (err->file[0] && err->line > 0)
        snprintf(buf, size, "%s:%ld: %s", err->file, err->line, err->msg);
    else if (err->file[0])
        snprintf(buf, size, "%s: %s", err->file, err->msg);
    else
        snprintf(buf, size, "%s", err->msg);
}

void rs_err_clear(rs_err *err)
{
    if (!err) return;
    memset(err, 0, sizeof *err);
}
