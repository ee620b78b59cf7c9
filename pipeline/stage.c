/* stage: running a stage, its report and <stage>.json, fingerprints for rerun decisions,
 * the skips of a run, and the shared program entry of rhoscan-<stage> (see stage.h). */
#include "pipeline/stage.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#include "common/fileio.h"
#include "common/log.h"
#include "common/par.h"
#include "pipeline/effective.h"
#include "pipeline/options.h"
#include "pipeline/report.h"
#include "pipeline/version.h"

void rs_skips_add(rs_skips *s, const char *stage, const char *what, const char *why)
{
    char line[768];
    /* The driver's own skips are whole stages ("stage mesh"): they need no prefix. */
    int n = strcmp(stage, "run") == 0 ? snprintf(line, sizeof line, "  %s: %s\n", what, why)
                                      : snprintf(line, sizeof line, "  %s: %s: %s\n", stage, what, why);
    if (n <= 0) return;
    char *grown = realloc(s->lines, s->len + (size_t)n + 1);
    if (!grown) return;
    memcpy(grown + s->len, line, (size_t)n + 1);
    s->lines = grown;
    s->len += (size_t)n;
}

void rs_skips_log(const rs_skips *s)
{
    if (s->len) rs_log_info("what was skipped, and why:\n%.*s", (int)s->len - 1, s->lines);
}

void rs_skips_release(rs_skips *s)
{
    free(s->lines);
    s->lines = NULL;
    s->len = 0;
}

void rs_report_skip(rs_report *rep, const char *what, const char *why_fmt, ...)
{
    char why[512];
    va_list ap;
    va_start(ap, why_fmt);
    vsnprintf(why, sizeof why, why_fmt, ap);
    va_end(ap);
    rs_log_info("skipped %s: %s", what, why);
    if (!rep) return;
    if (rep->skips) rs_skips_add(rep->skips, rep->stage, what, why);
    if (!rep->skipped) return;
    rs_json *o = rs_json_push_obj(rep->skipped);
    rs_json_set_str(o, "what", what);
    rs_json_set_str(o, "why", why);
}

void rs_report_time(rs_report *rep, const char *step, double seconds)
{
    if (rep && rep->timings) rs_json_set_num(rep->timings, step, seconds);
}

int rs_workdir(const rs_config *cfg, char *out, size_t n, rs_err *err)
{
    if (!rs_config_path(cfg, "pipeline", "workdir", out, n))
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0, "[pipeline] workdir is not set");
    return rs_mkdir_p(out, err);
}

const char *rs_work_path(const rs_config *cfg, const char *name, char *out, size_t n)
{
    char dir[4096];
    if (!rs_config_path(cfg, "pipeline", "workdir", dir, sizeof dir)) dir[0] = 0;
    return rs_path_join(out, n, dir, name);
}

/* Calls fn(word, user) for each space-separated word of list. */
static void each_word(const char *list, void (*fn)(const char *, void *), void *user)
{
    char word[128];
    while (list && *list) {
        while (*list == ' ') list++;
        size_t k = strcspn(list, " ");
        if (k == 0) break;
        snprintf(word, sizeof word, "%.*s", (int)(k < sizeof word ? k : sizeof word - 1), list);
        fn(word, user);
        list += k;
    }
}

typedef struct {
    const rs_config *cfg;
    uint64_t hash;
    rs_json *inputs; /* optional: file -> hex hash */
} fp_state;

static void fp_file(fp_state *s, const char *path)
{
    uint64_t h = 0;
    if (rs_hash_file(path, &h, NULL) != 0) h = 0; /* missing: the stage itself will say so */
    s->hash = rs_hash_bytes(path, strlen(path), s->hash);
    s->hash = rs_hash_bytes(&h, sizeof h, s->hash);
    if (s->inputs) {
        char hex[32];
        snprintf(hex, sizeof hex, "%016" PRIx64, h);
        rs_json_set_str(s->inputs, path, h ? hex : "missing");
    }
}

static void fp_one_section(fp_state *s, const char *section);

/* A section and its named instances: "capture" takes in [capture.NAME] too (the further
 * captures), so that adding or changing one reruns the stages that read them. */
static void fp_section(const char *section, void *user)
{
    fp_state *s = user;
    fp_one_section(s, section);
    const char *names[64];
    int n = rs_config_sections(s->cfg, section, names, 64);
    for (int i = 0; i < n && i < 64; i++)
        if (strchr(names[i], '.')) fp_one_section(s, names[i]);
}

static void fp_one_section(fp_state *s, const char *section)
{
    char *text = rs_config_section_text(s->cfg, section);
    if (text) s->hash = rs_hash_bytes(text, strlen(text), s->hash);
    free(text);
    /* Files named by the section's path keys are inputs too ([capture.NAME] has [capture]'s keys). */
    size_t blen = strcspn(section, ".");
    for (const rs_cfg_key *k = rs_cfg_keys; k->section; k++) {
        if (strlen(k->section) != blen || strncmp(k->section, section, blen) != 0) continue;
        char path[4096];
        if (k->type == RS_CFG_PATH && rs_config_path(s->cfg, section, k->key, path, sizeof path)) {
            if (strcmp(section, "pipeline") != 0) fp_file(s, path);
        } else if (k->type == RS_CFG_PATHS) {
            int n = rs_config_path_count(s->cfg, section, k->key);
            for (int i = 0; i < n; i++)
                if (rs_config_path_at(s->cfg, section, k->key, i, path, sizeof path)) fp_file(s, path);
        }
    }
}

static void fp_input(const char *name, void *user)
{
    fp_state *s = user;
    char path[4096];
    fp_file(s, rs_work_path(s->cfg, name, path, sizeof path));
}

static uint64_t fingerprint(const rs_stage_def *def, const rs_config *cfg, rs_json *inputs)
{
    fp_state s = {cfg, RS_HASH_SEED, inputs};
    s.hash = rs_hash_bytes(RHOSCAN_VERSION, strlen(RHOSCAN_VERSION), s.hash);
    s.hash = rs_hash_bytes(def->name, strlen(def->name), s.hash);
    each_word(def->sections, fp_section, &s);
    each_word(def->inputs, fp_input, &s);
    return s.hash;
}

int rs_stage_fingerprint(const rs_stage_def *def, const rs_config *cfg, uint64_t *fp, rs_err *err)
{
    *fp = fingerprint(def, cfg, NULL);
    return 0;
}

/* The state file: "fingerprint HEX" then "output NAME HEX" per output (0 when absent). */
static const char *state_path(const rs_stage_def *def, const rs_config *cfg, char *out, size_t n)
{
    char name[256];
    snprintf(name, sizeof name, ".rhoscan/%s.state", def->name);
    return rs_work_path(cfg, name, out, n);
}

typedef struct {
    const rs_config *cfg;
    char *buf;
    size_t len, cap;
} state_buf;

static void state_output(const char *name, void *user)
{
    state_buf *b = user;
    char path[4096];
    uint64_t h = 0;
    if (rs_hash_file(rs_work_path(b->cfg, name, path, sizeof path), &h, NULL) != 0) h = 0;
    int k = snprintf(b->buf + b->len, b->cap - b->len, "output %s %016" PRIx64 "\n", name, h);
    if (k > 0 && (size_t)k < b->cap - b->len) b->len += (size_t)k;
}

static char *state_text(const rs_stage_def *def, const rs_config *cfg, uint64_t fp)
{
    state_buf b = {cfg, malloc(8192), 0, 8192};
    if (!b.buf) return NULL;
    b.len = (size_t)snprintf(b.buf, b.cap, "fingerprint %016" PRIx64 "\n", fp);
    each_word(def->outputs, state_output, &b);
    return b.buf;
}

int rs_stage_up_to_date(const rs_stage_def *def, const rs_config *cfg, char *why, size_t n)
{
    char path[4096];
    char *old = NULL;
    size_t size;
    if (rs_read_file(state_path(def, cfg, path, sizeof path), &old, &size, NULL) != 0) {
        snprintf(why, n, "no record of an earlier run");
        return 0;
    }
    uint64_t fp = fingerprint(def, cfg, NULL);
    char *now = state_text(def, cfg, fp);
    int same_fp = now && strncmp(old, now, strlen("fingerprint ") + 16) == 0;
    int same = now && strcmp(old, now) == 0;
    if (!same_fp)
        snprintf(why, n, "its inputs or config sections [%s] changed", def->sections);
    else if (!same)
        snprintf(why, n, "its outputs were changed or removed since the last run");
    else
        snprintf(why, n, "inputs and config sections [%s] unchanged since the last run", def->sections);
    free(old);
    free(now);
    return same;
}

/* The process's peak resident memory in MB so far (Linux VmHWM), NAN when unknown. Read from
 * inside: a parent's getrusage of its child also counts the parent's pages at the fork. */
static double peak_rss_mb(void)
{
    FILE *f = fopen("/proc/self/status", "r");
    if (!f) return NAN;
    char line[256];
    double kb = NAN;
    while (fgets(line, sizeof line, f))
        if (sscanf(line, "VmHWM: %lf kB", &kb) == 1) break;
    fclose(f);
    return kb / 1024;
}

const rs_stage_def *rs_stage_lookup(const rs_stage_def *table, const char *name)
{
    for (const rs_stage_def *d = table; d->name; d++)
        if (strcmp(d->name, name) == 0) return d;
    return NULL;
}

/* Removes the work folder this run created when nothing was written into it but the state
 * folder: a failed first run leaves no empty folder behind (rmdir refuses anything else). */
static void remove_if_created(const char *dir, int existed)
{
    char path[4096];
    if (existed) return;
    rmdir(rs_path_join(path, sizeof path, dir, ".rhoscan"));
    rmdir(dir);
}

/* CPU seconds of the process so far (every thread). */
static double cpu_seconds(void)
{
    struct timespec ts;
    return clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts) == 0 ? (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec : NAN;
}

void rs_stage_report(const rs_config *cfg, const char *const *stages)
{
    char dir[4096];
    rs_err err;
    rs_err_clear(&err);
    double t0 = rs_now(), c0 = cpu_seconds();
    char truth[4096];
    const char *tp =
        rs_config_has(cfg, "report", "truth") ? rs_config_path(cfg, "report", "truth", truth, sizeof truth) : NULL;
    rs_report_opts o = {dir, stages, tp, NULL};
    if (rs_workdir(cfg, dir, sizeof dir, &err) != 0 || rs_report_write(&o, &err) != 0) {
        rs_log_warn("report: report.html not written: %s%s%s", err.file, err.file[0] ? ": " : "", err.msg);
        return;
    }
    rs_log_info("report: %s/report.html (%.3f s, CPU %.3f s)", dir, rs_now() - t0, cpu_seconds() - c0);
}

/* In an MPI run, what the stage's ranks exchanged (common/par.h): the host's, not the result's. */
/* The pixel rows each rank computed in the stage (observe and render split by rows), in rank
 * order: every rank's share is there, so a rank that skipped its rows shows (tests/mpi). */
static void report_rows(rs_json *r, size_t rows)
{
    uint64_t mine = rows;
    unsigned char *all = NULL;
    size_t bytes = 0;
    rs_err err;
    rs_err_clear(&err);
    if (rs_par_allgather_bytes(&mine, sizeof mine, &all, &bytes, NULL, &err) != 0) return;
    uint64_t sum = 0, v;
    for (size_t k = 0; k + sizeof v <= bytes; k += sizeof v) {
        memcpy(&v, all + k, sizeof v);
        sum += v;
    }
    if (sum > 0) {
        rs_json *per = rs_json_set_arr(r, "rows_per_rank");
        for (size_t k = 0; k + sizeof v <= bytes; k += sizeof v) {
            memcpy(&v, all + k, sizeof v);
            rs_json_push_num(per, (double)v);
        }
    }
    free(all);
}

static void report_ranks(rs_report *rep, const rs_par_traffic *before, size_t rows, double cpu)
{
    if (rs_par_world_size() <= 1) return;
    rs_par_traffic now = rs_par_traffic_now();
    /* Collective for a stage of every rank: each rank's CPU seconds, in rank order. */
    unsigned char *all = NULL;
    size_t bytes = 0;
    rs_err err;
    rs_err_clear(&err);
    if (rs_par_allgather_bytes(&cpu, sizeof cpu, &all, &bytes, NULL, &err) != 0) bytes = 0;
    rs_json *r = rs_json_set_obj(rep->metrics, "mpi");
    rs_json_set_int(r, "ranks", rs_par_world_size());
    rs_json_set_int(r, "ranks_on_host", rs_par_local_size());
#ifdef _OPENMP
    rs_json_set_int(r, "threads_per_rank", omp_get_max_threads());
#endif
    rs_json_set_str(r, "ran_on", rs_par_size() > 1 ? "every rank" : "rank 0");
    rs_json_set_num(r, "rank0_bytes", now.bytes - before->bytes);
    rs_json_set_num(r, "rank0_messages", now.messages - before->messages);
    rs_json *per = rs_json_set_arr(r, "cpu_time_s_per_rank");
    for (size_t k = 0; k + sizeof cpu <= bytes; k += sizeof cpu) {
        double c;
        memcpy(&c, all + k, sizeof c);
        rs_json_push_num(per, c);
    }
    free(all);
    report_rows(r, rows);
}

/* The stage on this rank: def->run, then (rank 0) <stage>.json and the state file. */
static int execute_here(const rs_stage_def *def, const rs_config *cfg, rs_skips *skips, rs_err *err)
{
    char dir[4096], path[4096];
    int existed = rs_config_path(cfg, "pipeline", "workdir", dir, sizeof dir) && access(dir, F_OK) == 0;
    if (rs_workdir(cfg, dir, sizeof dir, err) != 0) return -1;
    if (rs_mkdir_p(rs_path_join(path, sizeof path, dir, ".rhoscan"), err) != 0) return -1;

    rs_report rep = {rs_json_object(), NULL, NULL, skips, def->name};
    if (!rep.metrics) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    rs_json_set_str(rep.metrics, "stage", def->name);
    rs_json_set_str(rep.metrics, "program", "rhoscan " RHOSCAN_VERSION);
    rs_json_set_str(rep.metrics, "config", rs_config_file(cfg));
    rs_json *inputs = rs_json_set_obj(rep.metrics, "inputs");
    uint64_t fp = fingerprint(def, cfg, inputs);
    rep.timings = rs_json_set_obj(rep.metrics, "timings_s");
    rep.skipped = rs_json_set_arr(rep.metrics, "skipped");

    rs_log_info("%s: started", def->name);
    rs_par_traffic traffic = rs_par_traffic_now();
    size_t rows0 = rs_par_rows_total();
    double t0 = rs_now(), c0 = cpu_seconds();
    size_t warned = rs_log_warning_count();
    int rc = def->run(cfg, &rep, err);
    double wall = rs_now() - t0, cpu = cpu_seconds() - c0;
    /* A stage of every rank can fail on rank 0 alone (its files, written there alone): every
     * rank must know before report_ranks' collective, or the others would wait in it forever. */
    if (rs_par_size() > 1 && rs_par_any(rc != 0) && rc == 0)
        rc = rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "%s: the stage failed on another MPI rank (rank 0 says why)",
                        def->name);
    if (rc != 0) {
        rs_json_free(rep.metrics);
        remove_if_created(dir, existed);
        return -1;
    }
    rs_json_set_num(rep.metrics, "wall_time_s", wall);
    rs_json_set_num(rep.metrics, "cpu_time_s", cpu); /* every thread's, this process */
    report_ranks(&rep, &traffic, rs_par_rows_total() - rows0, cpu);
    if (!rs_par_is_root()) { /* rank 0 writes the stage's record */
        rs_json_free(rep.metrics);
        return 0;
    }
    if (rs_log_warning_count() > warned) {           /* what it warned of, for the report */
        rs_json *w = rs_json_set_arr(rep.metrics, "warnings");
        for (size_t k = warned; k < rs_log_warning_count(); k++) rs_json_push_str(w, rs_log_warning(k));
    }
    double peak = peak_rss_mb();
    if (!isnan(peak)) rs_json_set_num(rep.metrics, "peak_rss_mb", peak); /* the process's, so far */
    char hex[32];
    snprintf(hex, sizeof hex, "%016" PRIx64, fp);
    rs_json_set_str(rep.metrics, "fingerprint", hex);
    char name[256];
    snprintf(name, sizeof name, "%s.json", def->name);
    rc = rs_json_write(rep.metrics, rs_path_join(path, sizeof path, dir, name), err);
    rs_json_free(rep.metrics);
    if (rc != 0) return -1;

    char *state = state_text(def, cfg, fp);
    if (!state) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    rc = rs_write_file_atomic(state_path(def, cfg, path, sizeof path), state, strlen(state), err);
    free(state);
    if (rc == 0) rs_log_info("%s: done in %.2f s", def->name, wall);
    return rc;
}

int rs_stage_execute(const rs_stage_def *def, const rs_config *cfg, rs_skips *skips, rs_err *err)
{
    int rc = 0;
    if (rs_par_world_size() <= 1) return execute_here(def, cfg, skips, err);
    if (def->every_rank) {
        rc = execute_here(def, cfg, skips, err);
    } else if (rs_par_world_rank() == 0) { /* its library calls see a team of one */
        rs_par_solo_begin();
        rc = execute_here(def, cfg, skips, err);
        rs_par_solo_end();
    }
    /* Also the barrier: no rank reads the stage's outputs before rank 0 has written them. */
    if (rs_par_any(rc != 0) && rc == 0)
        rc = rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "%s: the stage failed on another MPI rank (rank 0 says why)",
                        def->name);
    return rc;
}

int rs_stdout_check(const char *prog)
{
    if (fflush(stdout) == 0 && !ferror(stdout)) return 0;
    fprintf(stderr, "%s: cannot write to standard output: %s\n", prog, strerror(errno));
    return 2;
}

rs_config *rs_program_config(const char *path, const char *const *sets, int *exit_code)
{
    rs_err err;
    rs_err_clear(&err);
    rs_config *cfg = rs_config_load(path, sets, &err);
    if (!cfg) {
        rs_log_error(&err);
        *exit_code = err.kind ? (int)err.kind : 1;
        return NULL;
    }
#ifdef _OPENMP
    long threads = rs_config_int(cfg, "pipeline", "threads");
    if (threads > 0) {
        omp_set_num_threads((int)threads);
    } else if (rs_par_local_size() > 1 && !getenv("OMP_NUM_THREADS")) {
        /* MPI ranks sharing a host share its cores: not every rank on every core. The host's
         * count, not omp_get_num_procs: a launcher may have bound the rank to fewer. */
        long host = sysconf(_SC_NPROCESSORS_ONLN), cores = host / rs_par_local_size();
        omp_set_num_threads(cores > 1 ? (int)cores : 1);
        rs_par_set_solo_threads((int)host); /* rank 0 alone: the other ranks sleep */
    }
#endif
    return cfg;
}

enum { STAGE_SET, STAGE_PRINT_CONFIG, STAGE_QUIET, STAGE_VERBOSE, STAGE_HELP, STAGE_VERSION, STAGE_OPTIONS };
static const rs_option stage_options[] = {
    [STAGE_SET] = {"set", "section.key=value", "override a config key (repeatable); configs/KEYS.md lists them"},
    [STAGE_PRINT_CONFIG] = {"print-config", NULL, "print the stage's config sections as in effect, run nothing"},
    [STAGE_QUIET] = {"quiet", NULL, "warnings and errors only"},
    [STAGE_VERBOSE] = {"verbose", NULL, "debugging messages too"},
    [STAGE_HELP] = {"help", NULL, "this text", 'h'},
    [STAGE_VERSION] = {"version", NULL, "the version and git commit", 'V'},
    [STAGE_OPTIONS] = {NULL}};

static void stage_usage(const char *stage, FILE *out)
{
    fprintf(out,
            "usage: rhoscan-%s [OPTIONS] CONFIG   (or: rhoscan %s [OPTIONS] CONFIG)\n"
            "Runs the %s stage of rhoscan on the work folder named by CONFIG ([pipeline] workdir).\n"
            "Options may stand before or after CONFIG; --NAME=VALUE works as --NAME VALUE.\n",
            stage, stage, stage);
    rs_options_print(out, stage_options);
    fputs(RS_PATHS_NOTE, out);
}

/* The stage's config sections as in effect, each value with where it came from. */
static int print_config(const rs_stage_def *def, const rs_config *cfg, const char *prog)
{
    rs_config_print_sections(cfg, def->sections, stdout);
    return rs_stdout_check(prog);
}

/* 1 when word is one of the space-separated words of list. */
static int has_word(const char *list, const char *word)
{
    size_t n = strlen(word);
    for (const char *w = list; w && (w = strstr(w, word)); w += n)
        if ((w == list || w[-1] == ' ') && (w[n] == ' ' || w[n] == 0)) return 1;
    return 0;
}

typedef struct {
    const rs_config *cfg;
    const char *missing_path;
    const char *found; /* the input's name when it is the missing file */
    char name[128];
} missing_state;

static void match_input(const char *name, void *user)
{
    missing_state *m = user;
    char path[4096];
    if (!m->found && strcmp(rs_work_path(m->cfg, name, path, sizeof path), m->missing_path) == 0) {
        snprintf(m->name, sizeof m->name, "%s", name);
        m->found = m->name;
    }
}

void rs_stage_explain_missing(const rs_stage_def *def, const rs_stage_def *table, const rs_config *cfg, rs_err *err)
{
    if (!err || !err->file[0] || access(err->file, F_OK) == 0) return;
    missing_state m = {cfg, err->file, NULL, ""};
    each_word(def->inputs, match_input, &m);
    if (!m.found) return;
    const rs_stage_def *producer = NULL;
    for (const rs_stage_def *d = table; d && d->name && !producer; d++)
        if (has_word(d->outputs, m.found)) producer = d;
    size_t len = strlen(err->msg);
    if (producer)
        snprintf(err->msg + len, sizeof err->msg - len,
                 "; the %s stage writes %s: run `rhoscan run %s` (or `rhoscan %s %s`) first", producer->name, m.found,
                 rs_config_file(cfg), producer->name, rs_config_file(cfg));
    else
        snprintf(err->msg + len, sizeof err->msg - len, "; an earlier stage writes %s: run `rhoscan run %s` first",
                 m.found, rs_config_file(cfg));
}

/* Runs the stage and logs the summary of its skips; the exit code. */
static int run_stage(const rs_stage_def *def, const rs_stage_def *table, const rs_config *cfg)
{
    rs_err err;
    rs_err_clear(&err);
    rs_skips skips = {0};
    int rc = 0;
    if (rs_stage_execute(def, cfg, &skips, &err) != 0) {
        rs_stage_explain_missing(def, table, cfg, &err);
        rs_log_error(&err);
        rc = err.kind ? (int)err.kind : 3;
    } else {
        rs_skips_log(&skips);
        if (rs_config_bool(cfg, "report", "write") && rs_par_world_rank() == 0) rs_stage_report(cfg, NULL);
    }
    rs_skips_release(&skips);
    return rc;
}

int rs_stage_main(const rs_stage_def *def, int argc, char **argv)
{
    return rs_stage_main_of(def, NULL, argc, argv);
}

int rs_stage_main_of(const rs_stage_def *def, const rs_stage_def *table, int argc, char **argv)
{
    const char *stage = def->name;
    char prog[128];
    snprintf(prog, sizeof prog, "rhoscan-%s", stage);
    rs_program_start(prog);
    const char **sets = calloc((size_t)argc + 1, sizeof *sets);
    int nsets = 0, want_config = 0;
    rs_opt_scan opt;
    rs_opt_begin(&opt, stage_options, argc, argv, 1);
    for (int o; (o = rs_opt_next(&opt)) != RS_OPT_END;) {
        switch (o) {
        case STAGE_SET: sets[nsets++] = opt.value; break;
        case STAGE_PRINT_CONFIG: want_config = 1; break;
        case STAGE_QUIET: rs_log_set_level(RS_LOG_WARN); break;
        case STAGE_VERBOSE: rs_log_set_level(RS_LOG_DEBUG); break;
        case STAGE_HELP:
            stage_usage(stage, stdout);
            free(sets);
            return rs_stdout_check(prog);
        case STAGE_VERSION:
            printf("%s\n", rs_version());
            free(sets);
            return rs_stdout_check(prog);
        default:
            rs_opt_unexpected(&opt, prog);
            stage_usage(stage, stderr);
            free(sets);
            return 1;
        }
    }
    if (!opt.operand) {
        stage_usage(stage, stderr);
        free(sets);
        return 1;
    }
    int rc = 0;
    rs_config *cfg = rs_program_config(opt.operand, sets, &rc);
    free(sets);
    if (!cfg) return rc;
    if (want_config)
        rc = rs_par_world_rank() == 0 ? print_config(def, cfg, prog) : 0;
    else
        rc = run_stage(def, table, cfg);
    rs_config_free(cfg);
    return rc;
}
