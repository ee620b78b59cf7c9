/* e57: the E57 reader's XML side and its streaming API (see e57.h): the header, the XML section,
 * data3D's scans (pose, prototype roles, grid bounds, intensity and colour limits), images2D's
 * images, and the chunks of posed points. */
#include "common/e57.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/e57_internal.h"
#include "common/log.h"

typedef struct e57_scan {
    rs_e57_scan_info info;
    const e57_node *points;
    double int_min, int_max; /* intensity limits (max <= min: values used as they are) */
    double col_min[3], col_max[3];
} e57_scan;

struct rs_e57 {
    e57_file file;
    char name[512];
    e57_node *root;
    e57_scan *scans;
    int nscans;
    rs_e57_image_info *images;
    int nimages;
    /* the scan being read */
    int cur;
    e57_cv cv;
    double *vals[E57_R_NROLES];
    rs_e57_points out;
};

static const char *const role_names[E57_R_NROLES] = {
    [E57_R_X] = "cartesianX",
    [E57_R_Y] = "cartesianY",
    [E57_R_Z] = "cartesianZ",
    [E57_R_RANGE] = "sphericalRange",
    [E57_R_AZ] = "sphericalAzimuth",
    [E57_R_EL] = "sphericalElevation",
    [E57_R_CINV] = "cartesianInvalidState",
    [E57_R_SINV] = "sphericalInvalidState",
    [E57_R_ROW] = "rowIndex",
    [E57_R_COL] = "columnIndex",
    [E57_R_INT] = "intensity",
    [E57_R_RED] = "colorRed",
    [E57_R_GREEN] = "colorGreen",
    [E57_R_BLUE] = "colorBlue",
    [E57_R_NX] = "nor:normalX",
    [E57_R_NY] = "nor:normalY",
    [E57_R_NZ] = "nor:normalZ",
};

static int role_of(const char *name)
{
    for (int r = 1; r < E57_R_NROLES; r++)
        if (strcmp(name, role_names[r]) == 0) return r;
    return E57_R_NONE;
}

/* The prototype field of a role, or NULL. */
static const e57_node *proto_field(const e57_node *points, int role)
{
    return e57_child(e57_child(points, "prototype"), role_names[role]);
}

/* A field's value range as the prototype declares it (Integer/ScaledInteger; Float: its
 * minimum/maximum attributes when given); 0 when it has none. */
static int field_range(const e57_node *n, const char *file, double *lo, double *hi, rs_err *err)
{
    *lo = *hi = 0;
    if (!n) return 0;
    double scale = 1, offset = 0;
    if (n->type == E57_T_SCALED &&
        (e57_attr_real(n, "scale", 1, file, &scale, err) != 0 ||
         e57_attr_real(n, "offset", 0, file, &offset, err) != 0))
        return -1;
    if (!e57_attr(n, "minimum") || !e57_attr(n, "maximum")) return 0;
    if (e57_attr_real(n, "minimum", 0, file, lo, err) != 0 || e57_attr_real(n, "maximum", 0, file, hi, err) != 0)
        return -1;
    if (n->type == E57_T_SCALED) {
        *lo = *lo * scale + offset;
        *hi = *hi * scale + offset;
        if (scale < 0) {
            double t = *lo;
            *lo = *hi;
            *hi = t;
        }
    }
    return 0;
}

/* Limits from a limits structure (e.g. intensityLimits/intensityMinimum), else the field's range. */
static int limits(const e57_node *scan, const char *group, const char *lo_name, const char *hi_name,
                  const e57_node *field, const char *file, double *lo, double *hi, rs_err *err)
{
    const e57_node *g = e57_child(scan, group);
    if (g && e57_child(g, lo_name) && e57_child(g, hi_name))
        return e57_child_number(g, lo_name, 0, file, lo, err) != 0 ||
                e57_child_number(g, hi_name, 0, file, hi, err) != 0
            ? -1
            : 0;
    return field_range(field, file, lo, hi, err);
}

/* The grid's bounds: indexBounds, else the rowIndex/columnIndex ranges; refused (unorganized)
 * when absent or far larger than the records (16 times and a million cells: a grid's cells
 * cost 25 bytes each, so a lying indexBounds cannot ask for much more than the points). */
static int grid_bounds(e57_scan *s, const e57_node *scan, const char *file, rs_err *err)
{
    rs_e57_scan_info *in = &s->info;
    const e57_node *row = proto_field(s->points, E57_R_ROW), *col = proto_field(s->points, E57_R_COL);
    if (!row || !col) return 0;
    double r0, r1, c0, c1;
    if (limits(scan, "indexBounds", "rowMinimum", "rowMaximum", row, file, &r0, &r1, err) != 0 ||
        limits(scan, "indexBounds", "columnMinimum", "columnMaximum", col, file, &c0, &c1, err) != 0)
        return -1;
    double cells = (r1 - r0 + 1) * (c1 - c0 + 1);
    if (!(r1 >= r0 && c1 >= c0) || r1 - r0 >= 2147483647.0 || c1 - c0 >= 2147483647.0 ||
        cells > 16.0 * (double)in->records + 1e6) {
        rs_log_warn("%s: scan %s: rows %g..%g, columns %g..%g do not bound a grid of about its %llu points; read "
                    "as unorganized",
                    file, in->name, r0, r1, c0, c1, (unsigned long long)in->records);
        return 0;
    }
    in->grid = 1;
    in->row_min = (int64_t)r0;
    in->row_max = (int64_t)r1;
    in->col_min = (int64_t)c0;
    in->col_max = (int64_t)c1;
    return 0;
}

/* One data3D entry. */
static int parse_scan(rs_e57 *e, const e57_node *scan, e57_scan *s, rs_err *err)
{
    const char *file = e->name;
    rs_e57_scan_info *in = &s->info;
    char path[256];
    e57_path(scan, path, sizeof path);
    e57_child_string(scan, "name", in->name, sizeof in->name);
    e57_child_string(scan, "guid", in->guid, sizeof in->guid);
    if (!in->name[0]) snprintf(in->name, sizeof in->name, "%.127s", path);
    const e57_node *pose = e57_child(scan, "pose");
    in->has_pose = pose != NULL;
    if (e57_pose(pose, file, in->rotation, in->translation, err) != 0) return -1;
    s->points = e57_child(scan, "points");
    int64_t records = 0;
    if (!s->points || s->points->type != E57_T_CVECTOR)
        return rs_err_set(err, RS_ERR_INPUT, file, scan->line, "XML %s: no points CompressedVector", path);
    if (e57_attr_int(s->points, "recordCount", 0, file, &records, err) != 0) return -1;
    in->records = records > 0 ? (uint64_t)records : 0;
    int cart = proto_field(s->points, E57_R_X) && proto_field(s->points, E57_R_Y) && proto_field(s->points, E57_R_Z);
    int sph =
        proto_field(s->points, E57_R_RANGE) && proto_field(s->points, E57_R_AZ) && proto_field(s->points, E57_R_EL);
    if (!cart && !sph)
        return rs_err_set(err, RS_ERR_INPUT, file, s->points->line,
                          "XML %s/points/prototype: no coordinates; expected cartesianX/Y/Z or "
                          "sphericalRange/Azimuth/Elevation",
                          path);
    in->spherical = !cart;
    in->has_intensity = proto_field(s->points, E57_R_INT) != NULL;
    in->has_rgb =
        proto_field(s->points, E57_R_RED) && proto_field(s->points, E57_R_GREEN) && proto_field(s->points, E57_R_BLUE);
    in->has_normals =
        proto_field(s->points, E57_R_NX) && proto_field(s->points, E57_R_NY) && proto_field(s->points, E57_R_NZ);
    if (limits(scan, "intensityLimits", "intensityMinimum", "intensityMaximum", proto_field(s->points, E57_R_INT), file,
               &s->int_min, &s->int_max, err) != 0)
        return -1;
    static const char *const lo[3] = {"colorRedMinimum", "colorGreenMinimum", "colorBlueMinimum"};
    static const char *const hi[3] = {"colorRedMaximum", "colorGreenMaximum", "colorBlueMaximum"};
    for (int k = 0; k < 3 && in->has_rgb; k++)
        if (limits(scan, "colorLimits", lo[k], hi[k], proto_field(s->points, E57_R_RED + k), file, &s->col_min[k],
                   &s->col_max[k], err) != 0)
            return -1;
    return grid_bounds(s, scan, file, err);
}

static int child_real(const e57_node *n, const char *name, double *out, const char *file, rs_err *err)
{
    return e57_child_number(n, name, 0, file, out, err);
}

/* The Leica dist:distortion structure of a pinhole image. */
static int parse_distortion(const e57_node *d, rs_e57_image_info *im, const char *file, rs_err *err)
{
    if (!d) return 0;
    im->has_distortion = 1;
    char name[16];
    for (int k = 0; k < 6; k++) {
        snprintf(name, sizeof name, "dist:CV_K%d", k + 1);
        if (child_real(d, name, &im->k[k], file, err) != 0) return -1;
    }
    return child_real(d, "dist:CV_P1", &im->p[0], file, err) || child_real(d, "dist:CV_P2", &im->p[1], file, err) ||
            child_real(d, "dist:CV_CX", &im->cx, file, err) || child_real(d, "dist:CV_CY", &im->cy, file, err) ||
            child_real(d, "dist:CV_FX", &im->fx, file, err) || child_real(d, "dist:CV_FY", &im->fy, file, err)
        ? -1
        : 0;
}

/* The representation's blob (jpegImage or pngImage) and sizes. */
static int parse_representation(rs_e57 *e, const e57_node *rep, rs_e57_image_info *im, rs_err *err)
{
    const char *file = e->name;
    char path[256];
    e57_path(rep, path, sizeof path);
    const e57_node *blob = e57_child(rep, "jpegImage");
    im->png = blob == NULL;
    if (!blob) blob = e57_child(rep, "pngImage");
    if (!blob || blob->type != E57_T_BLOB)
        return rs_err_set(err, RS_ERR_INPUT, file, rep->line, "XML %s: no jpegImage or pngImage Blob", path);
    int64_t off, len, w, h;
    if (e57_attr_int(blob, "fileOffset", -1, file, &off, err) != 0 ||
        e57_attr_int(blob, "length", -1, file, &len, err) != 0)
        return -1;
    if (off < 0 || len < 0)
        return rs_err_set(err, RS_ERR_INPUT, file, blob->line, "XML %s/%s: no fileOffset or length", path, blob->name);
    im->blob_offset = (uint64_t)off;
    im->blob_length = (uint64_t)len;
    double dw, dh;
    if (child_real(rep, "imageWidth", &dw, file, err) != 0 || child_real(rep, "imageHeight", &dh, file, err) != 0)
        return -1;
    w = (int64_t)dw;
    h = (int64_t)dh;
    if (w < 0 || h < 0 || w > 1 << 20 || h > 1 << 20)
        return rs_err_set(err, RS_ERR_INPUT, file, rep->line,
                          "XML %s: image %lld x %lld; expected 0 to 2^20 pixels a side", path, (long long)w,
                          (long long)h);
    im->width = (int)w;
    im->height = (int)h;
    return child_real(rep, "pixelWidth", &im->pixel_width, file, err) ||
            child_real(rep, "pixelHeight", &im->pixel_height, file, err) ||
            child_real(rep, "focalLength", &im->focal_length, file, err) ||
            child_real(rep, "principalPointX", &im->principal_x, file, err) ||
            child_real(rep, "principalPointY", &im->principal_y, file, err) ||
            child_real(rep, "radius", &im->radius, file, err)
        ? -1
        : 0;
}

static int parse_image(rs_e57 *e, const e57_node *img, rs_e57_image_info *im, rs_err *err)
{
    static const struct {
        const char *name;
        rs_e57_projection p;
    } reps[] = {{"sphericalRepresentation", RS_E57_SPHERICAL},
                {"pinholeRepresentation", RS_E57_PINHOLE},
                {"cylindricalRepresentation", RS_E57_CYLINDRICAL},
                {"visualReferenceRepresentation", RS_E57_VISUAL}};
    char path[256];
    e57_path(img, path, sizeof path);
    e57_child_string(img, "name", im->name, sizeof im->name);
    e57_child_string(img, "guid", im->guid, sizeof im->guid);
    e57_child_string(img, "associatedData3DGuid", im->associated_scan, sizeof im->associated_scan);
    if (!im->name[0]) snprintf(im->name, sizeof im->name, "%.127s", path);
    const e57_node *pose = e57_child(img, "pose");
    im->has_pose = pose != NULL;
    if (e57_pose(pose, e->name, im->rotation, im->translation, err) != 0) return -1;
    for (size_t k = 0; k < sizeof reps / sizeof reps[0]; k++) {
        const e57_node *rep = e57_child(img, reps[k].name);
        if (!rep) continue;
        im->projection = reps[k].p;
        /* dist:distortion stands beside the representation (libE57Format), or inside it. */
        const e57_node *dist = e57_child(img, "dist:distortion");
        return parse_representation(e, rep, im, err) != 0
            ? -1
            : parse_distortion(dist ? dist : e57_child(rep, "dist:distortion"), im, e->name, err);
    }
    return rs_err_set(err, RS_ERR_INPUT, e->name, img->line,
                      "XML %s: no spherical, pinhole, cylindrical or visual reference representation", path);
}

/* data3D and images2D (either may be absent or empty). */
static int parse_root(rs_e57 *e, rs_err *err)
{
    const e57_node *d3 = e57_child(e->root, "data3D"), *i2 = e57_child(e->root, "images2D");
    int ns = d3 ? d3->nchildren : 0, ni = i2 ? i2->nchildren : 0;
    e->scans = calloc((size_t)ns + 1, sizeof *e->scans);
    e->images = calloc((size_t)ni + 1, sizeof *e->images);
    if (!e->scans || !e->images) return rs_err_set(err, RS_ERR_SYSTEM, e->name, 0, "out of memory");
    int i = 0;
    for (const e57_node *c = ns ? d3->child : NULL; c; c = c->next, i++, e->nscans++)
        if (parse_scan(e, c, &e->scans[i], err) != 0) return -1;
    i = 0;
    for (const e57_node *c = ni ? i2->child : NULL; c; c = c->next, i++, e->nimages++)
        if (parse_image(e, c, &e->images[i], err) != 0) return -1;
    return 0;
}

static uint64_t le64(const uint8_t *p)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--) v = v << 8 | p[i];
    return v;
}

static rs_e57 *open_any(const char *path, const void *mem, size_t size, rs_err *err)
{
    rs_e57 *e = calloc(1, sizeof *e);
    if (!e) {
        rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
        return NULL;
    }
    snprintf(e->name, sizeof e->name, "%s", path ? path : "(memory)");
    e->cur = -1;
    uint8_t h[48];
    char *xml = NULL;
    if (e57_file_open(&e->file, e->name, mem, size, err) != 0 || e57_read_logical(&e->file, 0, h, 48, err) != 0)
        goto fail;
    uint64_t xoff = le64(h + 24), xlen = le64(h + 32), xlog;
    if (e57_logical_of(&e->file, xoff, "offset 24, xmlPhysicalOffset", &xlog, err) != 0) goto fail;
    if (xlen == 0 || xlen > e57_logical_size(&e->file) - xlog) {
        rs_err_set(err, RS_ERR_INPUT, e->name, 0,
                   "offset 32: xmlLogicalLength %llu; expected 1 to %llu (the data bytes after the XML's offset)",
                   (unsigned long long)xlen, (unsigned long long)(e57_logical_size(&e->file) - xlog));
        goto fail;
    }
    if (!(xml = malloc((size_t)xlen + 1))) {
        rs_err_set(err, RS_ERR_SYSTEM, e->name, 0, "out of memory for %llu bytes of XML", (unsigned long long)xlen);
        goto fail;
    }
    if (e57_read_logical(&e->file, xlog, xml, (size_t)xlen, err) != 0) goto fail;
    e->root = e57_xml_parse(xml, (size_t)xlen, e->name, err);
    free(xml);
    xml = NULL;
    if (!e->root || parse_root(e, err) != 0) goto fail;
    return e;
fail:
    free(xml);
    rs_e57_close(e);
    return NULL;
}

rs_e57 *rs_e57_open(const char *path, rs_err *err)
{
    return open_any(path, NULL, 0, err);
}

rs_e57 *rs_e57_open_mem(const void *data, size_t size, const char *name, rs_err *err)
{
    static const uint8_t none[1];
    return open_any(name ? name : "(memory)", data ? data : none, size, err);
}

static void end_scan(rs_e57 *e)
{
    e57_cv_free(&e->cv);
    for (int r = 0; r < E57_R_NROLES; r++) {
        free(e->vals[r]);
        e->vals[r] = NULL;
    }
    free(e->out.xyz);
    free(e->out.valid);
    free(e->out.intensity);
    free(e->out.rgb);
    free(e->out.normal);
    free(e->out.row);
    free(e->out.col);
    memset(&e->out, 0, sizeof e->out);
    e->cur = -1;
}

void rs_e57_close(rs_e57 *e)
{
    if (!e) return;
    end_scan(e);
    e57_file_close(&e->file);
    e57_xml_free(e->root);
    free(e->scans);
    free(e->images);
    free(e);
}

int rs_e57_scan_count(const rs_e57 *e)
{
    return e->nscans;
}
const rs_e57_scan_info *rs_e57_scan(const rs_e57 *e, int i)
{
    return i >= 0 && i < e->nscans ? &e->scans[i].info : NULL;
}
int rs_e57_image_count(const rs_e57 *e)
{
    return e->nimages;
}
const rs_e57_image_info *rs_e57_image(const rs_e57 *e, int i)
{
    return i >= 0 && i < e->nimages ? &e->images[i] : NULL;
}

int rs_e57_scan_begin(rs_e57 *e, int i, rs_err *err)
{
    end_scan(e);
    if (i < 0 || i >= e->nscans) return rs_err_set(err, RS_ERR_INTERNAL, e->name, 0, "no scan %d", i);
    const e57_scan *s = &e->scans[i];
    if (e57_cv_open(&e->cv, &e->file, s->points, role_of, err) != 0) {
        end_scan(e);
        return -1;
    }
    int ok = 1;
    for (int k = 0; k < e->cv.nfields; k++) {
        int r = e->cv.fields[k].role;
        if (r != E57_R_NONE && !e->vals[r]) ok &= (e->vals[r] = malloc(RS_E57_CHUNK * sizeof(double))) != NULL;
    }
    const rs_e57_scan_info *in = &s->info;
    rs_e57_points *o = &e->out;
    ok &= (o->xyz = malloc(RS_E57_CHUNK * 3 * sizeof *o->xyz)) != NULL;
    ok &= (o->valid = malloc(RS_E57_CHUNK)) != NULL;
    if (in->has_intensity) ok &= (o->intensity = malloc(RS_E57_CHUNK * sizeof *o->intensity)) != NULL;
    if (in->has_rgb) ok &= (o->rgb = malloc(RS_E57_CHUNK * 3)) != NULL;
    if (in->has_normals) ok &= (o->normal = malloc(RS_E57_CHUNK * 3 * sizeof *o->normal)) != NULL;
    if (in->grid) ok &= (o->row = malloc(RS_E57_CHUNK * sizeof *o->row)) != NULL;
    if (in->grid) ok &= (o->col = malloc(RS_E57_CHUNK * sizeof *o->col)) != NULL;
    if (!ok) {
        end_scan(e);
        return rs_err_set(err, RS_ERR_SYSTEM, e->name, 0, "out of memory");
    }
    e->cur = i;
    return 0;
}

/* v scaled from lo..hi to 0..1 (as it is when the limits are not usable), through the
 * reciprocal of hi - lo (exact when it is a power of two, as 0..1 is). */
static double unit(double v, double lo, double hi)
{
    return hi > lo ? (v - lo) * (1.0 / (hi - lo)) : v;
}

/* The values of record i into point i of the chunk. */
static void assemble(const e57_scan *s, double *const *v, size_t i, rs_e57_points *o)
{
    const rs_e57_scan_info *in = &s->info;
    double x, y, z;
    int valid = 1;
    if (in->spherical) {
        double r = v[E57_R_RANGE][i], az = v[E57_R_AZ][i], el = v[E57_R_EL][i];
        x = r * cos(el) * cos(az);
        y = r * cos(el) * sin(az);
        z = r * sin(el);
        if (v[E57_R_SINV] && v[E57_R_SINV][i] != 0) valid = 0;
    } else {
        x = v[E57_R_X][i];
        y = v[E57_R_Y][i];
        z = v[E57_R_Z][i];
        if (v[E57_R_CINV] && v[E57_R_CINV][i] != 0) valid = 0;
    }
    if (!isfinite(x) || !isfinite(y) || !isfinite(z)) valid = 0, x = y = z = 0;
    const double *R = in->rotation, *t = in->translation;
    o->xyz[3 * i + 0] = R[0] * x + R[1] * y + R[2] * z + t[0];
    o->xyz[3 * i + 1] = R[3] * x + R[4] * y + R[5] * z + t[1];
    o->xyz[3 * i + 2] = R[6] * x + R[7] * y + R[8] * z + t[2];
    o->valid[i] = (uint8_t)valid;
    if (o->intensity) {
        double u = unit(v[E57_R_INT][i], s->int_min, s->int_max);
        o->intensity[i] = isfinite(u) ? (float)u : 0.0f;
    }
    for (int k = 0; k < 3 && o->rgb; k++) {
        double u = unit(v[E57_R_RED + k][i], s->col_min[k], s->col_max[k]) * 255.0;
        o->rgb[3 * i + k] = (uint8_t)(u > 0 ? (u < 255 ? (int)(u + 0.5) : 255) : 0); /* rounded half up */
    }
    if (o->normal) {
        double nx = v[E57_R_NX][i], ny = v[E57_R_NY][i], nz = v[E57_R_NZ][i];
        for (int k = 0; k < 3; k++) {
            double w = R[3 * k] * nx + R[3 * k + 1] * ny + R[3 * k + 2] * nz;
            o->normal[3 * i + k] = isfinite(w) ? (float)w : 0.0f;
        }
    }
    if (o->row) {
        o->row[i] = (int64_t)v[E57_R_ROW][i];
        o->col[i] = (int64_t)v[E57_R_COL][i];
    }
}

int rs_e57_scan_next(rs_e57 *e, rs_e57_points *out, rs_err *err)
{
    if (e->cur < 0) return rs_err_set(err, RS_ERR_INTERNAL, e->name, 0, "rs_e57_scan_next before rs_e57_scan_begin");
    long n = e57_cv_read(&e->cv, &e->file, e->vals, RS_E57_CHUNK, err);
    if (n < 0) return -1;
    const e57_scan *s = &e->scans[e->cur];
    for (long i = 0; i < n; i++) assemble(s, e->vals, (size_t)i, &e->out);
    e->out.n = (size_t)n;
    *out = e->out;
    return n > 0;
}

int rs_e57_image_blob(rs_e57 *e, int i, uint8_t **data, size_t *size, rs_err *err)
{
    const rs_e57_image_info *im = rs_e57_image(e, i);
    *data = NULL;
    *size = 0;
    if (!im) return rs_err_set(err, RS_ERR_INTERNAL, e->name, 0, "no image %d", i);
    uint64_t start;
    char what[200];
    snprintf(what, sizeof what, "image \"%s\"'s blob", im->name);
    if (e57_logical_of(&e->file, im->blob_offset, what, &start, err) != 0) return -1;
    uint8_t h[16];
    if (e57_read_logical(&e->file, start, h, 16, err) != 0) return -1;
    uint64_t section = le64(h + 8);
    if (h[0] != 0 || section < 16 + im->blob_length)
        return rs_err_set(err, RS_ERR_INPUT, e->name, 0,
                          "offset %llu (%s): blob section id %d, length %llu; expected id 0 and at least %llu bytes",
                          (unsigned long long)im->blob_offset, what, h[0], (unsigned long long)section,
                          (unsigned long long)(16 + im->blob_length));
    if (im->blob_length > e57_logical_size(&e->file))
        return rs_err_set(err, RS_ERR_INPUT, e->name, 0, "%s: length %llu exceeds the file", what,
                          (unsigned long long)im->blob_length);
    *data = malloc(im->blob_length ? (size_t)im->blob_length : 1);
    if (!*data) return rs_err_set(err, RS_ERR_SYSTEM, e->name, 0, "out of memory for %s", what);
    if (e57_read_logical(&e->file, start + 16, *data, (size_t)im->blob_length, err) != 0) {
        free(*data);
        *data = NULL;
        return -1;
    }
    *size = (size_t)im->blob_length;
    return 0;
}
