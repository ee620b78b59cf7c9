/* config_priv: what config.c, config_value.c and config_doc.c share (not for other modules):
 * checking names and values against the key table, canonical text, growable strings. */
#ifndef RS_CONFIG_PRIV_H
#define RS_CONFIG_PRIV_H

#include <stddef.h>
#include "common/config.h"

/* Longest resolved path a config may hold (PATH_MAX on Linux, with its NUL). */
#define RS_CFG_PATH_MAX 4096

/* A growable NUL-terminated string; `failed` is set once an allocation fails. */
typedef struct rs_cfg_buf {
    char *s;
    size_t len, cap;
    int failed;
} rs_cfg_buf;

void rs_cfg_buf_printf(rs_cfg_buf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
void rs_cfg_buf_put(rs_cfg_buf *b, const char *s, size_t n);

/* One value checked against its row. Paths are resolved to absolute, normalised text. */
typedef struct rs_cfg_value {
    long i;       /* INT */
    int b;        /* BOOL */
    double r[9];  /* REAL (r[0]), VEC3, ROTATION */
    int nr;       /* count of r in use */
    char **paths; /* PATH (one) and PATHS; malloc'd */
    int npaths;
} rs_cfg_value;

/* Checks text for row k; relative paths are resolved against base_dir (absolute). Returns 0, or -1
 * with what was wrong in `why` ("expected a real in [0, 1] (m)"), or -2 when out of memory. */
int rs_cfg_parse(const rs_cfg_key *k, const char *text, const char *base_dir, rs_cfg_value *v, char *why, size_t n);
void rs_cfg_value_clear(rs_cfg_value *v);
/* Appends the canonical text of a checked value (text is the value as given; used for STRING and
 * ENUM): numbers in the shortest form that reads back exactly, paths absolute. */
void rs_cfg_format(const rs_cfg_key *k, const char *text, const rs_cfg_value *v, rs_cfg_buf *b);
/* What row k accepts, e.g. "a real in [0.0001, 10000]" (no unit). */
void rs_cfg_describe(const rs_cfg_key *k, char *buf, size_t n);
/* The table row of section ("mesh", or "capture.NAME" for the keys of "capture") and key, or NULL. */
const rs_cfg_key *rs_cfg_find_row(const char *section, const char *key);
/* 0 if section names a known section; otherwise -1 with the reason (and the nearest valid
 * section) in why. */
int rs_cfg_check_section(const char *section, char *why, size_t n);
/* "[sec] key: unknown key; did you mean ...?" (or where the key belongs, or the valid keys). */
void rs_cfg_unknown_key(const char *section, const char *key, char *why, size_t n);
/* Levenshtein distance (strings longer than 127 characters count as far from everything). */
int rs_cfg_distance(const char *a, const char *b);
/* base_dir + "/" + path (unless path is absolute), with "." and ".." removed lexically.
 * Returns 0, or -1 when the result would not fit in out[n]. */
int rs_cfg_resolve(const char *base_dir, const char *path, char *out, size_t n);

#endif
