/* eval: rhoscan-eval's computation: reads a truth folder and a work folder, measures the
 * albedo, coverage, irradiance and re-render errors, writes eval.json and eval_error.exr/.png. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "tools/eval/eval.h"
#include "common/faceprop.h"
#include "common/fileio.h"
#include "common/image.h"
#include "common/ply.h"
#include "tools/eval/eval_priv.h"

void rs_eval_opts_default(rs_eval_opts *o)
{
    memset(o, 0, sizeof *o);
    o->tol_m = 0.15;            /* as the shared reference set's eval_albedo.py */
    o->concave_threshold = 0.2; /* docs/ACCURACY.md says why */
    o->max_error = o->max_error_all = o->min_coverage = NAN;
}

static void eval_free(ev *e)
{
    rs_truth_free(&e->tr);
    rs_mesh_free(e->res);
    rs_ply_free(e->res_ply);
    free(e->alb);
    free(e->rel);
    free(e->sel);
    rs_eval_match_free(&e->m);
    rs_image_free(e->ids);
    rs_image_free(e->pano);
    rs_image_free(e->dc);
    rs_image_free(e->dd);
    rs_image_free(e->di);
    rs_image_free(e->synth);
}

static const char *join(char *buf, size_t n, const char *dir, const char *name)
{
    return rs_path_join(buf, n, dir, name);
}

static int load_truth(ev *e, const char *dir, rs_err *err)
{
    char path[4096];
    join(path, sizeof path, dir, "truth.ply");
    if (rs_truth_read(path, &e->tr, err) != 0) return -1;
    e->truth = e->tr.mesh;
    e->truth_ply = e->tr.ply;
    e->nt = e->tr.nt;
    e->nparts = e->tr.nparts;
    e->tpart = e->tr.part;
    e->trgb = e->tr.rgb;
    return 0;
}

static int load_result(ev *e, const char *dir, rs_err *err)
{
    char path[4096];
    join(path, sizeof path, dir, "albedo.ply");
    if (!(e->res = rs_mesh_read(path, &e->res_ply, err))) return -1;
    size_t nf = e->nf = e->res->nfaces;
    /* one block: alb esky g (3 each), obs est area encl (1 each); rel sgn (1 each) */
    if (!(e->alb = malloc((13 * nf + 1) * sizeof *e->alb)) || !(e->rel = malloc((2 * nf + 1) * sizeof *e->rel)) ||
        !(e->sel = calloc(nf + 1, 1)))
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu facets", nf);
    e->esky = e->alb + 3 * nf;
    e->g = e->alb + 6 * nf;
    e->obs = e->alb + 9 * nf;
    e->est = e->alb + 10 * nf;
    e->area = e->alb + 11 * nf;
    e->encl = e->alb + 12 * nf;
    e->sgn = e->rel + nf;
    if (rs_faceprop_get_rgb(e->res_ply, path, "albedo", nf, e->alb, err) != 0 ||
        rs_faceprop_get_rgb(e->res_ply, path, "irradiance_sky", nf, e->esky, err) != 0 ||
        rs_faceprop_get_rgb(e->res_ply, path, "irradiance_inter", nf, e->g, err) != 0 ||
        rs_faceprop_get(e->res_ply, path, "observed", nf, e->obs, err) != 0 ||
        rs_faceprop_get(e->res_ply, path, "estimable", nf, e->est, err) != 0)
        return -1;
    rs_truth_unshift(e->res, e->res_ply);
    for (size_t f = 0; f < nf; f++) {
        rs_v3 c, n;
        rs_mesh_face(e->res, f, &c, &n, &e->area[f]);
    }
    return 0;
}

/* Reads an image of the camera view; all must share the facet-id image's size. */
static rs_image *load_view(const char *dir, const char *name, int channels, const rs_image *like, rs_err *err)
{
    char path[4096];
    rs_image *img = rs_image_read(join(path, sizeof path, dir, name), err);
    if (!img) return NULL;
    if (img->channels != channels || (like && (img->width != like->width || img->height != like->height))) {
        rs_err_set(err, RS_ERR_INPUT, path, 0, "%d x %d, %d channels: expected %d x %d, %d channel%s (the camera view)",
                   img->width, img->height, img->channels, like ? like->width : img->width,
                   like ? like->height : img->height, channels, channels > 1 ? "s" : "");
        rs_image_free(img);
        return NULL;
    }
    return img;
}

/* The area-weighted statistics of rel over the facets in mask (pipeline/truth.h) under key. */
static void put_stats(rs_json *parent, const char *key, const ev *e, const uint8_t *mask, size_t *idx)
{
    rs_truth_stats st;
    rs_truth_stats_of(e->rel, e->sgn, e->area, mask, e->nf, idx, &st);
    if (st.facets == 0) {
        rs_json_set_parsed(parent, key, "null");
        return;
    }
    rs_json *s = rs_json_set_obj(parent, key);
    rs_json_set_int(s, "facets", (long long)st.facets);
    rs_json_set_num(s, "area_m2", st.area);
    rs_json_set_num(s, "mean_rel", st.mean_rel);
    rs_json_set_num(s, "median_rel", st.median_rel);
    rs_json_set_num(s, "p95_rel", st.p95_rel);
    rs_json_set_num(s, "bias_rel", st.bias_rel);
}

double rs_eval_get(const rs_json *doc, const char *path)
{
    char key[256];
    const rs_json *j = doc;
    for (const char *p = path; j && *p;) {
        size_t n = strcspn(p, ".");
        if (n >= sizeof key) return NAN;
        memcpy(key, p, n);
        key[n] = 0;
        j = rs_json_get(j, key);
        p += n + (p[n] == '.');
    }
    char *t = j ? rs_json_text(j) : NULL;
    char *end = NULL;
    double v = t ? strtod(t, &end) : NAN;
    if (t && end == t) v = !strncmp(t, "true", 4) ? 1 : !strncmp(t, "false", 5) ? 0 : NAN;
    free(t);
    return v;
}

int rs_eval_run(const rs_eval_opts *o, rs_json **result, int *passed, rs_err *err)
{
    ev e;
    memset(&e, 0, sizeof e);
    rs_json *doc = rs_json_object();
    size_t *idx = NULL;
    uint8_t *mask = NULL, *good = NULL;
    double *gshare = NULL;
    int rc = -1;
    const char *out_dir = o->out_dir ? o->out_dir : o->work_dir;
    *passed = 0;
    if (!doc) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    if (rs_mkdir_p(out_dir, err) != 0 || load_truth(&e, o->truth_dir, err) != 0 ||
        load_result(&e, o->work_dir, err) != 0)
        goto out;
    if (!(e.ids = load_view(o->work_dir, "facet_id.exr", 1, NULL, err)) ||
        !(e.pano = load_view(o->truth_dir, "pano.exr", 3, e.ids, err)) ||
        !(e.dc = load_view(o->truth_dir, "pano_diffcol.exr", 3, e.ids, err)) ||
        !(e.dd = load_view(o->truth_dir, "pano_diffdir.exr", 3, e.ids, err)) ||
        !(e.di = load_view(o->truth_dir, "pano_diffind.exr", 3, e.ids, err)) ||
        !(e.synth = load_view(o->work_dir, "synth.exr", 3, e.ids, err)))
        goto out;
    if (rs_eval_match_facets(e.res, e.truth, e.tpart, e.trgb, o->tol_m, &e.m, err) != 0 ||
        rs_eval_enclosure(e.res, e.encl, err) != 0)
        goto out;

    size_t nf = e.nf, nonfinite = 0, n_obs = 0, n_est = 0, n_match = 0;
    idx = malloc((nf + 1) * sizeof *idx);
    mask = calloc(nf + 1, 1);
    good = calloc(nf + 1, 1);
    gshare = calloc((size_t)e.nparts + 1, sizeof *gshare);
    if (!idx || !mask || !good || !gshare) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    for (size_t f = 0; f < nf; f++) {
        const double *a = e.alb + 3 * f, *t = e.m.truth_rgb + 3 * f;
        int finite = isfinite(a[0]) && isfinite(a[1]) && isfinite(a[2]);
        good[f] = e.obs[f] > 0 && e.est[f] > 0;
        n_obs += e.obs[f] > 0;
        n_est += good[f];
        n_match += e.m.part[f] >= 0;
        if (good[f] && !finite) nonfinite++;
        e.rel[f] = e.sgn[f] = 0;
        if (!(good[f] && finite && e.m.part[f] >= 0)) continue;
        e.sel[f] = 1;
        rs_truth_facet_error(a, t, &e.rel[f], &e.sgn[f]);
    }
    rs_json_set_str(doc, "program", "rhoscan-eval");
    rs_json_set_str(doc, "version", RHOSCAN_VERSION);
    rs_json_set_str(doc, "truth_dir", o->truth_dir);
    rs_json_set_str(doc, "work_dir", o->work_dir);
    rs_json_set_num(doc, "tolerance_m", o->tol_m);
    rs_json_set_int(doc, "facets_total", (long long)nf);
    rs_json_set_int(doc, "matched", (long long)n_match);
    rs_json_set_int(doc, "observed", (long long)n_obs);
    rs_json_set_int(doc, "estimable", (long long)n_est);
    rs_json_set_int(doc, "nonfinite_albedo", (long long)nonfinite);

    /* Camera view first: it gives each part's true interreflection share. */
    if (rs_eval_camera(&e, good, doc, out_dir, gshare, err) != 0) goto out;

    /* Part labels: concave when the scanned model fills enough of its facets' hemispheres. */
    int np = e.nparts;
    double *encl_sum = calloc((size_t)np + 1, sizeof *encl_sum), *area_sum = calloc((size_t)np + 1, sizeof *area_sum);
    if (!encl_sum || !area_sum) {
        free(encl_sum);
        free(area_sum);
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    for (size_t f = 0; f < nf; f++)
        if (e.m.part[f] >= 0) {
            encl_sum[e.m.part[f]] += e.encl[f] * e.area[f];
            area_sum[e.m.part[f]] += e.area[f];
        }
    rs_json *parts = rs_json_set_obj(doc, "parts");
    for (int p = 0; p < np; p++) {
        char key[16];
        snprintf(key, sizeof key, "%d", p);
        double encl = area_sum[p] > 0 ? encl_sum[p] / area_sum[p] : NAN;
        rs_json *pj = rs_json_set_obj(parts, key);
        for (size_t t = 0; t < e.nt; t++)
            if (e.tpart[t] == p) {
                rs_json *a = rs_json_set_arr(pj, "truth_albedo");
                for (int c = 0; c < 3; c++) rs_json_push_num(a, e.trgb[3 * t + c]);
                break;
            }
        rs_json_set_num(pj, "enclosure", encl);
        rs_json_set_num(pj, "truth_interreflection_share", gshare[p]);
        rs_json_set_bool(pj, "concave", encl >= o->concave_threshold);
        for (int interior = 1; interior >= 0; interior--) {
            for (size_t f = 0; f < nf; f++) mask[f] = e.sel[f] && e.m.part[f] == p && (!interior || e.m.interior[f]);
            put_stats(pj, interior ? "interior" : "all", &e, mask, idx);
        }
    }
    rs_json *alb = rs_json_set_obj(doc, "albedo");
    rs_json_set_num(alb, "concave_threshold", o->concave_threshold);
    for (int split = 0; split < 3; split++) {
        const char *name[3] = {NULL, "concave_parts", "convex_parts"};
        rs_json *grp = split == 0 ? alb : rs_json_set_obj(alb, name[split]);
        for (int interior = 1; interior >= 0; interior--) {
            for (size_t f = 0; f < nf; f++) {
                int p = e.m.part[f];
                int is_cc = p >= 0 && area_sum[p] > 0 && encl_sum[p] / area_sum[p] >= o->concave_threshold;
                mask[f] = e.sel[f] && (!interior || e.m.interior[f]) && (split == 0 || (split == 1) == is_cc);
            }
            put_stats(grp, interior ? "interior" : "all", &e, mask, idx);
        }
    }
    free(encl_sum);
    free(area_sum);

    /* Thresholds and the verdict. */
    rs_json *fails = rs_json_set_arr(doc, "failures");
    int nfail = 0;
    char msg[256];
    double mi = rs_eval_get(doc, "albedo.interior.mean_rel"), ma = rs_eval_get(doc, "albedo.all.mean_rel");
    if (nonfinite) {
        snprintf(msg, sizeof msg, "%zu observed, estimable facets have a non-finite albedo", nonfinite);
        rs_json_push_str(fails, msg), nfail++;
    }
    if (isfinite(o->max_error) && !(mi <= o->max_error)) {
        snprintf(msg, sizeof msg, "interior mean relative error %.4f > --max-error %.4f", mi, o->max_error);
        rs_json_push_str(fails, msg), nfail++;
    }
    if (isfinite(o->max_error_all) && !(ma <= o->max_error_all)) {
        snprintf(msg, sizeof msg, "mean relative error over all facets %.4f > --max-error-all %.4f", ma,
                 o->max_error_all);
        rs_json_push_str(fails, msg), nfail++;
    }
    double coverage = rs_eval_get(doc, "coverage.share");
    if (isfinite(o->min_coverage) && !(coverage >= o->min_coverage)) {
        snprintf(msg, sizeof msg, "coverage %.4f < --min-coverage %.4f", coverage, o->min_coverage);
        rs_json_push_str(fails, msg), nfail++;
    }
    rs_json *th = rs_json_set_obj(doc, "thresholds");
    rs_json_set_num(th, "max_error", o->max_error);
    rs_json_set_num(th, "max_error_all", o->max_error_all);
    rs_json_set_num(th, "min_coverage", o->min_coverage);
    rs_json_set_bool(doc, "passed", nfail == 0);
    *passed = nfail == 0;

    char path[4096];
    const char *jp = o->json_path ? o->json_path : join(path, sizeof path, out_dir, "eval.json");
    if (rs_json_write(doc, jp, err) != 0) goto out;
    rc = 0;
out:
    free(idx);
    free(mask);
    free(good);
    free(gshare);
    eval_free(&e);
    if (rc == 0 && result)
        *result = doc;
    else
        rs_json_free(doc);
    return rc;
}
