/* cloud_text: XYZ/CSV text point clouds (exports of CloudCompare, scanners' office software)
 * read with a column map from the config. Exports rs_cloud_read_text (cloud.h). */
#include "common/cloud.h"

#include <ctype.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/fileio.h"

enum { COL_SKIP, COL_X, COL_Y, COL_Z, COL_I, COL_R, COL_G, COL_B };
#define MAX_COLS 64

/* Parses the column map; returns the column count or -1. */
static int parse_columns(const char *spec, int *kind, const char *name, rs_err *err)
{
    static const struct {
        const char *word;
        int kind;
    } words[] = {{"x", COL_X},    {"y", COL_Y},    {"z", COL_Z},     {"intensity", COL_I}, {"i", COL_I},
                 {"r", COL_R},    {"g", COL_G},    {"b", COL_B},     {"red", COL_R},       {"green", COL_G},
                 {"blue", COL_B}, {"-", COL_SKIP}, {"nx", COL_SKIP}, {"ny", COL_SKIP},     {"nz", COL_SKIP}};
    int n = 0, seen[8] = {0};
    const char *p = spec ? spec : "x y z";
    while (*p) {
        while (*p && (isspace((unsigned char)*p) || *p == ',')) p++;
        if (!*p) break;
        const char *s = p;
        while (*p && !isspace((unsigned char)*p) && *p != ',') p++;
        size_t len = (size_t)(p - s);
        int k = -1;
        for (size_t w = 0; w < sizeof words / sizeof *words; w++)
            if (strlen(words[w].word) == len && strncmp(words[w].word, s, len) == 0) k = words[w].kind;
        if (k < 0)
            return rs_err_set(err, RS_ERR_INPUT, name, 0,
                              "[ingest] columns: \"%.*s\" is not a column name; expected "
                              "x y z intensity r g b (or red green blue), nx ny nz or - for a column to ignore",
                              (int)(len < 40 ? len : 40), s);
        if (k != COL_SKIP && seen[k]++)
            return rs_err_set(err, RS_ERR_INPUT, name, 0,
                              "[ingest] columns: \"%.*s\" named twice; expected each "
                              "quantity once",
                              (int)len, s);
        if (n == MAX_COLS)
            return rs_err_set(err, RS_ERR_INPUT, name, 0, "[ingest] columns: more than %d columns", MAX_COLS);
        kind[n++] = k;
    }
    if (!seen[COL_X] || !seen[COL_Y] || !seen[COL_Z])
        return rs_err_set(err, RS_ERR_INPUT, name, 0, "[ingest] columns = \"%s\": expected x, y and z among them",
                          spec);
    if ((seen[COL_R] || seen[COL_G] || seen[COL_B]) && !(seen[COL_R] && seen[COL_G] && seen[COL_B]))
        return rs_err_set(err, RS_ERR_INPUT, name, 0, "[ingest] columns = \"%s\": expected all of r g b or none", spec);
    return n;
}

static int is_sep(char ch)
{
    return ch == ' ' || ch == '\t' || ch == ',' || ch == ';' || ch == '\r';
}

/* A value of column k in its documented range (cloud.h): coordinates up to RS_CLOUD_MAX_M,
 * intensities within float (they are stored as float), colours 0 to 255. */
static int check_value(int kind, int k, double v, const char *path, long line, rs_err *err)
{
    if ((kind == COL_X || kind == COL_Y || kind == COL_Z) && !(fabs(v) <= RS_CLOUD_MAX_M))
        return rs_err_set(err, RS_ERR_INPUT, path, line, "column %d: coordinate %g; expected -%g to %g (m)", k + 1, v,
                          RS_CLOUD_MAX_M, RS_CLOUD_MAX_M);
    if (kind == COL_I && !(fabs(v) <= FLT_MAX))
        return rs_err_set(err, RS_ERR_INPUT, path, line,
                          "column %d: intensity %g; expected a number within the float range", k + 1, v);
    if ((kind == COL_R || kind == COL_G || kind == COL_B) && !(v >= 0 && v <= 255))
        return rs_err_set(err, RS_ERR_INPUT, path, line, "column %d: colour %g; expected 0 to 255 (or 0 to 1)", k + 1,
                          v);
    return 0;
}

rs_cloud *rs_cloud_read_text(const char *path, const char *columns, rs_err *err)
{
    int kind[MAX_COLS];
    int ncols = parse_columns(columns, kind, path, err);
    if (ncols < 0) return NULL;
    int want_i = 0, want_rgb = 0;
    for (int k = 0; k < ncols; k++) {
        want_i |= kind[k] == COL_I;
        want_rgb |= kind[k] == COL_R;
    }
    char *data;
    size_t size;
    if (rs_read_file(path, &data, &size, err) != 0) return NULL;
    rs_cloud *c = calloc(1, sizeof *c);
    size_t lines = 1;
    for (size_t i = 0; i < size; i++) lines += data[i] == '\n';
    float *rgbf = NULL;
    if (c) {
        c->xyz = malloc(lines * 3 * sizeof *c->xyz);
        c->valid = malloc(lines);
        if (want_i) c->intensity = malloc(lines * sizeof *c->intensity);
        if (want_rgb) {
            c->rgb = malloc(lines * 3);
            rgbf = malloc(lines * 3 * sizeof *rgbf);
        }
    }
    if (!c || !c->xyz || !c->valid || (want_i && !c->intensity) || (want_rgb && (!c->rgb || !rgbf))) {
        rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory for %zu lines", lines);
        goto fail;
    }
    float rgb_max = 0;
    long line = 0;
    const char *p = data, *end = data + size;
    while (p < end) {
        const char *nl = memchr(p, '\n', (size_t)(end - p)), *le = nl ? nl : end;
        const char *ls = p;
        p = nl ? nl + 1 : end;
        line++;
        while (ls < le && is_sep(*ls)) ls++;
        if (ls == le || *ls == '#' || (le - ls >= 2 && ls[0] == '/' && ls[1] == '/')) continue;
        double v[MAX_COLS];
        int n = 0;
        const char *q = ls;
        while (q < le) {
            while (q < le && is_sep(*q)) q++;
            if (q >= le) break;
            const char *ts = q;
            while (q < le && !is_sep(*q)) q++;
            char buf[64];
            size_t len = (size_t)(q - ts), keep = len < sizeof buf ? len : sizeof buf - 1;
            memcpy(buf, ts, keep);
            buf[keep] = 0;
            char *stop;
            double x = strtod(buf, &stop);
            if (len >= sizeof buf || stop != buf + len || !isfinite(x)) {
                if (c->npoints == 0 && n == 0) break; /* a header line before any point: n stays 0 */
                rs_err_set(err, RS_ERR_INPUT, path, line, "column %d \"%s\": expected a finite number", n + 1, buf);
                goto fail;
            }
            if (n < MAX_COLS) v[n] = x;
            n++;
        }
        if (n == 0) continue;
        if (n == 1 && c->npoints == 0) continue; /* Leica PTS: a point count before the points */
        if (n < ncols) {
            rs_err_set(err, RS_ERR_INPUT, path, line, "%d numbers; expected %d ([ingest] columns)", n, ncols);
            goto fail;
        }
        size_t i = c->npoints++;
        for (int k = 0; k < ncols; k++) {
            if (check_value(kind[k], k, v[k], path, line, err) != 0) goto fail;
            switch (kind[k]) {
            case COL_X: c->xyz[3 * i] = v[k]; break;
            case COL_Y: c->xyz[3 * i + 1] = v[k]; break;
            case COL_Z: c->xyz[3 * i + 2] = v[k]; break;
            case COL_I: c->intensity[i] = (float)v[k]; break;
            case COL_R:
            case COL_G:
            case COL_B:
                rgbf[3 * i + kind[k] - COL_R] = (float)v[k];
                rgb_max = fmaxf(rgb_max, (float)v[k]);
                break;
            default: break;
            }
        }
        c->valid[i] = 1;
    }
    if (c->npoints == 0) {
        rs_err_set(err, RS_ERR_INPUT, path, 0,
                   "no point lines; expected lines of numbers in the order of "
                   "[ingest] columns = \"%s\"",
                   columns ? columns : "x y z");
        goto fail;
    }
    if (want_rgb) {
        float scale = rgb_max > 1 ? 1.0f : 255.0f; /* 0..1 floats or 0..255 integers */
        for (size_t k = 0; k < 3 * c->npoints; k++) {
            float x = rgbf[k] * scale;
            c->rgb[k] = (uint8_t)(x < 255 ? lroundf(x) : 255);
        }
    }
    free(rgbf);
    free(data);
    return c;
fail:
    free(rgbf);
    free(data);
    rs_cloud_free(c);
    return NULL;
}
