/* json: a small ordered JSON tree and its writer (see json.h). */
#include "common/json.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/fileio.h"

typedef enum { J_NULL, J_NUM, J_INT, J_STR, J_BOOL, J_RAW, J_OBJ, J_ARR } j_kind;

struct rs_json {
    j_kind kind;
    char *key; /* member name inside an object */
    double num;
    long long inum;
    char *str;             /* J_STR, J_RAW */
    rs_json *first, *last; /* children of J_OBJ / J_ARR */
    rs_json *next;
};

static rs_json *j_new(j_kind kind)
{
    rs_json *j = calloc(1, sizeof *j);
    if (j) j->kind = kind;
    return j;
}

rs_json *rs_json_object(void)
{
    return j_new(J_OBJ);
}
rs_json *rs_json_array(void)
{
    return j_new(J_ARR);
}

void rs_json_free(rs_json *j)
{
    while (j) {
        rs_json *next = j->next;
        rs_json_free(j->first);
        free(j->key);
        free(j->str);
        free(j);
        j = next;
    }
}

static void j_append(rs_json *parent, rs_json *child)
{
    if (parent->last)
        parent->last->next = child;
    else
        parent->first = child;
    parent->last = child;
}

rs_json *rs_json_get(const rs_json *obj, const char *key)
{
    if (!obj || obj->kind != J_OBJ) return NULL;
    for (rs_json *c = obj->first; c; c = c->next)
        if (strcmp(c->key, key) == 0) return c;
    return NULL;
}

/* Adds (or replaces in place, keeping the order) the member key of obj. */
static rs_json *j_set(rs_json *obj, const char *key, j_kind kind)
{
    if (!obj || obj->kind != J_OBJ) return NULL;
    rs_json *c = rs_json_get(obj, key);
    if (c) {
        rs_json_free(c->first);
        free(c->str);
        c->first = c->last = NULL;
        c->str = NULL;
        c->kind = kind;
        return c;
    }
    c = j_new(kind);
    if (!c) return NULL;
    c->key = strdup(key);
    j_append(obj, c);
    return c;
}

static rs_json *j_push(rs_json *arr, j_kind kind)
{
    if (!arr || arr->kind != J_ARR) return NULL;
    rs_json *c = j_new(kind);
    if (c) j_append(arr, c);
    return c;
}

rs_json *rs_json_set_num(rs_json *obj, const char *key, double v)
{
    rs_json *c = j_set(obj, key, J_NUM);
    if (c) c->num = v;
    return c;
}

rs_json *rs_json_set_int(rs_json *obj, const char *key, long long v)
{
    rs_json *c = j_set(obj, key, J_INT);
    if (c) c->inum = v;
    return c;
}

rs_json *rs_json_set_str(rs_json *obj, const char *key, const char *s)
{
    rs_json *c = j_set(obj, key, J_STR);
    if (c) c->str = strdup(s ? s : "");
    return c;
}

rs_json *rs_json_set_bool(rs_json *obj, const char *key, int b)
{
    rs_json *c = j_set(obj, key, J_BOOL);
    if (c) c->inum = b != 0;
    return c;
}

rs_json *rs_json_set_raw(rs_json *obj, const char *key, const char *json_text)
{
    rs_json *c = j_set(obj, key, J_RAW);
    if (c) c->str = strdup(json_text);
    return c;
}

rs_json *rs_json_set_obj(rs_json *obj, const char *key)
{
    return j_set(obj, key, J_OBJ);
}
rs_json *rs_json_set_arr(rs_json *obj, const char *key)
{
    return j_set(obj, key, J_ARR);
}

rs_json *rs_json_push_num(rs_json *arr, double v)
{
    rs_json *c = j_push(arr, J_NUM);
    if (c) c->num = v;
    return c;
}

rs_json *rs_json_push_str(rs_json *arr, const char *s)
{
    rs_json *c = j_push(arr, J_STR);
    if (c) c->str = strdup(s ? s : "");
    return c;
}

rs_json *rs_json_push_obj(rs_json *arr)
{
    return j_push(arr, J_OBJ);
}

typedef struct {
    char *buf;
    size_t len, cap;
    int oom;
} j_buf;

static void jb_put(j_buf *b, const char *s, size_t n)
{
    if (b->oom) return;
    if (b->len + n + 1 > b->cap) {
        size_t cap = b->cap ? b->cap : 256;
        while (cap < b->len + n + 1) cap *= 2;
        char *nb = realloc(b->buf, cap);
        if (!nb) {
            b->oom = 1;
            return;
        }
        b->buf = nb;
        b->cap = cap;
    }
    memcpy(b->buf + b->len, s, n);
    b->len += n;
    b->buf[b->len] = 0;
}

static void jb_str(j_buf *b, const char *s)
{
    jb_put(b, s, strlen(s));
}

static void jb_quoted(j_buf *b, const char *s)
{
    jb_put(b, "\"", 1);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        char esc[8];
        if (c == '"' || c == '\\') {
            esc[0] = '\\';
            esc[1] = (char)c;
            jb_put(b, esc, 2);
        } else if (c == '\n') {
            jb_str(b, "\\n");
        } else if (c < 0x20) {
            snprintf(esc, sizeof esc, "\\u%04x", c);
            jb_str(b, esc);
        } else {
            jb_put(b, (const char *)&c, 1);
        }
    }
    jb_put(b, "\"", 1);
}

static void jb_indent(j_buf *b, int depth)
{
    for (int i = 0; i < depth; i++) jb_put(b, "  ", 2);
}

static void j_write(j_buf *b, const rs_json *j, int depth)
{
    char num[64];
    switch (j->kind) {
    case J_NULL: jb_str(b, "null"); break;
    case J_NUM:
        if (!isfinite(j->num))
            jb_str(b, "null");
        else {
            snprintf(num, sizeof num, "%.10g", j->num);
            jb_str(b, num);
        }
        break;
    case J_INT:
        snprintf(num, sizeof num, "%lld", j->inum);
        jb_str(b, num);
        break;
    case J_BOOL: jb_str(b, j->inum ? "true" : "false"); break;
    case J_STR: jb_quoted(b, j->str); break;
    case J_RAW: jb_str(b, j->str); break;
    case J_OBJ:
    case J_ARR: {
        int obj = j->kind == J_OBJ;
        if (!j->first) {
            jb_str(b, obj ? "{}" : "[]");
            break;
        }
        jb_str(b, obj ? "{\n" : "[\n");
        for (const rs_json *c = j->first; c; c = c->next) {
            jb_indent(b, depth + 1);
            if (obj) {
                jb_quoted(b, c->key);
                jb_str(b, ": ");
            }
            j_write(b, c, depth + 1);
            jb_str(b, c->next ? ",\n" : "\n");
        }
        jb_indent(b, depth);
        jb_str(b, obj ? "}" : "]");
        break;
    }
    }
}

char *rs_json_text(const rs_json *j)
{
    j_buf b = {0};
    j_write(&b, j, 0);
    jb_str(&b, "\n");
    if (b.oom) {
        free(b.buf);
        return NULL;
    }
    return b.buf;
}

int rs_json_write(const rs_json *j, const char *path, rs_err *err)
{
    char *text = rs_json_text(j);
    if (!text) return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory formatting JSON");
    int rc = rs_write_file_atomic(path, text, strlen(text), err);
    free(text);
    return rc;
}
