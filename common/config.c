/* config: loads INI files with libinih, checks every key against rs_cfg_keys (config_keys.c),
 * applies --set overrides, and answers the typed getters of config.h. */
#include "common/config.h"
#include "common/config_priv.h"

/* Debian's libinih 55 is built with INI_HANDLER_LINENO=1 (its ini_parse_stream passes the line
 * number as a fifth argument; checked in the disassembly), but its ini.h defaults the macro to 0:
 * the handler type must be declared to match the library, not the header's default. */
#define INI_HANDLER_LINENO 1
#include <ini.h>

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Longest line accepted. libinih's heap buffer grows up to ini_max_line (which must exceed the
 * longest line by 3); longer lines would be split silently, so they are refused beforehand. */
#define LINE_LIMIT 65000
/* libinih keeps section names in a 50-byte buffer and cuts longer ones. */
#define SECTION_NAME_MAX 49
/* A config is a page of text; anything bigger is the wrong file. */
#define FILE_LIMIT (16L << 20)

typedef struct entry {
    const rs_cfg_key *key;
    char *section;      /* as written: "mesh", "capture.north" */
    char *text;         /* the value as given, trimmed */
    rs_cfg_value value; /* checked, paths resolved */
    long line;          /* 0 for --set */
} entry;

typedef struct section_seen {
    char *name;
    long line; /* heading line; 0 when only --set named it */
} section_seen;

struct rs_config {
    char *file, *dir;
    char *cwd; /* what relative paths given with --set are relative to */
    entry *entries;
    int nentries, cap_entries;
    section_seen *sections;
    int nsections, cap_sections;
};

typedef struct load_ctx {
    rs_config *cfg;
    const char *name; /* file name for messages */
    rs_err *err;
    int failed; /* err holds the first error */
} load_ctx;

static void die(const char *fmt, ...) __attribute__((format(printf, 1, 2), noreturn));
static void die(const char *fmt, ...)
{
    /* Programming errors only (a key missing from the table, a getter of the wrong type):
     * user input never gets here, it is refused at load time. */
    va_list ap;
    va_start(ap, fmt);
    fputs("rhoscan: config: programming error: ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    abort();
}

static int oom(rs_err *err)
{
    return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory while reading the configuration");
}

/* Copies s[0..n) without surrounding white space into a new string. */
static char *trimmed(const char *s, size_t n)
{
    while (n > 0 && isspace((unsigned char)*s)) s++, n--;
    while (n > 0 && isspace((unsigned char)s[n - 1])) n--;
    return strndup(s, n);
}

static entry *find_entry(const rs_config *cfg, const char *section, const char *key)
{
    for (int i = 0; i < cfg->nentries; i++)
        if (strcmp(cfg->entries[i].section, section) == 0 && strcmp(cfg->entries[i].key->key, key) == 0)
            return &cfg->entries[i];
    return NULL;
}

static section_seen *find_section(const rs_config *cfg, const char *name)
{
    for (int i = 0; i < cfg->nsections; i++)
        if (strcmp(cfg->sections[i].name, name) == 0) return &cfg->sections[i];
    return NULL;
}

static int add_section(rs_config *cfg, const char *name, long line)
{
    if (find_section(cfg, name)) return 0;
    if (cfg->nsections == cfg->cap_sections) {
        int cap = cfg->cap_sections ? 2 * cfg->cap_sections : 8;
        section_seen *s = realloc(cfg->sections, (size_t)cap * sizeof *s);
        if (!s) return -1;
        cfg->sections = s;
        cfg->cap_sections = cap;
    }
    section_seen *s = &cfg->sections[cfg->nsections];
    if (!(s->name = strdup(name))) return -1;
    s->line = line;
    cfg->nsections++;
    return 0;
}

/* Checks and stores one value. file/line place messages ("--set" and 0 for overrides); a file
 * may not give a key twice, an override replaces what the file gave. */
static int set_value(rs_config *cfg, const char *file, long line, const char *section, const char *key,
                     const char *text, rs_err *err)
{
    char why[900];
    if (!*key)
        return rs_err_set(err, RS_ERR_INPUT, file, line,
                          "[%s] = \"%.120s\": a value with no key "
                          "name; expected key = value",
                          section, text);
    const rs_cfg_key *k = rs_cfg_find_row(section, key);
    if (!k) {
        rs_cfg_unknown_key(section, key, why, sizeof why);
        return rs_err_set(err, RS_ERR_INPUT, file, line, "%s", why);
    }
    entry *old = find_entry(cfg, section, key);
    if (old && old->line > 0 && line > 0)
        return rs_err_set(err, RS_ERR_INPUT, file, line,
                          "[%s] %s is given twice, on lines %ld "
                          "and %ld; keep one",
                          section, key, old->line, line);
    rs_cfg_value v;
    /* A path in the file is relative to the file; one typed on the command line, to the folder
     * the command was typed in, as every other program's arguments are. */
    int rc = rs_cfg_parse(k, text, line > 0 ? cfg->dir : cfg->cwd, &v, why, sizeof why);
    if (rc == -2) return oom(err);
    if (rc)
        return rs_err_set(err, RS_ERR_INPUT, file, line, "[%s] %s = \"%.120s%s\": %s", section, key, text,
                          strlen(text) > 120 ? "..." : "", why);
    char *text_copy = strdup(text);
    if (!text_copy) {
        rs_cfg_value_clear(&v);
        return oom(err);
    }
    if (old) {
        free(old->text);
        rs_cfg_value_clear(&old->value);
    } else {
        if (cfg->nentries == cfg->cap_entries) {
            int cap = cfg->cap_entries ? 2 * cfg->cap_entries : 16;
            entry *e = realloc(cfg->entries, (size_t)cap * sizeof *e);
            if (!e) {
                free(text_copy);
                rs_cfg_value_clear(&v);
                return oom(err);
            }
            cfg->entries = e;
            cfg->cap_entries = cap;
        }
        old = &cfg->entries[cfg->nentries];
        if (!(old->section = strdup(section))) {
            free(text_copy);
            rs_cfg_value_clear(&v);
            return oom(err);
        }
        cfg->nentries++;
    }
    old->key = k;
    old->text = text_copy;
    old->value = v;
    old->line = line;
    return 0;
}

/* libinih calls this for every "key = value" (value trimmed, inline comment removed). */
static int on_value(void *user, const char *section, const char *key, const char *value, int line)
{
    load_ctx *c = user;
    char why[900];
    char *sec = trimmed(section, strlen(section));
    if (!sec)
        oom(c->err);
    else if (!*sec)
        rs_err_set(c->err, RS_ERR_INPUT, c->name, line,
                   "%s = \"%.120s\": a key outside any "
                   "section; put it under a [section] heading",
                   key, value);
    else if (rs_cfg_check_section(sec, why, sizeof why) != 0) {
        section_seen *s = find_section(c->cfg, sec);
        rs_err_set(c->err, RS_ERR_INPUT, c->name, s ? s->line : line, "%s", why);
    } else if (set_value(c->cfg, c->name, line, sec, key, value, c->err) == 0) {
        free(sec);
        return 1;
    }
    free(sec);
    c->failed = 1;
    return 0; /* stops libinih (ini_stop_on_first_error) */
}

/* Before libinih runs: refuse overlong lines (libinih would split them) and NUL bytes, and
 * record section headings with their lines, so that sections without keys are seen too. */
static int scan_lines(rs_config *cfg, const char *text, size_t size, const char *name, rs_err *err)
{
    const char *nul = memchr(text, '\0', size);
    long line = 1;
    for (const char *p = text; p < text + size; line++) {
        const char *end = memchr(p, '\n', (size_t)(text + size - p));
        if (!end) end = text + size;
        if (nul && nul < end) return rs_err_set(err, RS_ERR_INPUT, name, line, "a NUL byte: expected a text file");
        if (end - p > LINE_LIMIT)
            return rs_err_set(err, RS_ERR_INPUT, name, line,
                              "line of %ld characters: expected at "
                              "most %d",
                              (long)(end - p), LINE_LIMIT);
        if (line == 1 && end - p >= 3 && memcmp(p, "\xEF\xBB\xBF", 3) == 0) p += 3;
        while (p < end && isspace((unsigned char)*p)) p++;
        const char *close = p < end && *p == '[' ? memchr(p, ']', (size_t)(end - p)) : NULL;
        if (close) {
            char *sec = trimmed(p + 1, (size_t)(close - p - 1));
            if (!sec) return oom(err);
            int rc = strlen(sec) > SECTION_NAME_MAX ? 1 : add_section(cfg, sec, line);
            if (rc == 1)
                rs_err_set(err, RS_ERR_INPUT, name, line,
                           "[%.60s...]: section name longer than %d "
                           "characters",
                           sec, SECTION_NAME_MAX);
            free(sec);
            if (rc) return rc == 1 ? -1 : oom(err);
        }
        p = end + 1;
    }
    return 0;
}

static void ini_setup(void)
{
    /* Debian's build exposes libinih's switches as process-wide globals; set all that matter,
     * every time. So configs are loaded from one thread at a time (programs load theirs first). */
    static char comment_chars[] = ";#";
    ini_use_stack = false;
    ini_allow_realloc = true;
    ini_initial_alloc = 256;
    ini_max_line = LINE_LIMIT + 16;
    ini_allow_multiline = false; /* an indented line is an ordinary line, not a continuation */
    ini_allow_bom = true;
    ini_allow_inline_comments = true;
    ini_inline_comment_prefixes = comment_chars;
    ini_start_comment_prefixes = comment_chars;
    ini_stop_on_first_error = true;
    ini_allow_no_value = false;
}

static int parse_text(rs_config *cfg, const char *text, size_t size, const char *name, rs_err *err)
{
    if (scan_lines(cfg, text, size, name, err) != 0) return -1;
    load_ctx ctx = {cfg, name, err, 0};
    ini_setup();
    int rc = ini_parse_string(text, on_value, &ctx);
    if (ctx.failed) return -1;
    if (rc == -2) return oom(err);
    if (rc > 0) {
        const char *p = text;
        for (int l = 1; l < rc && p; l++) {
            p = strchr(p, '\n');
            if (p) p++;
        }
        size_t len = p ? strcspn(p, "\r\n") : 0;
        return rs_err_set(err, RS_ERR_INPUT, name, rc,
                          "\"%.*s%s\": expected \"key = value\", "
                          "\"[section]\" or a comment",
                          (int)(len > 120 ? 120 : len), p ? p : "", len > 120 ? "..." : "");
    }
    char why[900];
    for (int i = 0; i < cfg->nsections; i++) /* sections without keys */
        if (rs_cfg_check_section(cfg->sections[i].name, why, sizeof why) != 0)
            return rs_err_set(err, RS_ERR_INPUT, name, cfg->sections[i].line, "%s", why);
    return 0;
}

static int apply_override(rs_config *cfg, const char *o, rs_err *err)
{
    const char *eq = strchr(o, '=');
    char *left = eq ? trimmed(o, (size_t)(eq - o)) : NULL;
    char *value = eq ? trimmed(eq + 1, strlen(eq + 1)) : NULL;
    char *dot = left ? strrchr(left, '.') : NULL; /* the last dot: capture.north.position */
    char why[900];
    int rc = -1;
    if (eq && (!left || !value))
        rc = oom(err);
    else if (!dot || dot == left || !dot[1])
        rs_err_set(err, RS_ERR_INPUT, "--set", 0, "\"%.200s\": expected section.key=value", o);
    else {
        *dot = '\0';
        if (rs_cfg_check_section(left, why, sizeof why) != 0)
            rs_err_set(err, RS_ERR_INPUT, "--set", 0, "%s", why);
        else if (add_section(cfg, left, 0) != 0)
            oom(err);
        else
            rc = set_value(cfg, "--set", 0, left, dot + 1, value, err);
    }
    free(left);
    free(value);
    return rc;
}

static char *absolute_dir(const char *dir, rs_err *err)
{
    char cwd[RS_CFG_PATH_MAX] = "", out[RS_CFG_PATH_MAX];
    if ((!dir || dir[0] != '/') && !getcwd(cwd, sizeof cwd)) {
        rs_err_errno(err, NULL, "cannot get the current folder");
        return NULL;
    }
    if (rs_cfg_resolve(cwd, dir ? dir : ".", out, sizeof out) != 0) {
        rs_err_set(err, RS_ERR_INPUT, dir, 0, "folder name longer than %d characters", RS_CFG_PATH_MAX - 1);
        return NULL;
    }
    char *s = strdup(out);
    if (!s) oom(err);
    return s;
}

static rs_config *load_text(const char *text, size_t size, const char *name, const char *dir,
                            const char *const *overrides, rs_err *err)
{
    rs_config *cfg = calloc(1, sizeof *cfg);
    if (!cfg || !(cfg->file = strdup(name))) {
        free(cfg);
        oom(err);
        return NULL;
    }
    if (!(cfg->dir = absolute_dir(dir, err)) || !(cfg->cwd = absolute_dir(NULL, err)) ||
        parse_text(cfg, text, size, name, err) != 0)
        goto fail;
    for (int i = 0; overrides && overrides[i]; i++)
        if (apply_override(cfg, overrides[i], err) != 0) goto fail;
    return cfg;
fail:
    rs_config_free(cfg);
    return NULL;
}

rs_config *rs_config_load_string(const char *text, const char *name, const char *base_dir, const char *const *overrides,
                                 rs_err *err)
{
    return load_text(text, strlen(text), name ? name : "(string)", base_dir, overrides, err);
}

rs_config *rs_config_load(const char *path, const char *const *overrides, rs_err *err)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        rs_err_set(err, RS_ERR_INPUT, path, 0, "cannot open the config file: %s", strerror(errno));
        return NULL;
    }
    char *text = NULL;
    size_t size = 0, cap = 0;
    int failed = 0;
    for (;;) {
        if (cap - size < 4096 + 1) {
            size_t new_cap = cap ? 2 * cap : 8192;
            char *t = new_cap > (size_t)FILE_LIMIT ? NULL : realloc(text, new_cap);
            if (!t) {
                failed = new_cap > (size_t)FILE_LIMIT ? 2 : 1;
                break;
            }
            text = t;
            cap = new_cap;
        }
        size_t got = fread(text + size, 1, cap - size - 1, f);
        size += got;
        if (got == 0) break;
    }
    if (!failed && ferror(f)) {
        rs_err_set(err, RS_ERR_INPUT, path, 0, "cannot read the config file: %s", strerror(errno));
        failed = 3;
    }
    fclose(f);
    if (failed == 1) oom(err);
    if (failed == 2) rs_err_set(err, RS_ERR_INPUT, path, 0, "larger than %ld MiB: not a config file", FILE_LIMIT >> 20);
    if (failed) {
        free(text);
        return NULL;
    }
    text[size] = '\0';
    /* The folder of the file is what relative paths in it are relative to. */
    char *dir = strdup(path);
    if (!dir) {
        free(text);
        oom(err);
        return NULL;
    }
    char *slash = strrchr(dir, '/');
    if (slash) *(slash == dir ? slash + 1 : slash) = '\0';
    rs_config *cfg = load_text(text, size, path, slash ? dir : ".", overrides, err);
    free(dir);
    free(text);
    return cfg;
}

void rs_config_free(rs_config *cfg)
{
    if (!cfg) return;
    for (int i = 0; i < cfg->nentries; i++) {
        free(cfg->entries[i].section);
        free(cfg->entries[i].text);
        rs_cfg_value_clear(&cfg->entries[i].value);
    }
    for (int i = 0; i < cfg->nsections; i++) free(cfg->sections[i].name);
    free(cfg->entries);
    free(cfg->sections);
    free(cfg->file);
    free(cfg->dir);
    free(cfg->cwd);
    free(cfg);
}

/* ---- getters: the table row must exist and have one of the types in `types` (bit mask) ---- */

#define T(type) (1u << (type))

static const rs_cfg_key *row_for(const char *section, const char *key, unsigned types, const char *caller)
{
    char why[900];
    if (!section || !key) die("%s called with a NULL section or key", caller);
    if (rs_cfg_check_section(section, why, sizeof why) != 0) die("%s: %s", caller, why);
    const rs_cfg_key *k = rs_cfg_find_row(section, key);
    if (!k) die("%s: [%s] %s is not in the key table (common/config_keys.c)", caller, section, key);
    if (!(T(k->type) & types))
        die("%s: [%s] %s has type %d, which this getter does not read", caller, section, key, (int)k->type);
    return k;
}

/* The value in effect: the given one, else the default parsed into *tmp (caller clears it), else
 * NULL. *text gets the value's text. */
static const rs_cfg_value *value_for(const rs_config *cfg, const char *section, const char *key, unsigned types,
                                     const char *caller, rs_cfg_value *tmp, const char **text)
{
    const rs_cfg_key *k = row_for(section, key, types, caller);
    memset(tmp, 0, sizeof *tmp);
    const entry *e = find_entry(cfg, section, key);
    if (e) {
        *text = e->text;
        return &e->value;
    }
    *text = k->def;
    if (!k->def) return NULL;
    char why[900];
    if (rs_cfg_parse(k, k->def, cfg->dir, tmp, why, sizeof why) != 0)
        die("the default of [%s] %s, \"%s\", is invalid: %s", k->section, key, k->def, why);
    return tmp;
}

rs_cfg_origin rs_config_origin(const rs_config *cfg, const char *section, const char *key)
{
    const rs_cfg_key *k = row_for(section, key, ~0u, "rs_config_origin");
    const entry *e = find_entry(cfg, section, key);
    if (e) return e->line > 0 ? RS_CFG_FROM_FILE : RS_CFG_FROM_SET;
    return k->def ? RS_CFG_FROM_DEFAULT : RS_CFG_UNSET;
}

int rs_config_has(const rs_config *cfg, const char *section, const char *key)
{
    row_for(section, key, ~0u, "rs_config_has");
    return find_entry(cfg, section, key) != NULL;
}

const char *rs_config_string(const rs_config *cfg, const char *section, const char *key)
{
    rs_cfg_value tmp;
    const char *text;
    value_for(cfg, section, key, T(RS_CFG_STRING) | T(RS_CFG_ENUM), "rs_config_string", &tmp, &text);
    rs_cfg_value_clear(&tmp);
    return text;
}

long rs_config_int(const rs_config *cfg, const char *section, const char *key)
{
    rs_cfg_value tmp;
    const char *text;
    const rs_cfg_value *v = value_for(cfg, section, key, T(RS_CFG_INT), "rs_config_int", &tmp, &text);
    if (!v) die("rs_config_int: [%s] %s has no default; check rs_config_has first", section, key);
    long i = v->i;
    rs_cfg_value_clear(&tmp);
    return i;
}

/* NAN when the key is unset and has no default. */
double rs_config_real(const rs_config *cfg, const char *section, const char *key)
{
    rs_cfg_value tmp;
    const char *text;
    const rs_cfg_value *v = value_for(cfg, section, key, T(RS_CFG_REAL), "rs_config_real", &tmp, &text);
    double r = v ? v->r[0] : NAN;
    rs_cfg_value_clear(&tmp);
    return r;
}

int rs_config_bool(const rs_config *cfg, const char *section, const char *key)
{
    rs_cfg_value tmp;
    const char *text;
    const rs_cfg_value *v = value_for(cfg, section, key, T(RS_CFG_BOOL), "rs_config_bool", &tmp, &text);
    if (!v) die("rs_config_bool: [%s] %s has no default; check rs_config_has first", section, key);
    int b = v->b;
    rs_cfg_value_clear(&tmp);
    return b;
}

int rs_config_reals(const rs_config *cfg, const char *section, const char *key, double *out)
{
    rs_cfg_value tmp;
    const char *text;
    const rs_cfg_value *v =
        value_for(cfg, section, key, T(RS_CFG_VEC3) | T(RS_CFG_ROTATION), "rs_config_reals", &tmp, &text);
    if (v) memcpy(out, v->r, (size_t)v->nr * sizeof *out);
    rs_cfg_value_clear(&tmp);
    return v ? 0 : -1;
}

static const char *path_out(const rs_config *cfg, const char *section, const char *key, int i, char *out, size_t n,
                            unsigned types, const char *caller)
{
    rs_cfg_value tmp;
    const char *text;
    const rs_cfg_value *v = value_for(cfg, section, key, types, caller, &tmp, &text);
    if (v && (i < 0 || i >= v->npaths))
        die("%s: [%s] %s has %d paths, asked for number %d", caller, section, key, v->npaths, i);
    if (v && strlen(v->paths[i]) >= n)
        die("%s: a buffer of %zu bytes is too small; use %d", caller, n, RS_CFG_PATH_MAX);
    if (v) memcpy(out, v->paths[i], strlen(v->paths[i]) + 1);
    rs_cfg_value_clear(&tmp);
    return v ? out : NULL;
}

const char *rs_config_path(const rs_config *cfg, const char *section, const char *key, char *out, size_t n)
{
    return path_out(cfg, section, key, 0, out, n, T(RS_CFG_PATH), "rs_config_path");
}

int rs_config_path_count(const rs_config *cfg, const char *section, const char *key)
{
    rs_cfg_value tmp;
    const char *text;
    const rs_cfg_value *v =
        value_for(cfg, section, key, T(RS_CFG_PATH) | T(RS_CFG_PATHS), "rs_config_path_count", &tmp, &text);
    int count = v ? v->npaths : 0;
    rs_cfg_value_clear(&tmp);
    return count;
}

const char *rs_config_path_at(const rs_config *cfg, const char *section, const char *key, int i, char *out, size_t n)
{
    return path_out(cfg, section, key, i, out, n, T(RS_CFG_PATH) | T(RS_CFG_PATHS), "rs_config_path_at");
}

/* Returns how many sections match (names gets the first max of them). */
int rs_config_sections(const rs_config *cfg, const char *base, const char **names, int max)
{
    size_t blen = strlen(base);
    int count = 0;
    for (int i = 0; i < cfg->nsections; i++) {
        const char *s = cfg->sections[i].name;
        if (strncmp(s, base, blen) != 0 || (s[blen] != '\0' && s[blen] != '.')) continue;
        if (names && count < max) names[count] = s;
        count++;
    }
    return count;
}

char *rs_config_section_text(const rs_config *cfg, const char *section)
{
    char why[900];
    if (rs_cfg_check_section(section, why, sizeof why) != 0) die("rs_config_section_text: %s", why);
    rs_cfg_buf b = {0};
    rs_cfg_buf_printf(&b, "[%s]\n", section);
    size_t blen = strcspn(section, ".");
    for (const rs_cfg_key *k = rs_cfg_keys; k->section; k++) {
        if (strlen(k->section) != blen || strncmp(k->section, section, blen) != 0) continue;
        rs_cfg_value tmp;
        const char *text;
        const rs_cfg_value *v = value_for(cfg, section, k->key, ~0u, "rs_config_section_text", &tmp, &text);
        if (v) {
            rs_cfg_buf_printf(&b, "%s = ", k->key);
            rs_cfg_format(k, text, v, &b);
            rs_cfg_buf_put(&b, "\n", 1);
        }
        rs_cfg_value_clear(&tmp);
    }
    if (b.failed) {
        free(b.s);
        return NULL;
    }
    return b.s;
}

const char *rs_config_file(const rs_config *cfg)
{
    return cfg->file;
}

const char *rs_config_dir(const rs_config *cfg)
{
    return cfg->dir;
}
