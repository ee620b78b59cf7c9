/* report_truth: the report's comparison with a truth PLY ([report] truth): per facet the signed
 * relative albedo error (the error map), per truth part the area-weighted statistics, with the
 * definitions of pipeline/truth.h (the shared evaluator's). Also written as
 * report/truth_error.json, in the evaluator's --json layout (all, interior, parts). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/faceprop.h"
#include "common/fileio.h"
#include "common/json.h"
#include "common/mesh.h"
#include "pipeline/report_priv.h"
#include "pipeline/truth.h"

#define TRUTH_TOL_M 0.15 /* the evaluator's default --tol */

static void stats_json(rs_json *parent, const char *key, const rs_truth_stats *st)
{
    if (st->facets == 0) {
        rs_json_set_parsed(parent, key, "null");
        return;
    }
    rs_json *s = rs_json_set_obj(parent, key);
    rs_json_set_int(s, "facets", (long long)st->facets);
    rs_json_set_num(s, "area", st->area);
    rs_json_set_num(s, "mean_rel", st->mean_rel);
    rs_json_set_num(s, "median_rel", st->median_rel);
    rs_json_set_num(s, "p95_rel", st->p95_rel);
    rs_json_set_num(s, "bias_rel", st->bias_rel);
}

static void stats_row(rs_html *h, const char *what, const double *rgb, const rs_truth_stats *st)
{
    rs_html_put(h, "<tr><td>");
    rs_html_esc(h, what);
    if (rgb)
        rs_html_printf(h, "</td><td>%.3f %.3f %.3f", rgb[0], rgb[1], rgb[2]);
    else
        rs_html_put(h, "</td><td>");
    if (st->facets)
        rs_html_printf(h,
                       "</td><td class=\"n\">%zu</td><td class=\"n\">%.3g</td><td class=\"n\">%.2f</td><td "
                       "class=\"n\">%.2f</td><td class=\"n\">%.2f</td><td class=\"n\">%+.2f</td></tr>",
                       st->facets, st->area, 100 * st->mean_rel, 100 * st->median_rel, 100 * st->p95_rel,
                       100 * st->bias_rel);
    else
        rs_html_put(h, "</td><td class=\"n\">0</td><td colspan=\"5\">no observed, estimable facet inside it</td></tr>");
}

/* The per-part table into h and the JSON into doc, from the facets' errors. */
static void part_table(rs_html *h, rs_json *doc, const rs_truth *t, const rs_eval_match *m, const double *rel,
                       const double *sgn, const double *area, const uint8_t *sel, size_t nf)
{
    uint8_t *mask = malloc(nf + 1);
    size_t *idx = malloc((nf + 1) * sizeof *idx);
    if (!mask || !idx) goto out;
    rs_truth_stats st;
    rs_html_put(h,
                "<table><tr><th>truth part</th><th>truth albedo (R G B)</th><th>facets</th><th>area m^2</th>"
                "<th>mean %</th><th>median %</th><th>95th pct %</th><th>bias %</th></tr>");
    rs_truth_stats_of(rel, sgn, area, sel, nf, idx, &st);
    stats_json(doc, "all", &st);
    stats_row(h, "all matched facets", NULL, &st);
    for (size_t f = 0; f < nf; f++) mask[f] = sel[f] && m->interior[f];
    rs_truth_stats_of(rel, sgn, area, mask, nf, idx, &st);
    stats_json(doc, "interior", &st);
    stats_row(h, "interior facets (inside one part)", NULL, &st);
    rs_json *parts = rs_json_set_obj(doc, "parts");
    for (int p = 0; p < t->nparts; p++) {
        const double *rgb = NULL;
        for (size_t k = 0; k < t->nt && !rgb; k++)
            if (t->part[k] == p) rgb = t->rgb + 3 * k;
        for (size_t f = 0; f < nf; f++) mask[f] = sel[f] && m->interior[f] && m->part[f] == p;
        rs_truth_stats_of(rel, sgn, area, mask, nf, idx, &st);
        char key[16];
        snprintf(key, sizeof key, "%d", p);
        if (st.facets) stats_json(parts, key, &st); /* the evaluator lists parts with selected facets */
        if (rgb) stats_row(h, key, rgb, &st);
    }
    rs_html_put(h, "</table>");
out:
    free(mask);
    free(idx);
}

int rs_report_truth(rs_html *h, const char *workdir, const char *truth_path, double **truth_err, rs_err *err)
{
    *truth_err = NULL;
    rs_truth t;
    char path[4096];
    if (rs_truth_read(truth_path, &t, err) != 0) return -1;
    rs_ply *ply = NULL;
    rs_mesh *res = rs_mesh_read(rs_path_join(path, sizeof path, workdir, "albedo.ply"), &ply, err);
    rs_eval_match m = {0};
    int rc = -1;
    size_t nf = res ? res->nfaces : 0;
    double *v = malloc((7 * nf + 1) * sizeof *v); /* alb 3, obs, est, rel, sgn; area below */
    double *area = malloc((nf + 1) * sizeof *area), *e = malloc((nf + 1) * sizeof *e);
    uint8_t *sel = calloc(nf + 1, 1);
    rs_json *doc = rs_json_object();
    if (!res) goto out;
    rs_truth_unshift(res, ply);
    if (!v || !area || !e || !sel || !doc) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the truth comparison");
        goto out;
    }
    double *alb = v, *obs = v + 3 * nf, *est = v + 4 * nf, *rel = v + 5 * nf, *sgn = v + 6 * nf;
    if (rs_faceprop_get_rgb(ply, path, "albedo", nf, alb, err) != 0 ||
        rs_faceprop_get(ply, path, "observed", nf, obs, err) != 0 ||
        rs_faceprop_get(ply, path, "estimable", nf, est, err) != 0 ||
        rs_eval_match_facets(res, t.mesh, t.part, t.rgb, TRUTH_TOL_M, &m, err) != 0)
        goto out;
    for (size_t f = 0; f < nf; f++) {
        rs_v3 c, n;
        rs_mesh_face(res, f, &c, &n, &area[f]);
        const double *a = alb + 3 * f;
        sel[f] = obs[f] > 0 && est[f] > 0 && m.part[f] >= 0 && isfinite(a[0]) && isfinite(a[1]) && isfinite(a[2]);
        rel[f] = sgn[f] = 0;
        if (sel[f]) rs_truth_facet_error(a, m.truth_rgb + 3 * f, &rel[f], &sgn[f]);
        e[f] = sel[f] ? sgn[f] : NAN;
    }
    rs_html_put(h, "<section id=\"truth\"><h2>Albedo against the truth</h2><p class=\"note\">Truth <code>");
    rs_html_esc(h, truth_path);
    rs_html_put(h,
                "</code>. Relative error |rho - truth| / truth, mean over R, G, B, area-weighted over the "
                "observed, estimable facets matched to the truth (the shared evaluator's definitions: seven points "
                "per facet, within 0.15 m, majority part; a part's row counts its interior facets only).</p>");
    part_table(h, doc, &t, &m, rel, sgn, area, sel, nf);
    rs_html_put(h, "</section>");
    rc = rs_json_write(doc, rs_path_join(path, sizeof path, workdir, "report/truth_error.json"), err);
    if (rc == 0) {
        *truth_err = e;
        e = NULL;
    }
out:
    rs_json_free(doc);
    rs_eval_match_free(&m);
    rs_mesh_free(res);
    rs_ply_free(ply);
    rs_truth_free(&t);
    free(v);
    free(area);
    free(e);
    free(sel);
    return rc;
}
