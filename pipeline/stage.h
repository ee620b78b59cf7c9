/* stage: what every stage shares. A stage is a function
 *     int rs_<name>_run(const rs_config *cfg, rs_report *rep, rs_err *err)
 * that reads its inputs from the work folder and its config sections, writes its outputs
 * atomically, and records counts, timings and skips in rep. rs_stage_main() turns it into a
 * program; the driver (pipeline/driver.h: rhoscan run) calls the same functions through a
 * table of stages (stages/stages.h: rs_stage_table). */
#ifndef RS_STAGE_H
#define RS_STAGE_H

#include <stddef.h>
#include <stdint.h>
#include "common/config.h"
#include "common/err.h"
#include "common/json.h"

/* What a run skipped, in order, for the summary at its end: a line "  stage: what: why" per
 * skip. The program (a stage program or the driver) owns it; start with {0}. */
typedef struct rs_skips {
    char *lines;
    size_t len;
} rs_skips;

void rs_skips_add(rs_skips *s, const char *stage, const char *what, const char *why);
/* Logs "what was skipped, and why:" and the lines; nothing when there are none. */
void rs_skips_log(const rs_skips *s);
void rs_skips_release(rs_skips *s);

typedef struct rs_report {
    rs_json *metrics;  /* the stage's <stage>.json object; add fields freely */
    rs_json *skipped;  /* array of {"what", "why"}, or NULL */
    rs_json *timings;  /* object: step -> seconds, or NULL */
    rs_skips *skips;   /* the run's skips, for its summary; NULL when none is kept */
    const char *stage; /* the name its skips are listed under in skips ("mesh") */
} rs_report;

/* Records that something was skipped and why: logged, added to rep->skipped and rep->skips
 * (rep may be NULL: logged only). */
void rs_report_skip(rs_report *rep, const char *what, const char *why_fmt, ...) __attribute__((format(printf, 3, 4)));
void rs_report_time(rs_report *rep, const char *step, double seconds);

typedef int (*rs_stage_fn)(const rs_config *cfg, rs_report *rep, rs_err *err);

typedef struct rs_stage_def {
    const char *name; /* "mesh" */
    rs_stage_fn run;
    const char *sections; /* config sections it reads, space-separated */
    const char *inputs;   /* work-folder files it reads, space-separated */
    const char *outputs;  /* work-folder files it writes, space-separated */
    const char *help;
    int every_rank; /* in an MPI run (common/par.h): 1 runs it on every rank, whose costly loops
                       split their work; 0 (the default) on rank 0 alone, the others waiting */
} rs_stage_def;

/* The stage called name in table (ended by {NULL}), or NULL. */
const rs_stage_def *rs_stage_lookup(const rs_stage_def *table, const char *name);

/* The work folder of a config ([pipeline] workdir, resolved), created if needed. */
int rs_workdir(const rs_config *cfg, char *out, size_t n, rs_err *err);
/* workdir/name into out. */
const char *rs_work_path(const rs_config *cfg, const char *name, char *out, size_t n);

/* Runs one stage: calls def->run, writes <stage>.json (metrics, timings, skips, fingerprint,
 * input checksums) and the state file used for rerun decisions. The stage's skips are also
 * added to skips (may be NULL), under the stage's name. In an MPI run it is collective: rank 0
 * alone writes <stage>.json and the state, and every rank returns when rank 0's files are
 * written; -1 on every rank when the stage failed on any. */
int rs_stage_execute(const rs_stage_def *def, const rs_config *cfg, rs_skips *skips, rs_err *err);

/* After a stage or a run: the run report (pipeline/report.h) for cfg's work folder and its
 * [report] truth (stages: the pipeline's names in order, or NULL: metrics.json's). A failure is
 * logged as a warning: the stages' outputs stand without the page. */
void rs_stage_report(const rs_config *cfg, const char *const *stages);

/* The fingerprint of a stage's inputs: program version, its config sections as in effect,
 * and the contents of every input file (work-folder inputs and the files its keys name). */
int rs_stage_fingerprint(const rs_stage_def *def, const rs_config *cfg, uint64_t *fp, rs_err *err);
/* 1 when the recorded state says the stage ran with this fingerprint and its outputs are
 * unchanged since; 0 otherwise with the reason in why. */
int rs_stage_up_to_date(const rs_stage_def *def, const rs_config *cfg, char *why, size_t n);

/* After a program printed data to stdout: 0, or 2 (system error) with a message naming prog
 * when the data did not all get out (a full disk, /dev/full, a closed pipe). */
int rs_stdout_check(const char *prog);

/* A program's config: loads path with the --set overrides and applies [pipeline] threads.
 * NULL after logging the error, with *exit_code set to the error's exit code. */
rs_config *rs_program_config(const char *path, const char *const *sets, int *exit_code);

/* Shared program entry for rhoscan-<stage>: options --set section.key=value (repeatable),
 * --print-config, --quiet, --verbose, --help (pipeline/options.h); CONFIG anywhere among them.
 * Logs the summary of what the stage skipped. Returns the exit code. */
int rs_stage_main(const rs_stage_def *def, int argc, char **argv);
/* The same, for `rhoscan STAGE CONFIG`: table (the whole pipeline's, or NULL) names the stage
 * that writes a missing input in the error. */
int rs_stage_main_of(const rs_stage_def *def, const rs_stage_def *table, int argc, char **argv);

/* When err names a work-folder input of def that does not exist, appends which stage of table
 * writes it (table may be NULL) and what to run first. */
void rs_stage_explain_missing(const rs_stage_def *def, const rs_stage_def *table, const rs_config *cfg, rs_err *err);

#endif
