/* ply: the in-memory PLY model (builders, look-ups, free) and the writer (ascii and binary
 * little endian, buffered through an atomic file). The reader is in ply_read.c. */
#include "common/ply.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/fileio.h"
#include "common/ply_internal.h"

const size_t rs_ply_type_size[RS_PLY_NTYPES] = {1, 1, 2, 2, 4, 4, 4, 8};
const char *const rs_ply_type_name[RS_PLY_NTYPES] = {"char", "uchar", "short", "ushort",
                                                     "int",  "uint",  "float", "double"};
const double rs_ply_type_min[RS_PLY_NTYPES] = {-128.0, 0.0, -32768.0, 0.0, -2147483648.0, 0.0, -FLT_MAX, -DBL_MAX};
const double rs_ply_type_max[RS_PLY_NTYPES] = {127.0,        255.0,        32767.0, 65535.0,
                                               2147483647.0, 4294967295.0, FLT_MAX, DBL_MAX};

int rs_ply_type_valid(int type)
{
    return type >= RS_PLY_INT8 && type <= RS_PLY_FLOAT64;
}
int rs_ply_type_is_int(rs_ply_type type)
{
    return type <= RS_PLY_UINT32;
}

void *rs_ply_grow(void *arr, size_t n, size_t item_size)
{
    if (n != 0 && (n & (n - 1)) != 0) return arr; /* capacity is the next power of two >= n */
    size_t cap = n ? 2 * n : 1;
    if (cap > SIZE_MAX / item_size) return NULL;
    return realloc(arr, cap * item_size);
}

/* ---- model ---- */

rs_ply *rs_ply_new(void)
{
    return calloc(1, sizeof(rs_ply));
}

void rs_ply_free(rs_ply *ply)
{
    if (!ply) return;
    for (int e = 0; e < ply->nelements; e++) {
        rs_ply_element *el = &ply->elements[e];
        for (int p = 0; p < el->nprops; p++) {
            free(el->props[p].data);
            free(el->props[p].offsets);
        }
        free(el->props);
    }
    free(ply->elements);
    for (int c = 0; c < ply->ncomments; c++) free(ply->comments[c]);
    free(ply->comments);
    free(ply);
}

static int name_ok(const char *name)
{
    return name && name[0] && strlen(name) < sizeof(((rs_ply_prop *)0)->name);
}

rs_ply_element *rs_ply_add_element(rs_ply *ply, const char *name, size_t count)
{
    if (!ply || !name_ok(name) || rs_ply_find_element(ply, name)) return NULL;
    rs_ply_element *els = rs_ply_grow(ply->elements, (size_t)ply->nelements, sizeof *els);
    if (!els) return NULL;
    ply->elements = els;
    rs_ply_element *el = &els[ply->nelements++];
    memset(el, 0, sizeof *el);
    strcpy(el->name, name);
    el->count = count;
    return el;
}

/* A zeroed property slot at the end of el->props; the caller fills it and counts it. */
static rs_ply_prop *new_prop(rs_ply_element *el, const char *name, rs_ply_type type)
{
    if (!el || !name_ok(name) || !rs_ply_type_valid((int)type) || rs_ply_find_prop(el, name)) return NULL;
    rs_ply_prop *props = rs_ply_grow(el->props, (size_t)el->nprops, sizeof *props);
    if (!props) return NULL;
    el->props = props;
    rs_ply_prop *p = &props[el->nprops];
    memset(p, 0, sizeof *p);
    strcpy(p->name, name);
    p->type = type;
    return p;
}

static double *alloc_values(size_t n)
{
    if (n > SIZE_MAX / sizeof(double)) return NULL;
    return calloc(n ? n : 1, sizeof(double));
}

rs_ply_prop *rs_ply_add_scalar(rs_ply_element *el, const char *name, rs_ply_type type, const double *values)
{
    rs_ply_prop *p = new_prop(el, name, type);
    if (!p || !(p->data = alloc_values(el->count))) return NULL;
    if (values && el->count) memcpy(p->data, values, el->count * sizeof(double));
    el->nprops++;
    return p;
}

rs_ply_prop *rs_ply_declare_scalar(rs_ply_element *el, const char *name, rs_ply_type type)
{
    rs_ply_prop *p = new_prop(el, name, type);
    if (!p) return NULL;
    el->nprops++;
    return p;
}

rs_ply_prop *rs_ply_add_scalar_f(rs_ply_element *el, const char *name, rs_ply_type type, const float *values)
{
    rs_ply_prop *p = new_prop(el, name, type);
    if (!p || !(p->data = alloc_values(el->count))) return NULL;
    if (values)
        for (size_t k = 0; k < el->count; k++) p->data[k] = values[k];
    el->nprops++;
    return p;
}

rs_ply_prop *rs_ply_add_list_fixed(rs_ply_element *el, const char *name, rs_ply_type count_type, rs_ply_type item_type,
                                   int n, const double *items)
{
    if (n < 0 || !rs_ply_type_valid((int)count_type) || !rs_ply_type_is_int(count_type) ||
        (double)n > rs_ply_type_max[count_type])
        return NULL;
    rs_ply_prop *p = new_prop(el, name, item_type);
    if (!p) return NULL;
    size_t count = el->count;
    if (n && count > SIZE_MAX / sizeof(double) / (size_t)n) return NULL;
    if (count >= SIZE_MAX / sizeof(size_t)) return NULL;
    p->data = alloc_values(count * (size_t)n);
    p->offsets = malloc((count + 1) * sizeof(size_t));
    if (!p->data || !p->offsets) {
        free(p->data);
        free(p->offsets);
        return NULL;
    }
    p->is_list = 1;
    p->count_type = count_type;
    for (size_t k = 0; k <= count; k++) p->offsets[k] = k * (size_t)n;
    if (items && count && n) memcpy(p->data, items, count * (size_t)n * sizeof(double));
    el->nprops++;
    return p;
}

int rs_ply_add_comment(rs_ply *ply, const char *fmt, ...)
{
    if (!ply || !fmt) return -1;
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (n < 0) return -1;
    char *s = malloc((size_t)n + 1);
    char **comments = rs_ply_grow(ply->comments, (size_t)ply->ncomments, sizeof *comments);
    if (!s || !comments) {
        free(s);
        return -1;
    }
    ply->comments = comments;
    va_start(ap, fmt);
    vsnprintf(s, (size_t)n + 1, fmt, ap);
    va_end(ap);
    ply->comments[ply->ncomments++] = s;
    return 0;
}

rs_ply_element *rs_ply_find_element(const rs_ply *ply, const char *name)
{
    if (!ply || !name) return NULL;
    for (int e = 0; e < ply->nelements; e++)
        if (strcmp(ply->elements[e].name, name) == 0) return &ply->elements[e];
    return NULL;
}

rs_ply_prop *rs_ply_find_prop(const rs_ply_element *el, const char *name)
{
    if (!el || !name) return NULL;
    for (int p = 0; p < el->nprops; p++)
        if (strcmp(el->props[p].name, name) == 0) return &el->props[p];
    return NULL;
}

const char *rs_ply_find_comment(const rs_ply *ply, const char *key)
{
    if (!ply || !key || !key[0]) return NULL;
    size_t n = strlen(key);
    for (int c = 0; c < ply->ncomments; c++) {
        const char *s = ply->comments[c];
        if (strncmp(s, key, n) != 0 || (s[n] != '\0' && s[n] != ' ' && s[n] != '\t')) continue;
        s += n;
        while (*s == ' ' || *s == '\t') s++;
        return s;
    }
    return NULL;
}

/* ---- writer ---- */

#define OUT_CAP (1u << 20)

/* Output buffered in 1 MiB chunks: files have millions of faces. */
typedef struct {
    rs_atomic_file f;
    unsigned char *buf;
    size_t len;
    rs_err *err;
} out_buf;

static int out_flush(out_buf *o)
{
    if (o->len && rs_atomic_write(&o->f, o->buf, o->len, o->err) != 0) return -1;
    o->len = 0;
    return 0;
}

/* Makes room for n <= OUT_CAP bytes at o->buf + o->len. */
static int out_room(out_buf *o, size_t n)
{
    return o->len + n > OUT_CAP ? out_flush(o) : 0;
}

static int out_str(out_buf *o, const char *s)
{
    size_t n = strlen(s);
    if (n > OUT_CAP) return out_flush(o) || rs_atomic_write(&o->f, s, n, o->err);
    if (out_room(o, n)) return -1;
    memcpy(o->buf + o->len, s, n);
    o->len += n;
    return 0;
}

/* Rounds integers (half away from zero) and saturates every type to its range; NaN becomes 0
 * for integers. Float infinities and NaN are kept. */
static double convert(double v, rs_ply_type t)
{
    if (t == RS_PLY_FLOAT64) return v;
    if (isnan(v)) return rs_ply_type_is_int(t) ? 0.0 : v;
    if (rs_ply_type_is_int(t))
        v = round(v);
    else if (isinf(v))
        return v;
    if (v < rs_ply_type_min[t]) return rs_ply_type_min[t];
    if (v > rs_ply_type_max[t]) return rs_ply_type_max[t];
    return t == RS_PLY_FLOAT32 ? (double)(float)v : v;
}

/* Room for the longest value text: "%.17g" of a double is at most 24 characters. */
#define VALUE_TEXT_MAX 32

static void put_ascii(out_buf *o, double v, rs_ply_type t, char sep)
{
    char *s = (char *)o->buf + o->len;
    int n;
    v = convert(v, t);
    if (t == RS_PLY_FLOAT32)
        n = snprintf(s, VALUE_TEXT_MAX, "%.9g", v);
    else if (t == RS_PLY_FLOAT64)
        n = snprintf(s, VALUE_TEXT_MAX, "%.17g", v);
    else
        n = snprintf(s, VALUE_TEXT_MAX, "%lld", (long long)v);
    s[n] = sep;
    o->len += (size_t)n + 1;
}

static void put_binary(out_buf *o, double v, rs_ply_type t)
{
    uint64_t bits;
    v = convert(v, t);
    if (t == RS_PLY_FLOAT32) {
        float f = (float)v;
        uint32_t u;
        memcpy(&u, &f, 4);
        bits = u;
    } else if (t == RS_PLY_FLOAT64) {
        memcpy(&bits, &v, 8);
    } else {
        bits = (uint64_t)(int64_t)v; /* two's complement: the low bytes are right for each type */
    }
    unsigned char *p = o->buf + o->len;
    for (size_t i = 0; i < rs_ply_type_size[t]; i++) p[i] = (unsigned char)(bits >> (8 * i));
    o->len += rs_ply_type_size[t];
}

static int name_writable(const char *name)
{
    if (!memchr(name, '\0', 64) || !name[0]) return 0;
    for (const char *c = name; *c; c++)
        if (*c == ' ' || *c == '\t' || *c == '\n' || *c == '\r') return 0;
    return 1;
}

/* An element whose values come from a record callback: properties declared without data. */
static int is_streamed(const rs_ply_element *el)
{
    return el->nprops > 0 && !el->props[0].data && !el->props[0].is_list;
}

/* Checks what the header cannot say: names with spaces, list counts beyond the count type;
 * with a record callback (streaming), that streamed elements hold declared scalars only. */
static int check_writable(const rs_ply *ply, const char *path, int streaming, rs_err *err)
{
    for (int e = 0; e < ply->nelements; e++) {
        const rs_ply_element *el = &ply->elements[e];
        if (!name_writable(el->name))
            return rs_err_set(err, RS_ERR_INTERNAL, path, 0, "element %d: name must be 1..63 characters without spaces",
                              e);
        int streamed = streaming && is_streamed(el);
        for (int i = 0; i < el->nprops; i++) {
            const rs_ply_prop *p = &el->props[i];
            if (!name_writable(p->name) || !rs_ply_type_valid((int)p->type))
                return rs_err_set(err, RS_ERR_INTERNAL, path, 0, "element '%s' property %d: bad name or type", el->name,
                                  i);
            if (streamed) {
                if (p->data || p->is_list)
                    return rs_err_set(err, RS_ERR_INTERNAL, path, 0,
                                      "element '%s' property '%s': a streamed "
                                      "element takes declared scalar properties only",
                                      el->name, p->name);
                continue;
            }
            if (el->count && !p->data && (!p->is_list || !p->offsets))
                return rs_err_set(err, RS_ERR_INTERNAL, path, 0, "element '%s' property '%s': no data", el->name,
                                  p->name);
            if (!p->is_list) continue;
            if (!p->offsets || !rs_ply_type_valid((int)p->count_type) || !rs_ply_type_is_int(p->count_type))
                return rs_err_set(err, RS_ERR_INTERNAL, path, 0,
                                  "element '%s' list '%s': needs offsets and an integer count type", el->name, p->name);
            for (size_t k = 0; k < el->count; k++) {
                if (p->offsets[k + 1] < p->offsets[k] ||
                    (double)(p->offsets[k + 1] - p->offsets[k]) > rs_ply_type_max[p->count_type])
                    return rs_err_set(err, RS_ERR_INPUT, path, 0,
                                      "element '%s' %zu: list '%s' has %zu items, more than its "
                                      "count type %s can hold",
                                      el->name, k, p->name, p->offsets[k + 1] - p->offsets[k],
                                      rs_ply_type_name[p->count_type]);
            }
        }
    }
    return 0;
}

static int write_header(out_buf *o, const rs_ply *ply, int binary)
{
    char line[256];
    if (out_str(o, binary ? "ply\nformat binary_little_endian 1.0\n" : "ply\nformat ascii 1.0\n")) return -1;
    for (int c = 0; c < ply->ncomments; c++) {
        if (out_str(o, "comment ")) return -1;
        /* A line break inside a comment would end the header line early. */
        for (const char *s = ply->comments[c]; *s; s++) {
            if (out_room(o, 1)) return -1;
            o->buf[o->len++] = (unsigned char)(*s == '\n' || *s == '\r' ? ' ' : *s);
        }
        if (out_str(o, "\n")) return -1;
    }
    for (int e = 0; e < ply->nelements; e++) {
        const rs_ply_element *el = &ply->elements[e];
        snprintf(line, sizeof line, "element %s %zu\n", el->name, el->count);
        if (out_str(o, line)) return -1;
        for (int i = 0; i < el->nprops; i++) {
            const rs_ply_prop *p = &el->props[i];
            if (p->is_list)
                snprintf(line, sizeof line, "property list %s %s %s\n", rs_ply_type_name[p->count_type],
                         rs_ply_type_name[p->type], p->name);
            else
                snprintf(line, sizeof line, "property %s %s\n", rs_ply_type_name[p->type], p->name);
            if (out_str(o, line)) return -1;
        }
    }
    return out_str(o, "end_header\n");
}

/* Records from the callback: one values array, reused, so nothing grows with the count. */
static int write_streamed(out_buf *o, const rs_ply_element *el, int binary, rs_ply_record_fn fn, void *ctx)
{
    double *v = malloc((size_t)el->nprops * sizeof *v);
    if (!v) return rs_err_set(o->err, RS_ERR_SYSTEM, NULL, 0, "out of memory writing element '%s'", el->name);
    int rc = 0;
    for (size_t k = 0; k < el->count && rc == 0; k++) {
        if ((rc = fn(ctx, el, k, v, o->err)) != 0) break;
        for (int i = 0; i < el->nprops && rc == 0; i++) {
            if ((rc = out_room(o, VALUE_TEXT_MAX)) != 0) break;
            if (binary)
                put_binary(o, v[i], el->props[i].type);
            else
                put_ascii(o, v[i], el->props[i].type, i + 1 < el->nprops ? ' ' : '\n');
        }
    }
    free(v);
    return rc;
}

static int write_element(out_buf *o, const rs_ply_element *el, int binary)
{
    for (size_t k = 0; k < el->count; k++) {
        for (int i = 0; i < el->nprops; i++) {
            const rs_ply_prop *p = &el->props[i];
            char sep = i + 1 < el->nprops ? ' ' : '\n';
            if (!p->is_list) {
                if (out_room(o, VALUE_TEXT_MAX)) return -1;
                if (binary)
                    put_binary(o, p->data[k], p->type);
                else
                    put_ascii(o, p->data[k], p->type, sep);
                continue;
            }
            size_t first = p->offsets[k], n = p->offsets[k + 1] - first;
            if (out_room(o, VALUE_TEXT_MAX)) return -1;
            if (binary)
                put_binary(o, (double)n, p->count_type);
            else
                put_ascii(o, (double)n, p->count_type, n ? ' ' : sep);
            for (size_t j = 0; j < n; j++) {
                if (out_room(o, VALUE_TEXT_MAX)) return -1;
                if (binary)
                    put_binary(o, p->data[first + j], p->type);
                else
                    put_ascii(o, p->data[first + j], p->type, j + 1 < n ? ' ' : sep);
            }
        }
    }
    return 0;
}

static int write_ply(const rs_ply *ply, const char *path, int binary, rs_ply_record_fn fn, void *ctx, rs_err *err)
{
    if (!ply || !path) return rs_err_set(err, RS_ERR_INTERNAL, path, 0, "rs_ply_write: no ply or path");
    if (check_writable(ply, path, fn != NULL, err)) return -1;
    out_buf o = {.err = err};
    if (!(o.buf = malloc(OUT_CAP)))
        return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory for the output buffer");
    if (rs_atomic_open(&o.f, path, err)) {
        free(o.buf);
        return -1;
    }
    int rc = write_header(&o, ply, binary);
    for (int e = 0; rc == 0 && e < ply->nelements; e++)
        rc = fn && is_streamed(&ply->elements[e]) ? write_streamed(&o, &ply->elements[e], binary, fn, ctx)
                                                  : write_element(&o, &ply->elements[e], binary);
    if (rc == 0) rc = out_flush(&o);
    if (rc == 0) rc = rs_atomic_commit(&o.f, err);
    if (rc != 0) rs_atomic_abort(&o.f);
    free(o.buf);
    return rc;
}

int rs_ply_write(const rs_ply *ply, const char *path, int binary, rs_err *err)
{
    return write_ply(ply, path, binary, NULL, NULL, err);
}

int rs_ply_write_records(const rs_ply *ply, const char *path, int binary, rs_ply_record_fn fn, void *ctx, rs_err *err)
{
    if (!fn) return rs_err_set(err, RS_ERR_INTERNAL, path, 0, "rs_ply_write_records: no record callback");
    return write_ply(ply, path, binary, fn, ctx, err);
}
