/* log: stderr diagnostics and progress (see log.h). A bar redrawn in place on a terminal,
 * a plain line every 10 % otherwise, so that CI logs stay readable. */
#include "common/log.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include "common/par.h"

static char log_program[64] = "rhoscan";
static rs_log_level log_level = RS_LOG_INFO;

void rs_log_init(const char *program)
{
    snprintf(log_program, sizeof log_program, "%s", program);
}

void rs_log_set_level(rs_log_level level)
{
    log_level = level;
}
const char *rs_log_program(void)
{
    return log_program;
}

/* In an MPI run every rank would say the same: the ranks other than 0 warn and inform not at
 * all (rs_log_error still prints on every rank). */
static int quiet_rank(void)
{
    return rs_par_world_rank() != 0;
}

static void log_v(rs_log_level level, const char *tag, const char *fmt, va_list ap)
{
    if (level > log_level || quiet_rank()) return;
    char line[2048];
    vsnprintf(line, sizeof line, fmt, ap);
    fprintf(stderr, "%s: %s%s\n", log_program, tag, line);
}

void rs_log_info(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    log_v(RS_LOG_INFO, "", fmt, ap);
    va_end(ap);
}

/* The warnings of the process, kept for the report (the first RS_LOG_KEPT_WARNINGS of them). */
#define RS_LOG_KEPT_WARNINGS 64
static char *warnings[RS_LOG_KEPT_WARNINGS];
static size_t nwarnings;

void rs_log_warn(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    log_v(RS_LOG_WARN, "warning: ", fmt, ap);
    va_end(ap);
    char line[2048];
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
#pragma omp critical(rs_log_warnings)
    {
        if (nwarnings < RS_LOG_KEPT_WARNINGS) warnings[nwarnings] = strdup(line);
        if (nwarnings < RS_LOG_KEPT_WARNINGS && warnings[nwarnings]) nwarnings++;
    }
}

size_t rs_log_warning_count(void)
{
    return nwarnings;
}

const char *rs_log_warning(size_t k)
{
    return k < nwarnings ? warnings[k] : "";
}

void rs_log_debug(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    log_v(RS_LOG_DEBUG, "", fmt, ap);
    va_end(ap);
}

void rs_log_error(const rs_err *err)
{
    char buf[2048];
    rs_err_format(err, buf, sizeof buf);
    fprintf(stderr, "%s: %s\n", log_program, buf);
}

double rs_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

struct rs_progress {
    char what[128];
    size_t total, done;
    int tty, last_step; /* last printed tenth (plain) or bar width (tty) */
    double start;
};

rs_progress *rs_progress_start(const char *what, size_t total)
{
    if (quiet_rank()) return NULL; /* rank 0 shows the run's progress */
    rs_progress *p = calloc(1, sizeof *p);
    if (!p) return NULL;
    snprintf(p->what, sizeof p->what, "%s", what);
    p->total = total ? total : 1;
    p->tty = isatty(STDERR_FILENO) && log_level >= RS_LOG_INFO;
    p->start = rs_now();
    p->last_step = -1;
    return p;
}

static void progress_draw(rs_progress *p)
{
    const int width = 30;
    double frac = (double)p->done / (double)p->total;
    if (frac > 1) frac = 1;
    if (p->tty) {
        int fill = (int)(frac * width);
        int pct = (int)(frac * 100);
        if (pct == p->last_step) return;
        p->last_step = pct;
        char bar[64];
        for (int i = 0; i < width; i++) bar[i] = i < fill ? '#' : '.';
        bar[width] = 0;
        fprintf(stderr, "\r%s: %s [%s] %3d%%", log_program, p->what, bar, pct);
        fflush(stderr);
    } else {
        int tenth = (int)(frac * 10);
        if (tenth == p->last_step || tenth == 0 || tenth == 10) return;
        p->last_step = tenth;
        if (log_level >= RS_LOG_INFO)
            fprintf(stderr, "%s: %s: %d%% (%.1f s)\n", log_program, p->what, tenth * 10, rs_now() - p->start);
    }
}

void rs_progress_add(rs_progress *p, size_t done)
{
    if (!p) return;
#pragma omp critical(rs_progress)
    {
        p->done += done;
        progress_draw(p);
    }
}

void rs_progress_end(rs_progress *p)
{
    if (!p) return;
    if (p->tty) fprintf(stderr, "\r\033[K");
    if (log_level >= RS_LOG_INFO)
        fprintf(stderr, "%s: %s: done in %.2f s\n", log_program, p->what, rs_now() - p->start);
    free(p);
}
