/* driver: rhoscan run over a table of stages (see driver.h). */
#include "pipeline/driver.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/fileio.h"
#include "common/log.h"
#include "common/par.h"
#include "pipeline/effective.h"
#include "pipeline/options.h"
#include "pipeline/report.h"
#include "pipeline/version.h"

enum {
    RUN_FROM,
    RUN_ONLY,
    RUN_FORCE,
    RUN_SET,
    RUN_PRINT_CONFIG,
    RUN_QUIET,
    RUN_VERBOSE,
    RUN_HELP,
    RUN_VERSION,
    RUN_OPTIONS
};
static const rs_option run_options[] = {
    [RUN_FROM] = {"from", "STAGE", "run STAGE and every later stage, whether or not they changed"},
    [RUN_ONLY] = {"only", "STAGE", "run STAGE alone"},
    [RUN_FORCE] = {"force", NULL, "run every stage"},
    [RUN_SET] = {"set", "s.k=v", "override a config key (repeatable); configs/KEYS.md lists them"},
    [RUN_PRINT_CONFIG] = {"print-config", NULL, "print the configuration in effect and where each value came from"},
    [RUN_QUIET] = {"quiet", NULL, "warnings and errors only"},
    [RUN_VERBOSE] = {"verbose", NULL, "debugging messages too"},
    [RUN_HELP] = {"help", NULL, "this text", 'h'},
    [RUN_VERSION] = {"version", NULL, "the version and git commit", 'V'},
    [RUN_OPTIONS] = {NULL}};

static void usage(const rs_stage_def *stages, FILE *out)
{
    fprintf(out,
            "usage: rhoscan run [OPTIONS] CONFIG     run the pipeline: every stage whose inputs or config changed\n"
            "       rhoscan STAGE [OPTIONS] CONFIG   run one stage (the same as the program rhoscan-STAGE)\n"
            "       rhoscan help [STAGE]             this text, or a stage's\n"
            "       rhoscan report WORKDIR           rebuild WORKDIR/report.html from its files (runs no stage)\n"
            "       rhoscan version                  the version and git commit (also --version)\n"
            "Options of run (before or after CONFIG; --NAME=VALUE works as --NAME VALUE):\n");
    rs_options_print(out, run_options);
    fprintf(out, "Stages, in order:\n");
    for (const rs_stage_def *d = stages; d->name; d++) fprintf(out, "  %-12s %s\n", d->name, d->help);
    fputs(RS_PATHS_NOTE, out);
    fputs("Exit codes: 0 success, 1 bad input or config, 2 system error (I/O, memory), 3 internal error.\n", out);
}

int rs_merge_metrics(const rs_stage_def *stages, const rs_config *cfg, const rs_json *run, rs_err *err)
{
    rs_json *all = rs_json_object();
    if (!all) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    rs_json_set_str(all, "program", "rhoscan " RHOSCAN_VERSION);
    rs_json_set_str(all, "git_commit", rs_version_commit());
    rs_json_set_str(all, "config", rs_config_file(cfg));
    rs_config_effective_json(cfg, all);
    rs_json *by_stage = rs_json_set_obj(all, "stages");
    for (const rs_stage_def *d = stages; d->name; d++) {
        char name[128], path[4096];
        char *text = NULL;
        size_t size;
        snprintf(name, sizeof name, "%s.json", d->name);
        if (rs_read_file(rs_work_path(cfg, name, path, sizeof path), &text, &size, NULL) == 0 && size > 1)
            rs_json_set_parsed(by_stage, d->name, text);
        free(text);
    }
    char *run_text = rs_json_text(run);
    if (run_text) {
        run_text[strlen(run_text) - 1] = 0; /* drop the newline */
        rs_json_set_parsed(all, "run", run_text);
    }
    free(run_text);
    char path[4096];
    int rc = rs_json_write(all, rs_work_path(cfg, "metrics.json", path, sizeof path), err);
    rs_json_free(all);
    return rc;
}

/* Why stage d is not run, into why ("" when it is run). */
static void why_not_run(const rs_stage_def *d, const rs_config *cfg, const rs_run_opts *opts, int reached_from,
                        char *why, size_t n)
{
    if (!reached_from) {
        snprintf(why, n, "before --from %s", opts->from);
    } else if (opts->force || opts->only || opts->from) {
        why[0] = 0;
    } else if (rs_stage_up_to_date(d, cfg, why, n)) {
        /* why holds the reason it is current */
    } else {
        rs_log_info("%s: rerun: %s", d->name, why);
        why[0] = 0;
    }
}

/* The run's last line: what ran and what did not, in words that fit the count. */
static void log_done(const rs_stage_def *stages, const rs_run_opts *opts, int nran, double seconds)
{
    int nstages = 0;
    while (stages[nstages].name) nstages++;
    if (opts->only)
        rs_log_info("done in %.1f s: stage %s %s (see metrics.json)", seconds, opts->only, nran ? "run" : "not run");
    else if (nran == 0)
        rs_log_info("done in %.1f s: every stage was up to date, nothing run (see metrics.json)", seconds);
    else if (nran == nstages)
        rs_log_info("done in %.1f s: all %d stages run (see metrics.json)", seconds, nstages);
    else
        rs_log_info("done in %.1f s: %d of %d stages run, the other %d %s (see metrics.json)", seconds, nran, nstages,
                    nstages - nran, opts->from ? "before --from" : "up to date");
}

/* report.html for the run (pipeline/report.h), stage names from the table. */
static void report_after(const rs_stage_def *stages, const rs_config *cfg)
{
    const char *names[64];
    int n = 0;
    for (const rs_stage_def *d = stages; d->name && n < 63; d++) names[n++] = d->name;
    names[n] = NULL;
    rs_stage_report(cfg, names);
}

int rs_run_pipeline(const rs_stage_def *stages, const rs_config *cfg, const rs_run_opts *opts, rs_err *err)
{
    rs_skips skips = {0};
    rs_report run_rep = {NULL, NULL, NULL, &skips, "run"}; /* the driver's own skips: whole stages */
    rs_json *run = rs_json_object();
    rs_json *ran = rs_json_set_arr(run, "ran"), *skipped = rs_json_set_arr(run, "skipped");
    int reached_from = opts->from == NULL, rc = 0, nran = 0;
    double t0 = rs_now();
    for (const rs_stage_def *d = stages; d->name; d++) {
        char why[512];
        if (opts->from && strcmp(d->name, opts->from) == 0) reached_from = 1;
        if (opts->only && strcmp(d->name, opts->only) != 0) continue;
        why[0] = 0;
        if (rs_par_world_rank() == 0) why_not_run(d, cfg, opts, reached_from, why, sizeof why);
        rs_par_bcast(why, sizeof why); /* MPI: rank 0's records decide for every rank */
        if (why[0]) {
            char what[64];
            snprintf(what, sizeof what, "stage %s", d->name);
            rs_report_skip(&run_rep, what, "%s", why);
            rs_json *o = rs_json_push_obj(skipped);
            rs_json_set_str(o, "stage", d->name);
            rs_json_set_str(o, "why", why);
            continue;
        }
        if (rs_stage_execute(d, cfg, &skips, err) != 0) {
            rs_stage_explain_missing(d, stages, cfg, err);
            rc = -1;
            break;
        }
        rs_json_push_str(ran, d->name);
        nran++;
    }
    rs_json_set_num(run, "wall_time_s", rs_now() - t0);
    if (rc == 0) {
        rs_skips_log(&skips);
        rc = rs_par_world_rank() == 0 ? rs_merge_metrics(stages, cfg, run, err) : 0;
        if (rc == 0) log_done(stages, opts, nran, rs_now() - t0);
        if (rc == 0 && nran > 0 && rs_config_bool(cfg, "report", "write") && rs_par_world_rank() == 0)
            report_after(stages, cfg);
    }
    rs_skips_release(&skips);
    rs_json_free(run);
    return rc;
}

/* `rhoscan run`'s options after the word run into opts, sets and *config: 0; -1 when --help or
 * --version was printed (the program then exits 0); else the exit code after saying what was
 * wrong. */
static int read_run_options(const rs_stage_def *stages, int argc, char **argv, rs_run_opts *opts, const char **sets,
                            const char **config, int *print_config)
{
    int nsets = 0;
    rs_opt_scan opt;
    rs_opt_begin(&opt, run_options, argc, argv, 2);
    for (int o; (o = rs_opt_next(&opt)) != RS_OPT_END;) {
        switch (o) {
        case RUN_FROM: opts->from = opt.value; break;
        case RUN_ONLY: opts->only = opt.value; break;
        case RUN_FORCE: opts->force = 1; break;
        case RUN_SET: sets[nsets++] = opt.value; break;
        case RUN_QUIET: rs_log_set_level(RS_LOG_WARN); break;
        case RUN_VERBOSE: rs_log_set_level(RS_LOG_DEBUG); break;
        case RUN_PRINT_CONFIG: *print_config = 1; break;
        case RUN_HELP: usage(stages, stdout); return rs_stdout_check("rhoscan") ? 2 : -1;
        case RUN_VERSION: printf("%s\n", rs_version()); return rs_stdout_check("rhoscan") ? 2 : -1;
        default:
            rs_opt_unexpected(&opt, "rhoscan");
            usage(stages, stderr);
            return 1;
        }
    }
    *config = opt.operand;
    const char *stage_arg = opts->from ? opts->from : opts->only;
    int unknown = stage_arg && !rs_stage_lookup(stages, stage_arg);
    if (!*config || unknown || (opts->from && opts->only)) {
        if (unknown)
            fprintf(stderr, "rhoscan: unknown stage '%s'\n", stage_arg);
        else if (opts->from && opts->only)
            fprintf(stderr, "rhoscan: give --from or --only, not both\n");
        usage(stages, stderr);
        return 1;
    }
    return 0;
}

/* `rhoscan run ...`: the exit code. */
static int run_command(const rs_stage_def *stages, int argc, char **argv)
{
    const char **sets = calloc((size_t)argc + 1, sizeof *sets);
    const char *config = NULL;
    rs_run_opts opts = {NULL, NULL, 0};
    int print_config = 0;
    int rc = read_run_options(stages, argc, argv, &opts, sets, &config, &print_config);
    if (rc != 0) {
        free(sets);
        return rc < 0 ? 0 : rc; /* -1: help or version printed */
    }
    rs_config *cfg = rs_program_config(config, sets, &rc);
    free(sets);
    if (!cfg) return rc;
    if (print_config) {
        if (rs_par_world_rank() == 0) rs_config_print_sections(cfg, NULL, stdout);
        rc = rs_stdout_check("rhoscan");
    } else {
        rs_err err;
        rs_err_clear(&err);
        if (rs_run_pipeline(stages, cfg, &opts, &err) != 0) {
            rs_log_error(&err);
            rc = err.kind ? (int)err.kind : 3;
        }
    }
    rs_config_free(cfg);
    return rc;
}

/* `rhoscan report WORKDIR`: the exit code. */
static int report_command(const rs_stage_def *stages, int argc, char **argv)
{
    if (argc != 3 || argv[2][0] == '-') {
        fprintf(stderr, "usage: rhoscan report WORKDIR   (rebuilds WORKDIR/report.html; runs no stage)\n");
        return 1;
    }
    char probe[4096], bench[4096];
    if (!rs_file_exists(rs_path_join(probe, sizeof probe, argv[2], "metrics.json")) &&
        !rs_file_exists(rs_path_join(bench, sizeof bench, argv[2], "bench.csv"))) {
        fprintf(stderr,
                "rhoscan: report: %s: no metrics.json or bench.csv: not a work folder of rhoscan run or "
                "rhoscan-bench\n",
                argv[2]);
        return 1;
    }
    const char *names[64];
    int n = 0;
    for (const rs_stage_def *d = stages; d->name && n < 63; d++) names[n++] = d->name;
    names[n] = NULL;
    rs_err err;
    rs_err_clear(&err);
    rs_report_opts o = {argv[2], names, NULL, NULL};
    if (rs_report_write(&o, &err) != 0) {
        rs_log_error(&err);
        return err.kind ? (int)err.kind : 3;
    }
    rs_log_info("report: %s/report.html", argv[2]);
    return 0;
}

static int is_any(const char *arg, const char *a, const char *b, const char *c)
{
    return strcmp(arg, a) == 0 || strcmp(arg, b) == 0 || strcmp(arg, c) == 0;
}

int rs_driver_main(const rs_stage_def *stages, int argc, char **argv)
{
    rs_program_start("rhoscan");
    if (argc < 2) {
        usage(stages, stderr);
        return 1;
    }
    const char *command = argv[1];
    if (is_any(command, "help", "--help", "-h")) {
        const rs_stage_def *d = argc > 2 ? rs_stage_lookup(stages, argv[2]) : NULL;
        if (d) { /* rhoscan help STAGE: the stage's own --help */
            char *help_argv[] = {argv[2], "--help", NULL};
            return rs_stage_main(d, 2, help_argv);
        }
        usage(stages, stdout);
        return rs_stdout_check("rhoscan");
    }
    if (is_any(command, "version", "--version", "-V")) {
        printf("%s\n", rs_version());
        return rs_stdout_check("rhoscan");
    }
    if (strcmp(command, "run") == 0) return run_command(stages, argc, argv);
    if (strcmp(command, "report") == 0) return report_command(stages, argc, argv);
    const rs_stage_def *d = rs_stage_lookup(stages, command);
    if (d) return rs_stage_main_of(d, stages, argc - 1, argv + 1); /* git-style: rhoscan mesh CONFIG */
    fprintf(stderr, "rhoscan: unknown command '%s'\n", command);
    usage(stages, stderr);
    return 1;
}
