/* ptx: the Leica PTX reader (see ptx.h; docs/DESIGN.md, section Scan files): one or more organized scans back
 * to back, each registered by its 4x4 matrix. */
#include "common/ptx.h"

#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/fileio.h"

/* A cursor over the text, one line at a time. Blank lines are skipped wherever they occur. */
typedef struct ptx_text {
    const char *p, *end;
    long line; /* number of the line last returned by next_line */
    long next; /* number of the line starting at p */
    const char *name;
    const char *ls, *le; /* the line last returned (without its end of line) */
} ptx_text;

/* At most 7 numbers on a point line; longer lines are an error, counted up to 16 tokens. */
#define PTX_MAX_TOKENS 16

static int is_space(char ch)
{
    return ch == ' ' || ch == '\t' || ch == '\r' || ch == '\v' || ch == '\f';
}

/* Advances to the next non-blank line; returns 0 at the end of the text. */
static int next_line(ptx_text *t)
{
    while (t->p < t->end) {
        const char *ls = t->p;
        const char *nl = memchr(ls, '\n', (size_t)(t->end - ls));
        const char *le = nl ? nl : t->end;
        t->p = nl ? nl + 1 : t->end;
        t->line = t->next++;
        for (const char *q = ls; q < le; q++)
            if (!is_space(*q)) {
                t->ls = ls;
                t->le = le;
                return 1;
            }
    }
    t->line = t->next; /* errors at the end point just past the last line */
    return 0;
}

/* Why a token was refused (filled by parse_numbers, reported by bad_token). */
typedef struct ptx_bad {
    int index; /* 1-based token number */
    size_t len;
    char text[64];
    int not_finite;
} ptx_bad;

/* Splits the current line into tokens and parses up to max of them as finite numbers.
 * Returns the token count (saturating at PTX_MAX_TOKENS), or -1 with *bad filled for a token
 * that is not a finite number. */
static int parse_numbers(const ptx_text *t, double *out, int max, ptx_bad *bad)
{
    const char *q = t->ls;
    int n = 0;
    while (q < t->le) {
        while (q < t->le && is_space(*q)) q++;
        if (q >= t->le) break;
        const char *ts = q;
        while (q < t->le && !is_space(*q)) q++;
        size_t len = (size_t)(q - ts);
        if (n < max) {
            /* strtod needs a terminated string and the buffer need not be one: copy the token. */
            char buf[64];
            size_t keep = len < sizeof buf ? len : sizeof buf - 1;
            memcpy(buf, ts, keep);
            buf[keep] = 0;
            char *stop;
            double v = strtod(buf, &stop);
            if (len >= sizeof buf || stop != buf + len || !isfinite(v)) {
                bad->index = n + 1;
                bad->len = len;
                for (size_t i = 0; i < keep; i++) /* printable in messages, even for binary junk */
                    bad->text[i] = ts[i] > 32 && ts[i] < 127 ? ts[i] : '?';
                bad->text[keep] = 0;
                bad->not_finite = len < sizeof buf && stop == buf + len;
                return -1;
            }
            out[n] = v;
        }
        if (n < PTX_MAX_TOKENS) n++;
    }
    return n;
}

static int bad_token(const ptx_text *t, const ptx_bad *bad, const char *label, rs_err *err)
{
    if (bad->len >= sizeof bad->text)
        return rs_err_set(err, RS_ERR_INPUT, t->name, t->line, "%s: token %d is %zu characters long; expected a number",
                          label, bad->index, bad->len);
    return rs_err_set(err, RS_ERR_INPUT, t->name, t->line, "%s: token %d \"%s\" is %s; expected a finite number", label,
                      bad->index, bad->text, bad->not_finite ? "not finite" : "not a number");
}

/* Reads one header line of exactly n numbers. */
static int header_numbers(ptx_text *t, double *out, int n, int scan, const char *what, rs_err *err)
{
    char label[160];
    snprintf(label, sizeof label, "scan %d header, %s", scan, what);
    if (!next_line(t))
        return rs_err_set(err, RS_ERR_INPUT, t->name, t->line, "%s: the file ends; expected %d number%s", label, n,
                          n == 1 ? "" : "s");
    ptx_bad bad;
    int got = parse_numbers(t, out, n, &bad);
    if (got < 0) return bad_token(t, &bad, label, err);
    if (got != n)
        return rs_err_set(err, RS_ERR_INPUT, t->name, t->line, "%s: found %d%s tokens; expected %d", label, got,
                          got >= PTX_MAX_TOKENS ? " or more" : "", n);
    return 0;
}

/* A grid dimension: an integer in 1 .. INT_MAX. */
static int header_count(ptx_text *t, int scan, const char *what, int *out, rs_err *err)
{
    double v;
    if (header_numbers(t, &v, 1, scan, what, err) != 0) return -1;
    if (v != floor(v) || v < 1 || v > INT_MAX)
        return rs_err_set(err, RS_ERR_INPUT, t->name, t->line,
                          "scan %d header, %s: found %.17g; expected an integer from 1 to %d", scan, what, v, INT_MAX);
    *out = (int)v;
    return 0;
}

/* Room for n more points in c (arrays grow; rgb is created when first needed). */
static int cloud_reserve(rs_cloud *c, size_t n, int want_rgb, const char *name, rs_err *err)
{
    size_t total = c->npoints + n;
    double *xyz = realloc(c->xyz, total * 3 * sizeof *xyz);
    if (xyz) c->xyz = xyz;
    float *in = realloc(c->intensity, total * sizeof *in);
    if (in) c->intensity = in;
    uint8_t *valid = realloc(c->valid, total);
    if (valid) c->valid = valid;
    if (!xyz || !in || !valid) return rs_err_set(err, RS_ERR_SYSTEM, name, 0, "out of memory for %zu points", total);
    if (want_rgb || c->rgb) {
        uint8_t *rgb = realloc(c->rgb, total * 3);
        if (!rgb) return rs_err_set(err, RS_ERR_SYSTEM, name, 0, "out of memory for %zu colours", total);
        if (!c->rgb) memset(rgb, 0, c->npoints * 3); /* earlier scans had no colour */
        c->rgb = rgb;
    }
    return 0;
}

/* Parses one scan starting at its column-count line (already known to exist). */
static int read_scan(ptx_text *t, rs_cloud *c, int scan, rs_err *err)
{
    int cols = 0, rows = 0;
    double pos[3], axes[9], T[16];
    if (header_count(t, scan, "number of columns", &cols, err) != 0) return -1;
    if (header_count(t, scan, "number of rows", &rows, err) != 0) return -1;
    if (header_numbers(t, pos, 3, scan, "scanner position", err) != 0) return -1;
    for (int i = 0; i < 3; i++)
        if (header_numbers(t, axes + 3 * i, 3, scan,
                           i == 0       ? "scanner x axis"
                               : i == 1 ? "scanner y axis"
                                        : "scanner z axis",
                           err) != 0)
            return -1;
    long matrix_line = 0;
    for (int i = 0; i < 4; i++) {
        char what[48];
        snprintf(what, sizeof what, "transform row %d", i + 1);
        if (header_numbers(t, T + 4 * i, 4, scan, what, err) != 0) return -1;
        if (i == 0) matrix_line = t->line;
    }
    /* Row-vector form: x' = x*T[0] + y*T[4] + z*T[8] + T[12]. A singular linear part would
     * flatten the scan; a scale is allowed (PDAL's multiple-and-transform.ptx has one). */
    double det =
        T[0] * (T[5] * T[10] - T[6] * T[9]) - T[1] * (T[4] * T[10] - T[6] * T[8]) + T[2] * (T[4] * T[9] - T[5] * T[8]);
    double scale = 0;
    for (int i = 0; i < 12; i++)
        if (i % 4 != 3) scale = fmax(scale, fabs(T[i]));
    if (!(fabs(det) > 1e-12 * scale * scale * scale))
        return rs_err_set(err, RS_ERR_INPUT, t->name, matrix_line,
                          "scan %d: the 4x4 transform is singular (determinant %.3g); expected a rotation, "
                          "possibly scaled, and a translation",
                          scan, det);

    /* Each point line holds at least "0 0 0" plus an end of line: this bounds the counts by
     * the bytes left, before anything is allocated (no overflow, no huge allocation). */
    size_t left = (size_t)(t->end - t->p);
    size_t npts = (size_t)cols * (size_t)rows;
    if ((size_t)rows > SIZE_MAX / (size_t)cols || npts > left / 6 + 1)
        return rs_err_set(err, RS_ERR_INPUT, t->name, t->line,
                          "scan %d: %d columns x %d rows need at least %.0f bytes of point lines, but only %zu bytes "
                          "follow; the file is truncated or the counts are wrong",
                          scan, cols, rows, 6.0 * cols * rows, left);

    size_t first = c->npoints;
    if (cloud_reserve(c, npts, 0, t->name, err) != 0) return -1;
    int have_rgb = c->rgb != NULL;
    char label[128];
    ptx_bad bad;
    for (size_t k = 0; k < npts; k++) {
        double v[7] = {0, 0, 0, 0, 0, 0, 0};
        if (!next_line(t))
            return rs_err_set(err, RS_ERR_INPUT, t->name, t->line,
                              "scan %d: the file ends after %zu of %zu points (%d columns x %d rows); "
                              "expected a line \"x y z intensity [r g b]\"",
                              scan, k, npts, cols, rows);
        int n = parse_numbers(t, v, 7, &bad);
        int no_return = n >= 3 && v[0] == 0 && v[1] == 0 && v[2] == 0;
        /* "x y z intensity" or "x y z intensity r g b"; a bare "0 0 0" is a no-return point. */
        int ok = n == 4 || n == 7 || (n == 3 && no_return);
        if (!ok || (n == 7 && (v[4] < 0 || v[4] > 255 || v[5] < 0 || v[5] > 255 || v[6] < 0 || v[6] > 255)))
            snprintf(label, sizeof label, "scan %d point %zu (column %zu, row %zu)", scan, k + 1, k / (size_t)rows,
                     k % (size_t)rows);
        if (n < 0) return bad_token(t, &bad, label, err);
        if (!ok)
            return rs_err_set(err, RS_ERR_INPUT, t->name, t->line,
                              "%s: found %d%s numbers; expected 4 (x y z intensity) or 7 (x y z intensity r g b)",
                              label, n, n >= PTX_MAX_TOKENS ? " or more" : "");
        size_t i = first + k;
        if (n == 7) {
            for (int j = 4; j < 7; j++)
                if (v[j] < 0 || v[j] > 255)
                    return rs_err_set(err, RS_ERR_INPUT, t->name, t->line, "%s: colour value %g; expected 0 to 255",
                                      label, v[j]);
            if (!have_rgb) {
                if (cloud_reserve(c, npts, 1, t->name, err) != 0) return -1;
                memset(c->rgb + 3 * first, 0, 3 * k);
                have_rgb = 1;
            }
        }
        if (have_rgb)
            for (int j = 0; j < 3; j++) c->rgb[3 * i + j] = (uint8_t)lround(v[4 + j]);
        c->xyz[3 * i + 0] = v[0] * T[0] + v[1] * T[4] + v[2] * T[8] + T[12];
        c->xyz[3 * i + 1] = v[0] * T[1] + v[1] * T[5] + v[2] * T[9] + T[13];
        c->xyz[3 * i + 2] = v[0] * T[2] + v[1] * T[6] + v[2] * T[10] + T[14];
        for (int j = 0; j < 3; j++)
            if (!(fabs(c->xyz[3 * i + j]) <= RS_CLOUD_MAX_M)) {
                snprintf(label, sizeof label, "scan %d point %zu", scan, k + 1);
                return rs_err_set(err, RS_ERR_INPUT, t->name, t->line,
                                  "%s: coordinate %g after the scan's transform; expected -%g to %g (m)", label,
                                  c->xyz[3 * i + j], RS_CLOUD_MAX_M, RS_CLOUD_MAX_M);
            }
        if (!(fabs(v[3]) <= FLT_MAX)) /* stored as float */
            return rs_err_set(err, RS_ERR_INPUT, t->name, t->line,
                              "scan %d point %zu: intensity %g; expected a number within the float range", scan, k + 1,
                              v[3]);
        c->intensity[i] = (float)v[3];
        c->valid[i] = !no_return;
    }

    rs_scan *scans = realloc(c->scans, (size_t)(c->nscans + 1) * sizeof *scans);
    if (!scans) return rs_err_set(err, RS_ERR_SYSTEM, t->name, 0, "out of memory");
    c->scans = scans;
    rs_scan *s = &c->scans[c->nscans++];
    s->cols = cols;
    s->rows = rows;
    s->first = first;
    /* The position line is the scanner centre in the registered (world) frame already: in
     * every file checked (PDAL's test files, the reference scans) it equals the matrix's
     * translation row, i.e. the image of the scanner-local origin. Transforming it again
     * would be wrong (multiple-and-transform.ptx would put the scanner at 1.2e6, 1.6e6, 800). */
    memcpy(s->position, pos, sizeof pos);
    c->npoints = first + npts;
    return 0;
}

rs_cloud *rs_ptx_read_mem(const char *data, size_t size, const char *name, rs_err *err)
{
    ptx_text t = {data, data + size, 0, 1, name ? name : "(memory)", NULL, NULL};
    rs_cloud *c = calloc(1, sizeof *c);
    if (!c) {
        rs_err_set(err, RS_ERR_SYSTEM, name, 0, "out of memory");
        return NULL;
    }
    while (next_line(&t)) {
        t.p = t.ls; /* read_scan reads the column count itself */
        t.next = t.line;
        if (read_scan(&t, c, c->nscans + 1, err) != 0) {
            rs_cloud_free(c);
            return NULL;
        }
    }
    if (c->nscans == 0) {
        rs_err_set(err, RS_ERR_INPUT, t.name, 0, "no scan found; expected a PTX header (columns, rows, ...)");
        rs_cloud_free(c);
        return NULL;
    }
    return c;
}

rs_cloud *rs_ptx_read(const char *path, rs_err *err)
{
    char *data;
    size_t size;
    if (rs_read_file(path, &data, &size, err) != 0) return NULL;
    rs_cloud *c = rs_ptx_read_mem(data, size, path, err);
    free(data);
    return c;
}
