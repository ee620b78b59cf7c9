/* report_tables: the report's tables (counts, stages, warnings, configuration, provenance)
 * and the bench folder's plot (see report_priv.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include "common/fileio.h"
#include "pipeline/report_priv.h"
#include "pipeline/version.h"

static const cJSON *stage_of(const rs_report_data *d, const char *name)
{
    for (int k = 0; k < d->nstages; k++)
        if (strcmp(d->stages[k], name) == 0) return d->stage_json[k];
    return NULL;
}

static void count_row(rs_html *h, const char *what, double v, const char *from)
{
    rs_html_put(h, "<tr><td>");
    rs_html_esc(h, what);
    if (isfinite(v))
        rs_html_printf(h, "</td><td class=\"n\">%.0f</td><td>", v);
    else
        rs_html_put(h, "</td><td class=\"n\">-</td><td>");
    rs_html_esc(h, from);
    rs_html_put(h, "</td></tr>");
}

void rs_report_counts(rs_html *h, const rs_report_data *d)
{
    const cJSON *ing = stage_of(d, "ingest"), *mesh = stage_of(d, "mesh"), *refl = stage_of(d, "reflectance");
    const cJSON *irr = stage_of(d, "irradiance");
    double facets = rs_report_num(refl, "facets"), obs = rs_report_num(refl, "observed");
    if (!isfinite(facets)) facets = rs_report_num(mesh, "faces");
    rs_html_put(h, "<section id=\"counts\"><h2>Counts</h2><table><tr><th>what</th><th>count</th><th>from</th></tr>");
    count_row(h, "points read", rs_report_num(ing, "points"), "ingest.json points");
    count_row(h, "points with a return", rs_report_num(ing, "points_written"), "ingest.json points_written");
    count_row(h, "facets", facets, "reflectance.json facets (mesh.json faces)");
    count_row(h, "observed facets", obs, "reflectance.json observed");
    count_row(h, "estimable facets", rs_report_num(refl, "estimable"), "reflectance.json estimable");
    count_row(h, "unobserved facets", facets - obs, "facets - observed");
    count_row(h, "albedo above 1 (flagged)", rs_report_num(refl, "albedo_above_one"), "reflectance.json");
    count_row(h, "rays traced", rs_report_num(irr, "rays"), "irradiance.json rays");
    count_row(h, "sky pixels measured", rs_report_num(irr, "sky_pixels"), "irradiance.json sky_pixels");
    count_row(h, "sky pixels filled in", rs_report_num(irr, "filled_pixels"), "irradiance.json filled_pixels");
    rs_html_put(h, "</table></section>");
}

/* "ran" / "skipped: why" of stage name in metrics.json's run record; NULL when it has none. */
static const char *run_status(const rs_report_data *d, const char *name, char *buf, size_t n)
{
    const cJSON *run = cJSON_GetObjectItemCaseSensitive(d->metrics, "run"), *it;
    cJSON_ArrayForEach(it, cJSON_GetObjectItemCaseSensitive(run, "ran")) if (cJSON_IsString(it) &&
                                                                             strcmp(it->valuestring, name) ==
                                                                                 0) return "ran in the last run";
    cJSON_ArrayForEach(it, cJSON_GetObjectItemCaseSensitive(run, "skipped"))
    {
        const char *s = rs_report_str(it, "stage");
        if (s && strcmp(s, name) == 0) {
            snprintf(buf, n, "not run in the last run: %s", rs_report_str(it, "why") ? rs_report_str(it, "why") : "");
            return buf;
        }
    }
    return NULL;
}

void rs_report_stage_table(rs_html *h, const rs_report_data *d)
{
    rs_html_put(h,
                "<section id=\"stages\"><h2>Stages</h2><table><tr><th>stage</th><th>status</th><th>wall s</th>"
                "<th>CPU s</th><th>skipped inside the stage, and why</th></tr>");
    for (int k = 0; k < d->nstages; k++) {
        const cJSON *j = d->stage_json[k];
        char buf[600];
        const char *st = run_status(d, d->stages[k], buf, sizeof buf);
        if (!st) st = j ? "ran in an earlier run" : "never ran";
        rs_html_put(h, "<tr><td>");
        rs_html_esc(h, d->stages[k]);
        rs_html_put(h, "</td><td>");
        rs_html_esc(h, st);
        rs_html_printf(h, "</td><td class=\"n\">%.3f</td><td class=\"n\">%.3f</td><td>",
                       rs_report_num(j, "wall_time_s"), rs_report_num(j, "cpu_time_s"));
        const cJSON *it;
        cJSON_ArrayForEach(it, cJSON_GetObjectItemCaseSensitive(j, "skipped"))
        {
            rs_html_esc(h, rs_report_str(it, "what"));
            rs_html_put(h, ": ");
            rs_html_esc(h, rs_report_str(it, "why"));
            rs_html_put(h, "<br>");
        }
        rs_html_put(h, "</td></tr>");
    }
    rs_html_put(h, "</table></section>");
}

void rs_report_warnings(rs_html *h, const rs_report_data *d)
{
    rs_html_put(h, "<section id=\"warnings\"><h2>Warnings</h2>");
    int n = 0;
    for (int k = 0; k < d->nstages; k++) {
        const cJSON *it;
        cJSON_ArrayForEach(it, cJSON_GetObjectItemCaseSensitive(d->stage_json[k], "warnings"))
        {
            if (!cJSON_IsString(it)) continue;
            rs_html_put(h, n++ ? "<li>" : "<ul><li>");
            rs_html_esc(h, d->stages[k]);
            rs_html_put(h, ": ");
            rs_html_esc(h, it->valuestring);
            rs_html_put(h, "</li>");
        }
    }
    rs_html_put(h, n ? "</ul>" : "<p>None: no stage logged a warning in its last run.</p>");
    rs_html_put(h, "</section>");
}

void rs_report_config_table(rs_html *h, const rs_report_data *d)
{
    rs_html_put(h, "<section id=\"config\"><h2>Configuration in effect</h2>");
    const cJSON *eff = cJSON_GetObjectItemCaseSensitive(d->metrics, "effective_config"), *sec, *key;
    if (!eff) {
        rs_html_put(h, "<p class=\"note\">No metrics.json yet (written by rhoscan run).</p></section>");
        return;
    }
    rs_html_put(h, "<p>Config file: <code>");
    rs_html_esc(h, rs_report_str(d->metrics, "config"));
    rs_html_put(h, "</code></p><table><tr><th>key</th><th>value</th><th>from</th></tr>");
    cJSON_ArrayForEach(sec, eff) cJSON_ArrayForEach(key, sec)
    {
        rs_html_put(h, "<tr><td>");
        rs_html_esc(h, sec->string);
        rs_html_put(h, ".");
        rs_html_esc(h, key->string);
        rs_html_put(h, "</td><td>");
        rs_html_esc(h, rs_report_str(key, "value"));
        rs_html_put(h, "</td><td>");
        rs_html_esc(h, rs_report_str(key, "from"));
        rs_html_put(h, "</td></tr>");
    }
    rs_html_put(h, "</table></section>");
}

void rs_report_provenance(rs_html *h, const rs_report_data *d)
{
    char date[64];
    time_t now = time(NULL);
    struct tm tm;
    strftime(date, sizeof date, "%Y-%m-%d %H:%M:%S UTC", gmtime_r(&now, &tm));
    rs_html_put(h, "<section id=\"provenance\"><h2>Provenance</h2><table>");
    rs_html_put(h, "<tr><th>report written by</th><td>");
    rs_html_esc(h, rs_version());
    rs_html_put(h, "</td></tr><tr><th>run made by</th><td>");
    rs_html_esc(h, rs_report_str(d->metrics, "program"));
    rs_html_put(h, " commit ");
    rs_html_esc(h, rs_report_str(d->metrics, "git_commit"));
    rs_html_printf(h, "</td></tr><tr><th>report date</th><td>%s</td></tr><tr><th>machine threads</th><td>%ld</td></tr>",
                   date, sysconf(_SC_NPROCESSORS_ONLN));
    rs_html_put(h, "<tr><th>configured threads</th><td>");
    rs_html_esc(h, rs_report_config(d, "pipeline", "threads"));
    rs_html_put(h,
                " (0: all)</td></tr></table><h3>Input files (checksums as the stages recorded them)</h3>"
                "<table><tr><th>stage</th><th>file</th><th>64-bit content hash</th></tr>");
    for (int k = 0; k < d->nstages; k++) {
        const cJSON *it;
        cJSON_ArrayForEach(it, cJSON_GetObjectItemCaseSensitive(d->stage_json[k], "inputs"))
        {
            rs_html_put(h, "<tr><td>");
            rs_html_esc(h, d->stages[k]);
            rs_html_put(h, "</td><td>");
            rs_html_esc(h, it->string);
            rs_html_put(h, "</td><td><code>");
            rs_html_esc(h, cJSON_IsString(it) ? it->valuestring : "");
            rs_html_put(h, "</code></td></tr>");
        }
    }
    rs_html_put(h, "</table></section>");
}

/* The index of column name in a CSV header line, or -1. */
static int column(const char *header, const char *name)
{
    int k = 0;
    size_t n = strlen(name);
    for (const char *p = header; p; k++) {
        if (strncmp(p, name, n) == 0 && (p[n] == ',' || p[n] == '\n' || p[n] == '\r' || p[n] == 0)) return k;
        p = strchr(p, ',');
        if (p) p++;
    }
    return -1;
}

/* Field k of a CSV line into out. */
static void field(const char *line, int k, char *out, size_t n)
{
    const char *p = line;
    for (int i = 0; i < k && p; i++)
        if ((p = strchr(p, ','))) p++;
    size_t l = p ? strcspn(p, ",\r\n") : 0;
    snprintf(out, n, "%.*s", (int)(l < n ? l : n - 1), p ? p : "");
}

void rs_report_plot_bench(rs_html *h, const char *workdir)
{
    char path[4096], *text = NULL;
    size_t size;
    if (rs_read_file(rs_path_join(path, sizeof path, workdir, "bench.csv"), &text, &size, NULL) != 0) return;
    int ct = column(text, "t_total"), ce = column(text, "albedo_err"), cr = column(text, "row"),
        cf = column(text, "facets");
    enum { MAXPTS = 512 };
    static double x[MAXPTS], y[MAXPTS];
    static char names[MAXPTS][96];
    const char *labels[MAXPTS];
    int n = 0;
    for (char *line = strchr(text, '\n'); ct >= 0 && ce >= 0 && line && line[1] && n < MAXPTS;
         line = strchr(line, '\n')) {
        line++;
        char a[64], b[64], r[32], f[32];
        field(line, ct, a, sizeof a);
        field(line, ce, b, sizeof b);
        field(line, cr, r, sizeof r);
        field(line, cf, f, sizeof f);
        x[n] = strtod(a, NULL);
        y[n] = 100 * strtod(b, NULL);
        snprintf(names[n], sizeof names[n], "%s at %s facets", r, f);
        labels[n] = names[n];
        n++;
    }
    if (n > 0)
        rs_svg_pareto(h, "bench.csv: run time against albedo error (line: the Pareto front)", x, y, labels, n,
                      "run time of observe..render, s", "albedo error, %");
    free(text);
}
