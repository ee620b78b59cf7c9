/* e57_cloud: an E57 file's scans into one rs_cloud (see e57.h, rs_e57_read), chunk by chunk:
 * the cloud's arrays are the only copy of the points. Grids first (rs_scan, column by column as
 * PTX), unorganized points after them, as common/cloud.h's users expect. */
#include "common/e57.h"

#include <stdlib.h>
#include <string.h>

#include "common/log.h"

/* Points the cloud needs: a grid's cells, or a scan's records. */
static int cloud_size(rs_e57 *e, const char *name, size_t *total, int *want_int, int *want_rgb, rs_err *err)
{
    *total = 0;
    *want_int = *want_rgb = 0;
    uint64_t records = 0;
    for (int i = 0; i < rs_e57_scan_count(e); i++) {
        const rs_e57_scan_info *s = rs_e57_scan(e, i);
        uint64_t n =
            s->grid ? (uint64_t)(s->row_max - s->row_min + 1) * (uint64_t)(s->col_max - s->col_min + 1) : s->records;
        if (n > SIZE_MAX / 64 - *total)
            return rs_err_set(err, RS_ERR_INPUT, name, 0, "scan %s: %llu points; more than this machine can hold",
                              s->name, (unsigned long long)n);
        *total += (size_t)n;
        records += s->records;
        *want_int |= s->has_intensity;
        *want_rgb |= s->has_rgb;
    }
    if (records == 0)
        return rs_err_set(err, RS_ERR_INPUT, name, 0,
                          "no points: %d scan%s in data3D%s, %d image%s; expected at least one scan with points",
                          rs_e57_scan_count(e), rs_e57_scan_count(e) == 1 ? "" : "s",
                          rs_e57_scan_count(e) ? " with recordCount 0" : "", rs_e57_image_count(e),
                          rs_e57_image_count(e) == 1 ? "" : "s");
    return 0;
}

/* Scan i into its grid at c->npoints (cells no record fills stay invalid, at the scanner). */
static int read_grid(rs_e57 *e, int i, rs_cloud *c, rs_progress *pr, const char *name, rs_err *err)
{
    const rs_e57_scan_info *s = rs_e57_scan(e, i);
    size_t rows = (size_t)(s->row_max - s->row_min + 1), cols = (size_t)(s->col_max - s->col_min + 1);
    size_t first = c->npoints, cells = rows * cols, repeated = 0;
    for (size_t k = first; k < first + cells; k++) {
        memcpy(c->xyz + 3 * k, s->translation, sizeof s->translation);
        c->valid[k] = 0;
    }
    uint8_t *seen = calloc(cells ? cells : 1, 1);
    if (!seen) return rs_err_set(err, RS_ERR_SYSTEM, name, 0, "out of memory");
    rs_e57_points p;
    int r;
    uint64_t record = 0;
    while ((r = rs_e57_scan_next(e, &p, err)) > 0) {
        for (size_t j = 0; j < p.n; j++, record++) {
            int64_t row = p.row[j] - s->row_min, col = p.col[j] - s->col_min;
            if (row < 0 || col < 0 || (size_t)row >= rows || (size_t)col >= cols) {
                free(seen);
                return rs_err_set(err, RS_ERR_INPUT, name, 0,
                                  "scan %s, record %llu: row %lld, column %lld lie outside its grid (rows %lld..%lld, "
                                  "columns %lld..%lld from indexBounds)",
                                  s->name, (unsigned long long)record, (long long)p.row[j], (long long)p.col[j],
                                  (long long)s->row_min, (long long)s->row_max, (long long)s->col_min,
                                  (long long)s->col_max);
            }
            size_t cell = (size_t)col * rows + (size_t)row, k = first + cell;
            if (seen[cell]) { /* a later return of the same direction: the first one is kept */
                repeated++;
                continue;
            }
            seen[cell] = 1;
            memcpy(c->xyz + 3 * k, p.xyz + 3 * j, 3 * sizeof *c->xyz);
            c->valid[k] = p.valid[j];
            if (p.intensity) c->intensity[k] = p.intensity[j];
            if (p.rgb) memcpy(c->rgb + 3 * k, p.rgb + 3 * j, 3);
            if (c->normal) memcpy(c->normal + 3 * k, p.normal + 3 * j, 3 * sizeof *c->normal);
        }
        rs_progress_add(pr, p.n);
    }
    free(seen);
    if (r < 0) return -1;
    if (repeated)
        rs_log_warn("%s: scan %s: %zu records repeat a grid cell; the first of each kept", name, s->name, repeated);
    rs_scan *scans = realloc(c->scans, (size_t)(c->nscans + 1) * sizeof *scans);
    if (!scans) return rs_err_set(err, RS_ERR_SYSTEM, name, 0, "out of memory");
    c->scans = scans;
    rs_scan *g = &c->scans[c->nscans++];
    g->cols = (int)cols;
    g->rows = (int)rows;
    g->first = first;
    memcpy(g->position, s->translation, sizeof g->position);
    c->npoints = first + cells;
    return 0;
}

/* Scan i's valid points appended at c->npoints. */
static int read_loose(rs_e57 *e, int i, rs_cloud *c, rs_progress *pr, rs_err *err)
{
    rs_e57_points p;
    int r;
    while ((r = rs_e57_scan_next(e, &p, err)) > 0) {
        if (!memchr(p.valid, 0, p.n)) { /* all valid (the usual case): whole arrays at once */
            size_t k = c->npoints;
            memcpy(c->xyz + 3 * k, p.xyz, 3 * p.n * sizeof *c->xyz);
            memset(c->valid + k, 1, p.n);
            if (p.intensity) memcpy(c->intensity + k, p.intensity, p.n * sizeof *c->intensity);
            if (p.rgb) memcpy(c->rgb + 3 * k, p.rgb, 3 * p.n);
            if (c->normal) memcpy(c->normal + 3 * k, p.normal, 3 * p.n * sizeof *c->normal);
            c->npoints += p.n;
            rs_progress_add(pr, p.n);
            continue;
        }
        for (size_t j = 0; j < p.n; j++) {
            if (!p.valid[j]) continue;
            size_t k = c->npoints++;
            memcpy(c->xyz + 3 * k, p.xyz + 3 * j, 3 * sizeof *c->xyz);
            c->valid[k] = 1;
            if (p.intensity) c->intensity[k] = p.intensity[j];
            if (p.rgb) memcpy(c->rgb + 3 * k, p.rgb + 3 * j, 3);
            if (c->normal) memcpy(c->normal + 3 * k, p.normal + 3 * j, 3 * sizeof *c->normal);
        }
        rs_progress_add(pr, p.n);
    }
    return r < 0 ? -1 : 0;
}

/* The unorganized scans' common scanner position, when they all have the same pose. */
static void loose_viewpoint(rs_e57 *e, rs_cloud *c)
{
    int n = 0, same = 1;
    const double *t = NULL;
    for (int i = 0; i < rs_e57_scan_count(e); i++) {
        const rs_e57_scan_info *s = rs_e57_scan(e, i);
        if (s->grid || s->records == 0) continue;
        if (!s->has_pose) same = 0;
        if (t && memcmp(t, s->translation, sizeof s->translation) != 0) same = 0;
        t = s->translation;
        n++;
    }
    if (n > 0 && same) {
        c->has_viewpoint = 1;
        memcpy(c->viewpoint, t, sizeof c->viewpoint);
    }
}

static rs_cloud *read_all(rs_e57 *e, const char *name, rs_err *err)
{
    size_t total;
    int want_int, want_rgb;
    if (cloud_size(e, name, &total, &want_int, &want_rgb, err) != 0) return NULL;
    rs_cloud *c = calloc(1, sizeof *c);
    if (!c || rs_cloud_resize(c, total, want_int, want_rgb, err) != 0) {
        if (!c) rs_err_set(err, RS_ERR_SYSTEM, name, 0, "out of memory");
        rs_cloud_free(c);
        return NULL;
    }
    uint64_t records = 0;
    int normals = 1; /* carried when every scan with points has them */
    for (int i = 0; i < rs_e57_scan_count(e); i++) {
        records += rs_e57_scan(e, i)->records;
        if (rs_e57_scan(e, i)->records > 0 && !rs_e57_scan(e, i)->has_normals) normals = 0;
    }
    if (normals && !(c->normal = calloc(total ? 3 * total : 3, sizeof *c->normal))) {
        rs_err_set(err, RS_ERR_SYSTEM, name, 0, "out of memory for %zu normals", total);
        rs_cloud_free(c);
        return NULL;
    }
    rs_progress *pr = rs_progress_start("reading E57 points", (size_t)records);
    int ok = 1;
    for (int pass = 0; pass < 2 && ok; pass++) /* grids, then the unorganized scans */
        for (int i = 0; i < rs_e57_scan_count(e) && ok; i++) {
            const rs_e57_scan_info *s = rs_e57_scan(e, i);
            if (s->grid != (pass == 0) || s->records == 0) continue;
            ok = rs_e57_scan_begin(e, i, err) == 0 &&
                (pass == 0 ? read_grid(e, i, c, pr, name, err) : read_loose(e, i, c, pr, err)) == 0;
        }
    rs_progress_end(pr);
    if (!ok) {
        rs_cloud_free(c);
        return NULL;
    }
    loose_viewpoint(e, c);
    /* Dropped invalid points leave room at the end: give it back. */
    if (c->npoints < total && c->npoints > 0) {
        double *xyz = realloc(c->xyz, c->npoints * 3 * sizeof *xyz);
        if (xyz) c->xyz = xyz;
        float *nrm = c->normal ? realloc(c->normal, c->npoints * 3 * sizeof *nrm) : NULL;
        if (nrm) c->normal = nrm;
    }
    return c;
}

rs_cloud *rs_e57_read(const char *path, rs_err *err)
{
    rs_e57 *e = rs_e57_open(path, err);
    if (!e) return NULL;
    rs_cloud *c = read_all(e, path, err);
    rs_e57_close(e);
    return c;
}

rs_cloud *rs_e57_read_mem(const void *data, size_t size, const char *name, rs_err *err)
{
    rs_e57 *e = rs_e57_open_mem(data, size, name, err);
    if (!e) return NULL;
    rs_cloud *c = read_all(e, name ? name : "(memory)", err);
    rs_e57_close(e);
    return c;
}
