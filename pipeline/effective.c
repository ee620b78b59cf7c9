/* effective: the configuration in effect with the origin of every value (see effective.h). */
#include "pipeline/effective.h"

#include <stdlib.h>
#include <string.h>

static const char *origin_name(rs_cfg_origin o)
{
    switch (o) {
    case RS_CFG_FROM_DEFAULT: return "default";
    case RS_CFG_FROM_FILE: return "file";
    case RS_CFG_FROM_SET: return "--set";
    default: return "unset";
    }
}

/* Calls fn for each "key = value" of section as in effect (rs_config_section_text's lines). */
static void each_value(const rs_config *cfg, const char *section,
                       void (*fn)(void *user, const char *section, const char *key, const char *value), void *user)
{
    char *text = rs_config_section_text(cfg, section);
    if (!text) return;
    for (char *line = strtok(text, "\n"); line; line = strtok(NULL, "\n")) {
        char *eq = strstr(line, " = ");
        if (line[0] == '[' || !eq) continue;
        *eq = 0;
        fn(user, section, line, eq + 3);
    }
    free(text);
}

/* Calls fn for each section to show: the table's sections in order, and for each base the
 * [base.NAME] sections the config has after it. */
static void each_section(const rs_config *cfg, const char *words, void (*fn)(void *user, const char *section),
                         void *user)
{
    const char *seen[64];
    int nseen = 0;
    for (const rs_cfg_key *k = rs_cfg_keys; k->section; k++) {
        int dup = 0;
        for (int i = 0; i < nseen; i++) dup |= strcmp(seen[i], k->section) == 0;
        if (dup || nseen == 64) continue;
        seen[nseen++] = k->section;
        if (words) { /* only the sections named */
            size_t n = strlen(k->section);
            const char *w = words;
            int named = 0;
            while (!named && (w = strstr(w, k->section))) {
                named = (w == words || w[-1] == ' ') && (w[n] == ' ' || w[n] == 0);
                w += n;
            }
            if (!named) continue;
        }
        fn(user, k->section);
        const char *names[32];
        int count = rs_config_sections(cfg, k->section, names, 32);
        for (int i = 0; i < count && i < 32; i++)
            if (strcmp(names[i], k->section) != 0) fn(user, names[i]);
    }
}

typedef struct {
    const rs_config *cfg;
    FILE *out;
} print_state;

static void print_value(void *user, const char *section, const char *key, const char *value)
{
    print_state *p = user;
    fprintf(p->out, "%s = %s   ; %s\n", key, value, origin_name(rs_config_origin(p->cfg, section, key)));
}

static void print_section(void *user, const char *section)
{
    print_state *p = user;
    fprintf(p->out, "[%s]\n", section);
    each_value(p->cfg, section, print_value, p);
}

void rs_config_print_sections(const rs_config *cfg, const char *words, FILE *out)
{
    print_state p = {cfg, out};
    each_section(cfg, words, print_section, &p);
}

typedef struct {
    const rs_config *cfg;
    rs_json *sections, *set, *current;
} json_state;

static void json_value(void *user, const char *section, const char *key, const char *value)
{
    json_state *j = user;
    rs_cfg_origin o = rs_config_origin(j->cfg, section, key);
    rs_json *v = rs_json_set_obj(j->current, key);
    rs_json_set_str(v, "value", value);
    rs_json_set_str(v, "from", origin_name(o));
    if (o == RS_CFG_FROM_SET) {
        char line[4200];
        snprintf(line, sizeof line, "%s.%s=%s", section, key, value);
        rs_json_push_str(j->set, line);
    }
}

static void json_section(void *user, const char *section)
{
    json_state *j = user;
    j->current = rs_json_set_obj(j->sections, section);
    each_value(j->cfg, section, json_value, j);
}

void rs_config_effective_json(const rs_config *cfg, rs_json *obj)
{
    json_state j = {cfg, rs_json_set_obj(obj, "effective_config"), rs_json_set_arr(obj, "set"), NULL};
    each_section(cfg, NULL, json_section, &j);
}
