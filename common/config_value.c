/* config_value: checks section names, key names and values against the key table, writes a
 * value's canonical text, and describes what a row accepts (for error messages and KEYS.md). */
#include "common/config_priv.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* Tolerance on R^T R = I and det R = +1 for ROTATION values (config.h). */
#define ROTATION_TOL 1e-4
/* Values quoted in messages are cut to this many characters. */
#define QUOTE_MAX 120

/* Sections that may appear several times as "base.NAME", each with the keys of base. */
static const char *const named_sections[] = {"capture", NULL};

void rs_cfg_buf_put(rs_cfg_buf *b, const char *s, size_t n)
{
    if (b->failed) return;
    if (b->len + n + 1 > b->cap) {
        size_t cap = b->cap ? b->cap : 256;
        while (cap < b->len + n + 1) cap *= 2;
        char *p = realloc(b->s, cap);
        if (!p) {
            b->failed = 1;
            return;
        }
        b->s = p;
        b->cap = cap;
    }
    memcpy(b->s + b->len, s, n);
    b->len += n;
    b->s[b->len] = '\0';
}

void rs_cfg_buf_printf(rs_cfg_buf *b, const char *fmt, ...)
{
    char small[512];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(small, sizeof small, fmt, ap);
    va_end(ap);
    if (n < 0) {
        b->failed = 1;
        return;
    }
    if ((size_t)n < sizeof small) {
        rs_cfg_buf_put(b, small, (size_t)n);
        return;
    }
    char *big = malloc((size_t)n + 1);
    if (!big) {
        b->failed = 1;
        return;
    }
    va_start(ap, fmt);
    vsnprintf(big, (size_t)n + 1, fmt, ap);
    va_end(ap);
    rs_cfg_buf_put(b, big, (size_t)n);
    free(big);
}

/* min == max == 0 means no range (config_keys.c leaves the range of unbounded keys at zero). */
static int has_range(const rs_cfg_key *k)
{
    return !(k->min == 0 && k->max == 0);
}

static void describe_range(const rs_cfg_key *k, const char *what, char *buf, size_t n)
{
    int lo = has_range(k) && k->min > -1e299, hi = has_range(k) && k->max < 1e299;
    if (k->type == RS_CFG_INT) {
        if (lo && hi)
            snprintf(buf, n, "%s in [%ld, %ld]", what, (long)k->min, (long)k->max);
        else if (lo)
            snprintf(buf, n, "%s >= %ld", what, (long)k->min);
        else if (hi)
            snprintf(buf, n, "%s <= %ld", what, (long)k->max);
        else
            snprintf(buf, n, "%s", what);
    } else {
        if (lo && hi)
            snprintf(buf, n, "%s in [%.10g, %.10g]", what, k->min, k->max);
        else if (lo)
            snprintf(buf, n, "%s >= %.10g", what, k->min);
        else if (hi)
            snprintf(buf, n, "%s <= %.10g", what, k->max);
        else
            snprintf(buf, n, "%s", what);
    }
}

void rs_cfg_describe(const rs_cfg_key *k, char *buf, size_t n)
{
    switch (k->type) {
    case RS_CFG_STRING: snprintf(buf, n, "text"); break;
    case RS_CFG_PATH: snprintf(buf, n, "a path"); break;
    case RS_CFG_PATHS: snprintf(buf, n, "one or more paths separated by spaces"); break;
    case RS_CFG_INT: describe_range(k, "an integer", buf, n); break;
    case RS_CFG_REAL: describe_range(k, "a real", buf, n); break;
    case RS_CFG_BOOL: snprintf(buf, n, "true/false, yes/no, on/off or 1/0"); break;
    case RS_CFG_ENUM: {
        size_t len = (size_t)snprintf(buf, n, "one of ");
        for (const char *c = k->choices ? k->choices : ""; *c && len + 2 < n; c++)
            len += (size_t)snprintf(buf + len, n - len, *c == '|' ? ", " : "%c", *c);
        break;
    }
    case RS_CFG_VEC3: snprintf(buf, n, "3 finite reals"); break;
    case RS_CFG_ROTATION: snprintf(buf, n, "9 finite reals (a rotation matrix, row-major)"); break;
    default: snprintf(buf, n, "(unknown type %d)", (int)k->type); break;
    }
}

/* "expected <description> (<unit>)" into why. */
static int expected(const rs_cfg_key *k, const char *extra, char *why, size_t n)
{
    char desc[256];
    rs_cfg_describe(k, desc, sizeof desc);
    int unit = k->unit && *k->unit;
    snprintf(why, n, "expected %s%s%s%s%s", desc, unit ? " (" : "", unit ? k->unit : "", unit ? ")" : "",
             extra ? extra : "");
    return -1;
}

static int parse_long(const char *s, long *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (end == s || *end || errno == ERANGE || isspace((unsigned char)*s)) return -1;
    *out = v;
    return 0;
}

/* Reads up to max reals separated by spaces or commas; returns the count found (which may exceed
 * max), or -1 with the first bad token quoted into bad. */
static int parse_reals(const char *s, double *out, int max, char *bad, size_t n)
{
    int count = 0;
    for (;;) {
        while (*s && (isspace((unsigned char)*s) || *s == ',')) s++;
        if (!*s) return count;
        size_t len = strcspn(s, " \t\r\n\f\v,");
        char tok[64];
        char *end = NULL;
        double v = NAN;
        if (len < sizeof tok) {
            memcpy(tok, s, len);
            tok[len] = '\0';
            v = strtod(tok, &end);
        }
        if (len >= sizeof tok || end == tok || *end || !isfinite(v)) {
            snprintf(bad, n, "%.*s", (int)(len < QUOTE_MAX ? len : QUOTE_MAX), s);
            return -1;
        }
        if (count < max) out[count] = v;
        count++;
        s += len;
    }
}

static double rotation_deviation(const double *r, double *det)
{
    double worst = 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double d = 0;
            for (int k = 0; k < 3; k++) d += r[3 * k + i] * r[3 * k + j];
            d -= (i == j);
            if (fabs(d) > worst) worst = fabs(d);
        }
    *det = r[0] * (r[4] * r[8] - r[5] * r[7]) - r[1] * (r[3] * r[8] - r[5] * r[6]) + r[2] * (r[3] * r[7] - r[4] * r[6]);
    return worst;
}

static int add_path(rs_cfg_value *v, const char *base_dir, const char *path, char *why, size_t n)
{
    char resolved[RS_CFG_PATH_MAX];
    if (rs_cfg_resolve(base_dir, path, resolved, sizeof resolved) != 0) {
        snprintf(why, n, "the path is longer than %d characters once resolved", RS_CFG_PATH_MAX - 1);
        return -1;
    }
    char **paths = realloc(v->paths, (size_t)(v->npaths + 1) * sizeof *paths);
    if (!paths) return -2;
    v->paths = paths;
    if (!(paths[v->npaths] = strdup(resolved))) return -2;
    v->npaths++;
    return 0;
}

static int parse_paths(const rs_cfg_key *k, const char *text, const char *base_dir, rs_cfg_value *v, char *why,
                       size_t n)
{
    if (!*text) return expected(k, NULL, why, n);
    if (k->type == RS_CFG_PATH) return add_path(v, base_dir, text, why, n);
    /* PATHS: white space separates paths (a path in a list cannot contain spaces). */
    for (const char *s = text;;) {
        while (isspace((unsigned char)*s)) s++;
        if (!*s) return 0;
        size_t len = strcspn(s, " \t\r\n\f\v");
        char *one = strndup(s, len);
        if (!one) return -2;
        int rc = add_path(v, base_dir, one, why, n);
        free(one);
        if (rc) return rc;
        s += len;
    }
}

static int parse_inner(const rs_cfg_key *k, const char *text, const char *base_dir, rs_cfg_value *v, char *why,
                       size_t n)
{
    char bad[QUOTE_MAX + 8], extra[QUOTE_MAX + 64];
    switch (k->type) {
    case RS_CFG_STRING: return 0;
    case RS_CFG_PATH:
    case RS_CFG_PATHS: return parse_paths(k, text, base_dir, v, why, n);
    case RS_CFG_INT:
        if (parse_long(text, &v->i) != 0 || (has_range(k) && (v->i < k->min || v->i > k->max)))
            return expected(k, NULL, why, n);
        return 0;
    case RS_CFG_REAL: {
        int count = parse_reals(text, v->r, 1, bad, sizeof bad);
        if (count != 1 || (has_range(k) && (v->r[0] < k->min || v->r[0] > k->max))) return expected(k, NULL, why, n);
        v->nr = 1;
        return 0;
    }
    case RS_CFG_BOOL: {
        static const char *yes[] = {"true", "yes", "on", "1"}, *no[] = {"false", "no", "off", "0"};
        for (int i = 0; i < 4; i++) {
            if (strcasecmp(text, yes[i]) == 0 || strcasecmp(text, no[i]) == 0) {
                v->b = strcasecmp(text, yes[i]) == 0;
                return 0;
            }
        }
        return expected(k, NULL, why, n);
    }
    case RS_CFG_ENUM:
        for (const char *c = k->choices ? k->choices : ""; *c;) {
            size_t len = strcspn(c, "|");
            if (len == strlen(text) && strncmp(c, text, len) == 0) return 0;
            c += len + (c[len] == '|');
        }
        return expected(k, NULL, why, n);
    case RS_CFG_VEC3:
    case RS_CFG_ROTATION: {
        int want = k->type == RS_CFG_VEC3 ? 3 : 9;
        int count = parse_reals(text, v->r, want, bad, sizeof bad);
        if (count < 0) {
            snprintf(extra, sizeof extra, "; \"%s\" is not a finite real", bad);
            return expected(k, extra, why, n);
        }
        if (count != want) {
            snprintf(extra, sizeof extra, "; found %d number%s", count, count == 1 ? "" : "s");
            return expected(k, extra, why, n);
        }
        v->nr = want;
        if (k->type == RS_CFG_ROTATION) {
            double det, dev = rotation_deviation(v->r, &det);
            if (dev > ROTATION_TOL) {
                snprintf(why, n,
                         "not a rotation: R^T R differs from the identity by up to %.3g "
                         "(tolerance %g)",
                         dev, ROTATION_TOL);
                return -1;
            }
            if (fabs(det - 1) > ROTATION_TOL) {
                snprintf(why, n,
                         "not a rotation: its determinant is %.6g (a reflection; expected "
                         "+1 within %g)",
                         det, ROTATION_TOL);
                return -1;
            }
        }
        return 0;
    }
    }
    snprintf(why, n, "unknown key type %d in the key table", (int)k->type);
    return -1;
}

int rs_cfg_parse(const rs_cfg_key *k, const char *text, const char *base_dir, rs_cfg_value *v, char *why, size_t n)
{
    memset(v, 0, sizeof *v);
    int rc = parse_inner(k, text, base_dir, v, why, n);
    if (rc) rs_cfg_value_clear(v);
    return rc;
}

void rs_cfg_value_clear(rs_cfg_value *v)
{
    for (int i = 0; i < v->npaths; i++) free(v->paths[i]);
    free(v->paths);
    memset(v, 0, sizeof *v);
}

/* The shortest %g form that strtod reads back to exactly x. */
static void put_real(rs_cfg_buf *b, double x)
{
    char s[40];
    for (int prec = 1; prec <= 17; prec++) {
        snprintf(s, sizeof s, "%.*g", prec, x);
        if (strtod(s, NULL) == x) break;
    }
    rs_cfg_buf_printf(b, "%s", s);
}

void rs_cfg_format(const rs_cfg_key *k, const char *text, const rs_cfg_value *v, rs_cfg_buf *b)
{
    switch (k->type) {
    case RS_CFG_STRING:
    case RS_CFG_ENUM: rs_cfg_buf_printf(b, "%s", text); break;
    case RS_CFG_PATH:
    case RS_CFG_PATHS:
        for (int i = 0; i < v->npaths; i++) rs_cfg_buf_printf(b, "%s%s", i ? " " : "", v->paths[i]);
        break;
    case RS_CFG_INT: rs_cfg_buf_printf(b, "%ld", v->i); break;
    case RS_CFG_BOOL: rs_cfg_buf_printf(b, "%s", v->b ? "true" : "false"); break;
    case RS_CFG_REAL:
    case RS_CFG_VEC3:
    case RS_CFG_ROTATION:
        for (int i = 0; i < v->nr; i++) {
            if (i) rs_cfg_buf_put(b, " ", 1);
            put_real(b, v->r[i]);
        }
        break;
    }
}

int rs_cfg_distance(const char *a, const char *b)
{
    enum { MAXLEN = 127 };
    size_t na = strlen(a), nb = strlen(b);
    if (na > MAXLEN || nb > MAXLEN) return 1 << 20;
    int prev[MAXLEN + 1], cur[MAXLEN + 1];
    for (size_t j = 0; j <= nb; j++) prev[j] = (int)j;
    for (size_t i = 1; i <= na; i++) {
        cur[0] = (int)i;
        for (size_t j = 1; j <= nb; j++) {
            int sub = prev[j - 1] + (a[i - 1] != b[j - 1]);
            int del = prev[j] + 1, ins = cur[j - 1] + 1;
            cur[j] = sub < del ? (sub < ins ? sub : ins) : (del < ins ? del : ins);
        }
        memcpy(prev, cur, (nb + 1) * sizeof *cur);
    }
    return prev[nb];
}

int rs_cfg_resolve(const char *base_dir, const char *path, char *out, size_t n)
{
    /* Join, then rebuild component by component: "." dropped, ".." pops (never above "/"). */
    size_t bl = strlen(base_dir ? base_dir : ""), pl = strlen(path);
    char *joined = malloc(bl + pl + 3);
    if (!joined) return -1;
    if (path[0] == '/')
        snprintf(joined, bl + pl + 3, "%s", path);
    else
        snprintf(joined, bl + pl + 3, "/%s/%s", base_dir ? base_dir : "", path);
    size_t len = 0;
    int ok = 1;
    for (char *save = NULL, *c = strtok_r(joined, "/", &save); c; c = strtok_r(NULL, "/", &save)) {
        if (strcmp(c, ".") == 0) continue;
        if (strcmp(c, "..") == 0) {
            while (len > 0 && out[len - 1] != '/') len--;
            if (len > 0) len--;
            continue;
        }
        size_t cl = strlen(c);
        if (len + 1 + cl + 1 > n) {
            ok = 0;
            break;
        }
        out[len++] = '/';
        memcpy(out + len, c, cl);
        len += cl;
    }
    free(joined);
    if (!ok || n < 2) return -1;
    if (len == 0) out[len++] = '/';
    out[len] = '\0';
    return 0;
}

/* ---- section and key names ---- */

static int is_named_base(const char *base, size_t len)
{
    for (int i = 0; named_sections[i]; i++)
        if (strlen(named_sections[i]) == len && strncmp(named_sections[i], base, len) == 0) return 1;
    return 0;
}

/* The table row of section (base or base.NAME) and key, or NULL. */
const rs_cfg_key *rs_cfg_find_row(const char *section, const char *key)
{
    size_t blen = strcspn(section, ".");
    for (const rs_cfg_key *k = rs_cfg_keys; k->section; k++)
        if (strlen(k->section) == blen && strncmp(k->section, section, blen) == 0 && strcmp(k->key, key) == 0) return k;
    return NULL;
}

static int base_in_table(const char *base, size_t len)
{
    for (const rs_cfg_key *k = rs_cfg_keys; k->section; k++)
        if (strlen(k->section) == len && strncmp(k->section, base, len) == 0) return 1;
    return 0;
}

/* A suggestion is worth making when the names are closer than they are different. */
static int close_enough(int dist, const char *given)
{
    return dist <= 2 || 2 * dist <= (int)strlen(given);
}

/* 0 if section names a known section; otherwise -1 with the reason in why. */
int rs_cfg_check_section(const char *section, char *why, size_t n)
{
    size_t blen = strcspn(section, ".");
    const char *name = section[blen] ? section + blen + 1 : NULL;
    if (base_in_table(section, blen)) {
        if (!name) return 0;
        if (!is_named_base(section, blen)) {
            snprintf(why, n, "unknown section [%s]: only [%s.NAME] sections may carry a name", section,
                     named_sections[0]);
            return -1;
        }
        int ok = *name != '\0';
        for (const char *c = name; *c; c++)
            if (!isalnum((unsigned char)*c) && *c != '_' && *c != '-') ok = 0;
        if (ok) return 0;
        snprintf(why, n,
                 "bad section name [%s]: expected [%.*s.NAME] with a NAME of letters, "
                 "digits, '_' or '-'",
                 section, (int)blen, section);
        return -1;
    }
    char base[128];
    snprintf(base, sizeof base, "%.*s", (int)blen, section);
    const char *best = NULL;
    int best_dist = 1 << 30;
    for (const rs_cfg_key *k = rs_cfg_keys; k->section; k++) {
        int d = rs_cfg_distance(base, k->section);
        if (d < best_dist) best_dist = d, best = k->section;
    }
    if (best && close_enough(best_dist, base)) {
        snprintf(why, n, "unknown section [%s]; did you mean [%s%s%s]?", section, best,
                 name && is_named_base(best, strlen(best)) ? "." : "",
                 name && is_named_base(best, strlen(best)) ? name : "");
        return -1;
    }
    size_t len = (size_t)snprintf(why, n, "unknown section [%s]; the sections are", section);
    const char *prev = NULL;
    for (const rs_cfg_key *k = rs_cfg_keys; k->section && len < n; k++) {
        if (prev && strcmp(k->section, prev) == 0) continue;
        len += (size_t)snprintf(why + len, n - len, "%s [%s]", prev ? "," : "", k->section);
        prev = k->section;
    }
    return -1;
}

/* "unknown key" with the nearest key of the section, or where the key really belongs. */
void rs_cfg_unknown_key(const char *section, const char *key, char *why, size_t n)
{
    size_t blen = strcspn(section, ".");
    const rs_cfg_key *best = NULL, *elsewhere = NULL;
    int best_dist = 1 << 30;
    for (const rs_cfg_key *k = rs_cfg_keys; k->section; k++) {
        if (strlen(k->section) != blen || strncmp(k->section, section, blen) != 0) {
            if (strcmp(k->key, key) == 0 && !elsewhere) elsewhere = k;
            continue;
        }
        int d = rs_cfg_distance(key, k->key);
        if (d < best_dist) best_dist = d, best = k;
    }
    if (elsewhere)
        snprintf(why, n, "[%s] %s: unknown key; %s is a key of [%s]", section, key, key, elsewhere->section);
    else if (best && close_enough(best_dist, key))
        snprintf(why, n, "[%s] %s: unknown key; did you mean %s?", section, key, best->key);
    else {
        size_t len =
            (size_t)snprintf(why, n, "[%s] %s: unknown key; the keys of [%.*s] are", section, key, (int)blen, section);
        int first = 1;
        for (const rs_cfg_key *k = rs_cfg_keys; k->section && len < n; k++)
            if (strlen(k->section) == blen && strncmp(k->section, section, blen) == 0) {
                len += (size_t)snprintf(why + len, n - len, "%s %s", first ? "" : ",", k->key);
                first = 0;
            }
    }
}
