/* ply_read: the PLY reader behind rs_ply_read and rs_ply_read_mem (ascii, binary little and
 * big endian). Element counts are checked against the bytes that remain before allocating. */
#include "common/ply.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "common/fileio.h"
#include "common/ply_internal.h"

/* Bounds that keep garbage headers from costing quadratic time; real files are far below. */
#define MAX_ELEMENTS 1024
#define MAX_PROPS    4096
#define TOKEN_MAX    64

enum { FMT_NONE, FMT_ASCII, FMT_BINARY_LE, FMT_BINARY_BE };

typedef struct {
    const char *name; /* the file, for messages */
    rs_err *err;
    const unsigned char *p, *end; /* data cursor */
    int format;
    int swap;         /* binary: the file's byte order is not the host's */
    long line;        /* ascii: the line of the cursor */
    const char *rest; /* header: the line after the one being parsed */
} reader;

#define TYPE_NAMES                                                               \
    "char, uchar, short, ushort, int, uint, float, double, int8, uint8, int16, " \
    "uint16, int32, uint32, float32 or float64"

static int parse_type(const char *s, rs_ply_type *type)
{
    static const char *const alt[RS_PLY_NTYPES] = {"int8",  "uint8",  "int16",   "uint16",
                                                   "int32", "uint32", "float32", "float64"};
    for (int t = 0; t < RS_PLY_NTYPES; t++)
        if (strcmp(s, rs_ply_type_name[t]) == 0 || strcmp(s, alt[t]) == 0) {
            *type = (rs_ply_type)t;
            return 0;
        }
    return -1;
}

/* Up to max-1 bytes of s, with bytes that would garble a message shown as '?'. */
static const char *printable(const char *s, size_t n, char *out, size_t max)
{
    size_t i = 0;
    for (; i < n && i + 1 < max; i++) out[i] = (s[i] >= 32 && s[i] < 127) ? s[i] : '?';
    out[i] = '\0';
    return out;
}

/* ---- header ---- */

static int parse_count(const char *s, size_t *count)
{
    if (!*s || strlen(s) > 20) return -1;
    for (const char *c = s; *c; c++)
        if (*c < '0' || *c > '9') return -1;
    errno = 0;
    unsigned long long v = strtoull(s, NULL, 10);
    if (errno || v > SIZE_MAX) return -1;
    *count = (size_t)v;
    return 0;
}

/* Whether a line "end_header" follows: tells a missing end_header from a misspelt keyword. */
static int has_end_header(const char *p, const char *end)
{
    for (; end - p >= 10; p++) {
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        if (memcmp(p, "end_header", 10) == 0) return 1;
        if (!nl) return 0;
        p = nl;
    }
    return 0;
}

static int header_line(reader *r, rs_ply *ply, char *line, long lineno)
{
    const char *n = r->name;
    if (strncmp(line, "comment", 7) == 0 || strncmp(line, "obj_info", 8) == 0) {
        char *text = line + (line[0] == 'c' ? 7 : 8);
        if (*text == ' ' || *text == '\t')
            text++;
        else if (*text)
            goto keyword; /* "commentary ..." is not a comment */
        if (rs_ply_add_comment(ply, "%s", text))
            return rs_err_set(r->err, RS_ERR_SYSTEM, n, lineno, "out of memory for comments");
        return 0;
    }
keyword:;
    char *tok[6], *save = NULL;
    int ntok = 0;
    for (char *t = strtok_r(line, " \t", &save); t; t = strtok_r(NULL, " \t", &save)) {
        if (ntok == 6) break;
        tok[ntok++] = t;
    }
    if (ntok == 0) return 0; /* blank line */
    rs_ply_element *el = ply->nelements ? &ply->elements[ply->nelements - 1] : NULL;
    if (strcmp(tok[0], "format") == 0) {
        if (r->format != FMT_NONE) return rs_err_set(r->err, RS_ERR_INPUT, n, lineno, "a second 'format' line");
        if (ntok != 3)
            return rs_err_set(r->err, RS_ERR_INPUT, n, lineno,
                              "expected 'format <ascii|binary_little_endian|binary_big_endian> 1.0'");
        if (strcmp(tok[1], "ascii") == 0)
            r->format = FMT_ASCII;
        else if (strcmp(tok[1], "binary_little_endian") == 0)
            r->format = FMT_BINARY_LE;
        else if (strcmp(tok[1], "binary_big_endian") == 0)
            r->format = FMT_BINARY_BE;
        else
            return rs_err_set(r->err, RS_ERR_INPUT, n, lineno,
                              "unknown format '%s' (expected ascii, binary_little_endian or "
                              "binary_big_endian)",
                              tok[1]);
        char *endp;
        if (strtod(tok[2], &endp) != 1.0 || *endp)
            return rs_err_set(r->err, RS_ERR_INPUT, n, lineno, "unsupported PLY version '%s' (expected 1.0)", tok[2]);
        return 0;
    }
    if (strcmp(tok[0], "element") == 0) {
        size_t count;
        if (ntok != 3) return rs_err_set(r->err, RS_ERR_INPUT, n, lineno, "expected 'element <name> <count>'");
        if (strlen(tok[1]) >= sizeof el->name)
            return rs_err_set(r->err, RS_ERR_INPUT, n, lineno, "element name '%.20s...' is longer than 63 characters",
                              tok[1]);
        if (parse_count(tok[2], &count))
            return rs_err_set(r->err, RS_ERR_INPUT, n, lineno,
                              "element '%s': count '%.30s' is not a non-negative integer", tok[1], tok[2]);
        if (rs_ply_find_element(ply, tok[1]))
            return rs_err_set(r->err, RS_ERR_INPUT, n, lineno, "element '%s' declared twice", tok[1]);
        if (ply->nelements >= MAX_ELEMENTS)
            return rs_err_set(r->err, RS_ERR_INPUT, n, lineno, "more than %d elements", MAX_ELEMENTS);
        if (!rs_ply_add_element(ply, tok[1], count))
            return rs_err_set(r->err, RS_ERR_SYSTEM, n, lineno, "out of memory for elements");
        return 0;
    }
    if (strcmp(tok[0], "property") == 0) {
        int is_list = ntok >= 2 && strcmp(tok[1], "list") == 0;
        rs_ply_type type, count_type = RS_PLY_UINT8;
        if (!el) return rs_err_set(r->err, RS_ERR_INPUT, n, lineno, "'property' before any 'element' line");
        if (ntok != (is_list ? 5 : 3))
            return rs_err_set(r->err, RS_ERR_INPUT, n, lineno,
                              "expected 'property <type> <name>' or "
                              "'property list <count type> <item type> <name>'");
        const char *tname = tok[is_list ? 3 : 1], *pname = tok[is_list ? 4 : 2];
        if (is_list && (parse_type(tok[2], &count_type) || !rs_ply_type_is_int(count_type)))
            return rs_err_set(r->err, RS_ERR_INPUT, n, lineno,
                              "list '%s': count type '%s' is not an integer type (expected uchar, "
                              "ushort, uint, char, short, int or their intN names)",
                              pname, tok[2]);
        if (parse_type(tname, &type))
            return rs_err_set(r->err, RS_ERR_INPUT, n, lineno,
                              "property '%s': unknown type '%s' (expected " TYPE_NAMES ")", pname, tname);
        if (strlen(pname) >= sizeof el->name)
            return rs_err_set(r->err, RS_ERR_INPUT, n, lineno, "property name '%.20s...' is longer than 63 characters",
                              pname);
        if (rs_ply_find_prop(el, pname))
            return rs_err_set(r->err, RS_ERR_INPUT, n, lineno, "element '%s': property '%s' declared twice", el->name,
                              pname);
        if (el->nprops >= MAX_PROPS)
            return rs_err_set(r->err, RS_ERR_INPUT, n, lineno, "element '%s': more than %d properties", el->name,
                              MAX_PROPS);
        rs_ply_prop *props = rs_ply_grow(el->props, (size_t)el->nprops, sizeof *props);
        if (!props) return rs_err_set(r->err, RS_ERR_SYSTEM, n, lineno, "out of memory");
        el->props = props;
        rs_ply_prop *p = &props[el->nprops++];
        memset(p, 0, sizeof *p); /* data is allocated when the element's data is read */
        strcpy(p->name, pname);
        p->type = type;
        p->is_list = is_list;
        p->count_type = count_type;
        return 0;
    }
    char shown[40];
    if (!has_end_header(r->rest, (const char *)r->end))
        return rs_err_set(r->err, RS_ERR_INPUT, n, lineno,
                          "the header has no 'end_header' line (found '%s' where a header line "
                          "was expected)",
                          printable(tok[0], strlen(tok[0]), shown, 33));
    return rs_err_set(r->err, RS_ERR_INPUT, n, lineno,
                      "unknown header line '%s' (expected format, comment, obj_info, element, "
                      "property or end_header)",
                      printable(tok[0], strlen(tok[0]), shown, 33));
}

/* Parses the header and leaves r->p at the first data byte. */
static int read_header(reader *r, rs_ply *ply)
{
    const char *p = (const char *)r->p, *end = (const char *)r->end;
    char *line = NULL;
    size_t line_cap = 0;
    int rc = -1;
    for (long lineno = 1;; lineno++) {
        if (p >= end && lineno == 1) {
            rs_err_set(r->err, RS_ERR_INPUT, r->name, 0,
                       "not a PLY file: expected 'ply' on the first line, found an empty file");
            goto out;
        }
        if (p >= end) {
            rs_err_set(r->err, RS_ERR_INPUT, r->name, lineno - 1,
                       "the header has no 'end_header' line (the file ends at header line %ld)", lineno - 1);
            goto out;
        }
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        size_t len = (size_t)((nl ? nl : end) - p);
        const char *next = nl ? nl + 1 : end;
        if (len && p[len - 1] == '\r') len--;
        if (lineno == 1) {
            if (len != 3 || memcmp(p, "ply", 3) != 0) {
                char shown[40];
                rs_err_set(r->err, RS_ERR_INPUT, r->name, 1,
                           "not a PLY file: expected 'ply' on the first line, found '%s'",
                           printable(p, len, shown, 17));
                goto out;
            }
            p = next;
            continue;
        }
        if (len + 1 > line_cap) {
            char *grown = realloc(line, len + 1);
            if (!grown) {
                rs_err_set(r->err, RS_ERR_SYSTEM, r->name, lineno, "out of memory");
                goto out;
            }
            line = grown;
            line_cap = len + 1;
        }
        memcpy(line, p, len);
        line[len] = '\0';
        p = next;
        size_t trimmed = len;
        while (trimmed && (line[trimmed - 1] == ' ' || line[trimmed - 1] == '\t')) trimmed--;
        if (trimmed == 10 && memcmp(line, "end_header", 10) == 0) {
            if (r->format == FMT_NONE) {
                rs_err_set(r->err, RS_ERR_INPUT, r->name, lineno, "no 'format' line before end_header");
                goto out;
            }
            r->p = (const unsigned char *)p;
            r->line = lineno + 1;
            rc = 0;
            goto out;
        }
        if (memchr(line, '\0', len)) {
            rs_err_set(r->err, RS_ERR_INPUT, r->name, lineno,
                       "a NUL byte in the header (expected text lines up to end_header)");
            goto out;
        }
        r->rest = p;
        if (header_line(r, ply, line, lineno)) goto out;
    }
out:
    free(line);
    return rc;
}

/* ---- data ---- */

static double load_binary(const unsigned char *p, rs_ply_type t, int swap)
{
    unsigned char b[8];
    size_t n = rs_ply_type_size[t];
    if (swap)
        for (size_t i = 0; i < n; i++) b[i] = p[n - 1 - i];
    else
        memcpy(b, p, n);
    switch (t) {
    case RS_PLY_INT8: {
        int8_t v;
        memcpy(&v, b, 1);
        return v;
    }
    case RS_PLY_UINT8: return b[0];
    case RS_PLY_INT16: {
        int16_t v;
        memcpy(&v, b, 2);
        return v;
    }
    case RS_PLY_UINT16: {
        uint16_t v;
        memcpy(&v, b, 2);
        return v;
    }
    case RS_PLY_INT32: {
        int32_t v;
        memcpy(&v, b, 4);
        return v;
    }
    case RS_PLY_UINT32: {
        uint32_t v;
        memcpy(&v, b, 4);
        return v;
    }
    case RS_PLY_FLOAT32: {
        float v;
        memcpy(&v, b, 4);
        return v;
    }
    case RS_PLY_FLOAT64: {
        double v;
        memcpy(&v, b, 8);
        return v;
    }
    }
    return 0.0;
}

static int truncated(reader *r, const rs_ply_element *el, size_t k, const rs_ply_prop *p)
{
    return rs_err_set(r->err, RS_ERR_INPUT, r->name, r->format == FMT_ASCII ? r->line : 0,
                      "element '%s' %zu, property '%s': data ends after %zu of %zu '%s' elements "
                      "(truncated file?)",
                      el->name, k, p->name, k, el->count, el->name);
}

/* Next whitespace-separated token into tok (NUL-terminated); 0 when the data has run out. */
static int next_token(reader *r, char *tok, size_t *len)
{
    const unsigned char *p = r->p, *end = r->end;
    while (p < end && (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r' || *p == '\v' || *p == '\f')) {
        if (*p == '\n') r->line++;
        p++;
    }
    size_t n = 0;
    while (p < end && !(*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r' || *p == '\v' || *p == '\f')) {
        if (n + 1 < TOKEN_MAX) tok[n] = (char)*p;
        n++;
        p++;
    }
    r->p = p;
    tok[n < TOKEN_MAX ? n : TOKEN_MAX - 1] = '\0';
    *len = n;
    return n > 0;
}

/* Reads one value of type t: from the binary data, or the next ascii token checked to be a
 * number that fits t. Returns 0, 1 when the data has run out, -1 on a bad token. */
static int read_value(reader *r, rs_ply_type t, double *v, const rs_ply_element *el, size_t k, const rs_ply_prop *p,
                      const char *what)
{
    if (r->format != FMT_ASCII) {
        if ((size_t)(r->end - r->p) < rs_ply_type_size[t]) return 1;
        *v = load_binary(r->p, t, r->swap);
        r->p += rs_ply_type_size[t];
        return 0;
    }
    char tok[TOKEN_MAX], shown[TOKEN_MAX];
    size_t len;
    if (!next_token(r, tok, &len)) return 1;
    char *endp;
    /* strtof for float properties, so that ascii and binary files give the same values. */
    *v = t == RS_PLY_FLOAT32 ? (double)strtof(tok, &endp) : strtod(tok, &endp);
    int ok = len < TOKEN_MAX && endp != tok && *endp == '\0';
    if (ok && rs_ply_type_is_int(t)) ok = *v == floor(*v) && *v >= rs_ply_type_min[t] && *v <= rs_ply_type_max[t];
    if (ok) return 0;
    if (rs_ply_type_is_int(t))
        rs_err_set(r->err, RS_ERR_INPUT, r->name, r->line,
                   "element '%s' %zu, property '%s': %sexpected an integer in %.0f..%.0f (%s), "
                   "found '%s'",
                   el->name, k, p->name, what, rs_ply_type_min[t], rs_ply_type_max[t], rs_ply_type_name[t],
                   printable(tok, strlen(tok), shown, 33));
    else
        rs_err_set(r->err, RS_ERR_INPUT, r->name, r->line,
                   "element '%s' %zu, property '%s': %sexpected a number (%s), found '%s'", el->name, k, p->name, what,
                   rs_ply_type_name[t], printable(tok, strlen(tok), shown, 33));
    return -1;
}

/* The most items that can follow in the remaining data: binary item_size bytes each, ascii at
 * least two bytes (a digit and a separator) each except the last. */
static size_t max_items(const reader *r, size_t item_size)
{
    size_t left = (size_t)(r->end - r->p);
    return r->format == FMT_ASCII ? (left + 1) / 2 : left / item_size;
}

static int read_element(reader *r, rs_ply_element *el)
{
    size_t min_record = 0, cap = el->count, *list_cap = NULL;
    int rc = -1;
    if (el->nprops == 0) return 0;
    for (int i = 0; i < el->nprops; i++) {
        const rs_ply_prop *p = &el->props[i];
        min_record += r->format == FMT_ASCII ? 1 : rs_ply_type_size[p->is_list ? p->count_type : p->type];
    }
    /* A count the remaining data cannot hold fails while reading record max + 1 at the latest:
     * allocate only that much, so that a huge count in a garbage header allocates nothing big. */
    size_t fit = max_items(r, min_record > 0 ? min_record : 1);
    if (r->format == FMT_ASCII) fit /= min_record;
    if (cap > fit) cap = fit + 1;
    if (!(list_cap = calloc((size_t)el->nprops, sizeof *list_cap))) goto oom;
    for (int i = 0; i < el->nprops; i++) {
        rs_ply_prop *p = &el->props[i];
        if (!(p->data = calloc(cap ? cap : 1, sizeof(double)))) goto oom;
        list_cap[i] = cap ? cap : 1;
        if (p->is_list && !(p->offsets = calloc(cap + 1, sizeof(size_t)))) goto oom;
    }
    for (size_t k = 0; k < el->count; k++) {
        for (int i = 0; i < el->nprops; i++) {
            rs_ply_prop *p = &el->props[i];
            double v;
            int st;
            if (k >= cap) { /* cannot happen (see above); kept so garbage can never overflow */
                truncated(r, el, k, p);
                goto out;
            }
            if (!p->is_list) {
                if ((st = read_value(r, p->type, &v, el, k, p, ""))) {
                    if (st > 0) truncated(r, el, k, p);
                    goto out;
                }
                p->data[k] = v;
                continue;
            }
            if ((st = read_value(r, p->count_type, &v, el, k, p, "list count: "))) {
                if (st > 0) truncated(r, el, k, p);
                goto out;
            }
            if (v < 0) {
                rs_err_set(r->err, RS_ERR_INPUT, r->name, r->line * (r->format == FMT_ASCII),
                           "element '%s' %zu, list '%s': negative item count %.0f (expected 0 or "
                           "more)",
                           el->name, k, p->name, v);
                goto out;
            }
            size_t n = (size_t)v, at = p->offsets[k];
            if (n > max_items(r, rs_ply_type_size[p->type])) {
                rs_err_set(r->err, RS_ERR_INPUT, r->name, r->line * (r->format == FMT_ASCII),
                           "element '%s' %zu, list '%s': %zu items announced, but the data ends "
                           "after %zu of %zu '%s' elements (truncated file or bad count?)",
                           el->name, k, p->name, n, k, el->count, el->name);
                goto out;
            }
            if (at + n > list_cap[i]) {
                size_t grown = list_cap[i] * 2 > at + n ? list_cap[i] * 2 : at + n;
                double *d = realloc(p->data, grown * sizeof(double));
                if (!d) goto oom;
                p->data = d;
                list_cap[i] = grown;
            }
            for (size_t j = 0; j < n; j++) {
                if ((st = read_value(r, p->type, &v, el, k, p, "list item: "))) {
                    if (st > 0) truncated(r, el, k, p);
                    goto out;
                }
                p->data[at + j] = v;
            }
            p->offsets[k + 1] = at + n;
        }
    }
    rc = 0;
    goto out;
oom:
    rs_err_set(r->err, RS_ERR_SYSTEM, r->name, 0, "element '%s': out of memory for %zu records", el->name, cap);
out:
    free(list_cap);
    return rc;
}

rs_ply *rs_ply_read_mem(const char *data, size_t size, const char *name, rs_err *err)
{
    const uint16_t one = 1;
    unsigned char host_little;
    memcpy(&host_little, &one, 1);
    reader r = {.name = name ? name : "<memory>", .err = err};
    r.p = (const unsigned char *)(data ? data : "");
    r.end = r.p + (data ? size : 0);
    rs_ply *ply = rs_ply_new();
    if (!ply) {
        rs_err_set(err, RS_ERR_SYSTEM, r.name, 0, "out of memory");
        return NULL;
    }
    if (read_header(&r, ply)) goto fail;
    r.swap = (r.format == FMT_BINARY_LE) != (host_little == 1) && r.format != FMT_ASCII;
    for (int e = 0; e < ply->nelements; e++)
        if (read_element(&r, &ply->elements[e])) goto fail;
    return ply; /* whatever follows the last element is ignored */
fail:
    rs_ply_free(ply);
    return NULL;
}

rs_ply *rs_ply_read(const char *path, rs_err *err)
{
    char *data = NULL;
    size_t size = 0;
    if (rs_read_file(path, &data, &size, err)) return NULL;
    rs_ply *ply = rs_ply_read_mem(data, size, path, err);
    free(data);
    return ply;
}

/* ---- record by record (rs_ply_read_records) ---- */

#define HEAD_MAX    ((size_t)1 << 20) /* a header longer than this is read the whole-file way */
#define BLOCK_BYTES ((size_t)1 << 20)

static int has_lists(const rs_ply_element *el)
{
    for (int i = 0; i < el->nprops; i++)
        if (el->props[i].is_list) return 1;
    return 0;
}

/* The fallback: the whole file in memory, then its scalar elements handed over and dropped;
 * elements with lists keep their data in the header. */
static int records_whole(const char *path, rs_ply_record_fn fn, void *ctx, rs_ply **header, rs_err *err)
{
    rs_ply *ply = rs_ply_read(path, err);
    if (!ply) return -1;
    int rc = 0;
    for (int e = 0; e < ply->nelements && rc == 0; e++) {
        rs_ply_element *el = &ply->elements[e];
        if (el->nprops == 0 || has_lists(el)) continue;
        double *v = malloc((size_t)el->nprops * sizeof *v);
        if (!v) {
            rc = rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
            break;
        }
        for (size_t k = 0; k < el->count && rc == 0; k++) {
            for (int i = 0; i < el->nprops; i++) v[i] = el->props[i].data[k];
            rc = fn(ctx, el, k, v, err);
        }
        free(v);
        for (int i = 0; i < el->nprops; i++) {
            free(el->props[i].data);
            el->props[i].data = NULL;
        }
    }
    if (rc == 0 && header)
        *header = ply;
    else
        rs_ply_free(ply);
    return rc;
}

/* One binary element of scalars, read in blocks of records and decoded into doubles. */
static int records_binary(reader *r, FILE *fp, rs_ply_element *el, size_t *left, rs_ply_record_fn fn, void *ctx)
{
    size_t rec = 0;
    for (int i = 0; i < el->nprops; i++) rec += rs_ply_type_size[el->props[i].type];
    if (rec == 0 || el->count == 0) return 0;
    if (el->count > *left / rec) { /* the same message as the whole-file reader's */
        size_t k = *left / rec, rem = *left - k * rec, i = 0, at = 0;
        while (at + rs_ply_type_size[el->props[i].type] <= rem) at += rs_ply_type_size[el->props[i++].type];
        return truncated(r, el, k, &el->props[i]);
    }
    size_t per_block = BLOCK_BYTES / rec ? BLOCK_BYTES / rec : 1;
    unsigned char *block = malloc(per_block * rec);
    double *v = malloc((size_t)el->nprops * sizeof *v);
    int rc = 0;
    if (!block || !v) rc = rs_err_set(r->err, RS_ERR_SYSTEM, r->name, 0, "out of memory");
    for (size_t k0 = 0; rc == 0 && k0 < el->count; k0 += per_block) {
        size_t n = el->count - k0 < per_block ? el->count - k0 : per_block;
        if (fread(block, rec, n, fp) != n) {
            rc = rs_err_errno(r->err, r->name, "read failed");
            break;
        }
        const unsigned char *p = block;
        for (size_t k = 0; k < n && rc == 0; k++) {
            for (int i = 0; i < el->nprops; i++) {
                v[i] = load_binary(p, el->props[i].type, r->swap);
                p += rs_ply_type_size[el->props[i].type];
            }
            rc = fn(ctx, el, k0 + k, v, r->err);
        }
    }
    *left -= el->count * rec;
    free(block);
    free(v);
    return rc;
}

int rs_ply_read_records(const char *path, rs_ply_record_fn fn, void *ctx, rs_ply **header, rs_err *err)
{
    if (header) *header = NULL;
    FILE *fp = fopen(path, "rb");
    if (!fp) return rs_err_errno(err, path, "cannot open");
    struct stat st;
    if (fstat(fileno(fp), &st) != 0 || !S_ISREG(st.st_mode)) {
        fclose(fp);
        return rs_err_set(err, RS_ERR_INPUT, path, 0, "not a regular file");
    }
    size_t size = (size_t)st.st_size, head = size < HEAD_MAX ? size : HEAD_MAX;
    unsigned char *buf = malloc(head + 1);
    rs_ply *ply = rs_ply_new();
    if (!buf || !ply) {
        free(buf);
        rs_ply_free(ply);
        fclose(fp);
        return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
    }
    /* The header from the first block; anything unusual (a bad header, ascii, lists) goes the
     * whole-file way, whose reader gives the messages. */
    rs_err quiet = {0};
    reader r = {.name = path, .err = &quiet, .p = buf, .end = buf + head};
    int stream = head == 0 || fread(buf, 1, head, fp) == head;
    stream = stream && read_header(&r, ply) == 0 && r.format != FMT_ASCII;
    for (int e = 0; stream && e < ply->nelements; e++) stream = !has_lists(&ply->elements[e]);
    size_t offset = (size_t)(r.p - buf);
    free(buf);
    if (!stream || fseeko(fp, (off_t)offset, SEEK_SET) != 0) {
        rs_ply_free(ply);
        fclose(fp);
        return records_whole(path, fn, ctx, header, err);
    }
    const uint16_t one = 1;
    unsigned char host_little;
    memcpy(&host_little, &one, 1);
    r.swap = (r.format == FMT_BINARY_LE) != (host_little == 1);
    r.err = err;
    size_t left = size - offset;
    int rc = 0;
    for (int e = 0; e < ply->nelements && rc == 0; e++) rc = records_binary(&r, fp, &ply->elements[e], &left, fn, ctx);
    fclose(fp);
    if (rc == 0 && header)
        *header = ply;
    else
        rs_ply_free(ply);
    return rc;
}
