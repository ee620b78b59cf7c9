/* colmap_text: the line cursor behind the COLMAP model, views and control-point readers (private to
 * calib/colmap*.c): whitespace-separated fields, errors naming the file, the line and the field. */
#ifndef RS_COLMAP_TEXT_H
#define RS_COLMAP_TEXT_H

#include <stddef.h>
#include "common/err.h"

typedef struct rs_ctext {
    char path[4096];
    char *text;     /* the whole file; the caller frees it */
    char *next, *p; /* the next line; the rest of the current one */
    long line;      /* 1-based number of the current line */
    int field;      /* fields read on it */
} rs_ctext;

/* Reads path whole (a missing file is an input error naming it). */
int rs_ctext_open(rs_ctext *c, const char *path, rs_err *err);
/* Moves to the next line (CR LF tolerated); 0 at the end of the file. */
int rs_ctext_next_line(rs_ctext *c);
/* 1 when the current line is empty or a `#` comment. */
int rs_ctext_blank(const rs_ctext *c);
/* 1 when fields remain on the line. */
int rs_ctext_more(const rs_ctext *c);
/* The next field into tok (cut to n - 1 characters); returns its whole length, 0 when the line
 * has no more. */
size_t rs_ctext_token(rs_ctext *c, char *tok, size_t n);
/* The next field as a name of at most n - 1 characters; missing or longer is an error naming `what`. */
int rs_ctext_name(rs_ctext *c, const char *what, char *tok, size_t n, rs_err *err);
/* Parse the next field; a missing or malformed field is an error naming `what`. */
int rs_ctext_long(rs_ctext *c, const char *what, long *v, rs_err *err);
int rs_ctext_real(rs_ctext *c, const char *what, double *v, rs_err *err);
int rs_ctext_missing(rs_ctext *c, const char *what, rs_err *err);
/* An error when fields remain after `what`. */
int rs_ctext_end(rs_ctext *c, const char *what, rs_err *err);

#endif
