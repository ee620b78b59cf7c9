/* e57_xml: the E57 XML section (ASTM E2807, section 8) parsed by libexpat into a tree of typed
 * elements, and the queries the reader makes of it. Namespace prefixes are kept in the names
 * ("nor:normalX"): extensions are recognised by their usual prefix and otherwise ignored. */
#include "common/e57_internal.h"

#include <errno.h>
#include <expat.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "common/vec.h"

#define E57_MAX_DEPTH 64

typedef struct xml_state {
    XML_Parser parser;
    e57_node *root, *cur;
    int depth;
    int failed; /* out of memory or too deep (err set) */
    const char *file;
    rs_err *err;
} xml_state;

static const struct {
    const char *name;
    e57_type type;
} types[] = {{"Structure", E57_T_STRUCT},
             {"Vector", E57_T_VECTOR},
             {"CompressedVector", E57_T_CVECTOR},
             {"Integer", E57_T_INTEGER},
             {"ScaledInteger", E57_T_SCALED},
             {"Float", E57_T_FLOAT},
             {"String", E57_T_STRING},
             {"Blob", E57_T_BLOB}};

static void node_free(e57_node *n)
{
    while (n) {
        e57_node *next = n->next;
        node_free(n->child);
        free(n->name);
        free(n->text);
        if (n->attrs)
            for (char **a = n->attrs; *a; a++) free(*a);
        free(n->attrs);
        free(n);
        n = next;
    }
}

void e57_xml_free(e57_node *root)
{
    node_free(root);
}

static void fail(xml_state *s, rs_err_kind kind, const char *msg)
{
    if (!s->failed) rs_err_set(s->err, kind, s->file, (long)XML_GetCurrentLineNumber(s->parser), "XML: %s", msg);
    s->failed = 1;
    XML_StopParser(s->parser, XML_FALSE);
}

static e57_node *new_node(xml_state *s, const char *name, const char **attrs)
{
    e57_node *n = calloc(1, sizeof *n);
    int na = 0;
    while (attrs[na]) na++;
    if (n) n->attrs = calloc((size_t)na + 1, sizeof *n->attrs);
    if (n) n->name = strdup(name);
    if (!n || !n->attrs || !n->name) {
        if (n) free(n->attrs);
        if (n) free(n->name);
        free(n);
        return NULL;
    }
    for (int i = 0; i < na; i++)
        if (!(n->attrs[i] = strdup(attrs[i]))) {
            n->name[0] = 0;
            node_free(n);
            return NULL;
        }
    n->line = (long)XML_GetCurrentLineNumber(s->parser);
    const char *type = NULL;
    for (int i = 0; attrs[i]; i += 2)
        if (strcmp(attrs[i], "type") == 0) type = attrs[i + 1];
    for (size_t t = 0; type && t < sizeof types / sizeof types[0]; t++)
        if (strcmp(type, types[t].name) == 0) n->type = types[t].type;
    return n;
}

static void XMLCALL on_start(void *ud, const char *name, const char **attrs)
{
    xml_state *s = ud;
    if (s->failed) return;
    if (++s->depth > E57_MAX_DEPTH)
        return fail(s, RS_ERR_INPUT, "elements nested deeper than 64; expected an E57 tree");
    e57_node *n = new_node(s, name, attrs);
    if (!n) return fail(s, RS_ERR_SYSTEM, "out of memory");
    n->parent = s->cur;
    if (!s->cur) {
        if (s->root) {
            node_free(n);
            return fail(s, RS_ERR_INPUT, "a second root element");
        }
        s->root = n;
    } else {
        if (s->cur->last)
            s->cur->last->next = n;
        else
            s->cur->child = n;
        s->cur->last = n;
        n->index = s->cur->nchildren++;
    }
    s->cur = n;
}

static void XMLCALL on_end(void *ud, const char *name)
{
    xml_state *s = ud;
    if (s->failed) return;
    s->depth--;
    if (s->cur) s->cur = s->cur->parent;
}

static void XMLCALL on_text(void *ud, const char *text, int len)
{
    xml_state *s = ud;
    if (s->failed || !s->cur || len <= 0) return;
    e57_node *n = s->cur;
    char *t = realloc(n->text, n->text_len + (size_t)len + 1);
    if (!t) return fail(s, RS_ERR_SYSTEM, "out of memory");
    memcpy(t + n->text_len, text, (size_t)len);
    n->text_len += (size_t)len;
    t[n->text_len] = 0;
    n->text = t;
}

static void fill_text(e57_node *n)
{
    for (; n; n = n->next) {
        if (!n->text) n->text = calloc(1, 1);
        fill_text(n->child);
    }
}

e57_node *e57_xml_parse(const char *xml, size_t n, const char *file, rs_err *err)
{
    xml_state s = {0};
    s.file = file;
    s.err = err;
    s.parser = XML_ParserCreate(NULL);
    if (!s.parser) {
        rs_err_set(err, RS_ERR_SYSTEM, file, 0, "out of memory for the XML parser");
        return NULL;
    }
    XML_SetUserData(s.parser, &s);
    XML_SetElementHandler(s.parser, on_start, on_end);
    XML_SetCharacterDataHandler(s.parser, on_text);
    int ok = 1;
    /* XML_Parse takes an int length: feed the text in pieces. */
    for (size_t at = 0; ok && !s.failed;) {
        size_t take = n - at > (1u << 30) ? (1u << 30) : n - at;
        int last = at + take == n;
        ok = XML_Parse(s.parser, xml + at, (int)take, last) == XML_STATUS_OK;
        at += take;
        if (last) break;
    }
    if (!ok && !s.failed)
        rs_err_set(err, RS_ERR_INPUT, file, (long)XML_GetCurrentLineNumber(s.parser),
                   "XML section, column %ld: %s; expected well-formed XML", (long)XML_GetCurrentColumnNumber(s.parser),
                   XML_ErrorString(XML_GetErrorCode(s.parser)));
    XML_ParserFree(s.parser);
    if (!ok || s.failed || !s.root) {
        if (ok && !s.failed) rs_err_set(err, RS_ERR_INPUT, file, 0, "XML section: no root element");
        node_free(s.root);
        return NULL;
    }
    fill_text(s.root);
    if (strcmp(s.root->name, "e57Root") != 0 || s.root->type != E57_T_STRUCT) {
        rs_err_set(err, RS_ERR_INPUT, file, s.root->line,
                   "XML: root element <%s>; expected <e57Root type=\"Structure\">", s.root->name);
        node_free(s.root);
        return NULL;
    }
    return s.root;
}

e57_node *e57_child(const e57_node *n, const char *name)
{
    if (!n) return NULL;
    for (e57_node *c = n->child; c; c = c->next)
        if (strcmp(c->name, name) == 0) return c;
    return NULL;
}

e57_node *e57_child_at(const e57_node *n, int i)
{
    if (!n) return NULL;
    for (e57_node *c = n->child; c; c = c->next)
        if (c->index == i) return c;
    return NULL;
}

const char *e57_attr(const e57_node *n, const char *name)
{
    for (char **a = n->attrs; a && a[0]; a += 2)
        if (strcmp(a[0], name) == 0) return a[1];
    return NULL;
}

void e57_path(const e57_node *n, char *buf, size_t size)
{
    if (!n || !n->parent) {
        snprintf(buf, size, "/");
        return;
    }
    const e57_node *chain[E57_MAX_DEPTH + 1];
    int k = 0;
    for (const e57_node *p = n; p->parent && k < E57_MAX_DEPTH; p = p->parent) chain[k++] = p;
    size_t at = 0;
    buf[0] = 0;
    while (k-- > 0 && at + 1 < size) {
        const e57_node *p = chain[k];
        int vec = p->parent->type == E57_T_VECTOR;
        int w = vec ? snprintf(buf + at, size - at, "/%d", p->index) : snprintf(buf + at, size - at, "/%s", p->name);
        if (w < 0) break;
        at += (size_t)w;
    }
}

static int bad_value(const e57_node *n, const char *file, const char *text, const char *expected, rs_err *err)
{
    char path[256];
    e57_path(n, path, sizeof path);
    return rs_err_set(err, RS_ERR_INPUT, file, n->line, "XML %s: \"%.40s\" is not %s", path, text, expected);
}

/* Parses text (surrounded by blanks or not) as a finite double; "" is 0. */
static int parse_real(const char *text, double *out)
{
    while (*text == ' ' || *text == '\t' || *text == '\n' || *text == '\r') text++;
    if (!*text) {
        *out = 0;
        return 0;
    }
    char *end;
    errno = 0;
    double v = strtod(text, &end);
    while (*end == ' ' || *end == '\t' || *end == '\n' || *end == '\r') end++;
    if (end == text || *end || !isfinite(v)) return -1;
    *out = v;
    return 0;
}

static int parse_int(const char *text, int64_t *out)
{
    while (*text == ' ' || *text == '\t' || *text == '\n' || *text == '\r') text++;
    if (!*text) {
        *out = 0;
        return 0;
    }
    char *end;
    errno = 0;
    long long v = strtoll(text, &end, 10);
    while (*end == ' ' || *end == '\t' || *end == '\n' || *end == '\r') end++;
    if (end == text || *end || errno == ERANGE) return -1;
    *out = v;
    return 0;
}

int e57_number(const e57_node *n, const char *file, double *out, rs_err *err)
{
    if (n->type == E57_T_INTEGER) {
        int64_t v;
        if (parse_int(n->text, &v) != 0) return bad_value(n, file, n->text, "an Integer", err);
        *out = (double)v;
        return 0;
    }
    if (n->type == E57_T_SCALED) {
        int64_t v;
        double scale, offset;
        if (parse_int(n->text, &v) != 0) return bad_value(n, file, n->text, "a ScaledInteger's raw value", err);
        if (e57_attr_real(n, "scale", 1, file, &scale, err) != 0 ||
            e57_attr_real(n, "offset", 0, file, &offset, err) != 0)
            return -1;
        *out = (double)v * scale + offset;
        return 0;
    }
    if (n->type == E57_T_FLOAT) {
        if (parse_real(n->text, out) != 0) return bad_value(n, file, n->text, "a finite Float", err);
        return 0;
    }
    return bad_value(n, file, n->name, "a number element (Integer, ScaledInteger or Float)", err);
}

int e57_integer(const e57_node *n, const char *file, int64_t *out, rs_err *err)
{
    if (n->type != E57_T_INTEGER) return bad_value(n, file, n->name, "an Integer element", err);
    if (parse_int(n->text, out) != 0) return bad_value(n, file, n->text, "an Integer", err);
    return 0;
}

int e57_child_number(const e57_node *n, const char *name, double def, const char *file, double *out, rs_err *err)
{
    const e57_node *c = e57_child(n, name);
    if (!c) {
        *out = def;
        return 0;
    }
    return e57_number(c, file, out, err);
}

void e57_child_string(const e57_node *n, const char *name, char *buf, size_t size)
{
    const e57_node *c = e57_child(n, name);
    snprintf(buf, size, "%s", c && c->type == E57_T_STRING ? c->text : "");
}

int e57_attr_int(const e57_node *n, const char *attr, int64_t def, const char *file, int64_t *out, rs_err *err)
{
    const char *a = e57_attr(n, attr);
    *out = def;
    if (!a) return 0;
    if (parse_int(a, out) != 0) {
        char what[96];
        snprintf(what, sizeof what, "an integer (attribute %s)", attr);
        return bad_value(n, file, a, what, err);
    }
    return 0;
}

int e57_attr_real(const e57_node *n, const char *attr, double def, const char *file, double *out, rs_err *err)
{
    const char *a = e57_attr(n, attr);
    *out = def;
    if (!a) return 0;
    if (parse_real(a, out) != 0) {
        char what[96];
        snprintf(what, sizeof what, "a finite number (attribute %s)", attr);
        return bad_value(n, file, a, what, err);
    }
    return 0;
}

int e57_pose(const e57_node *pose, const char *file, double R[9], double t[3], rs_err *err)
{
    static const double I[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    memcpy(R, I, sizeof I);
    t[0] = t[1] = t[2] = 0;
    if (!pose) return 0;
    const e57_node *tr = e57_child(pose, "translation"), *rot = e57_child(pose, "rotation");
    static const char *const axes[3] = {"x", "y", "z"};
    for (int j = 0; j < 3 && tr; j++)
        if (e57_child_number(tr, axes[j], 0, file, &t[j], err) != 0) return -1;
    if (!rot) return 0;
    double w, x, y, z;
    if (e57_child_number(rot, "w", 1, file, &w, err) != 0 || e57_child_number(rot, "x", 0, file, &x, err) != 0 ||
        e57_child_number(rot, "y", 0, file, &y, err) != 0 || e57_child_number(rot, "z", 0, file, &z, err) != 0)
        return -1;
    double norm = sqrt(w * w + x * x + y * y + z * z);
    char path[256];
    e57_path(rot, path, sizeof path);
    if (!(norm > 1e-12) || !isfinite(norm))
        return rs_err_set(err, RS_ERR_INPUT, file, rot->line,
                          "XML %s: quaternion (%g, %g, %g, %g); expected a unit quaternion", path, w, x, y, z);
    if (fabs(norm - 1) > 1e-6)
        rs_log_warn("%s: XML %s: quaternion (%g, %g, %g, %g) has length %g; normalised to unit length", file, path, w,
                    x, y, z, norm);
    if (norm != 1) {
        w /= norm;
        x /= norm;
        y /= norm;
        z /= norm;
    }
    rs_m3_from_quat(w, x, y, z, R);
    return 0;
}
