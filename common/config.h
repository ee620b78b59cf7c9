/* config: INI configuration files (libinih) checked against one table of known keys.
 * Precedence: built-in default < config file < --set section.key=value overrides.
 * Relative paths in the file are relative to the file's folder; in an override, to the current
 * folder (where the command was typed).
 * Sections named "capture.NAME" take the keys of "capture" (several captures).
 * Every key is validated at load time, so the getters below cannot fail. */
#ifndef RS_CONFIG_H
#define RS_CONFIG_H

#include <stddef.h>
#include "common/err.h"

typedef enum {
    RS_CFG_STRING,  /* free text */
    RS_CFG_PATH,    /* one file or folder, relative to the config file's folder */
    RS_CFG_PATHS,   /* one or more paths separated by white space */
    RS_CFG_INT,     /* integer in [min, max] */
    RS_CFG_REAL,    /* finite real in [min, max] */
    RS_CFG_BOOL,    /* true/false, yes/no, on/off, 1/0 */
    RS_CFG_ENUM,    /* one of `choices` ("a|b|c") */
    RS_CFG_VEC3,    /* three finite reals */
    RS_CFG_ROTATION /* nine finite reals, row-major, orthonormal with det +1 (tolerance 1e-4) */
} rs_cfg_type;

typedef struct rs_cfg_key {
    const char *section;
    const char *key;
    rs_cfg_type type;
    const char *def;     /* default as text; NULL: no default (unset unless given) */
    double min, max;     /* INT and REAL ranges (inclusive) */
    const char *choices; /* ENUM: "a|b|c" */
    const char *unit;    /* "m", "rad", "samples", "" ... */
    const char *stages;  /* the stages that read it, e.g. "mesh observe" */
    const char *help;    /* one line */
} rs_cfg_key;

/* The table of every key (config_keys.c), ended by an entry with section == NULL. */
extern const rs_cfg_key rs_cfg_keys[];

typedef struct rs_config rs_config;

/* Loads path (must exist) and applies overrides ("section.key=value", NULL-terminated list).
 * Errors name the file and line (or "--set" for an override) and what was expected:
 *   tower.ini:14: [mesh] facet_size = "-0.2": expected a real in [0.0001, 10000] (m)
 *   tower.ini:3: [mesh] facet_sise: unknown key; did you mean facet_size?
 * Unknown sections are errors too. Caller frees with rs_config_free. */
rs_config *rs_config_load(const char *path, const char *const *overrides, rs_err *err);
/* Same from a string; base_dir resolves relative paths; name is used in messages. */
rs_config *rs_config_load_string(const char *text, const char *name, const char *base_dir, const char *const *overrides,
                                 rs_err *err);
void rs_config_free(rs_config *cfg);

/* Where the value in effect comes from. */
typedef enum { RS_CFG_UNSET, RS_CFG_FROM_DEFAULT, RS_CFG_FROM_FILE, RS_CFG_FROM_SET } rs_cfg_origin;
rs_cfg_origin rs_config_origin(const rs_config *cfg, const char *section, const char *key);

/* 1 if the key was given in the file or an override (not only defaulted). */
int rs_config_has(const rs_config *cfg, const char *section, const char *key);
/* Getters: value in effect (given, else default). Calling them for a key that is not in the
 * table, or of another type, is a programming error (abort with a message). A REAL key unset
 * with no default reads as NAN; an INT or BOOL one aborts (check rs_config_has first). */
const char *rs_config_string(const rs_config *cfg, const char *section, const char *key); /* NULL if unset */
long rs_config_int(const rs_config *cfg, const char *section, const char *key);
double rs_config_real(const rs_config *cfg, const char *section, const char *key);
int rs_config_bool(const rs_config *cfg, const char *section, const char *key);
/* VEC3 into out[3], ROTATION into out[9]; returns 0, or -1 when unset with no default. */
int rs_config_reals(const rs_config *cfg, const char *section, const char *key, double *out);
/* PATH: resolved against the config's folder (absolute stays absolute) into out; NULL if unset. */
const char *rs_config_path(const rs_config *cfg, const char *section, const char *key, char *out, size_t n);
/* PATHS: number of paths; the i-th resolved into out. */
int rs_config_path_count(const rs_config *cfg, const char *section, const char *key);
const char *rs_config_path_at(const rs_config *cfg, const char *section, const char *key, int i, char *out, size_t n);

/* Section names present in the file matching base ("capture" matches "capture" and
 * "capture.NAME"), in file order; returns the count, names borrowed. */
int rs_config_sections(const rs_config *cfg, const char *base, const char **names, int max);

/* The settings in effect for one section as INI text that reads back in ("[mesh]\nkey = value\n",
 * keys in table order, defaults included, paths resolved to absolute). Caller frees.
 * Used for fingerprints (rerun decisions) and --print-config. */
char *rs_config_section_text(const rs_config *cfg, const char *section);

/* configs/KEYS.md: the key table rendered as markdown (one table per section: key, type, unit,
 * default, stages, help) under a short header on precedence and relative paths. Caller frees;
 * NULL when out of memory. A unit test keeps the committed file equal to this text. */
char *rs_config_keys_markdown(void);

/* The config file's path as given and its folder. */
const char *rs_config_file(const rs_config *cfg);
const char *rs_config_dir(const rs_config *cfg);

#endif
