/* log: diagnostics on stderr, prefixed with the program name, and progress reporting
 * (a bar when stderr is a terminal, a plain line every 10 % otherwise). */
#ifndef RS_LOG_H
#define RS_LOG_H

#include <stddef.h>
#include "common/err.h"

typedef enum { RS_LOG_QUIET = 0, RS_LOG_WARN = 1, RS_LOG_INFO = 2, RS_LOG_DEBUG = 3 } rs_log_level;

void rs_log_init(const char *program); /* program name for the prefix */
void rs_log_set_level(rs_log_level level);
const char *rs_log_program(void);
void rs_log_info(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
void rs_log_warn(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
/* The warnings logged so far by this process (at any level setting), in order: how many (at
 * most 64 are kept), and the k-th one's text without the prefix. */
size_t rs_log_warning_count(void);
const char *rs_log_warning(size_t k);
void rs_log_debug(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
/* Prints "program: file:line: msg" for an error record. */
void rs_log_error(const rs_err *err);

/* Progress of one long loop. Thread-safe: rs_progress_add may be called from OpenMP loops. */
typedef struct rs_progress rs_progress;
rs_progress *rs_progress_start(const char *what, size_t total);
void rs_progress_add(rs_progress *p, size_t done);
void rs_progress_end(rs_progress *p); /* prints "what: done in X s", frees p */

/* Monotonic wall clock in seconds. */
double rs_now(void);

#endif
