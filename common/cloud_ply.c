/* cloud_ply: point clouds as PLY files (see cloud_ply.h): cloud.ply, the ingest stage's
 * output, which keeps each scan's grid (scan, row, col per point and one "rhoscan_scan"
 * comment per scan), and PLY clouds written by other software. */
#include "common/cloud_ply.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"

#define SCAN_COMMENT      "rhoscan_scan"
#define ORIGIN_COMMENT    "rhoscan_origin"
#define VIEWPOINT_COMMENT "rhoscan_viewpoint"
#define UP_COMMENT        "rhoscan_normals_up"

/* The valid points one record at a time, in order (rs_ply_write_records): no table of the whole
 * cloud is built, so writing cloud.ply costs a buffer, not another copy of the points. */
typedef struct {
    const rs_cloud *c;
    size_t next; /* the point after the last one written */
} cloud_cursor;

static int cloud_record(void *ctx, const rs_ply_element *el, size_t k, double *v, rs_err *err)
{
    (void)el, (void)k, (void)err;
    cloud_cursor *cur = ctx;
    const rs_cloud *c = cur->c;
    while (!c->valid[cur->next]) cur->next++;
    size_t i = cur->next++;
    int n = 0;
    for (int j = 0; j < 3; j++) v[n++] = c->xyz[3 * i + j];
    if (c->intensity) v[n++] = c->intensity[i];
    if (c->rgb)
        for (int j = 0; j < 3; j++) v[n++] = c->rgb[3 * i + j];
    if (c->normal)
        for (int j = 0; j < 3; j++) v[n++] = c->normal[3 * i + j];
    if (c->nscans > 0) {
        /* Which scan the point belongs to: scans are contiguous runs, the rest is unorganized. */
        double scan = -1, row = -1, col = -1;
        for (int s = 0; s < c->nscans; s++) {
            const rs_scan *sc = &c->scans[s];
            size_t cells = (size_t)sc->cols * (size_t)sc->rows;
            if (i >= sc->first && i < sc->first + cells) {
                scan = s;
                col = (double)((i - sc->first) / (size_t)sc->rows);
                row = (double)((i - sc->first) % (size_t)sc->rows);
                break;
            }
        }
        v[n++] = scan, v[n++] = row, v[n++] = col;
    }
    return 0;
}

/* cloud.ply's header: the comments, then x y z, intensity, colour, normals and the grid cell as
 * the cloud has them (sh->... say which), for nvalid records. NULL when out of memory. */
static rs_ply *cloud_header(const rs_cloud *c, size_t nvalid)
{
    rs_ply *ply = rs_ply_new();
    if (!ply) return NULL;
    for (int s = 0; s < c->nscans; s++) {
        const rs_scan *sc = &c->scans[s];
        if (rs_ply_add_comment(ply, SCAN_COMMENT " %d %d %d %.17g %.17g %.17g", s, sc->cols, sc->rows, sc->position[0],
                               sc->position[1], sc->position[2]) != 0)
            goto nomem;
    }
    if ((c->origin[0] != 0 || c->origin[1] != 0 || c->origin[2] != 0) &&
        rs_ply_add_comment(ply, ORIGIN_COMMENT " %.17g %.17g %.17g", c->origin[0], c->origin[1], c->origin[2]) != 0)
        goto nomem;
    if (c->has_viewpoint &&
        rs_ply_add_comment(ply, VIEWPOINT_COMMENT " %.17g %.17g %.17g", c->viewpoint[0], c->viewpoint[1],
                           c->viewpoint[2]) != 0)
        goto nomem;
    if (!c->has_viewpoint && c->normals_up && rs_ply_add_comment(ply, UP_COMMENT) != 0) goto nomem;
    rs_ply_element *el = rs_ply_add_element(ply, "vertex", nvalid);
    if (!el || !rs_ply_declare_scalar(el, "x", RS_PLY_FLOAT64) || !rs_ply_declare_scalar(el, "y", RS_PLY_FLOAT64) ||
        !rs_ply_declare_scalar(el, "z", RS_PLY_FLOAT64))
        goto nomem;
    if (c->intensity && !rs_ply_declare_scalar(el, "intensity", RS_PLY_FLOAT32)) goto nomem;
    if (c->rgb &&
        (!rs_ply_declare_scalar(el, "red", RS_PLY_UINT8) || !rs_ply_declare_scalar(el, "green", RS_PLY_UINT8) ||
         !rs_ply_declare_scalar(el, "blue", RS_PLY_UINT8)))
        goto nomem;
    if (c->normal &&
        (!rs_ply_declare_scalar(el, "nx", RS_PLY_FLOAT32) || !rs_ply_declare_scalar(el, "ny", RS_PLY_FLOAT32) ||
         !rs_ply_declare_scalar(el, "nz", RS_PLY_FLOAT32)))
        goto nomem;
    if (c->nscans > 0 &&
        (!rs_ply_declare_scalar(el, "scan", RS_PLY_INT32) || !rs_ply_declare_scalar(el, "row", RS_PLY_INT32) ||
         !rs_ply_declare_scalar(el, "col", RS_PLY_INT32)))
        goto nomem;
    return ply;
nomem:
    rs_ply_free(ply);
    return NULL;
}

int rs_cloud_write_ply(const rs_cloud *c, const char *path, rs_err *err)
{
    size_t nvalid = 0;
    for (size_t i = 0; i < c->npoints; i++) nvalid += c->valid[i] != 0;
    rs_ply *ply = cloud_header(c, nvalid);
    if (!ply)
        return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory building the PLY header of %zu points", nvalid);
    cloud_cursor cur = {c, 0};
    int rc = rs_ply_write_records(ply, path, 1, cloud_record, &cur, err);
    rs_ply_free(ply);
    return rc;
}

int rs_cloud_write_ply_stream(const rs_cloud *shape, size_t count, rs_ply_record_fn fn, void *ctx, const char *path,
                              rs_err *err)
{
    rs_ply *ply = cloud_header(shape, count);
    if (!ply)
        return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory building the PLY header of %zu points", count);
    int rc = rs_ply_write_records(ply, path, 1, fn, ctx, err);
    rs_ply_free(ply);
    return rc;
}

static const double *scalar(const rs_ply_element *el, const char *name)
{
    const rs_ply_prop *p = rs_ply_find_prop(el, name);
    return p && !p->is_list ? p->data : NULL;
}

/* The scans described by the file's comments; returns their count or -1. */
static int read_scan_comments(const rs_ply *ply, const char *name, rs_scan **out, rs_err *err)
{
    int n = 0;
    for (int i = 0; i < ply->ncomments; i++)
        if (strncmp(ply->comments[i], SCAN_COMMENT " ", sizeof SCAN_COMMENT) == 0) n++;
    *out = NULL;
    if (n == 0) return 0;
    rs_scan *scans = calloc((size_t)n, sizeof *scans);
    char *seen = calloc((size_t)n, 1);
    if (!scans || !seen) {
        free(scans);
        free(seen);
        return rs_err_set(err, RS_ERR_SYSTEM, name, 0, "out of memory");
    }
    for (int i = 0; i < ply->ncomments; i++) {
        const char *cm = ply->comments[i];
        if (strncmp(cm, SCAN_COMMENT " ", sizeof SCAN_COMMENT) != 0) continue;
        int idx, cols, rows, used = 0;
        double p[3];
        if (sscanf(cm + sizeof SCAN_COMMENT, "%d %d %d %lf %lf %lf %n", &idx, &cols, &rows, p, p + 1, p + 2, &used) !=
                6 ||
            cm[sizeof SCAN_COMMENT + used] != '\0' || idx < 0 || idx >= n || seen[idx] || cols < 1 || rows < 1 ||
            !isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2])) {
            rs_err_set(err, RS_ERR_INPUT, name, 0,
                       "comment \"%.200s\": expected \"" SCAN_COMMENT " INDEX COLS ROWS PX PY PZ\" with INDEX from 0 "
                       "to %d (each once), COLS and ROWS >= 1 and a finite position",
                       cm, n - 1);
            free(scans);
            free(seen);
            return -1;
        }
        seen[idx] = 1;
        scans[idx].cols = cols;
        scans[idx].rows = rows;
        memcpy(scans[idx].position, p, sizeof p);
    }
    free(seen);
    *out = scans;
    return n;
}

/* The vertex properties a cloud is made of; NULL where the file has none. */
typedef struct ply_vertices {
    size_t n;
    const double *x, *y, *z, *intensity;
    const double *rgb[3];           /* red, green, blue: all three or none */
    double rgb_scale;               /* to 0..255: float colours are taken as 0..1, integer ones as 0..255 */
    const double *scan, *row, *col; /* the grid cell of each vertex (cloud.ply) */
    const double *nrm[3];           /* nx, ny, nz: all three or none */
} ply_vertices;

static int find_vertices(const rs_ply *ply, ply_vertices *v, const char *name, rs_err *err)
{
    const rs_ply_element *el = rs_ply_find_element(ply, "vertex");
    v->x = el ? scalar(el, "x") : NULL, v->y = el ? scalar(el, "y") : NULL, v->z = el ? scalar(el, "z") : NULL;
    if (!v->x || !v->y || !v->z)
        return rs_err_set(err, RS_ERR_INPUT, name, 0,
                          "no vertex element with scalar x, y and z; expected a point cloud");
    v->n = el->count;
    v->intensity = scalar(el, "intensity");
    v->rgb[0] = scalar(el, "red"), v->rgb[1] = scalar(el, "green"), v->rgb[2] = scalar(el, "blue");
    const rs_ply_prop *red_prop = rs_ply_find_prop(el, "red");
    if (!v->rgb[0] || !v->rgb[1] || !v->rgb[2]) v->rgb[0] = v->rgb[1] = v->rgb[2] = NULL;
    v->rgb_scale = v->rgb[0] && !(red_prop->type <= RS_PLY_UINT32) ? 255.0 : 1.0;
    v->scan = scalar(el, "scan"), v->row = scalar(el, "row"), v->col = scalar(el, "col");
    v->nrm[0] = scalar(el, "nx"), v->nrm[1] = scalar(el, "ny"), v->nrm[2] = scalar(el, "nz");
    if (!v->nrm[0] || !v->nrm[1] || !v->nrm[2]) v->nrm[0] = v->nrm[1] = v->nrm[2] = NULL;
    return 0;
}

/* A comment "KEY X Y Z" into out: 1 when found, 0 when absent, -1 when malformed. what says
 * what the numbers are, for the message. */
static int read_point_comment(const rs_ply *ply, const char *key, const char *what, double out[3], const char *name,
                              rs_err *err)
{
    const char *text = rs_ply_find_comment(ply, key);
    if (!text) return 0;
    int used = 0;
    if (sscanf(text, "%lf %lf %lf %n", out, out + 1, out + 2, &used) != 3 || text[used] != '\0' || !isfinite(out[0]) ||
        !isfinite(out[1]) || !isfinite(out[2]))
        return rs_err_set(err, RS_ERR_INPUT, name, 0, "comment \"%s %.200s\": expected three finite numbers (%s)", key,
                          text, what);
    return 1;
}

/* The comments into c: its scan grids (c->scans, and their count, checked against the
 * vertices' properties), origin and viewpoint. */
static int read_comments(const rs_ply *ply, const ply_vertices *v, rs_cloud *c, const char *name, rs_err *err)
{
    int nscans = read_scan_comments(ply, name, &c->scans, err);
    if (nscans < 0) return -1;
    if (read_point_comment(ply, ORIGIN_COMMENT, "the offset added to every coordinate", c->origin, name, err) < 0)
        return -1;
    int vp = read_point_comment(ply, VIEWPOINT_COMMENT, "the scanner centre", c->viewpoint, name, err);
    if (vp < 0) return -1;
    c->has_viewpoint = vp;
    c->normals_up = !vp && rs_ply_find_comment(ply, UP_COMMENT) != NULL;
    if (nscans > 0 && (!v->scan || !v->row || !v->col))
        return rs_err_set(err, RS_ERR_INPUT, name, 0,
                          "the file describes %d scan grid(s) but its vertices lack scan, row "
                          "and col properties",
                          nscans);
    c->nscans = nscans;
    return 0;
}

/* Grid points first, scan by scan, then the unorganized ones: sets each scan's first index
 * and allocates the points, every grid cell a no-return point at its scanner until a vertex
 * fills it. Grids are bounded by the point count so that a corrupt comment cannot ask for
 * terabytes. */
static int lay_out_points(rs_cloud *c, const ply_vertices *v, const char *name, rs_err *err)
{
    size_t grid = 0;
    for (int s = 0; s < c->nscans; s++) {
        c->scans[s].first = grid;
        grid += (size_t)c->scans[s].cols * (size_t)c->scans[s].rows;
        if (grid > 1000000 + 1000 * v->n)
            return rs_err_set(err, RS_ERR_INPUT, name, 0,
                              "scan grids of %zu cells for %zu points; expected at most "
                              "1000 cells per point (corrupt " SCAN_COMMENT " comment?)",
                              grid, v->n);
    }
    size_t loose = 0;
    for (size_t k = 0; k < v->n; k++)
        if (!c->nscans || v->scan[k] == -1) loose++;
    if (rs_cloud_resize(c, grid + loose, v->intensity != NULL, v->rgb[0] != NULL, err) != 0) return -1;
    c->npoints = grid + loose;
    if (v->nrm[0] && !(c->normal = calloc(3 * (c->npoints ? c->npoints : 1), sizeof *c->normal)))
        return rs_err_set(err, RS_ERR_SYSTEM, name, 0, "out of memory for %zu normals", c->npoints);
    memset(c->valid, 0, c->npoints);
    for (int s = 0; s < c->nscans; s++) {
        const rs_scan *sc = &c->scans[s];
        size_t n = (size_t)sc->cols * (size_t)sc->rows;
        for (size_t i = sc->first; i < sc->first + n; i++) memcpy(c->xyz + 3 * i, sc->position, sizeof sc->position);
    }
    return 0;
}

/* The point index of vertex k: its grid cell, or the next unorganized slot (*next_loose). */
static int vertex_index(const rs_cloud *c, const ply_vertices *v, size_t k, size_t *next_loose, size_t *index,
                        const char *name, rs_err *err)
{
    if (!c->nscans || v->scan[k] == -1) {
        *index = (*next_loose)++;
        return 0;
    }
    double s = v->scan[k], r = v->row[k], cl = v->col[k];
    if (!(s >= 0 && s < c->nscans && s == floor(s)) || !(r >= 0 && r < c->scans[(int)s].rows && r == floor(r)) ||
        !(cl >= 0 && cl < c->scans[(int)s].cols && cl == floor(cl)))
        return rs_err_set(err, RS_ERR_INPUT, name, 0,
                          "vertex %zu: scan %g, row %g, col %g is outside the grids "
                          "in the " SCAN_COMMENT " comments (or not -1 for a point outside them)",
                          k, s, r, cl);
    const rs_scan *sc = &c->scans[(int)s];
    *index = sc->first + (size_t)cl * (size_t)sc->rows + (size_t)r;
    if (c->valid[*index])
        return rs_err_set(err, RS_ERR_INPUT, name, 0,
                          "vertex %zu: scan %g, row %g, col %g holds a point already; "
                          "expected one point per grid cell",
                          k, s, r, cl);
    return 0;
}

/* Every vertex into its point, checked (finite coordinates, a grid cell of its own). */
static int place_vertices(rs_cloud *c, const ply_vertices *v, const char *name, rs_err *err)
{
    size_t next_loose = c->npoints - rs_cloud_unorganized(c); /* the first slot after the grids */
    for (size_t k = 0; k < v->n; k++) {
        if (!isfinite(v->x[k]) || !isfinite(v->y[k]) || !isfinite(v->z[k]))
            return rs_err_set(err, RS_ERR_INPUT, name, 0, "vertex %zu: (%g, %g, %g); expected finite coordinates", k,
                              v->x[k], v->y[k], v->z[k]);
        size_t i = 0;
        if (vertex_index(c, v, k, &next_loose, &i, name, err) != 0) return -1;
        c->xyz[3 * i] = v->x[k];
        c->xyz[3 * i + 1] = v->y[k];
        c->xyz[3 * i + 2] = v->z[k];
        c->valid[i] = 1;
        if (v->intensity) c->intensity[i] = isfinite(v->intensity[k]) ? (float)v->intensity[k] : 0.0f;
        if (v->rgb[0])
            for (int j = 0; j < 3; j++) {
                double x = v->rgb[j][k] * v->rgb_scale;
                c->rgb[3 * i + j] = (uint8_t)(x > 0 ? (x < 255 ? lround(x) : 255) : 0);
            }
        if (c->normal) {
            double nx = v->nrm[0][k], ny = v->nrm[1][k], nz = v->nrm[2][k], len = sqrt(nx * nx + ny * ny + nz * nz);
            if (!(len > 1e-6) || !isfinite(len)) { /* one unusable normal: the mesh stage estimates them all */
                rs_log_warn("%s: vertex %zu: normal (%g, %g, %g) is not a direction: the file's normals are not used",
                            name, k, nx, ny, nz);
                free(c->normal);
                c->normal = NULL;
                continue;
            }
            c->normal[3 * i] = (float)(nx / len), c->normal[3 * i + 1] = (float)(ny / len);
            c->normal[3 * i + 2] = (float)(nz / len);
        }
    }
    return 0;
}

rs_cloud *rs_cloud_from_ply(const rs_ply *ply, const char *name, rs_err *err)
{
    ply_vertices v = {0};
    if (find_vertices(ply, &v, name, err) != 0) return NULL;
    rs_cloud *c = calloc(1, sizeof *c);
    if (!c) {
        rs_err_set(err, RS_ERR_SYSTEM, name, 0, "out of memory");
        return NULL;
    }
    if (read_comments(ply, &v, c, name, err) != 0 || lay_out_points(c, &v, name, err) != 0 ||
        place_vertices(c, &v, name, err) != 0) {
        rs_cloud_free(c);
        return NULL;
    }
    return c;
}

rs_cloud *rs_cloud_read_ply(const char *path, rs_err *err)
{
    rs_ply *ply = rs_ply_read(path, err);
    if (!ply) return NULL;
    rs_cloud *c = rs_cloud_from_ply(ply, path, err);
    rs_ply_free(ply);
    return c;
}
