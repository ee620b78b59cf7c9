/* err: the error record every library function fills instead of printing.
 * Functions return 0 (or a pointer) on success and -1 (or NULL) on failure with *err set. */
#ifndef RS_ERR_H
#define RS_ERR_H

#include <stddef.h>

/* Categories map to the programs' exit codes. */
typedef enum {
    RS_OK = 0,
    RS_ERR_INPUT = 1,   /* bad input file, config or value */
    RS_ERR_SYSTEM = 2,  /* I/O, memory */
    RS_ERR_INTERNAL = 3 /* a bug or a library failure */
} rs_err_kind;

typedef struct rs_err {
    rs_err_kind kind;
    char file[512]; /* the file concerned, "" if none (a longer path shortened, its name kept) */
    long line;      /* 1-based line in that file, 0 if none */
    char msg[1024]; /* what was found and what was expected */
} rs_err;

/* Sets *err (if err is not NULL) and returns -1, so that `return rs_err_set(...)` reads well.
 * file may be NULL; line 0 means no line. */
int rs_err_set(rs_err *err, rs_err_kind kind, const char *file, long line, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));

/* Same, appending strerror(errno) to the message; kind RS_ERR_INPUT for a missing or
 * unreadable path (ENOENT, EACCES, EISDIR, ENOTDIR), RS_ERR_SYSTEM otherwise. */
int rs_err_errno(rs_err *err, const char *file, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* Sets err->file alone (when the file is known only after the error was made). A path longer
 * than the field keeps its start and its end, the file's name whole: "/data/proj...dir/name.ply". */
void rs_err_set_file(rs_err *err, const char *file);

/* "file:line: msg" (parts that are empty are left out) into buf; when buf is too small the path
 * is shortened first (its file name kept), then the message cut. */
void rs_err_format(const rs_err *err, char *buf, size_t size);

void rs_err_clear(rs_err *err);

#endif
