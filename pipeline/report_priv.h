/* report_priv: what report.c and report_tables.c share: the work folder's JSON records. */
#ifndef RS_REPORT_PRIV_H
#define RS_REPORT_PRIV_H

#include <cjson/cJSON.h>
#include "common/err.h"
#include "pipeline/report_html.h"

#define RS_REPORT_MAX_STAGES 32

typedef struct rs_report_data {
    const char *workdir;
    cJSON *metrics; /* metrics.json, or NULL */
    const char *stages[RS_REPORT_MAX_STAGES];
    cJSON *stage_json[RS_REPORT_MAX_STAGES]; /* <stage>.json as on disk, NULL when it never ran */
    int nstages;
} rs_report_data;

/* workdir/name parsed, or NULL when absent or not JSON. */
cJSON *rs_report_read_json(const char *workdir, const char *name);
double rs_report_num(const cJSON *obj, const char *key); /* NAN when absent */
const char *rs_report_str(const cJSON *obj, const char *key);
const char *rs_report_config(const rs_report_data *d, const char *section, const char *key);

/* The tables (report_tables.c). */
void rs_report_counts(rs_html *h, const rs_report_data *d);
void rs_report_stage_table(rs_html *h, const rs_report_data *d);
void rs_report_warnings(rs_html *h, const rs_report_data *d);
void rs_report_config_table(rs_html *h, const rs_report_data *d);
void rs_report_provenance(rs_html *h, const rs_report_data *d);
/* Run time against albedo error with the Pareto front, when workdir holds rhoscan-bench's bench.csv. */
void rs_report_plot_bench(rs_html *h, const char *workdir);

/* The 3D view section when workdir has albedo.glb (report_model.c); nothing otherwise. */
struct rs_report_opts;
void rs_report_model3d(rs_html *h, const struct rs_report_opts *o);

/* The section comparing workdir/albedo.ply with the truth PLY truth_path into h, and
 * report/truth_error.json; *truth_err (caller frees) the signed relative error per facet, NAN
 * where not compared. -1 with *err when the truth or albedo.ply does not read. */
int rs_report_truth(rs_html *h, const char *workdir, const char *truth_path, double **truth_err, rs_err *err);

/* CPU seconds of the process so far (every thread). */
double rs_report_cpu_seconds(void);

#endif
