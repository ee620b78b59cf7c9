/* rhoscan: the driver. `rhoscan run CONFIG` runs the stages in order and reruns only those
 * whose inputs or config sections changed since the last run (recorded in the work folder),
 * saying what it skipped and why; then merges every <stage>.json into metrics.json. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/fileio.h"
#include "common/log.h"
#include "pipeline/options.h"
#include "pipeline/stage.h"

static void usage(FILE *out)
{
    fprintf(out,
            "usage: rhoscan run [--from STAGE] [--only STAGE] [--force] [--set section.key=value]... CONFIG\n"
            "       rhoscan help\n"
            "Options may stand before or after CONFIG.\n"
            "  --from STAGE   run STAGE and every later stage, whether or not they changed\n"
            "  --only STAGE   run STAGE alone\n"
            "  --force        run every stage\n"
            "  --set s.k=v    override a config key (repeatable); configs/KEYS.md lists them\n"
            "  --quiet, --verbose\n"
            "Stages, in order (each is also a program rhoscan-STAGE CONFIG):\n");
    for (const rs_stage_def *d = rs_stage_table; d->name; d++) fprintf(out, "  %-12s %s\n", d->name, d->help);
}

/* metrics.json: every stage's own JSON as it is on disk, plus what this run did. */
static int merge_metrics(const rs_config *cfg, rs_json *run, rs_err *err)
{
    rs_json *all = rs_json_object();
    if (!all) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    rs_json_set_str(all, "program", "rhoscan " RHOSCAN_VERSION);
    rs_json_set_str(all, "config", rs_config_file(cfg));
    rs_json *stages = rs_json_set_obj(all, "stages");
    for (const rs_stage_def *d = rs_stage_table; d->name; d++) {
        char name[128], path[4096];
        char *text = NULL;
        size_t size;
        snprintf(name, sizeof name, "%s.json", d->name);
        if (rs_read_file(rs_work_path(cfg, name, path, sizeof path), &text, &size, NULL) == 0 && size > 1)
            rs_json_set_raw(stages, d->name, text);
        free(text);
    }
    char *run_text = rs_json_text(run);
    if (run_text) {
        run_text[strlen(run_text) - 1] = 0; /* drop the newline */
        rs_json_set_raw(all, "run", run_text);
    }
    free(run_text);
    char path[4096];
    int rc = rs_json_write(all, rs_work_path(cfg, "metrics.json", path, sizeof path), err);
    rs_json_free(all);
    return rc;
}

static int run_pipeline(const rs_config *cfg, const char *from, const char *only, int force, rs_err *err)
{
    rs_json *run = rs_json_object();
    rs_json *ran = rs_json_set_arr(run, "ran"), *skipped = rs_json_set_arr(run, "skipped");
    int reached_from = from == NULL, rc = 0, nran = 0;
    double t0 = rs_now();
    for (const rs_stage_def *d = rs_stage_table; d->name; d++) {
        char why[512];
        if (from && strcmp(d->name, from) == 0) reached_from = 1;
        if (only && strcmp(d->name, only) != 0) continue;
        if (!reached_from) {
            snprintf(why, sizeof why, "before --from %s", from);
        } else if (force || only || from) {
            why[0] = 0;
        } else if (rs_stage_up_to_date(d, cfg, why, sizeof why)) {
            /* why holds the reason it is current */
        } else {
            rs_log_info("%s: rerun: %s", d->name, why);
            why[0] = 0;
        }
        if (why[0]) {
            rs_log_info("skipped stage %s: %s", d->name, why);
            {
                char what[64];
                snprintf(what, sizeof what, "stage %s", d->name);
                rs_report_skip(NULL, what, "%s", why);
            }
            rs_json *o = rs_json_push_obj(skipped);
            rs_json_set_str(o, "stage", d->name);
            rs_json_set_str(o, "why", why);
            continue;
        }
        if (rs_stage_execute(d, cfg, err) != 0) {
            rc = -1;
            break;
        }
        rs_json_push_str(ran, d->name);
        nran++;
    }
    rs_json_set_num(run, "wall_time_s", rs_now() - t0);
    if (rc == 0) {
        rs_report_skips_summary();
        rc = merge_metrics(cfg, run, err);
        if (rc == 0)
            rs_log_info("done in %.1f s: %d stage%s run, the rest up to date (see metrics.json)", rs_now() - t0, nran,
                        nran == 1 ? "" : "s");
    }
    rs_json_free(run);
    return rc;
}

int main(int argc, char **argv)
{
    rs_program_start("rhoscan");
    if (argc < 2 || strcmp(argv[1], "help") == 0 || strcmp(argv[1], "--help") == 0) {
        usage(argc < 2 ? stderr : stdout);
        return argc < 2 ? 1 : rs_stdout_check("rhoscan");
    }
    if (strcmp(argv[1], "run") != 0) {
        fprintf(stderr, "rhoscan: unknown command '%s'\n", argv[1]);
        usage(stderr);
        return 1;
    }
    const char **sets = calloc((size_t)argc + 1, sizeof *sets);
    const char *config = NULL, *from = NULL, *only = NULL;
    int nsets = 0, force = 0;
    for (int i = 2; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--set") == 0 && i + 1 < argc)
            sets[nsets++] = argv[++i];
        else if (strncmp(a, "--set=", 6) == 0)
            sets[nsets++] = a + 6;
        else if (strcmp(a, "--from") == 0 && i + 1 < argc)
            from = argv[++i];
        else if (strcmp(a, "--only") == 0 && i + 1 < argc)
            only = argv[++i];
        else if (strcmp(a, "--force") == 0)
            force = 1;
        else if (strcmp(a, "--quiet") == 0)
            rs_log_set_level(RS_LOG_WARN);
        else if (strcmp(a, "--verbose") == 0)
            rs_log_set_level(RS_LOG_DEBUG);
        else if (a[0] == '-' || config) {
            fprintf(stderr, "rhoscan: unexpected argument '%s'\n", a);
            usage(stderr);
            free(sets);
            return 1;
        } else
            config = a;
    }
    const char *stage_arg = from ? from : only;
    if (!config || (stage_arg && !rs_stage_find(stage_arg)) || (from && only)) {
        if (stage_arg && !rs_stage_find(stage_arg))
            fprintf(stderr, "rhoscan: unknown stage '%s'\n", stage_arg);
        else if (from && only)
            fprintf(stderr, "rhoscan: give --from or --only, not both\n");
        usage(stderr);
        free(sets);
        return 1;
    }
    int rc = 0;
    rs_config *cfg = rs_program_config(config, sets, &rc);
    free(sets);
    if (!cfg) return rc;
    rs_err err;
    rs_err_clear(&err);
    if (run_pipeline(cfg, from, only, force, &err) != 0) {
        rs_log_error(&err);
        rc = err.kind ? (int)err.kind : 3;
    }
    rs_config_free(cfg);
    return rc;
}
