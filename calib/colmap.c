/* colmap: the reader of COLMAP's text model (see colmap.h); the alignment and the poses are in
 * colmap_align.c. The formats are those of COLMAP 3.8's model_converter (src/base/reconstruction.cc). */
#include "calib/colmap.h"

#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "calib/calib_math.h"
#include "calib/colmap_text.h"
#include "common/fileio.h"

/* COLMAP 3.8's camera models (src/base/camera_models.h) and their parameter counts. */
static const struct {
    const char *name;
    int params;
} camera_models[] = {{"SIMPLE_PINHOLE", 3},
                     {"PINHOLE", 4},
                     {"SIMPLE_RADIAL", 4},
                     {"RADIAL", 5},
                     {"OPENCV", 8},
                     {"OPENCV_FISHEYE", 8},
                     {"FULL_OPENCV", 12},
                     {"FOV", 5},
                     {"SIMPLE_RADIAL_FISHEYE", 4},
                     {"RADIAL_FISHEYE", 5},
                     {"THIN_PRISM_FISHEYE", 12},
                     {NULL, 0}};

int rs_colmap_model_params(const char *model)
{
    for (int i = 0; camera_models[i].name; i++)
        if (strcmp(camera_models[i].name, model) == 0) return camera_models[i].params;
    return -1;
}

/* --- the line cursor shared with colmap_align.c (colmap_text.h) --- */

int rs_ctext_next_line(rs_ctext *c)
{
    if (!c->next || !*c->next) return 0;
    c->p = c->next;
    char *nl = strchr(c->next, '\n');
    if (nl) {
        *nl = 0;
        c->next = nl + 1;
    } else {
        c->next = c->p + strlen(c->p);
    }
    size_t n = strlen(c->p);
    if (n && c->p[n - 1] == '\r') c->p[n - 1] = 0; /* files edited on Windows */
    c->line++;
    c->field = 0;
    while (*c->p == ' ' || *c->p == '\t') c->p++;
    return 1;
}

int rs_ctext_blank(const rs_ctext *c)
{
    return c->p[0] == 0 || c->p[0] == '#';
}

int rs_ctext_more(const rs_ctext *c)
{
    return c->p[strspn(c->p, " \t")] != 0;
}

size_t rs_ctext_token(rs_ctext *c, char *tok, size_t n)
{
    while (*c->p == ' ' || *c->p == '\t') c->p++;
    if (!*c->p) return 0;
    size_t k = strcspn(c->p, " \t");
    snprintf(tok, n, "%.*s", (int)(k < n ? k : n - 1), c->p);
    c->p += k;
    c->field++;
    return k;
}

int rs_ctext_name(rs_ctext *c, const char *what, char *tok, size_t n, rs_err *err)
{
    size_t k = rs_ctext_token(c, tok, n);
    if (!k) return rs_ctext_missing(c, what, err);
    if (k >= n)
        return rs_err_set(err, RS_ERR_INPUT, c->path, c->line,
                          "field %d (%s) = \"%.40s...\" has %zu characters: expected "
                          "at most %zu",
                          c->field, what, tok, k, n - 1);
    return 0;
}

/* A number field longer than the buffer would be read cut ("1.0000...05" as 1): refused. */
static int number_token(rs_ctext *c, const char *what, char *tok, size_t n, rs_err *err)
{
    size_t k = rs_ctext_token(c, tok, n);
    if (!k) return rs_ctext_missing(c, what, err);
    if (k >= n)
        return rs_err_set(err, RS_ERR_INPUT, c->path, c->line,
                          "field %d (%s) = \"%.40s...\" has %zu characters: expected a number of at most %zu", c->field,
                          what, tok, k, n - 1);
    return 0;
}

int rs_ctext_missing(rs_ctext *c, const char *what, rs_err *err)
{
    return rs_err_set(err, RS_ERR_INPUT, c->path, c->line, "field %d: expected %s, found the end of the line",
                      c->field + 1, what);
}

int rs_ctext_long(rs_ctext *c, const char *what, long *v, rs_err *err)
{
    char tok[128], *end;
    if (number_token(c, what, tok, sizeof tok, err) != 0) return -1;
    errno = 0;
    *v = strtol(tok, &end, 10);
    if (end == tok || *end || errno)
        return rs_err_set(err, RS_ERR_INPUT, c->path, c->line, "field %d (%s) = \"%s\": expected an integer", c->field,
                          what, tok);
    return 0;
}

int rs_ctext_real(rs_ctext *c, const char *what, double *v, rs_err *err)
{
    char tok[128], *end;
    if (number_token(c, what, tok, sizeof tok, err) != 0) return -1;
    *v = strtod(tok, &end);
    if (end == tok || *end || !isfinite(*v))
        return rs_err_set(err, RS_ERR_INPUT, c->path, c->line, "field %d (%s) = \"%s\": expected a finite number",
                          c->field, what, tok);
    return 0;
}

int rs_ctext_end(rs_ctext *c, const char *what, rs_err *err)
{
    char tok[128];
    if (rs_ctext_token(c, tok, sizeof tok))
        return rs_err_set(err, RS_ERR_INPUT, c->path, c->line,
                          "field %d = \"%s\": expected the end of the line "
                          "after %s",
                          c->field, tok, what);
    return 0;
}

int rs_ctext_open(rs_ctext *c, const char *path, rs_err *err)
{
    memset(c, 0, sizeof *c);
    snprintf(c->path, sizeof c->path, "%s", path);
    size_t size;
    if (!rs_file_exists(path)) return rs_err_errno(err, path, "cannot open");
    if (rs_read_file(path, &c->text, &size, err) != 0) return -1;
    if (strlen(c->text) != size) {
        free(c->text);
        c->text = NULL;
        return rs_err_set(err, RS_ERR_INPUT, path, 0, "contains a NUL byte: expected a text file");
    }
    c->next = c->text;
    return 0;
}

/* --- the three files --- */

/* Focal lengths (the first one or two parameters, px) must be positive; the models with one
 * focal length are the SIMPLE_ and RADIAL ones. */
static int check_camera_params(rs_ctext *c, const rs_colmap_camera *cam, rs_err *err)
{
    int nfocal = strncmp(cam->model, "SIMPLE_", 7) == 0 || strncmp(cam->model, "RADIAL", 6) == 0 ? 1 : 2;
    for (int k = 0; k < nfocal; k++)
        if (!(cam->params[k] > 0))
            return rs_err_set(err, RS_ERR_INPUT, c->path, c->line,
                              "field %d (parameter %d of %s, a focal length) = %g: expected a focal length > 0 (px)",
                              5 + k, k + 1, cam->model, cam->params[k]);
    return 0;
}

static int read_cameras(const char *path, rs_colmap_model *m, rs_err *err)
{
    rs_ctext c;
    if (rs_ctext_open(&c, path, err) != 0) return -1;
    int cap = 0, rc = 0;
    while (rc == 0 && rs_ctext_next_line(&c)) {
        if (rs_ctext_blank(&c)) continue;
        if (m->ncameras == cap) {
            cap = cap ? 2 * cap : 8;
            void *p = realloc(m->cameras, (size_t)cap * sizeof *m->cameras);
            if (!p) {
                rc = rs_err_set(err, RS_ERR_SYSTEM, path, c.line, "out of memory");
                break;
            }
            m->cameras = p;
        }
        rs_colmap_camera *cam = &m->cameras[m->ncameras];
        memset(cam, 0, sizeof *cam);
        long w = 0, h = 0;
        if (rs_ctext_long(&c, "CAMERA_ID", &cam->id, err) != 0)
            rc = -1;
        else if (cam->id < 0 || cam->id > UINT32_MAX)
            rc = rs_err_set(err, RS_ERR_INPUT, path, c.line, "field 1 (CAMERA_ID) = %ld: expected 0 to 4294967295",
                            cam->id);
        else if (rs_ctext_name(&c, "MODEL", cam->model, sizeof cam->model, err) != 0)
            rc = -1;
        else if ((cam->nparams = rs_colmap_model_params(cam->model)) < 0)
            rc = rs_err_set(err, RS_ERR_INPUT, path, c.line,
                            "field 2 (MODEL) = \"%s\": expected one of COLMAP's "
                            "camera models (SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, OPENCV_FISHEYE, "
                            "FULL_OPENCV, FOV, SIMPLE_RADIAL_FISHEYE, RADIAL_FISHEYE, THIN_PRISM_FISHEYE)",
                            cam->model);
        else if (rs_ctext_long(&c, "WIDTH", &w, err) != 0 || rs_ctext_long(&c, "HEIGHT", &h, err) != 0)
            rc = -1;
        else if (w < 1 || h < 1 || w > 1000000 || h > 1000000)
            rc = rs_err_set(err, RS_ERR_INPUT, path, c.line,
                            "WIDTH HEIGHT = %ld %ld: expected an image size in "
                            "pixels, 1 to 1000000",
                            w, h);
        for (int k = 0; rc == 0 && k < cam->nparams; k++) {
            char what[96];
            snprintf(what, sizeof what, "parameter %d of %d of %s", k + 1, cam->nparams, cam->model);
            rc = rs_ctext_real(&c, what, &cam->params[k], err);
        }
        if (rc == 0) rc = rs_ctext_end(&c, "the camera's parameters", err);
        if (rc == 0) rc = check_camera_params(&c, cam, err);
        for (int k = 0; rc == 0 && k < m->ncameras; k++)
            if (m->cameras[k].id == cam->id)
                rc = rs_err_set(err, RS_ERR_INPUT, path, c.line, "CAMERA_ID %ld is listed twice: expected unique ids",
                                cam->id);
        cam->width = (int)w;
        cam->height = (int)h;
        if (rc == 0) m->ncameras++;
    }
    free(c.text);
    if (rc == 0 && m->ncameras == 0)
        rc = rs_err_set(err, RS_ERR_INPUT, path, 0,
                        "no camera: expected lines `CAMERA_ID MODEL WIDTH HEIGHT PARAMS...`");
    return rc;
}

static int cmp_point(const void *a, const void *b)
{
    long x = ((const rs_colmap_point *)a)->id, y = ((const rs_colmap_point *)b)->id;
    return (x > y) - (x < y);
}

const rs_colmap_point *rs_colmap_find_point(const rs_colmap_model *m, long id)
{
    rs_colmap_point key = {.id = id};
    return m->npoints ? bsearch(&key, m->points, (size_t)m->npoints, sizeof key, cmp_point) : NULL;
}

const rs_colmap_image *rs_colmap_find_image(const rs_colmap_model *m, const char *name)
{
    for (int i = 0; i < m->nimages; i++)
        if (strcmp(m->images[i].name, name) == 0) return &m->images[i];
    return NULL;
}

static const rs_colmap_image *image_by_id(const rs_colmap_model *m, long id)
{
    for (int i = 0; i < m->nimages; i++)
        if (m->images[i].id == id) return &m->images[i];
    return NULL;
}

static int read_points(const char *path, rs_colmap_model *m, rs_err *err)
{
    rs_ctext c;
    if (rs_ctext_open(&c, path, err) != 0) return -1;
    int cap = 0, rc = 0;
    while (rc == 0 && rs_ctext_next_line(&c)) {
        if (rs_ctext_blank(&c)) continue;
        if (m->npoints == cap) {
            cap = cap ? 2 * cap : 1024;
            void *p = realloc(m->points, (size_t)cap * sizeof *m->points);
            if (!p) {
                rc = rs_err_set(err, RS_ERR_SYSTEM, path, c.line, "out of memory");
                break;
            }
            m->points = p;
        }
        rs_colmap_point *pt = &m->points[m->npoints];
        memset(pt, 0, sizeof *pt);
        pt->line = c.line;
        long rgb[3];
        if (rs_ctext_long(&c, "POINT3D_ID", &pt->id, err) != 0 || rs_ctext_real(&c, "X", &pt->xyz.x, err) != 0 ||
            rs_ctext_real(&c, "Y", &pt->xyz.y, err) != 0 || rs_ctext_real(&c, "Z", &pt->xyz.z, err) != 0 ||
            rs_ctext_long(&c, "R", &rgb[0], err) != 0 || rs_ctext_long(&c, "G", &rgb[1], err) != 0 ||
            rs_ctext_long(&c, "B", &rgb[2], err) != 0 || rs_ctext_real(&c, "ERROR", &pt->error_px, err) != 0) {
            rc = -1;
            break;
        }
        if (pt->id < 0)
            rc = rs_err_set(err, RS_ERR_INPUT, path, c.line, "field 1 (POINT3D_ID) = %ld: expected an id >= 0", pt->id);
        else if (!(pt->error_px >= 0))
            rc = rs_err_set(err, RS_ERR_INPUT, path, c.line,
                            "field 8 (ERROR) = %g: expected a mean reprojection error >= 0 (px)", pt->error_px);
        for (int k = 0; k < 3 && rc == 0; k++) {
            if (rgb[k] < 0 || rgb[k] > 255)
                rc = rs_err_set(err, RS_ERR_INPUT, path, c.line, "field %d (%c) = %ld: expected a colour 0..255", 5 + k,
                                "RGB"[k], rgb[k]);
            pt->rgb[k] = (unsigned char)rgb[k];
        }
        /* TRACK[] as (IMAGE_ID, POINT2D_IDX): the image ids are checked once images.txt is read. */
        while (rc == 0 && rs_ctext_more(&c)) {
            long id, idx;
            if (rs_ctext_long(&c, "TRACK IMAGE_ID", &id, err) != 0 ||
                rs_ctext_long(&c, "TRACK POINT2D_IDX", &idx, err) != 0) {
                snprintf(err->msg + strlen(err->msg), sizeof err->msg - strlen(err->msg),
                         " (TRACK[] holds IMAGE_ID POINT2D_IDX pairs)");
                rc = -1;
            }
            pt->track++;
        }
        if (rc == 0) m->npoints++;
    }
    free(c.text);
    if (rc != 0) return -1;
    if (m->npoints > 1) qsort(m->points, (size_t)m->npoints, sizeof *m->points, cmp_point); /* NULL when empty */
    for (int i = 1; i < m->npoints; i++)
        if (m->points[i].id == m->points[i - 1].id)
            return rs_err_set(err, RS_ERR_INPUT, path, m->points[i].line,
                              "POINT3D_ID %ld is listed twice (also on line %ld): expected unique ids", m->points[i].id,
                              m->points[i - 1].line);
    return 0;
}

/* One image's header line (IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME). */
static int image_header(rs_ctext *c, const rs_colmap_model *m, rs_colmap_image *im, rs_err *err)
{
    static const char *const qn[4] = {"QW", "QX", "QY", "QZ"};
    if (rs_ctext_long(c, "IMAGE_ID", &im->id, err) != 0) return -1;
    for (int k = 0; k < 4; k++)
        if (rs_ctext_real(c, qn[k], &im->q[k], err) != 0) return -1;
    if (rs_ctext_real(c, "TX", &im->t.x, err) != 0 || rs_ctext_real(c, "TY", &im->t.y, err) != 0 ||
        rs_ctext_real(c, "TZ", &im->t.z, err) != 0 || rs_ctext_long(c, "CAMERA_ID", &im->camera_id, err) != 0)
        return -1;
    if (im->id < 0 || im->id > UINT32_MAX || im->camera_id < 0 || im->camera_id > UINT32_MAX)
        return rs_err_set(err, RS_ERR_INPUT, c->path, c->line,
                          "IMAGE_ID %ld, CAMERA_ID %ld: expected ids from 0 to 4294967295", im->id, im->camera_id);
    if (rs_ctext_name(c, "NAME", im->name, sizeof im->name, err) != 0) return -1;
    if (rs_ctext_end(c, "NAME", err) != 0) return -1;
    double qq = im->q[0] * im->q[0] + im->q[1] * im->q[1] + im->q[2] * im->q[2] + im->q[3] * im->q[3];
    /* COLMAP writes unit quaternions to 17 digits; a far-off norm means a broken or hand-made file. */
    if (fabs(sqrt(qq) - 1) > 1e-3)
        return rs_err_set(err, RS_ERR_INPUT, c->path, c->line,
                          "QW QX QY QZ = %g %g %g %g has norm %g: expected a unit "
                          "quaternion (world -> camera rotation)",
                          im->q[0], im->q[1], im->q[2], im->q[3], sqrt(qq));
    for (int k = 0; k < 4; k++) im->q[k] /= sqrt(qq);
    int known = 0;
    for (int k = 0; k < m->ncameras; k++) known |= m->cameras[k].id == im->camera_id;
    if (!known)
        return rs_err_set(err, RS_ERR_INPUT, c->path, c->line,
                          "field 9 (CAMERA_ID) = %ld: expected a camera of "
                          "cameras.txt",
                          im->camera_id);
    rs_m3_from_quat(im->q[0], im->q[1], im->q[2], im->q[3],
                    im->rot_cam_world); /* COLMAP's QuaternionToRotationMatrix */
    im->centre = rs_v3_scale(rs_m3_mul_vt(im->rot_cam_world, im->t), -1);
    return 0;
}

/* One image's 2D point line: POINTS2D[] as (X, Y, POINT3D_ID). */
static int image_points(rs_ctext *c, const rs_colmap_model *m, rs_colmap_image *im, rs_err *err)
{
    while (rs_ctext_more(c)) {
        double x, y;
        long id;
        if (rs_ctext_real(c, "POINTS2D X", &x, err) != 0 || rs_ctext_real(c, "POINTS2D Y", &y, err) != 0 ||
            rs_ctext_long(c, "POINT3D_ID", &id, err) != 0) {
            snprintf(err->msg + strlen(err->msg), sizeof err->msg - strlen(err->msg),
                     " (the line after an image holds X Y POINT3D_ID triples)");
            return -1;
        }
        im->points2d++;
        if (id == -1) continue;
        if (!rs_colmap_find_point(m, id))
            return rs_err_set(err, RS_ERR_INPUT, c->path, c->line,
                              "field %d (POINT3D_ID) = %ld: expected -1 or a "
                              "point of points3D.txt (image %s)",
                              c->field, id, im->name);
        im->points2d_with_3d++;
    }
    return 0;
}

static int read_images(const char *path, rs_colmap_model *m, rs_err *err)
{
    rs_ctext c;
    if (rs_ctext_open(&c, path, err) != 0) return -1;
    int cap = 0, rc = 0;
    while (rc == 0 && rs_ctext_next_line(&c)) {
        if (rs_ctext_blank(&c)) continue;
        if (m->nimages == cap) {
            cap = cap ? 2 * cap : 16;
            void *p = realloc(m->images, (size_t)cap * sizeof *m->images);
            if (!p) {
                rc = rs_err_set(err, RS_ERR_SYSTEM, path, c.line, "out of memory");
                break;
            }
            m->images = p;
        }
        rs_colmap_image *im = &m->images[m->nimages];
        memset(im, 0, sizeof *im);
        im->line = c.line;
        if (image_header(&c, m, im, err) != 0)
            rc = -1;
        else if (image_by_id(m, im->id))
            rc = rs_err_set(err, RS_ERR_INPUT, path, c.line,
                            "IMAGE_ID %ld is listed twice (also on line %ld): "
                            "expected unique ids",
                            im->id, image_by_id(m, im->id)->line);
        else if (rs_colmap_find_image(m, im->name))
            rc =
                rs_err_set(err, RS_ERR_INPUT, path, c.line, "NAME %s is listed twice: expected unique names", im->name);
        /* As in COLMAP's reader, the line after the header is the 2D points, even when empty. */
        else if (!rs_ctext_next_line(&c))
            rc = rs_err_set(err, RS_ERR_INPUT, path, c.line,
                            "image %s: expected a line of 2D points after it "
                            "(X Y POINT3D_ID triples, possibly empty), found the end of the file",
                            im->name);
        else if (image_points(&c, m, im, err) != 0)
            rc = -1;
        if (rc == 0) m->nimages++;
    }
    free(c.text);
    if (rc == 0 && m->nimages == 0)
        rc = rs_err_set(err, RS_ERR_INPUT, path, 0,
                        "no image: expected `IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME` "
                        "lines, each followed by its 2D points");
    return rc;
}

/* Every track's IMAGE_ID must be an image of images.txt: reread the track of each point. */
static int check_tracks(const char *path, const rs_colmap_model *m, rs_err *err)
{
    rs_ctext c;
    if (rs_ctext_open(&c, path, err) != 0) return -1;
    int rc = 0;
    while (rc == 0 && rs_ctext_next_line(&c)) {
        if (rs_ctext_blank(&c)) continue;
        char tok[64];
        for (int k = 0; k < 8; k++) rs_ctext_token(&c, tok, sizeof tok);
        long id, idx;
        while (rc == 0 && rs_ctext_token(&c, tok, sizeof tok)) {
            id = strtol(tok, NULL, 10);
            rs_ctext_token(&c, tok, sizeof tok);
            idx = strtol(tok, NULL, 10);
            const rs_colmap_image *im = image_by_id(m, id);
            if (!im)
                rc = rs_err_set(err, RS_ERR_INPUT, path, c.line,
                                "field %d (TRACK IMAGE_ID) = %ld: expected an "
                                "image of images.txt",
                                c.field - 1, id);
            else if (idx < 0 || idx >= im->points2d)
                rc = rs_err_set(err, RS_ERR_INPUT, path, c.line,
                                "field %d (TRACK POINT2D_IDX) = %ld: image %ld (%s) "
                                "has %d 2D points: expected 0 to %d",
                                c.field, idx, id, im->name, im->points2d, im->points2d - 1);
        }
    }
    free(c.text);
    return rc;
}

int rs_colmap_read(const char *dir, rs_colmap_model *m, rs_err *err)
{
    char cams[4096], imgs[4096], pts[4096];
    memset(m, 0, sizeof *m);
    snprintf(cams, sizeof cams, "%s/cameras.txt", dir);
    snprintf(imgs, sizeof imgs, "%s/images.txt", dir);
    snprintf(pts, sizeof pts, "%s/points3D.txt", dir);
    if (read_cameras(cams, m, err) != 0 || read_points(pts, m, err) != 0 || read_images(imgs, m, err) != 0 ||
        check_tracks(pts, m, err) != 0) {
        rs_colmap_release(m);
        return -1;
    }
    return 0;
}

void rs_colmap_release(rs_colmap_model *m)
{
    if (!m) return;
    free(m->cameras);
    free(m->images);
    free(m->points);
    memset(m, 0, sizeof *m);
}
