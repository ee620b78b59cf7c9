/* options: the command line of every rhoscan program (rhoscan-<stage> and the driver), read
 * against a small table of options, and what a program does at start.
 *
 * An option is --NAME, or --NAME VALUE / --NAME=VALUE when it takes a value; a one-letter
 * spelling (-h) may stand for one. Any other argument starting with '-' is unexpected; the
 * first that does not is the operand (CONFIG), and options may stand before or after it.
 * A program declares its options as a table indexed by its own enum and handles each option
 * as rs_opt_next returns it, in command-line order (so --quiet --verbose ends verbose), e.g.
 *
 *     enum { OPT_FORCE, OPT_SET, OPT_COUNT };
 *     static const rs_option options[] = {
 *         [OPT_FORCE] = {"force", NULL, "run every stage"},
 *         [OPT_SET] = {"set", "s.k=v", "override a config key (repeatable)"},
 *         [OPT_COUNT] = {NULL}};
 *     rs_opt_scan s;
 *     rs_opt_begin(&s, options, argc, argv, 2);
 *     for (int o; (o = rs_opt_next(&s)) != RS_OPT_END;)
 *         switch (o) { case OPT_FORCE: ...; case OPT_SET: use(s.value); ...; default: refuse(s.bad); }
 *     config = s.operand;
 */
#ifndef RS_OPTIONS_H
#define RS_OPTIONS_H

#include <stdio.h>

typedef struct rs_option {
    const char *name;       /* "print-config": the option --print-config; NULL ends a table */
    const char *value_name; /* what it takes, for the usage text ("STAGE"); NULL when it takes none */
    const char *help;       /* one line for the usage text; NULL: listed with the others without */
    char letter;            /* a one-letter spelling ('h': -h), or 0 */
} rs_option;

/* Reading one command line; the fields below `next` are what the last rs_opt_next found. */
typedef struct rs_opt_scan {
    const rs_option *table;
    int argc;
    char **argv;
    int next;            /* argv index still to read */
    const char *value;   /* the value of the option just returned (NULL for one that takes none) */
    const char *bad;     /* the argument just refused (RS_OPT_BAD) */
    const char *operand; /* the operand (CONFIG) once read, else NULL */
} rs_opt_scan;

enum {
    RS_OPT_END = -1, /* every argument was read */
    RS_OPT_BAD = -2  /* s->bad is unexpected: an unknown option, a value option without its value, a
                        value given to an option that takes none, or a second operand */
};

/* Starts reading argv[first..argc-1] against table (ended by {NULL}). */
void rs_opt_begin(rs_opt_scan *s, const rs_option *table, int argc, char **argv, int first);
/* The next option's index in the table (its value in s->value), RS_OPT_BAD or RS_OPT_END.
 * Operands are not returned: the first is kept in s->operand, a second is RS_OPT_BAD. */
int rs_opt_next(rs_opt_scan *s);
/* "PROG: unexpected argument 'ARG'" on stderr for the argument RS_OPT_BAD refused. */
void rs_opt_unexpected(const rs_opt_scan *s, const char *prog);

/* One line per option of table for a usage text, "  --from STAGE   help", then those without
 * help together on one line ("  --quiet, --verbose"). */
void rs_options_print(FILE *out, const rs_option *table);

/* What every program does first: names itself for messages (common/log.h) and reads the test
 * hooks of its environment, once: RHOSCAN_FAULT=enospc:N makes the N-th atomic write of the
 * process fail as a full disk would (common/fileio.h: rs_fault_inject_enospc). */
void rs_program_start(const char *prog);

#endif
