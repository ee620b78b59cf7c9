/* rhoscan-bench: run time against albedo error on procedural building scenes with a known
 * answer. Per facet count: scene, sky, truth and panorama into WORK/facets_N, then the real stage
 * programs (observe, irradiance, reflectance, render) per sweep row, one CSV line per row. */
#define _DEFAULT_SOURCE /* wait4, getopt_long */
#include <errno.h>
#include <getopt.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#include "common/faceprop.h"
#include "common/fileio.h"
#include "common/log.h"
#include "common/mesh.h"
#include "bench/scenegen.h"
#include "bench/truth.h"

typedef struct {
    const char *name;      /* row label in the CSV */
    int samples, sky, sun; /* [irradiance] samples, sky_samples, sun_samples */
    const char *method;    /* [reflectance] method */
    const char *extra;     /* further overrides, "section.key=value" separated by spaces, or "" */
} bench_row;

/* The accuracy sweep at small facet counts; `scale` rows at every count. Rows that differ in
 * one switch only show what a skip or an option buys (docs/BENCHMARKS.md). */
static const bench_row SWEEP[] = {
    {"s16", 16, 32, 8, "interreflection", ""},
    {"s32", 32, 64, 8, "interreflection", ""},
    {"s64", 64, 128, 16, "interreflection", ""},
    {"s128", 128, 256, 32, "interreflection", ""},
    {"default", 256, 512, 64, "interreflection", ""},
    {"s1024", 1024, 1024, 256, "interreflection", ""},
    {"scale", 64, 64, 16, "interreflection", ""},
    {"scale_no_relay", 64, 64, 16, "interreflection", "irradiance.relay_share=1"},
    {"survey", 256, 32, 16, "interreflection", ""},
    {"survey_no_relay", 256, 32, 16, "interreflection", "irradiance.relay_share=1"},
    {"survey_512", 512, 32, 16, "interreflection", ""},
    {"scale_no_pool", 64, 64, 16, "interreflection", "reflectance.pool_accuracy=0"},
    {"default_no_pool", 256, 512, 64, "interreflection", "reflectance.pool_accuracy=0"},
    {"s1024_no_pool", 1024, 1024, 256, "interreflection", "reflectance.pool_accuracy=0"},
    {"scale_adaptive", 64, 64, 16, "interreflection", "irradiance.sun_target_error=0.01"},
    {"scale_target", 64, 64, 16, "interreflection", "irradiance.target_error=0.02"},
    {"s64_target", 64, 128, 16, "interreflection", "irradiance.target_error=0.02"},
    {"s64_target_05", 64, 128, 16, "interreflection", "irradiance.target_error=0.05"},
    {"s64_target_10", 64, 128, 16, "interreflection", "irradiance.target_error=0.1"},
    {"scale_target_05", 64, 64, 16, "interreflection", "irradiance.target_error=0.05"},
    {"default_target", 256, 512, 64, "interreflection", "irradiance.target_error=0.01"},
    {"scale_all_facets", 64, 64, 16, "interreflection", "irradiance.skip_unseen=false"},
    {"default_all_facets", 256, 512, 64, "interreflection", "irradiance.skip_unseen=false"},
    {"scale_trace_convex", 64, 64, 16, "interreflection", "irradiance.skip_convex=false"},
    {"default_trace_convex", 256, 512, 64, "interreflection", "irradiance.skip_convex=false"},
    {"scale_no_sky_sh", 64, 64, 16, "interreflection", "irradiance.sh_max_error=0"},
    {"default_no_sky_sh", 256, 512, 64, "interreflection", "irradiance.sh_max_error=0"},
    {"sun_set_forced", 256, 512, 64, "interreflection", "irradiance.sun_threshold=1"},
    {"no_sun_rays", 256, 512, 0, "interreflection", ""},
    {"cosine_only", 256, 0, 0, "interreflection", ""},
    {"direct", 256, 512, 64, "direct", ""},
    {"paper", 256, 512, 64, "paper", ""},
};
static const char *const FULL_ROWS =
    "s16,s32,s64,s128,default,s1024,scale,scale_adaptive,scale_target,s64_target,"
    "s64_target_05,s64_target_10,default_target,scale_all_facets,default_all_facets,default_trace_convex,"
    "no_sun_rays,cosine_only,direct,paper";
static const char *const SCALE_ROWS = "scale,survey,survey_no_relay,scale_adaptive,scale_target,scale_all_facets,"
                                      "scale_trace_convex";

typedef struct {
    char bindir[PATH_MAX], work[PATH_MAX], csv[PATH_MAX + 256];
    const char *sky;
    int width, threads, truth_factor, full;
    const char *rows;         /* comma-separated row names, NULL: by --sweep */
    const char *sampling_ref; /* row whose albedo, from another seed, measures sampling error */
    uint32_t seed;
} bench_opts;

/* A number "key": value from a stage's JSON file; NAN when absent. */
static double json_num(const char *path, const char *key)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NAN;
    static char buf[1 << 16];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = 0;
    char pat[128];
    snprintf(pat, sizeof pat, "\"%s\": ", key);
    const char *p = strstr(buf, pat);
    return p ? strtod(p + strlen(pat), NULL) : NAN;
}

/* Runs bin/rhoscan-<stage> with the overrides; wall time, the child's peak RSS (MB) and its CPU
 * time (user + system: the figure that other jobs on a shared machine do not inflate). The peak
 * is the one the stage wrote into its <stage>.json (peak_rss_mb): the kernel's figure for a
 * child also counts the pages this process held when it forked, which the truth of 10^6 facets
 * makes gigabytes. */
static int run_stage(const bench_opts *o, const char *stage, const char *config, const char *const *sets, int nsets,
                     double *seconds, double *peak_mb, double *cpu_s)
{
    char prog[PATH_MAX + 256];
    snprintf(prog, sizeof prog, "%s/rhoscan-%s", o->bindir, stage);
    const char *argv[64];
    int n = 0;
    argv[n++] = prog;
    argv[n++] = "--quiet";
    for (int k = 0; k < nsets && n < 60; k++) argv[n++] = "--set", argv[n++] = sets[k];
    argv[n++] = config;
    argv[n] = NULL;
    double t0 = rs_now();
    time_t started = time(NULL);
    pid_t pid = fork();
    if (pid < 0) return -1;
    if (pid == 0) {
        execv(prog, (char *const *)argv);
        _exit(127);
    }
    int status;
    struct rusage ru;
    if (wait4(pid, &status, 0, &ru) < 0) return -1;
    *seconds = rs_now() - t0;
    *peak_mb = ru.ru_maxrss / 1024.0;
    char json[PATH_MAX + 256];
    const char *slash = strrchr(config, '/');
    snprintf(json, sizeof json, "%.*s%s.json", slash ? (int)(slash - config + 1) : 0, config, stage);
    struct stat st;
    double own = json_num(json, "peak_rss_mb");
    if (stat(json, &st) == 0 && st.st_mtime >= started && own > 0) *peak_mb = own; /* written by this run */
    *cpu_s = ru.ru_utime.tv_sec + ru.ru_stime.tv_sec + 1e-6 * (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        fprintf(stderr, "rhoscan-bench: %s failed (status %d)\n", prog, status);
        return -1;
    }
    return 0;
}

typedef struct {
    double albedo_err, albedo_p90, irr_err, estimable_share;
    double sampling_err; /* against the --sampling-ref albedo; NAN without one */
} bench_err;

/* The --sampling-ref run's albedo per facet (3 channels; NAN where not estimable). */
typedef struct {
    double *rho;
} bench_ref;

static int cmp_pair(const void *a, const void *b)
{
    const double *x = a, *y = b;
    return (x[0] > y[0]) - (x[0] < y[0]);
}

/* Area-weighted mean relative albedo error (mean of the channels) and irradiance error
 * (luminance of E_sky + G) over the estimable facets, against the truth; with ref, the same
 * albedo error against ref's albedo: what sampling alone contributes, since both runs share
 * every bias of the method and differ only in their random sequences. With copy_ref, the run's
 * albedo is kept in copy_ref instead. */
static int measure(const char *dir, const rs_bench_truth *t, const bench_ref *ref, bench_ref *copy_ref, bench_err *out,
                   rs_err *err)
{
    char path[PATH_MAX + 256];
    snprintf(path, sizeof path, "%s/albedo.ply", dir);
    rs_ply *ply = NULL;
    rs_mesh *m = rs_mesh_read(path, &ply, err);
    if (!m) return -1;
    size_t nf = m->nfaces;
    double *rho = malloc(3 * nf * sizeof *rho), *es = malloc(3 * nf * sizeof *es), *gi = malloc(3 * nf * sizeof *gi),
           *est = malloc(nf * sizeof *est), *pairs = malloc(2 * nf * sizeof *pairs);
    int rc = -1;
    if (!rho || !es || !gi || !est || !pairs || nf != t->nfaces) {
        rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory or facet count differs from the truth");
        goto out;
    }
    if (rs_faceprop_get_rgb(ply, path, "albedo", nf, rho, err) ||
        rs_faceprop_get_rgb(ply, path, "irradiance_sky", nf, es, err) ||
        rs_faceprop_get_rgb(ply, path, "irradiance_inter", nf, gi, err) ||
        rs_faceprop_get(ply, path, "estimable", nf, est, err))
        goto out;
    if (copy_ref) {
        copy_ref->rho = malloc(3 * nf * sizeof *copy_ref->rho);
        if (!copy_ref->rho) {
            rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
            goto out;
        }
        for (size_t k = 0; k < 3 * nf; k++) copy_ref->rho[k] = est[k / 3] > 0 ? rho[k] : NAN;
    }
    double sa = 0, se = 0, wsum = 0, area_all = 0, ss = 0, wss = 0;
    size_t np = 0;
    for (size_t f = 0; f < nf; f++) {
        rs_v3 c, n;
        double a, ea = 0, ee = 0, et = 0, eh = 0;
        rs_mesh_face(m, f, &c, &n, &a);
        static const double Y[3] = {0.2126, 0.7152, 0.0722};
        for (int ch = 0; ch < 3; ch++) {
            et += Y[ch] * (t->esky[3 * f + ch] + t->G[3 * f + ch]);
            eh += Y[ch] * (es[3 * f + ch] + gi[3 * f + ch]);
        }
        if (t->L[3 * f] > 0) area_all += a;
        if (!(est[f] > 0) || !(et > 0)) continue;
        for (int ch = 0; ch < 3; ch++) ea += fabs(rho[3 * f + ch] - t->rho[3 * f + ch]) / t->rho[3 * f + ch] / 3;
        ee = fabs(eh - et) / et;
        sa += a * ea;
        se += a * ee;
        if (ref && ref->rho[3 * f] > 0 && ref->rho[3 * f + 1] > 0 && ref->rho[3 * f + 2] > 0) {
            double es3 = 0;
            for (int ch = 0; ch < 3; ch++)
                es3 += fabs(rho[3 * f + ch] - ref->rho[3 * f + ch]) / ref->rho[3 * f + ch] / 3;
            ss += a * es3;
            wss += a;
        }
        wsum += a;
        pairs[2 * np] = ea, pairs[2 * np + 1] = a, np++;
    }
    qsort(pairs, np, 2 * sizeof *pairs, cmp_pair);
    double acc = 0;
    out->albedo_p90 = 0;
    for (size_t k = 0; k < np; k++)
        if ((acc += pairs[2 * k + 1]) >= 0.9 * wsum) {
            out->albedo_p90 = pairs[2 * k];
            break;
        }
    out->albedo_err = wsum > 0 ? sa / wsum : NAN;
    out->sampling_err = wss > 0 ? ss / wss : NAN;
    out->irr_err = wsum > 0 ? se / wsum : NAN;
    out->estimable_share = area_all > 0 ? wsum / area_all : 0;
    rc = 0;
out:
    free(rho), free(es), free(gi), free(est), free(pairs);
    rs_ply_free(ply);
    rs_mesh_free(m);
    return rc;
}

/* Scene, truth and panorama of one facet count into dir; config.ini beside them. */
static rs_bench_truth *prepare(const bench_opts *o, size_t facets, const bench_row *rows, int nrows, const char *dir,
                               size_t *nf_out, rs_err *err)
{
    int smax = 0, kmax = 0, umax = 0;
    for (int r = 0; r < nrows; r++) {
        smax = rows[r].samples > smax ? rows[r].samples : smax;
        kmax = rows[r].sky > kmax ? rows[r].sky : kmax;
        umax = rows[r].sun > umax ? rows[r].sun : umax;
    }
    rs_bench_truth *t = NULL;
    rs_image *sky = NULL, *pano = NULL;
    rs_ply *ply = NULL;
    char path[PATH_MAX + 256];
    rs_bench_scene *sc = rs_bench_scene_new(facets, o->seed);
    if (!sc) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the scene"), NULL;
    *nf_out = sc->mesh->nfaces;
    if (!(sky = rs_bench_sky(o->width, o->sky, err))) goto fail;
    /* Truth: truth_factor times the largest sample counts of the sweep, and its own seed. */
    int F = o->truth_factor;
    if (!(t = rs_bench_truth_new(sc, sky, F * smax, F * (kmax ? kmax : 64), F * (umax ? umax : 16),
                                 o->seed * 7919u + 0x5eed, err)))
        goto fail;
    fprintf(stderr, "rhoscan-bench: %zu facets: truth %.3g rays (%zu facets gathered) in %.1f s\n", sc->mesh->nfaces,
            t->rays, t->gathered, t->seconds);
    if (!(pano = rs_bench_render(sc, t, sky, err))) goto fail;
    static const char *const rgb[] = {"R", "G", "B"};
    snprintf(path, sizeof path, "%s/pano.exr", dir);
    if (rs_image_write_exr(pano, path, rgb, 0, "rhoscan-bench truth panorama", err) != 0) goto fail;
    ply = rs_ply_new();
    if (!ply || !rs_mesh_to_ply(sc->mesh, ply)) goto fail;
    snprintf(path, sizeof path, "%s/scene.ply", dir);
    if (rs_ply_write(ply, path, 1, err) != 0) goto fail;
    /* truth.ply: the answer, for plots and for checking a run by hand. */
    rs_ply_free(ply);
    ply = rs_ply_new();
    rs_ply_element *faces = ply ? rs_mesh_to_ply(sc->mesh, ply) : NULL;
    double *part = malloc(sc->mesh->nfaces * sizeof *part);
    if (part)
        for (size_t f = 0; f < sc->mesh->nfaces; f++) part[f] = sc->part[f];
    int bad = !faces || !part || rs_faceprop_add_rgb(faces, "albedo", t->rho) != 0 ||
        rs_faceprop_add_rgb(faces, "irradiance_sky", t->esky) != 0 ||
        rs_faceprop_add_rgb(faces, "irradiance_inter", t->G) != 0 ||
        rs_faceprop_add_rgb(faces, "radiance", t->L) != 0 || !rs_ply_add_scalar(faces, "part", RS_PLY_UINT32, part);
    free(part);
    if (bad) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for truth.ply");
        goto fail;
    }
    snprintf(path, sizeof path, "%s/truth.ply", dir);
    if (rs_ply_write(ply, path, 1, err) != 0) goto fail;
    snprintf(path, sizeof path, "%s/config.ini", dir);
    FILE *f = fopen(path, "w");
    if (!f) {
        rs_err_errno(err, path, "cannot write");
        goto fail;
    }
    fprintf(f,
            "; written by rhoscan-bench: %zu facets, truth with %d x the samples\n[pipeline]\nworkdir = .\n"
            "threads = %d\n[report]\nwrite = false\n[mesh]\ninput_mesh = scene.ply\n[capture]\npanorama = "
            "pano.exr\nposition = %.6f %.6f %.6f\n",
            sc->mesh->nfaces, F, o->threads, sc->camera.x, sc->camera.y, sc->camera.z);
    fclose(f);
    goto out;
fail:
    rs_bench_truth_free(t);
    t = NULL;
out:
    rs_ply_free(ply);
    rs_image_free(sky);
    rs_image_free(pano);
    rs_bench_scene_free(sc);
    return t;
}

/* Irradiance, reflectance and (with_render) render of one row: wall seconds, peak MB and CPU
 * seconds per stage in t, m, c. seed_set, when not NULL, is one more override. */
static int run_row(const bench_opts *o, const bench_row *row, const char *config, const char *seed_set, int with_render,
                   double t[3], double m[3], double c[3])
{
    char sets[4][128], extra[512];
    const char *sp[16];
    int ns = 0;
    snprintf(sets[0], sizeof sets[0], "irradiance.samples=%d", row->samples);
    snprintf(sets[1], sizeof sets[1], "irradiance.sky_samples=%d", row->sky);
    snprintf(sets[2], sizeof sets[2], "irradiance.sun_samples=%d", row->sun);
    snprintf(sets[3], sizeof sets[3], "reflectance.method=%s", row->method);
    for (; ns < 4; ns++) sp[ns] = sets[ns];
    if (seed_set) sp[ns++] = seed_set;
    snprintf(extra, sizeof extra, "%s", row->extra);
    char *save = NULL;
    for (char *tok = strtok_r(extra, " ", &save); tok && ns < 16; tok = strtok_r(NULL, " ", &save)) sp[ns++] = tok;
    t[2] = m[2] = c[2] = 0;
    if (run_stage(o, "irradiance", config, sp, ns, &t[0], &m[0], &c[0]) != 0 ||
        run_stage(o, "reflectance", config, sp, ns, &t[1], &m[1], &c[1]) != 0)
        return -1;
    return with_render ? run_stage(o, "render", config, sp, ns, &t[2], &m[2], &c[2]) : 0;
}

static const bench_row *find_row(const char *name)
{
    for (size_t k = 0; k < sizeof SWEEP / sizeof *SWEEP; k++)
        if (!strcmp(SWEEP[k].name, name)) return &SWEEP[k];
    fprintf(stderr, "rhoscan-bench: unknown row '%s'\n", name);
    return NULL;
}

static void print_err(rs_err *err)
{
    char msg[2048];
    rs_err_format(err, msg, sizeof msg);
    fprintf(stderr, "rhoscan-bench: %s\n", msg);
}

static int bench_size(const bench_opts *o, size_t facets, FILE *csv)
{
    bench_row rows[sizeof SWEEP / sizeof *SWEEP];
    int nrows = 0;
    char names[1024], *save_rows = NULL;
    snprintf(names, sizeof names, "%s", o->rows ? o->rows : o->full ? FULL_ROWS : SCALE_ROWS);
    for (char *tok = strtok_r(names, ",", &save_rows); tok; tok = strtok_r(NULL, ",", &save_rows)) {
        const bench_row *row = find_row(tok);
        if (!row) return -1;
        if (nrows == (int)(sizeof rows / sizeof *rows)) {
            fprintf(stderr, "rhoscan-bench: --rows: more than %d rows\n", nrows);
            return -1;
        }
        rows[nrows++] = *row;
    }
    const bench_row *ref_row = o->sampling_ref ? find_row(o->sampling_ref) : NULL;
    if (o->sampling_ref && !ref_row) return -1;
    char dir[PATH_MAX + 64], config[PATH_MAX + 96];
    snprintf(dir, sizeof dir, "%s/facets_%zu", o->work, facets);
    mkdir(o->work, 0777);
    mkdir(dir, 0777);
    snprintf(config, sizeof config, "%s/config.ini", dir);
    rs_err err = {0};
    size_t nf;
    rs_bench_truth *t = prepare(o, facets, rows, nrows, dir, &nf, &err);
    if (!t) {
        print_err(&err);
        return -1;
    }
    bench_ref ref = {0};
    double t_mesh, t_obs, m_mesh, m_obs, c_mesh, c_obs;
    int rc = -1;
    if (run_stage(o, "mesh", config, NULL, 0, &t_mesh, &m_mesh, &c_mesh) != 0 ||
        run_stage(o, "observe", config, NULL, 0, &t_obs, &m_obs, &c_obs) != 0)
        goto out;
    if (ref_row) {
        /* Another seed than every row's, so that the reference's points are not a superset of a
         * row's (scrambled Sobol prefixes would make the two errors correlate). */
        char seed_set[64];
        snprintf(seed_set, sizeof seed_set, "irradiance.seed=%u", (o->seed + 1000003u) & 0x7fffffffu);
        double tt[3], mm[3], cc[3];
        bench_err e;
        if (run_row(o, ref_row, config, seed_set, 0, tt, mm, cc) != 0) goto out;
        if (measure(dir, t, NULL, &ref, &e, &err) != 0) {
            print_err(&err);
            goto out;
        }
        fprintf(stderr, "rhoscan-bench: %zu facets sampling reference %s (%s): albedo err %.4f\n", nf, ref_row->name,
                seed_set, e.albedo_err);
    }
    for (int r = 0; r < nrows; r++) {
        const bench_row *row = &rows[r];
        if (!strcmp(row->method, "paper") && nf > 4000) continue; /* O(m^3): [reflectance] paper_max_facets */
        double tt[3], mm[3], cc[3];
        if (run_row(o, row, config, NULL, 1, tt, mm, cc) != 0) goto out;
        double ti = tt[0], tr = tt[1], tn = tt[2], mi = mm[0], mr = mm[1], mn = mm[2], ci = cc[0], cr = cc[1],
               cn = cc[2];
        bench_err e;
        if (measure(dir, t, ref_row ? &ref : NULL, NULL, &e, &err) != 0) {
            print_err(&err);
            goto out;
        }
        char jp[PATH_MAX + 256];
        snprintf(jp, sizeof jp, "%s/irradiance.json", dir);
        double rays = json_num(jp, "rays"), rps = json_num(jp, "rays_per_second");
        double peak = fmax(fmax(m_obs, mi), fmax(mr, mn)), total = t_obs + ti + tr + tn;
        fprintf(csv,
                "%zu,%s,%s,%d,%d,%d,%s,%d,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.1f,%.0f,%.4g,%.5f,%.5f,"
                "%.5f,%.4f,%.1f,%.1f,%.1f,%.1f,%.5f\n",
                nf, row->name, row->method, row->samples, row->sky, row->sun, row->extra[0] ? row->extra : "-",
                o->threads, t_obs, ti, tr, tn, total, c_obs, ci, cr, cn, peak, rays, rps, e.albedo_err, e.albedo_p90,
                e.irr_err, e.estimable_share, m_obs, mi, mr, mn, e.sampling_err);
        fflush(csv);
        fprintf(
            stderr,
            "rhoscan-bench: %zu facets %-12s total %7.2f s (obs %.2f irr %.2f refl %.2f render %.2f; cpu %.2f) "
            "peak %.0f MB (obs %.0f irr %.0f refl %.0f render %.0f)  albedo err %.4f  E err %.4f  sampling err %.4f\n",
            nf, row->name, total, t_obs, ti, tr, tn, c_obs + ci + cr + cn, peak, m_obs, mi, mr, mn, e.albedo_err,
            e.irr_err, e.sampling_err);
    }
    rc = 0;
out:
    free(ref.rho);
    rs_bench_truth_free(t);
    return rc;
}

static void usage(FILE *f)
{
    fputs("usage: rhoscan-bench [--facets N[,N...]] [--sweep full|scale] [--rows R[,R...]] [--work DIR] [--csv FILE]\n"
          "                     [--sky FILE.hdr] [--width W] [--threads T] [--truth-factor F] [--seed S]\n"
          "                     [--sampling-ref ROW]\n"
          "Procedural building scenes with a known albedo; runs observe, irradiance, reflectance and render\n"
          "per sweep row and appends one CSV line per run (header written when the file is new).\n"
          "  --facets     facet counts (default 2000)\n"
          "  --sweep      full: samples, sun rays, methods (paper up to 4000 facets); scale: one row (default:\n"
          "               full up to 20000 facets, scale above)\n"
          "  --rows       row names (see SWEEP in bench/bench.c), comma-separated; overrides --sweep\n"
          "  --sky        an equirectangular HDR sky (e.g. ../shared/skies/pmndrs_park.hdr), or 'overcast'\n"
          "               (CIE overcast, no sun); default: a clear analytic sky with a sun\n"
          "  --width      panorama width (default 2048; height = width / 2)\n"
          "  --truth-factor  truth kernel samples as a multiple of the sweep's largest (default 16)\n"
          "  --sampling-ref ROW  run ROW first with another seed; each row's sampling_err is its albedo's\n"
          "               area-weighted mean relative difference from ROW's (e.g. s1024: the sampling error alone)\n",
          f);
}

int main(int argc, char **argv)
{
    bench_opts o = {.width = 2048, .threads = 0, .truth_factor = 16, .full = -1, .seed = 1};
    snprintf(o.work, sizeof o.work, "bench-work");
    char facets[1024] = "2000";
    static const struct option longopts[] = {
        {"facets", 1, 0, 'f'}, {"sweep", 1, 0, 'w'}, {"work", 1, 0, 'o'},         {"csv", 1, 0, 'c'},
        {"sky", 1, 0, 's'},    {"width", 1, 0, 'W'}, {"threads", 1, 0, 't'},      {"truth-factor", 1, 0, 'F'},
        {"seed", 1, 0, 'S'},   {"rows", 1, 0, 'r'},  {"sampling-ref", 1, 0, 'R'}, {"help", 0, 0, 'h'},
        {0, 0, 0, 0}};
    int c;
    o.csv[0] = 0;
    while ((c = getopt_long(argc, argv, "h", longopts, NULL)) != -1) {
        switch (c) {
        case 'f': snprintf(facets, sizeof facets, "%s", optarg); break;
        case 'w': o.full = !strcmp(optarg, "full") ? 1 : !strcmp(optarg, "scale") ? 0 : -2; break;
        case 'o': snprintf(o.work, sizeof o.work, "%s", optarg); break;
        case 'c': snprintf(o.csv, sizeof o.csv, "%s", optarg); break;
        case 's': o.sky = optarg; break;
        case 'W': o.width = atoi(optarg); break;
        case 't': o.threads = atoi(optarg); break;
        case 'F': o.truth_factor = atoi(optarg); break;
        case 'S': o.seed = (uint32_t)strtoul(optarg, NULL, 10); break;
        case 'r': o.rows = optarg; break;
        case 'R': o.sampling_ref = optarg; break;
        case 'h': usage(stdout); return 0;
        default: usage(stderr); return 1;
        }
    }
    if (o.full == -2 || o.width < 16 || o.width % 2 || o.truth_factor < 1 || o.threads < 0 || optind != argc) {
        usage(stderr);
        return 1;
    }
#ifdef _OPENMP
    if (o.threads > 0) omp_set_num_threads(o.threads);
#endif
    ssize_t n = readlink("/proc/self/exe", o.bindir, sizeof o.bindir - 1);
    if (n <= 0) return fprintf(stderr, "rhoscan-bench: cannot find its own folder\n"), 2;
    o.bindir[n] = 0;
    *strrchr(o.bindir, '/') = 0;
    if (!o.csv[0]) snprintf(o.csv, sizeof o.csv, "%s/bench.csv", o.work);
    mkdir(o.work, 0777);
    struct stat st;
    int fresh = stat(o.csv, &st) != 0 || st.st_size == 0;
    FILE *csv = fopen(o.csv, "a");
    if (!csv) return fprintf(stderr, "rhoscan-bench: %s: %s\n", o.csv, strerror(errno)), 2;
    if (fresh)
        fputs("facets,row,method,samples,sky_samples,sun_samples,extra,threads,t_observe,t_irradiance,"
              "t_reflectance,t_render,t_total,cpu_observe,cpu_irradiance,cpu_reflectance,cpu_render,peak_mb,rays,rays_"
              "per_s,albedo_err,albedo_err_p90,irradiance_err,"
              "estimable_share,peak_observe_mb,peak_irradiance_mb,peak_reflectance_mb,peak_render_mb,sampling_err\n",
              csv);
    int rc = 0;
    char *save = NULL;
    for (char *tok = strtok_r(facets, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        size_t nf = (size_t)strtod(tok, NULL);
        bench_opts oo = o;
        if (oo.full < 0) oo.full = nf <= 20000;
        if (nf < 100 || bench_size(&oo, nf, csv) != 0) rc = 1;
    }
    fclose(csv);
    return rc;
}
