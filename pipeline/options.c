/* options: the programs' command lines and start-up (see options.h). */
#include "pipeline/options.h"

#include <stdlib.h>
#include <string.h>
#include "common/fileio.h"
#include "common/log.h"
#include "common/par.h"

void rs_opt_begin(rs_opt_scan *s, const rs_option *table, int argc, char **argv, int first)
{
    memset(s, 0, sizeof *s);
    s->table = table;
    s->argc = argc;
    s->argv = argv;
    s->next = first;
}

/* The table entry arg spells (--name, --name=value, -l), with *inline_value set for
 * --name=value; NULL when none does. */
static const rs_option *find_option(const rs_option *table, const char *arg, const char **inline_value)
{
    *inline_value = NULL;
    for (const rs_option *o = table; o->name; o++) {
        if (arg[1] != '-') {
            if (o->letter && arg[1] == o->letter && arg[2] == 0) return o;
            continue;
        }
        size_t k = strlen(o->name);
        if (strncmp(arg + 2, o->name, k) != 0) continue;
        if (arg[2 + k] == 0) return o;
        if (arg[2 + k] == '=') {
            *inline_value = arg + 3 + k;
            return o;
        }
    }
    return NULL;
}

int rs_opt_next(rs_opt_scan *s)
{
    s->value = s->bad = NULL;
    while (s->next < s->argc) {
        const char *arg = s->argv[s->next++];
        if (arg[0] != '-') {
            if (!s->operand) {
                s->operand = arg;
                continue;
            }
            s->bad = arg;
            return RS_OPT_BAD;
        }
        const char *inline_value;
        const rs_option *o = find_option(s->table, arg, &inline_value);
        int takes_value = o && o->value_name;
        if (!o || (inline_value && !takes_value) || (takes_value && !inline_value && s->next >= s->argc)) {
            s->bad = arg;
            return RS_OPT_BAD;
        }
        if (takes_value) s->value = inline_value ? inline_value : s->argv[s->next++];
        return (int)(o - s->table);
    }
    return RS_OPT_END;
}

void rs_opt_unexpected(const rs_opt_scan *s, const char *prog)
{
    fprintf(stderr, "%s: unexpected argument '%s'\n", prog, s->bad ? s->bad : "");
}

/* "-h, --help" or "--from STAGE" into buf. */
static const char *spelling_of(const rs_option *o, char *buf, size_t n)
{
    char letter[8] = "";
    if (o->letter) snprintf(letter, sizeof letter, "-%c, ", o->letter);
    snprintf(buf, n, "%s--%s%s%s", letter, o->name, o->value_name ? " " : "", o->value_name ? o->value_name : "");
    return buf;
}

void rs_options_print(FILE *out, const rs_option *table)
{
    char spelling[128];
    int width = 0;
    for (const rs_option *o = table; o->name; o++) {
        int n = (int)strlen(spelling_of(o, spelling, sizeof spelling));
        if (o->help && n > width) width = n;
    }
    for (const rs_option *o = table; o->name; o++)
        if (o->help) fprintf(out, "  %-*s  %s\n", width, spelling_of(o, spelling, sizeof spelling), o->help);
    const char *sep = "  ";
    for (const rs_option *o = table; o->name; o++) {
        if (o->help) continue;
        fprintf(out, "%s--%s", sep, o->name);
        sep = ", ";
    }
    if (sep[0] == ',') fputc('\n', out);
}

void rs_program_start(const char *prog)
{
    rs_log_init(prog);
    rs_err err;
    rs_err_clear(&err);
    if (rs_par_init(&err) != 0) { /* started by an MPI launcher: MPI first, or nothing */
        rs_log_error(&err);
        exit(err.kind ? (int)err.kind : 2);
    }
    const char *fault = getenv("RHOSCAN_FAULT");
    if (fault && strncmp(fault, "enospc:", 7) == 0) rs_fault_inject_enospc(atol(fault + 7));
}
