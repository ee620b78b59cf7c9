/* rhoscan-eval: compares a run's work folder with a Cycles truth folder (tools/eval/eval.h);
 * exit 0 when every threshold given is met, 1 when one is missed or an input is bad. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "tools/eval/eval.h"
#include "common/log.h"

static const char *USAGE =
    "usage: rhoscan-eval TRUTH_DIR WORKDIR [options]\n"
    "  TRUTH_DIR  truth.ply, pano.exr, pano_diffcol.exr, pano_diffdir.exr, pano_diffind.exr (Cycles)\n"
    "  WORKDIR    a run's work folder: albedo.ply, facet_id.exr, synth.exr\n"
    "  --max-error X          fail when the area-weighted mean relative albedo error over facets\n"
    "                         inside one truth part exceeds X\n"
    "  --max-error-all X      the same over every matched facet\n"
    "  --min-coverage X       fail when the observed, estimable share of the model pixels is below X\n"
    "  --json OUT             write eval.json to OUT (default OUTDIR/eval.json)\n"
    "  --out OUTDIR           folder for eval.json, eval_error.exr/.png (default WORKDIR)\n"
    "  --tol M                match distance to the truth surface, metres (default 0.15)\n"
    "  --concave-threshold X  mean enclosure from which a part counts as concave (default 0.2)\n"
    "  --quiet                no summary on stderr\n"
    "Exit: 0 passed, 1 a threshold missed, a non-finite albedo, or bad input; 2 I/O; 3 internal.\n";

static int number(const char *opt, const char *s, double lo, double *out)
{
    char *end;
    double v = s ? strtod(s, &end) : NAN;
    if (!s || end == s || *end || !isfinite(v) || v < lo) {
        fprintf(stderr, "rhoscan-eval: %s \"%s\": expected a number >= %g\n", opt, s ? s : "", lo);
        return -1;
    }
    *out = v;
    return 0;
}

int main(int argc, char **argv)
{
    rs_log_init("rhoscan-eval");
    rs_eval_opts o;
    rs_eval_opts_default(&o);
    const char *pos[2] = {NULL, NULL};
    int npos = 0, quiet = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        int bad = 0;
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            fputs(USAGE, stdout);
            return 0;
        } else if (!strcmp(a, "--quiet"))
            quiet = 1;
        else if (!strcmp(a, "--max-error"))
            bad = number(a, v, 0, &o.max_error), i++;
        else if (!strcmp(a, "--max-error-all"))
            bad = number(a, v, 0, &o.max_error_all), i++;
        else if (!strcmp(a, "--min-coverage"))
            bad = number(a, v, 0, &o.min_coverage), i++;
        else if (!strcmp(a, "--tol"))
            bad = number(a, v, 1e-6, &o.tol_m), i++;
        else if (!strcmp(a, "--concave-threshold"))
            bad = number(a, v, 0, &o.concave_threshold), i++;
        else if (!strcmp(a, "--json") || !strcmp(a, "--out")) {
            if (!v) {
                fprintf(stderr, "rhoscan-eval: %s needs a path\n%s", a, USAGE);
                return 1;
            }
            *(a[2] == 'j' ? &o.json_path : &o.out_dir) = v;
            i++;
        } else if (a[0] == '-' && a[1]) {
            fprintf(stderr, "rhoscan-eval: unknown option \"%s\"\n%s", a, USAGE);
            return 1;
        } else if (npos < 2)
            pos[npos++] = a;
        else {
            fprintf(stderr, "rhoscan-eval: unexpected argument \"%s\"\n%s", a, USAGE);
            return 1;
        }
        if (bad) return 1;
    }
    if (npos != 2) {
        fprintf(stderr, "rhoscan-eval: expected TRUTH_DIR and WORKDIR\n%s", USAGE);
        return 1;
    }
    o.truth_dir = pos[0];
    o.work_dir = pos[1];
    rs_err err;
    rs_err_clear(&err);
    rs_json *doc = NULL;
    int passed = 0;
    if (rs_eval_run(&o, &doc, &passed, &err) != 0) {
        rs_log_error(&err);
        return err.kind ? (int)err.kind : 3;
    }
    if (!quiet) {
        fprintf(stderr,
                "rhoscan-eval: albedo interior: mean %.4f median %.4f p95 %.4f bias %+.4f | all: mean %.4f "
                "p95 %.4f | coverage %.3f\n",
                rs_eval_get(doc, "albedo.interior.mean_rel"), rs_eval_get(doc, "albedo.interior.median_rel"),
                rs_eval_get(doc, "albedo.interior.p95_rel"), rs_eval_get(doc, "albedo.interior.bias_rel"),
                rs_eval_get(doc, "albedo.all.mean_rel"), rs_eval_get(doc, "albedo.all.p95_rel"),
                rs_eval_get(doc, "coverage.share"));
        fprintf(stderr,
                "rhoscan-eval: E_sky vs pi DiffDir %.4f (bias %+.4f), G vs pi DiffInd %.4f (bias %+.4f), "
                "total %.4f (bias %+.4f); synth vs pano %.4f\n",
                rs_eval_get(doc, "irradiance.esky_rel"), rs_eval_get(doc, "irradiance.esky_bias"),
                rs_eval_get(doc, "irradiance.g_rel"), rs_eval_get(doc, "irradiance.g_bias"),
                rs_eval_get(doc, "irradiance.total_rel"), rs_eval_get(doc, "irradiance.total_bias"),
                rs_eval_get(doc, "synth.rel_diff"));
        if (!passed) {
            char *t = rs_json_text(rs_json_get(doc, "failures"));
            fprintf(stderr, "rhoscan-eval: FAILED: %s", t ? t : "\n");
            free(t);
        } else
            fprintf(stderr, "rhoscan-eval: passed\n");
    }
    rs_json_free(doc);
    return passed ? 0 : 1;
}
