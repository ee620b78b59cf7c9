/* ingest_stream: the ingest stage's streaming path. When every [ingest] scan file is LAS or an
 * E57 without scan grids and no whole-cloud cleaning is asked for (outlier removal off, no voxel
 * grid), cloud.ply is written from the readers' chunks, the files read several times, never
 * held: pass 1 counts the points kept, their bounding box (for recentring) and each LAS file's
 * colour depth; the coincident-point passes find exact copies a hash bucket at a time (a table of
 * at most BUCKET_POINTS points, the copies marked in a bitmap of one bit a point); two passes
 * give the mean and covariance of the distinct points (the collinearity check); the last writes
 * cloud.ply. The bytes are those of the whole-cloud path (same order, same arithmetic).
 * Exports rs_ingest_stream (stages/ingest/ingest_stream.h). */
#include "stages/ingest/ingest_stream.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/cloud_ply.h"
#include "common/e57.h"
#include "common/las.h"
#include "common/log.h"

/* Points hashed per coincident pass: a table of twice as many 24-byte slots (192 MB). The
 * environment variable RHOSCAN_INGEST_BUCKET_POINTS sets a smaller one (the tests: many passes
 * over a small file). */
static size_t bucket_points(void)
{
    const char *v = getenv("RHOSCAN_INGEST_BUCKET_POINTS");
    long n = v ? strtol(v, NULL, 10) : 0;
    return n >= 16 && n <= (1L << 22) ? (size_t)n : (size_t)1 << 22;
}
#define BUCKET_POINTS bucket_points()

static int grow(source *s, size_t n, rs_err *err)
{
    if (n <= s->cap) return 0;
    double *xyz = realloc(s->xyz, 3 * n * sizeof *xyz);
    if (xyz) s->xyz = xyz;
    float *in = realloc(s->in, n * sizeof *in), *nrm = realloc(s->nrm, 3 * n * sizeof *nrm);
    if (in) s->in = in;
    if (nrm) s->nrm = nrm;
    uint8_t *rgb = realloc(s->rgb, 3 * n);
    if (rgb) s->rgb = rgb;
    if (!xyz || !in || !nrm || !rgb) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for a chunk");
    s->cap = n;
    return 0;
}

static void close_file(source *s)
{
    rs_las_close(s->las);
    rs_e57_close(s->e57);
    s->las = NULL, s->e57 = NULL;
}

/* Opens file k (LAS or E57) for reading from its first point. */
static int open_file(source *s, int k, rs_err *err)
{
    close_file(s);
    s->file = k, s->scan = -1;
    rs_config_path_at(s->cfg, "ingest", "scan", k, s->path, sizeof s->path);
    memset(s->hist, 0, sizeof s->hist);
    if (s->info[k].las) {
        s->las = rs_las_open(s->path, err);
        return s->las ? 0 : -1;
    }
    s->e57 = rs_e57_open(s->path, err);
    return s->e57 ? 0 : -1;
}

/* The next LAS chunk's kept points into the source's chunk. */
static int next_las(source *s, rs_err *err)
{
    const rs_las_chunk *ch = rs_las_next(s->las, err);
    if (!ch) return -1;
    if (grow(s, ch->n, err) != 0) return -1;
    const file_info *fi = &s->info[s->file];
    size_t m = 0;
    s->raw_n = ch->n;
    for (size_t i = 0; i < ch->n; i++) {
        if (ch->withheld[i] && !s->keep_withheld) continue;
        s->hist[ch->classification[i]]++;
        if (s->keep && !s->keep[ch->classification[i]]) continue;
        for (int j = 0; j < 3; j++) s->xyz[3 * m + j] = ch->xyz[3 * i + j] - s->shift[j];
        if (s->xyz_only) {
            m++;
            continue;
        }
        s->in[m] = ch->intensity[i];
        if (s->survey && ch->rgb && (ch->rgb[3 * i] > 255 || ch->rgb[3 * i + 1] > 255 || ch->rgb[3 * i + 2] > 255))
            s->info[s->file].wide = 1;
        for (int j = 0; j < 3; j++) {
            uint16_t v = ch->rgb ? ch->rgb[3 * i + j] : 0;
            s->rgb[3 * m + j] = (uint8_t)(fi->wide ? v >> 8 : v);
            s->nrm[3 * m + j] = 0;
        }
        m++;
    }
    s->n = m;
    return ch->n > 0 ? 1 : 0;
}

/* The next E57 chunk's valid points (the next scan's when one ends). */
static int next_e57(source *s, rs_err *err)
{
    for (;;) {
        if (s->scan < 0 || s->scan >= rs_e57_scan_count(s->e57)) {
            int next = s->scan + 1;
            while (next < rs_e57_scan_count(s->e57) && rs_e57_scan(s->e57, next)->records == 0) next++;
            if (next >= rs_e57_scan_count(s->e57)) return 0;
            if (rs_e57_scan_begin(s->e57, next, err) != 0) return -1;
            s->scan = next;
        }
        rs_e57_points p;
        int r = rs_e57_scan_next(s->e57, &p, err);
        if (r < 0) return -1;
        if (r == 0) {
            int next = s->scan + 1;
            while (next < rs_e57_scan_count(s->e57) && rs_e57_scan(s->e57, next)->records == 0) next++;
            if (next >= rs_e57_scan_count(s->e57)) return 0;
            if (rs_e57_scan_begin(s->e57, next, err) != 0) return -1;
            s->scan = next;
            continue;
        }
        if (grow(s, p.n, err) != 0) return -1;
        size_t m = 0;
        s->raw_n = p.n;
        for (size_t i = 0; i < p.n; i++) {
            if (!p.valid[i]) continue;
            for (int j = 0; j < 3 && s->xyz_only; j++) s->xyz[3 * m + j] = p.xyz[3 * i + j] - s->shift[j];
            for (int j = 0; j < 3 && !s->xyz_only; j++) {
                s->xyz[3 * m + j] = p.xyz[3 * i + j] - s->shift[j];
                s->rgb[3 * m + j] = p.rgb ? p.rgb[3 * i + j] : 0;
                s->nrm[3 * m + j] = p.normal ? p.normal[3 * i + j] : 0;
            }
            s->in[m] = p.intensity ? p.intensity[i] : 0;
            m++;
        }
        s->n = m;
        return 1;
    }
}

/* The next chunk of any file: 1 (s->n may be 0), 0 at the end of the last file, -1 on error. */
static int source_next(source *s, rs_err *err)
{
    for (;;) {
        if (!s->las && !s->e57) {
            if (s->file + 1 >= s->nfiles) return 0;
            if (open_file(s, s->file + 1, err) != 0) return -1;
        }
        int r = s->las ? next_las(s, err) : next_e57(s, err);
        if (r != 0) return r;
        close_file(s); /* this file is done: the next one */
    }
}

static void source_rewind(source *s)
{
    close_file(s);
    s->file = -1;
    s->n = 0; /* the last pass's chunk is not this one's */
}

/* "LASF" (not LAZ: the whole-cloud path refuses it) or "ASTM-E57" whose scans have no grid. */
static int file_kind(const char *path, int *las)
{
    unsigned char h[105];
    FILE *f = fopen(path, "rb");
    if (!f) return 0;
    size_t n = fread(h, 1, sizeof h, f);
    fclose(f);
    if (n >= 105 && memcmp(h, "LASF", 4) == 0 && !(h[104] & 0xc0)) {
        *las = 1;
        return 1;
    }
    if (n < 8 || memcmp(h, "ASTM-E57", 8) != 0) return 0;
    rs_err err = {0};
    rs_e57 *e = rs_e57_open(path, &err);
    if (!e) return 0;
    int ok = rs_e57_scan_count(e) > 0;
    for (int i = 0; i < rs_e57_scan_count(e); i++) ok &= !rs_e57_scan(e, i)->grid;
    rs_e57_close(e);
    *las = 0;
    return ok;
}

int rs_ingest_cleans(const rs_config *cfg)
{
    return rs_config_int(cfg, "ingest", "outlier_neighbours") > 0 || rs_config_has(cfg, "ingest", "voxel_size");
}

int rs_ingest_can_stream(const rs_config *cfg)
{
    if (!rs_config_bool(cfg, "ingest", "streaming")) return 0;
    int n = rs_config_path_count(cfg, "ingest", "scan");
    for (int i = 0; i < n; i++) {
        char path[4096];
        int las;
        rs_config_path_at(cfg, "ingest", "scan", i, path, sizeof path);
        if (!file_kind(path, &las)) return 0;
    }
    return n > 0;
}

/* Pass 1, file k: its points kept, their box, its colour depth; the reader's refusals. */
static int survey_file(source *s, int k, double lo[3], double hi[3], rs_err *err)
{
    file_info *fi = &s->info[k];
    if (open_file(s, k, err) != 0) return -1;
    if (fi->las) {
        const rs_las_info *in = rs_las_info_of(s->las);
        fi->records = (size_t)in->npoints;
        fi->has_int = 1, fi->has_rgb = in->has_rgb;
    } else {
        int nrm = 1, n = 0, same = 1;
        const double *t = NULL;
        for (int i = 0; i < rs_e57_scan_count(s->e57); i++) {
            const rs_e57_scan_info *si = rs_e57_scan(s->e57, i);
            fi->records += (size_t)si->records;
            fi->has_int |= si->has_intensity, fi->has_rgb |= si->has_rgb;
            if (si->records == 0) continue;
            nrm &= si->has_normals;
            if (!si->has_pose || (t && memcmp(t, si->translation, sizeof si->translation) != 0)) same = 0;
            t = si->translation, n++;
        }
        fi->has_nrm = nrm && n > 0;
        if (n > 0 && same) fi->has_viewpoint = 1, memcpy(fi->viewpoint, t, sizeof fi->viewpoint);
        if (fi->records == 0)
            return rs_err_set(err, RS_ERR_INPUT, s->path, 0,
                              "no points: %d scan%s in data3D%s, %d image%s; expected at least one scan with points",
                              rs_e57_scan_count(s->e57), rs_e57_scan_count(s->e57) == 1 ? "" : "s",
                              rs_e57_scan_count(s->e57) ? " with recordCount 0" : "", rs_e57_image_count(s->e57),
                              rs_e57_image_count(s->e57) == 1 ? "" : "s");
    }
    char what[4200];
    snprintf(what, sizeof what, "reading %s (pass 1: counting)", s->path);
    rs_progress *pr = fi->records >= 1000000 ? rs_progress_start(what, fi->records) : NULL;
    int r;
    while ((r = fi->las ? next_las(s, err) : next_e57(s, err)) > 0) {
        for (size_t i = 0; i < s->n; i++)
            for (int j = 0; j < 3; j++) {
                lo[j] = fmin(lo[j], s->xyz[3 * i + j]);
                hi[j] = fmax(hi[j], s->xyz[3 * i + j]);
            }
        fi->kept += s->n;
        if (pr) rs_progress_add(pr, s->raw_n);
    }
    if (pr) rs_progress_end(pr);
    if (r < 0) return -1;
    if (fi->las) {
        uint64_t seen = 0;
        for (int c = 0; c < 256; c++) seen += s->hist[c];
        fi->withheld = fi->records - seen;
        if (fi->records > 0 && seen == 0)
            return rs_err_set(err, RS_ERR_INPUT, s->path, 0,
                              "every one of its %zu points is flagged withheld (not to be used); expected points to "
                              "keep, or [ingest] las_withheld = keep",
                              fi->records);
        if (s->keep && fi->kept == 0 && fi->records > 0) {
            char classes[512];
            size_t len = 0;
            classes[0] = '\0';
            for (int c = 0; c < 256 && len + 1 < sizeof classes; c++)
                if (s->hist[c])
                    len += (size_t)snprintf(classes + len, sizeof classes - len, "%s%d (%llu points)", len ? ", " : "",
                                            c, (unsigned long long)s->hist[c]);
            return rs_err_set(err, RS_ERR_INPUT, s->path, 0,
                              "no point of the %zu has a class listed in [ingest] las_classes; the file's classes: %s",
                              fi->records, classes);
        }
    }
    close_file(s);
    return 0;
}

/* Both paths' hash of a point (FNV-1a over the coordinates' bits, -0 as +0), so that the
 * streaming path meets coincident points in the whole-cloud path's order. */
uint64_t rs_ingest_point_hash(const double *p)
{
    uint64_t h = 0xcbf29ce484222325ULL;
    for (int j = 0; j < 3; j++) {
        double x = p[j] + 0.0; /* -0 -> +0 */
        uint64_t bits;
        memcpy(&bits, &x, sizeof bits);
        h = (h ^ bits) * 0x100000001b3ULL;
        h ^= h >> 31;
    }
    return h;
}

/* One bucket's points into a table of their coordinates (NaN: empty): a point equal to one
 * before it is marked dropped, the first kept, as in the whole-cloud path. */
static int coincident_pass(source *s, coincident *co, size_t bucket, size_t nbuckets, rs_err *err)
{
    size_t cap = 16;
    while (cap < 2 * (co->total / nbuckets + 1) && cap < 2 * BUCKET_POINTS) cap *= 2;
    double(*slot)[3] = malloc(cap * sizeof *slot);
    if (!slot) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the coincidence table");
    for (size_t k = 0; k < cap; k++) slot[k][0] = NAN;
    size_t used = 0, g = 0;
    int r;
    source_rewind(s);
    while ((r = source_next(s, err)) > 0)
        for (size_t i = 0; i < s->n; i++, g++) {
            const double *p = s->xyz + 3 * i;
            uint64_t h = rs_ingest_point_hash(p);
            if ((h >> 32) % nbuckets != bucket) continue;
            if (4 * (used + 1) > 3 * cap) { /* an unlucky bucket: a larger table */
                size_t ncap = 2 * cap;
                double(*ns)[3] = malloc(ncap * sizeof *ns);
                if (!ns) {
                    free(slot);
                    return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the coincidence table");
                }
                for (size_t k = 0; k < ncap; k++) ns[k][0] = NAN;
                for (size_t k = 0; k < cap; k++) {
                    if (isnan(slot[k][0])) continue;
                    size_t at = rs_ingest_point_hash(slot[k]) & (ncap - 1);
                    while (!isnan(ns[at][0])) at = (at + 1) & (ncap - 1);
                    memcpy(ns[at], slot[k], sizeof ns[at]);
                }
                free(slot);
                slot = ns, cap = ncap;
            }
            for (size_t k = h & (cap - 1);; k = (k + 1) & (cap - 1)) {
                if (isnan(slot[k][0])) {
                    memcpy(slot[k], p, sizeof slot[k]);
                    used++;
                    break;
                }
                if (p[0] == slot[k][0] && p[1] == slot[k][1] && p[2] == slot[k][2]) {
                    co->dropped[g >> 3] |= (uint8_t)(1u << (g & 7));
                    break;
                }
            }
        }
    free(slot);
    return r < 0 ? -1 : 0;
}

static int is_dropped(const coincident *co, size_t g)
{
    return co->dropped[g >> 3] >> (g & 7) & 1;
}

int rs_ingest_source_next(source *s, rs_err *err)
{
    return source_next(s, err);
}

void rs_ingest_source_rewind(source *s)
{
    source_rewind(s);
}

/* The whole-cloud path's collinearity test (ingest.c, collinear_points) over the distinct
 * points, in two passes (mean, then covariance) with its arithmetic. */
static int collinear_stream(source *s, const coincident *co, int *collinear, rs_err *err)
{
    double mean[3] = {0, 0, 0}, cov[6] = {0};
    for (int pass = 0; pass < 2; pass++) {
        size_t g = 0, n = 0;
        int r;
        source_rewind(s);
        while ((r = source_next(s, err)) > 0)
            for (size_t i = 0; i < s->n; i++, g++) {
                if (is_dropped(co, g)) continue;
                const double *p = s->xyz + 3 * i;
                if (pass == 0) {
                    n++;
                    for (int j = 0; j < 3; j++) mean[j] += (p[j] - mean[j]) / (double)n;
                    continue;
                }
                double d[3] = {p[0] - mean[0], p[1] - mean[1], p[2] - mean[2]};
                double q[6] = {d[0] * d[0], d[1] * d[1], d[2] * d[2], d[0] * d[1], d[0] * d[2], d[1] * d[2]};
                for (int j = 0; j < 6; j++) cov[j] += q[j];
            }
        if (r < 0) return -1;
    }
    double trace = cov[0] + cov[1] + cov[2];
    double minors =
        cov[0] * cov[1] - cov[3] * cov[3] + cov[0] * cov[2] - cov[4] * cov[4] + cov[1] * cov[2] - cov[5] * cov[5];
    *collinear = !(minors > RS_INGEST_MIN_SPREAD * RS_INGEST_MIN_SPREAD * trace * trace);
    return 0;
}

/* cloud.ply's records from the stream, the dropped points skipped. */
typedef struct writer {
    source *s;
    const coincident *co;
    size_t g, i; /* the next point (stream order) and its place in the chunk */
    int eof;
} writer;

static int write_record(void *ctx, const rs_ply_element *el, size_t k, double *v, rs_err *err)
{
    (void)el, (void)k;
    writer *w = ctx;
    source *s = w->s;
    for (;;) {
        while (w->i >= s->n) {
            int r = source_next(s, err);
            if (r < 0) return -1;
            if (r == 0) return rs_err_set(err, RS_ERR_INPUT, s->path, 0, "the file changed while it was read");
            w->i = 0;
        }
        if (!is_dropped(w->co, w->g)) break;
        w->i++, w->g++;
    }
    size_t i = w->i++;
    w->g++;
    int n = 0;
    for (int j = 0; j < 3; j++) v[n++] = s->xyz[3 * i + j];
    if (s->has_int) v[n++] = s->in[i];
    if (s->has_rgb)
        for (int j = 0; j < 3; j++) v[n++] = s->rgb[3 * i + j];
    if (s->has_nrm)
        for (int j = 0; j < 3; j++) v[n++] = s->nrm[3 * i + j];
    return 0;
}

int rs_ingest_write_points(source *s, const coincident *co, const rs_cloud *shape, size_t count, const char *path,
                           rs_err *err)
{
    source_rewind(s);
    writer w = {s, co, 0, 0, 0};
    return rs_cloud_write_ply_stream(shape, count, write_record, &w, path, err);
}

/* Pass 1 over every file: per-file counts and report entries, the cloud's shape (which
 * attributes, viewpoint, normals up), the box of the points. */
static int survey(source *s, rs_report *rep, rs_cloud *shape, double lo[3], double hi[3], size_t *total, rs_err *err)
{
    rs_json *files = rs_json_set_arr(rep->metrics, "files");
    int all_nrm = 1;
    uint64_t withheld = 0;
    *total = 0;
    s->survey = 1;
    for (int k = 0; k < s->nfiles; k++) {
        file_info *fi = &s->info[k];
        if (survey_file(s, k, lo, hi, err) != 0) return -1;
        if (fi->kept == 0)
            return rs_err_set(err, RS_ERR_INPUT, s->path, 0,
                              "[ingest] scan: no point with a return among its %zu (all 0 0 0 or none); expected a "
                              "scan of the scene",
                              fi->kept);
        rs_log_info("%s (%s): %zu points, %zu with a return, 0 scan grid(s) (streamed)", s->path,
                    fi->las ? "LAS" : "E57", fi->kept, fi->kept);
        rs_json *f = rs_json_push_obj(files);
        rs_json_set_str(f, "path", s->path);
        rs_json_set_int(f, "points", (long long)fi->kept);
        rs_json_set_int(f, "valid", (long long)fi->kept);
        rs_json_set_int(f, "scans", 0);
        s->has_int |= fi->has_int, s->has_rgb |= fi->has_rgb;
        all_nrm &= fi->has_nrm;
        shape->normals_up |= fi->las;
        if (fi->has_viewpoint && !shape->has_viewpoint) {
            shape->has_viewpoint = 1;
            memcpy(shape->viewpoint, fi->viewpoint, sizeof shape->viewpoint);
        }
        withheld += fi->withheld;
        *total += fi->kept;
    }
    s->survey = 0;
    s->has_nrm = all_nrm;
    if (withheld) {
        rs_json_set_int(rep->metrics, "las_withheld_dropped", (long long)withheld);
        rs_log_info("%llu LAS points flagged withheld: dropped ([ingest] las_withheld = keep keeps them)",
                    (unsigned long long)withheld);
    }
    /* Only which arrays exist matters to the header: one-byte stand-ins. */
    static float one_f[3];
    static uint8_t one_b[3];
    shape->intensity = s->has_int ? one_f : NULL;
    shape->rgb = s->has_rgb ? one_b : NULL;
    shape->normal = s->has_nrm ? one_f : NULL;
    return 0;
}

/* rs_cloud_recentre on the box of the points (no scan grids here). */
static void recentre(const rs_config *cfg, source *s, rs_cloud *shape, const double lo[3], const double hi[3])
{
    double limit = rs_config_real(cfg, "ingest", "recentre_above");
    int far = 0;
    for (int j = 0; j < 3; j++) far |= lo[j] <= hi[j] && fmax(fabs(lo[j]), fabs(hi[j])) > limit;
    if (!far) return;
    for (int j = 0; j < 3; j++) {
        s->shift[j] = lo[j] <= hi[j] ? floor(0.5 * (lo[j] + hi[j]) + 0.5) : 0;
        if (shape->has_viewpoint) shape->viewpoint[j] -= s->shift[j];
        shape->origin[j] += s->shift[j];
    }
    rs_log_info("georeferenced coordinates: recentred by (%.0f, %.0f, %.0f) m, kept as rhoscan_origin in "
                "cloud.ply and mesh.ply",
                shape->origin[0], shape->origin[1], shape->origin[2]);
}

/* The coincident passes, then the surface checks. */
static int check_points(const rs_config *cfg, source *s, rs_report *rep, coincident *co, rs_err *err)
{
    size_t nbuckets = (co->total + BUCKET_POINTS - 1) / BUCKET_POINTS;
    if (nbuckets < 1) nbuckets = 1;
    double t0 = rs_now();
    s->xyz_only = 1;
    rs_progress *pr = nbuckets > 1 ? rs_progress_start("coincident points (a pass per hash bucket)", nbuckets) : NULL;
    for (size_t b = 0; b < nbuckets; b++) {
        if (coincident_pass(s, co, b, nbuckets, err) != 0) {
            if (pr) rs_progress_end(pr);
            return -1;
        }
        if (pr) rs_progress_add(pr, 1);
    }
    if (pr) rs_progress_end(pr);
    size_t dropped = 0;
    for (size_t g = 0; g < co->total; g++) dropped += (size_t)is_dropped(co, g);
    co->distinct = co->total - dropped;
    rs_json_set_int(rep->metrics, "coincident_removed", (long long)dropped);
    if (dropped)
        rs_log_warn("%zu of %zu unorganized points repeat the coordinates of another point: dropped", dropped,
                    co->total);
    int collinear = 0;
    int bad = co->distinct >= 3 && collinear_stream(s, co, &collinear, err) != 0;
    s->xyz_only = 0;
    if (bad) return -1;
    rs_log_info("streamed checks (%zu coincident pass%s, 2 for the spread): %.2f s", nbuckets,
                nbuckets == 1 ? "" : "es", rs_now() - t0);
    if (rs_ingest_surface_check(cfg, co->total, co->distinct, collinear, err) != 0) return -1;
    if (rs_ingest_cleans(cfg)) return 0; /* rs_ingest_clean_stream reports them */
    rs_report_skip(rep, "outlier removal", "[ingest] outlier_neighbours = 0");
    rs_json_set_int(rep->metrics, "outliers_removed", 0);
    rs_report_skip(rep, "voxel downsampling", "[ingest] voxel_size not set");
    return 0;
}

int rs_ingest_stream(const rs_config *cfg, rs_report *rep, const char *path, rs_err *err)
{
    source s = {.cfg = cfg, .nfiles = rs_config_path_count(cfg, "ingest", "scan"), .file = -1};
    rs_cloud shape = {0};
    coincident co = {0};
    uint8_t keep[256];
    int rc = -1;
    const char *classes = rs_config_string(cfg, "ingest", "las_classes");
    if (classes && rs_las_parse_classes(classes, keep, err) != 0) {
        rs_err_set_file(err, rs_config_file(cfg));
        return -1;
    }
    s.keep = classes ? keep : NULL;
    s.keep_withheld = strcmp(rs_config_string(cfg, "ingest", "las_withheld"), "keep") == 0;
    s.info = calloc((size_t)s.nfiles, sizeof *s.info);
    if (!s.info) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    for (int k = 0; k < s.nfiles; k++) {
        char p[4096];
        rs_config_path_at(cfg, "ingest", "scan", k, p, sizeof p);
        file_kind(p, &s.info[k].las);
    }
    double t0 = rs_now(), lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    if (survey(&s, rep, &shape, lo, hi, &co.total, err) != 0) goto out;
    rs_report_time(rep, "read", rs_now() - t0);
    if (rs_config_reals(cfg, "ingest", "scanner_position", shape.viewpoint) == 0) shape.has_viewpoint = 1;
    recentre(cfg, &s, &shape, lo, hi);
    rs_json *origin = rs_json_set_arr(rep->metrics, "origin_m");
    for (int j = 0; j < 3; j++) rs_json_push_num(origin, shape.origin[j]);
    rs_json_set_int(rep->metrics, "points", (long long)co.total);
    rs_json_set_int(rep->metrics, "valid", (long long)co.total);
    rs_json_set_int(rep->metrics, "scans", 0);
    rs_json_set_int(rep->metrics, "unorganized", (long long)co.total);
    co.dropped = calloc(co.total / 8 + 1, 1);
    if (!co.dropped) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu points' bitmap", co.total);
        goto out;
    }
    if (check_points(cfg, &s, rep, &co, err) != 0) goto out;
    if (rs_ingest_cleans(cfg)) {
        double slo[3], shi[3];
        for (int j = 0; j < 3; j++) slo[j] = lo[j] - s.shift[j], shi[j] = hi[j] - s.shift[j];
        rc = rs_ingest_clean_stream(cfg, &s, rep, &co, &shape, slo, shi, path, err);
        goto out;
    }
    rs_json_set_int(rep->metrics, "points_written", (long long)co.distinct);
    t0 = rs_now();
    if (rs_ingest_write_points(&s, &co, &shape, co.distinct, path, err) != 0) goto out;
    rs_report_time(rep, "write", rs_now() - t0);
    rs_log_info("cloud.ply: %zu points written from the files' chunks (streaming: no whole cloud in memory)",
                co.distinct);
    rc = 0;
out:
    close_file(&s);
    free(s.info);
    free(s.xyz), free(s.in), free(s.nrm), free(s.rgb);
    free(co.dropped);
    return rc;
}
