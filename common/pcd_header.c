/* pcd_header: the PCD header check (see pcd_header.h). The format: PCL's "PCD file format"
 * (pointclouds.org, v0.7): header lines, each a keyword and its values, ending with DATA. */
#include "common/pcd_header.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/fileio.h"

#define MAX_FIELDS   256
#define MAX_COUNT    1000000
#define MAX_POINTS   2147483647L
#define MAX_LINE_TOK (MAX_FIELDS + 8)

typedef struct pcd_header {
    int nfields, nsize, ntype, ncount;
    long size[MAX_FIELDS], count[MAX_FIELDS];
    char type[MAX_FIELDS];
    long width, height, points; /* -1 when absent */
    char data[32];
    size_t data_at; /* offset of the first byte after the DATA line */
} pcd_header;

/* Splits line (modified) into at most max tokens; returns the count, max + 1 when more. */
static int tokens(char *line, char **tok, int max)
{
    int n = 0;
    for (char *p = strtok(line, " \t\r"); p; p = strtok(NULL, " \t\r")) {
        if (n == max) return max + 1;
        tok[n++] = p;
    }
    return n;
}

static int integer(const char *s, long lo, long hi, long *v)
{
    char *end;
    errno = 0;
    *v = strtol(s, &end, 10);
    return end != s && !*end && errno == 0 && *v >= lo && *v <= hi;
}

/* The header's keywords in the order the format prescribes. PCL sizes its buffer when it reads
 * POINTS, from the point size known then: a header in another order makes it write past it. */
static const char *const order[] = {"VERSION", "FIELDS",    "SIZE",   "TYPE", "COUNT", "WIDTH",
                                    "HEIGHT",  "VIEWPOINT", "POINTS", "DATA", NULL};

/* Each keyword once, in order; *last: the rank of the previous one (-1 before the first). */
static int check_order(const char *key, int *last, const char *name, long line, rs_err *err)
{
    int rank = 0;
    while (order[rank] && strcmp(order[rank], key) != 0) rank++;
    if (!order[rank]) return 0; /* an unknown keyword: header_line says so */
    if (rank <= *last)
        return rs_err_set(err, RS_ERR_INPUT, name, line,
                          "%s after %s: expected the header lines once each, in the order VERSION FIELDS SIZE TYPE "
                          "COUNT WIDTH HEIGHT VIEWPOINT POINTS DATA",
                          key, order[*last]);
    *last = rank;
    return 0;
}

/* One header line's keyword and values into h. */
static int header_line(pcd_header *h, char **tok, int n, const char *name, long line, rs_err *err)
{
    const char *key = tok[0];
    if (n > MAX_LINE_TOK - 1)
        return rs_err_set(err, RS_ERR_INPUT, name, line, "%s: more than %d values: expected at most %d fields", key,
                          MAX_LINE_TOK - 2, MAX_FIELDS);
    long v;
    if (strcmp(key, "FIELDS") == 0)
        h->nfields = n - 1;
    else if (strcmp(key, "SIZE") == 0 || strcmp(key, "COUNT") == 0) {
        int is_size = key[0] == 'S';
        for (int k = 1; k < n && k <= MAX_FIELDS; k++) {
            if (!integer(tok[k], 1, is_size ? 8 : MAX_COUNT, &v) || (is_size && v != 1 && v != 2 && v != 4 && v != 8))
                return rs_err_set(err, RS_ERR_INPUT, name, line, "%s value %d = \"%.20s\": expected %s", key, k, tok[k],
                                  is_size ? "1, 2, 4 or 8 (bytes)" : "an integer from 1 to 1000000");
            (is_size ? h->size : h->count)[k - 1] = v;
        }
        *(is_size ? &h->nsize : &h->ncount) = n - 1;
    } else if (strcmp(key, "TYPE") == 0) {
        for (int k = 1; k < n && k <= MAX_FIELDS; k++) {
            if (strlen(tok[k]) != 1 || !strchr("IUF", tok[k][0]))
                return rs_err_set(err, RS_ERR_INPUT, name, line, "TYPE value %d = \"%.20s\": expected I, U or F", k,
                                  tok[k]);
            h->type[k - 1] = tok[k][0];
        }
        h->ntype = n - 1;
    } else if (strcmp(key, "WIDTH") == 0 || strcmp(key, "HEIGHT") == 0 || strcmp(key, "POINTS") == 0) {
        if (n != 2 || !integer(tok[1], 0, MAX_POINTS, &v))
            return rs_err_set(err, RS_ERR_INPUT, name, line, "%s: expected one integer from 0 to %ld", key, MAX_POINTS);
        *(key[0] == 'W' ? &h->width : key[0] == 'H' ? &h->height : &h->points) = v;
    } else if (strcmp(key, "DATA") == 0) {
        if (n != 2 || (strcmp(tok[1], "ascii") && strcmp(tok[1], "binary") && strcmp(tok[1], "binary_compressed")))
            return rs_err_set(err, RS_ERR_INPUT, name, line, "DATA: expected ascii, binary or binary_compressed");
        snprintf(h->data, sizeof h->data, "%s", tok[1]);
    } else if (strcmp(key, "VIEWPOINT") == 0) {
        for (int k = 1; k < n; k++) {
            char *end;
            double x = strtod(tok[k], &end);
            if (end == tok[k] || *end || !isfinite(x)) n = 0;
        }
        if (n != 8)
            return rs_err_set(err, RS_ERR_INPUT, name, line,
                              "VIEWPOINT: expected 7 finite numbers (tx ty tz qw qx qy qz)");
    } else if (strcmp(key, "VERSION") != 0)
        return rs_err_set(err, RS_ERR_INPUT, name, line,
                          "\"%.20s\": expected a header line (VERSION, FIELDS, SIZE, TYPE, COUNT, WIDTH, HEIGHT, "
                          "VIEWPOINT, POINTS, DATA)",
                          key);
    return 0;
}

/* The header lines up to DATA into h. */
static int read_header(const char *data, size_t size, const char *name, pcd_header *h, rs_err *err)
{
    memset(h, 0, sizeof *h);
    h->width = h->height = h->points = -1;
    h->ncount = -1;
    long line = 0;
    int last = -1;
    for (size_t at = 0; at < size && !h->data[0];) {
        const char *nl = memchr(data + at, '\n', size - at);
        size_t len = nl ? (size_t)(nl - (data + at)) : size - at;
        line++;
        char buf[4096], *tok[MAX_LINE_TOK];
        if (len >= sizeof buf)
            return rs_err_set(err, RS_ERR_INPUT, name, line, "a header line of %zu bytes: expected at most %zu", len,
                              sizeof buf - 1);
        memcpy(buf, data + at, len);
        buf[len] = 0;
        at += len + (nl != NULL);
        if (memchr(buf, 0, len)) return rs_err_set(err, RS_ERR_INPUT, name, line, "a NUL byte in the header");
        /* As PCL reads it: an empty line is skipped, a line of blanks ends the header, '#' starts
         * a comment line only at its start (elsewhere PCL would take it for a value). */
        if (len == 0) continue;
        const char *first = buf + strspn(buf, " \t\r\v\f");
        if (*first == '#') continue;
        if (!*first || strchr(first, '#'))
            return rs_err_set(err, RS_ERR_INPUT, name, line,
                              *first ? "a '#' inside a header line: expected comments on lines of their own"
                                     : "a line of blanks in the header: expected header lines up to DATA");
        int n = tokens(buf, tok, MAX_LINE_TOK - 1);
        if (n == 0) continue; /* not reached: a line of blanks was refused above */
        if (check_order(tok[0], &last, name, line, err) != 0 || header_line(h, tok, n, name, line, err) != 0) return -1;
        h->data_at = at;
    }
    /* PCL goes on reading header lines after DATA until one is not (empty lines skipped, blanks
     * trimmed, keywords matched by prefix): data that starts with a keyword would be read as
     * header (a huge allocation, a use after free, found by fuzzing). */
    if (h->data[0]) {
        const char *p = data + h->data_at, *end = data + size;
        while (p < end && strchr(" \t\r\v\f\n", *p)) p++;
        static const char *const keys[] = {"#",     "VERSION", "FIELDS", "COLUMNS",   "SIZE",   "TYPE",
                                           "COUNT", "WIDTH",   "HEIGHT", "VIEWPOINT", "POINTS", "DATA"};
        for (size_t k = 0; k < sizeof keys / sizeof *keys; k++)
            if ((size_t)(end - p) >= strlen(keys[k]) && memcmp(p, keys[k], strlen(keys[k])) == 0)
                return rs_err_set(err, RS_ERR_INPUT, name, line + 1, "\"%s\" after the DATA line: expected the data",
                                  keys[k]);
    }
    if (!h->data[0])
        return rs_err_set(err, RS_ERR_INPUT, name, 0,
                          size ? "no DATA line: expected a PCD header (FIELDS, SIZE, TYPE, WIDTH, HEIGHT, POINTS, DATA)"
                               : "empty file: expected a PCD point cloud");
    return 0;
}

int rs_pcd_check(const char *data, size_t size, const char *name, rs_err *err)
{
    pcd_header *h = malloc(sizeof *h);
    if (!h) return rs_err_set(err, RS_ERR_SYSTEM, name, 0, "out of memory");
    int rc = -1;
    if (read_header(data, size, name, h, err) != 0) goto out;
    if (h->nfields < 1 || h->nsize != h->nfields || h->ntype != h->nfields ||
        (h->ncount >= 0 && h->ncount != h->nfields)) {
        rs_err_set(err, RS_ERR_INPUT, name, 0,
                   "FIELDS has %d names, SIZE %d values, TYPE %d, COUNT %d: expected one value each per field",
                   h->nfields, h->nsize, h->ntype, h->ncount < 0 ? h->nfields : h->ncount);
        goto out;
    }
    size_t step = 0;
    for (int k = 0; k < h->nfields; k++) {
        if (h->type[k] == 'F' && h->size[k] != 4 && h->size[k] != 8) {
            rs_err_set(err, RS_ERR_INPUT, name, 0, "field %d: TYPE F of SIZE %ld: expected 4 or 8 bytes", k + 1,
                       h->size[k]);
            goto out;
        }
        step += (size_t)h->size[k] * (size_t)(h->ncount < 0 ? 1 : h->count[k]);
    }
    if (h->width < 0 || h->height < 0 || (h->points >= 0 && h->points != h->width * h->height)) {
        rs_err_set(err, RS_ERR_INPUT, name, 0, "WIDTH %ld x HEIGHT %ld, POINTS %ld: expected WIDTH x HEIGHT = POINTS",
                   h->width, h->height, h->points);
        goto out;
    }
    unsigned long long need = (unsigned long long)h->width * (unsigned long long)h->height * step;
    /* PCL sizes its buffer as POINTS x the point's bytes in 32 bits. */
    if (need > (unsigned long long)MAX_POINTS) {
        rs_err_set(err, RS_ERR_INPUT, name, 0, "%ld points of %zu bytes: expected at most %ld bytes of points",
                   h->width * h->height, step, MAX_POINTS);
        goto out;
    }
    size_t rest = size - h->data_at;
    if (strcmp(h->data, "binary") == 0 && need > rest) {
        rs_err_set(err, RS_ERR_INPUT, name, 0, "%ld points of %zu bytes need %llu bytes of binary data; %zu follow",
                   h->width * h->height, step, need, rest);
        goto out;
    }
    if (strcmp(h->data, "binary_compressed") == 0) {
        uint32_t sizes[2] = {0, 0};
        if (rest >= 8) memcpy(sizes, data + h->data_at, 8);
        if (rest < 8 || sizes[0] > rest - 8 || sizes[1] != need) {
            rs_err_set(err, RS_ERR_INPUT, name, 0,
                       "binary_compressed data of %u bytes (%u uncompressed) after the header, %zu bytes in the file: "
                       "expected the compressed size within the file and %llu bytes uncompressed",
                       sizes[0], sizes[1], rest, need);
            goto out;
        }
    }
    rc = 0;
out:
    free(h);
    return rc;
}

int rs_pcd_check_file(const char *path, rs_err *err)
{
    char *data;
    size_t size;
    if (rs_read_file(path, &data, &size, err) != 0) return -1;
    int rc = rs_pcd_check(data, size, path, err);
    free(data);
    return rc;
}
