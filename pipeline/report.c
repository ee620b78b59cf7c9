/* report: WORKDIR/report.html (see report.h). */
#include "pipeline/report.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include "common/fileio.h"
#include "common/log.h"
#include "pipeline/report_html.h"
#include "pipeline/report_priv.h"
#include "pipeline/report_view.h"
#include "pipeline/version.h"

cJSON *rs_report_read_json(const char *workdir, const char *name)
{
    char path[4096], *text = NULL;
    size_t size;
    if (rs_read_file(rs_path_join(path, sizeof path, workdir, name), &text, &size, NULL) != 0) return NULL;
    cJSON *j = cJSON_Parse(text);
    free(text);
    return j;
}

double rs_report_num(const cJSON *obj, const char *key)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
    return cJSON_IsNumber(v) ? v->valuedouble : NAN;
}

const char *rs_report_str(const cJSON *obj, const char *key)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
    return cJSON_IsString(v) ? v->valuestring : NULL;
}

/* The value of section.key in metrics.json's effective configuration, or NULL. */
const char *rs_report_config(const rs_report_data *d, const char *section, const char *key)
{
    const cJSON *s =
        cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(d->metrics, "effective_config"), section);
    return rs_report_str(cJSON_GetObjectItemCaseSensitive(s, key), "value");
}

#define RS_REPORT_VIEW_WIDTH 400 /* pixels on the page of each camera-view image */

static const char STYLE[] =
    "body{font-family:sans-serif;margin:16px;color:#222;max-width:1900px}h1{font-size:22px}h2{font-size:18px;"
    "border-bottom:1px solid #ccc;margin-top:28px}table{border-collapse:collapse;font-size:13px}td,th{border:1px "
    "solid #ccc;padding:2px 6px;text-align:left;vertical-align:top}th{background:#eee}td.n{text-align:right;"
    "font-variant-numeric:tabular-nums}.views{display:flex;flex-wrap:wrap;gap:12px}.view{width:%dpx;font-size:12px}"
    ".view img{width:%dpx;height:%dpx;image-rendering:pixelated;display:block;border:1px solid #888}.tone{color:#555}"
    ".plots{display:flex;flex-wrap:wrap;gap:12px}.note{color:#555;font-size:13px}.bad{color:#a00}"
    "#model3d canvas{border:1px solid #888}";

/* The camera-view images with their colour bars. */
static void section_views(rs_html *h, const rs_report_views *v)
{
    rs_html_put(h, "<section id=\"views\"><h2>In the camera's view</h2>");
    if (v->missing[0]) {
        rs_html_put(h, "<p class=\"note\">Not shown: ");
        rs_html_esc(h, v->missing);
        rs_html_put(h, ".</p>");
    }
    rs_html_put(h, "<div class=\"views\">");
    for (int k = 0; k < v->n; k++) {
        const rs_report_image *im = &v->img[k];
        rs_html_put(h, "<figure class=\"view\"><figcaption><b>");
        rs_html_esc(h, im->title);
        rs_html_put(h, "</b></figcaption><img src=\"");
        rs_html_esc(h, im->file);
        rs_html_put(h, "\" alt=\"");
        rs_html_esc(h, im->title);
        rs_html_put(h, "\">");
        rs_svg_colorbar(h, im->map, im->lo, im->hi, im->unit,
                        v->width < RS_REPORT_VIEW_WIDTH ? v->width : RS_REPORT_VIEW_WIDTH);
        rs_html_put(h, "<div class=\"tone\">");
        rs_html_esc(h, im->tone);
        rs_html_put(h, "</div></figure>");
    }
    rs_html_put(h, "</div></section>");
}

/* Histograms of the per-facet albedo (luminance) and its uncertainty, estimable facets. */
static void plots_facets(rs_html *h, const rs_report_facets *f)
{
    double *v = malloc((f->nf + 1) * sizeof *v);
    if (!v) return;
    size_t n = 0;
    for (size_t i = 0; i < f->nf; i++)
        if (f->estimable[i]) v[n++] = 0.2126 * f->alb[3 * i] + 0.7152 * f->alb[3 * i + 1] + 0.0722 * f->alb[3 * i + 2];
    rs_svg_histogram(h, "albedo of the estimable facets", v, n, 0, 1, 40, "albedo (luminance), unitless");
    if (f->sigma) {
        n = 0;
        for (size_t i = 0; i < f->nf; i++)
            if (f->estimable[i]) v[n++] = f->sigma[i];
        rs_svg_histogram(h, "albedo uncertainty of the estimable facets", v, n, 0, 0.2, 40,
                         "relative standard uncertainty (1 sigma), unitless");
    }
    free(v);
}

/* Per-stage wall and CPU time. */
static void plot_times(rs_html *h, const rs_report_data *d)
{
    const char *labels[RS_REPORT_MAX_STAGES];
    double wall[RS_REPORT_MAX_STAGES], cpu[RS_REPORT_MAX_STAGES];
    int n = 0;
    for (int k = 0; k < d->nstages; k++) {
        if (!d->stage_json[k]) continue;
        labels[n] = d->stages[k];
        wall[n] = rs_report_num(d->stage_json[k], "wall_time_s");
        cpu[n] = rs_report_num(d->stage_json[k], "cpu_time_s");
        n++;
    }
    rs_svg_series s[2] = {{"wall", "#4878a8", wall}, {"CPU", "#e0a030", cpu}};
    rs_svg_bars(h, "time per stage (its last run)", labels, n, s, 2, "seconds");
}

/* The convergence of the reflectance stage's transport solve (solve_residuals). */
static void plot_convergence(rs_html *h, const rs_report_data *d)
{
    const cJSON *refl = NULL;
    for (int k = 0; k < d->nstages; k++)
        if (strcmp(d->stages[k], "reflectance") == 0) refl = d->stage_json[k];
    const cJSON *r = cJSON_GetObjectItemCaseSensitive(refl, "solve_residuals");
    int n = cJSON_GetArraySize(r);
    if (!cJSON_IsArray(r) || n == 0) {
        rs_html_put(h,
                    "<p class=\"note\">No convergence record (reflectance has not run, or ran before it kept "
                    "one).</p>");
        return;
    }
    double *y = malloc((size_t)n * sizeof *y);
    if (!y) return;
    int k = 0;
    const cJSON *it;
    cJSON_ArrayForEach(it, r) y[k++] = cJSON_IsNumber(it) ? it->valuedouble : NAN;
    rs_svg_log_line(h, "transport solve: largest relative change per sweep", y, n, "sweep",
                    "relative change (unitless)");
    free(y);
}

static void section_plots(rs_html *h, const rs_report_data *d, const rs_report_facets *f)
{
    rs_html_put(h, "<section id=\"plots\"><h2>Plots</h2><div class=\"plots\">");
    plot_times(h, d);
    if (f) plots_facets(h, f);
    plot_convergence(h, d);
    rs_report_plot_bench(h, d->workdir);
    rs_html_put(h, "</div></section>");
}

/* The stage names: the caller's, else metrics.json's stages in their order. */
static void load_data(const rs_report_opts *o, rs_report_data *d)
{
    memset(d, 0, sizeof *d);
    d->workdir = o->workdir;
    d->metrics = rs_report_read_json(o->workdir, "metrics.json");
    if (o->stages) {
        for (int k = 0; o->stages[k] && d->nstages < RS_REPORT_MAX_STAGES; k++) d->stages[d->nstages++] = o->stages[k];
    } else {
        const cJSON *it;
        cJSON_ArrayForEach(it, cJSON_GetObjectItemCaseSensitive(d->metrics, "stages")) if (d->nstages <
                                                                                           RS_REPORT_MAX_STAGES)
            d->stages[d->nstages++] = it->string;
    }
    for (int k = 0; k < d->nstages; k++) {
        char name[160];
        snprintf(name, sizeof name, "%s.json", d->stages[k]);
        d->stage_json[k] = rs_report_read_json(o->workdir, name);
    }
}

static void free_data(rs_report_data *d)
{
    for (int k = 0; k < d->nstages; k++) cJSON_Delete(d->stage_json[k]);
    cJSON_Delete(d->metrics); /* after: stage names may point into it */
}

/* The capture's panorama as pipeline/panorama.h decides it, from metrics.json's configuration
 * (the report runs without one): the calib stage's stitched panorama when [rig] file is set,
 * else [capture] panorama. */
static const char *pano_path(const rs_report_data *d, char *out, size_t n)
{
    /* RS_CALIB_PANO_FILE of pipeline/calib_files.h, not included: that module includes stage.h,
     * whose programs call the report (a cycle) */
    if (rs_report_config(d, "rig", "file")) return rs_path_join(out, n, d->workdir, "pano_stitched.exr");
    const char *p = rs_report_config(d, "capture", "panorama");
    if (!p) return NULL;
    snprintf(out, n, "%s", p);
    return out;
}

static void page_head(rs_html *h, const rs_report_data *d, const rs_report_views *v)
{
    int w = v->width ? v->width : 320, hh = v->height ? v->height : 160;
    if (w > RS_REPORT_VIEW_WIDTH) { /* shown at most this wide, so that four fit side by side */
        hh = (int)lrint((double)hh * RS_REPORT_VIEW_WIDTH / w);
        w = RS_REPORT_VIEW_WIDTH;
    }
    rs_html_put(h, "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>rhoscan report: ");
    rs_html_esc(h, d->workdir);
    rs_html_put(h, "</title><style>");
    rs_html_printf(h, STYLE, w, w, hh);
    rs_html_put(h, "</style></head><body><h1>rhoscan report</h1><p id=\"summary\">Work folder <code>");
    rs_html_esc(h, d->workdir);
    rs_html_put(h, "</code>");
    const char *method = rs_report_config(d, "reflectance", "method");
    if (method) {
        rs_html_put(h, ", reflectance method <b>");
        rs_html_esc(h, method);
        rs_html_put(h, "</b>");
    }
    double wall = rs_report_num(cJSON_GetObjectItemCaseSensitive(d->metrics, "run"), "wall_time_s");
    if (isfinite(wall)) rs_html_printf(h, ", last run %.2f s", wall);
    rs_html_put(h,
                ". Units: radiance W m^-2 sr^-1, irradiance W m^-2, albedo unitless (per unit of the "
                "panorama's radiance scale).</p>");
}

double rs_report_cpu_seconds(void)
{
    struct timespec ts;
    return clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts) == 0 ? (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec : NAN;
}

int rs_report_write(const rs_report_opts *o, rs_err *err)
{
    double t0 = rs_now(), c0 = rs_report_cpu_seconds();
    rs_report_data d;
    load_data(o, &d);
    char path[4096], pano[4096];
    rs_report_facets f;
    int have_f = 0, rc = -1;
    rs_path_join(path, sizeof path, o->workdir, "albedo.ply");
    if (rs_file_exists(path)) {
        if (rs_report_facets_read(path, &f, err) != 0) goto out_data;
        have_f = 1;
    }
    rs_html h = {0}, th = {0};
    double *terr = NULL;
    const char *truth = o->truth ? o->truth : rs_report_config(&d, "report", "truth");
    char dir[4096];
    if (rs_mkdir_p(rs_path_join(dir, sizeof dir, o->workdir, "report"), err) != 0) goto out;
    if (truth && have_f && rs_report_truth(&th, o->workdir, truth, &terr, err) != 0) goto out;
    rs_report_views v;
    if (rs_report_views_write(o->workdir, pano_path(&d, pano, sizeof pano), have_f ? &f : NULL, terr, &v, err) != 0)
        goto out;
    page_head(&h, &d, &v);
    section_views(&h, &v);
    section_plots(&h, &d, have_f ? &f : NULL);
    if (th.s) rs_html_put(&h, th.s);
    rs_report_model3d(&h, o);
    rs_report_counts(&h, &d);
    rs_report_stage_table(&h, &d);
    rs_report_warnings(&h, &d);
    rs_report_config_table(&h, &d);
    rs_report_provenance(&h, &d);
    rs_html_printf(&h, "<p class=\"note\" id=\"cost\">Report built in %.3f s (CPU %.3f s).</p>", rs_now() - t0,
                   rs_report_cpu_seconds() - c0);
    rs_html_put(&h, "</body></html>\n");
    if (h.failed)
        rs_err_set(err, RS_ERR_SYSTEM, o->workdir, 0, "out of memory for report.html");
    else
        rc = rs_write_file_atomic(rs_path_join(path, sizeof path, o->workdir, "report.html"), h.s, h.len, err);
out:
    rs_html_release(&h);
    rs_html_release(&th);
    free(terr);
    if (have_f) rs_report_facets_free(&f);
out_data:
    free_data(&d);
    return rc;
}
