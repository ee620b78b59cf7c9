/* driver: `rhoscan run CONFIG` runs a table of stages in order and reruns only those whose
 * inputs or config sections changed since the last run (recorded in the work folder), saying
 * what it skipped and why; then merges every <stage>.json into metrics.json. The table is the
 * caller's (stages/stages.h: rs_stage_table), so that this layer knows no stage. */
#ifndef RS_DRIVER_H
#define RS_DRIVER_H

#include "common/config.h"
#include "common/err.h"
#include "common/json.h"
#include "pipeline/stage.h"

/* Which stages a run runs: by default those not up to date (rs_stage_up_to_date). */
typedef struct rs_run_opts {
    const char *from; /* run this stage and every later one, changed or not; NULL: none */
    const char *only; /* run this stage alone; NULL: every stage */
    int force;        /* run every stage */
} rs_run_opts;

/* Runs stages (ended by {NULL}; from and only name stages of it) as opts says, logs the summary
 * of what was skipped, and writes metrics.json (rs_merge_metrics). Stops at the first stage
 * that fails, with its error. */
int rs_run_pipeline(const rs_stage_def *stages, const rs_config *cfg, const rs_run_opts *opts, rs_err *err);

/* metrics.json in the work folder: every stage's <stage>.json as it is on disk (stages that
 * never ran are left out) and run, what this run did. */
int rs_merge_metrics(const rs_stage_def *stages, const rs_config *cfg, const rs_json *run, rs_err *err);

/* The program rhoscan: `rhoscan run [--from STAGE] [--only STAGE] [--force] [--set s.k=v]...
 * [--quiet|--verbose] CONFIG` and `rhoscan help`, over stages. Returns the exit code. */
int rs_driver_main(const rs_stage_def *stages, int argc, char **argv);

#endif
