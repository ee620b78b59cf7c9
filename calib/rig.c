/* rig: rig files and lens models (see rig.h). The projection is written out here rather than
 * called through OpenCV so that it can stop at the edge of the usable field of view, per pixel,
 * which cv::projectPoints does not do. */
#include "calib/rig.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/image.h"

/* Radial derivative of the distorted radius: pinhole d/dr [r (1 + k1 r^2 + k2 r^4 + k3 r^6)],
 * fisheye d/dtheta [theta (1 + k1 theta^2 + ... + k4 theta^8)]. */
static double radial_slope(const rs_rig_camera *c, double r)
{
    double r2 = r * r;
    if (c->model == RS_LENS_PINHOLE)
        return 1 + 3 * c->dist[0] * r2 + 5 * c->dist[1] * r2 * r2 + 7 * c->dist[4] * r2 * r2 * r2;
    return 1 + 3 * c->dist[0] * r2 + 5 * c->dist[1] * r2 * r2 + 7 * c->dist[2] * r2 * r2 * r2 +
        9 * c->dist[3] * r2 * r2 * r2 * r2;
}

/* The largest field (tan of the angle, or the angle for fisheye) up to which the radial model
 * is one-to-one, with a 2 % margin; pinhole also stops at 80 degrees off the axis. */
static double usable_field(const rs_rig_camera *c)
{
    double limit = c->model == RS_LENS_PINHOLE ? tan(80 * M_PI / 180) : M_PI;
    const int steps = 20000;
    for (int k = 1; k <= steps; k++) {
        double r = limit * k / steps;
        if (radial_slope(c, r) <= 0.05) return 0.98 * limit * (k - 1) / steps;
    }
    return limit;
}

static int rotation_ok(const double r[9])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double d = r[i] * r[j] + r[3 + i] * r[3 + j] + r[6 + i] * r[6 + j];
            if (fabs(d - (i == j)) > 1e-4) return 0;
        }
    double det =
        r[0] * (r[4] * r[8] - r[5] * r[7]) - r[1] * (r[3] * r[8] - r[5] * r[6]) + r[2] * (r[3] * r[7] - r[4] * r[6]);
    return fabs(det - 1) < 1e-4;
}

/* Documented ranges of a rig file's values (rig.h). */
#define RIG_MAX_SIDE_PX    65536
#define RIG_MIN_FOCAL_PX   1.0 /* fewer pixels per radian than one is no camera */
#define RIG_MAX_FOCAL_PX   1e7
#define RIG_MAX_DISTORTION 1000.0
#define RIG_MAX_OFFSET_M   100.0

static int all_finite(const double *v, int n)
{
    for (int i = 0; i < n; i++)
        if (!isfinite(v[i])) return 0;
    return 1;
}

/* image_width or image_height: an integer from 1 to RIG_MAX_SIDE_PX, checked before any size
 * is computed from it. */
static int check_side(const char *path, int i, const rs_cv_camera *in, const char *key, double v, int has, rs_err *err)
{
    if (!has)
        return rs_err_set(err, RS_ERR_INPUT, path, 0, "camera %d (%s): %s is missing: expected the image size in px", i,
                          in->name, key);
    if (has != 1 || !(v >= 1 && v <= RIG_MAX_SIDE_PX && v == floor(v)))
        return rs_err_set(err, RS_ERR_INPUT, path, 0,
                          "camera %d (%s): %s = %s%.17g: expected an integer from 1 to %d (px)", i, in->name, key,
                          has != 1 ? "(not a number) " : "", v, RIG_MAX_SIDE_PX);
    return 0;
}

static int check_matrix(const char *path, int i, const rs_cv_camera *in, rs_err *err)
{
#define BAD(...) rs_err_set(err, RS_ERR_INPUT, path, 0, __VA_ARGS__)
    const double *k = in->camera_matrix;
    if (!in->has_matrix) return BAD("camera %d (%s): camera_matrix is missing (3 x 3)", i, in->name);
    for (int j = 0; j < 9; j++)
        if (!isfinite(k[j]))
            return BAD("camera %d (%s): camera_matrix entry %d (row %d, column %d) is %g: expected finite numbers", i,
                       in->name, j, j / 3 + 1, j % 3 + 1, k[j]);
    if (!(k[0] > 0 && k[4] > 0) || k[1] != 0 || k[3] != 0 || k[6] != 0 || k[7] != 0 || k[8] != 1)
        return BAD("camera %d (%s): camera_matrix [%g %g %g; %g %g %g; %g %g %g]: expected "
                   "[fx 0 cx; 0 fy cy; 0 0 1] with fx, fy > 0",
                   i, in->name, k[0], k[1], k[2], k[3], k[4], k[5], k[6], k[7], k[8]);
    if (k[0] < RIG_MIN_FOCAL_PX || k[4] < RIG_MIN_FOCAL_PX || k[0] > RIG_MAX_FOCAL_PX || k[4] > RIG_MAX_FOCAL_PX)
        return BAD("camera %d (%s): camera_matrix fx = %g, fy = %g: expected focal lengths from %g to %g px", i,
                   in->name, k[0], k[4], RIG_MIN_FOCAL_PX, RIG_MAX_FOCAL_PX);
    if (!(k[2] >= 0 && k[2] <= in->width && k[5] >= 0 && k[5] <= in->height))
        return BAD("camera %d (%s): camera_matrix principal point (cx, cy) = (%g, %g): expected it inside the "
                   "%.0f x %.0f image (0 <= cx <= image_width, 0 <= cy <= image_height, px)",
                   i, in->name, k[2], k[5], in->width, in->height);
    return 0;
#undef BAD
}

#define RIG_MIN_GAIN 1e-3
#define RIG_MAX_GAIN 1e3

double rs_rig_vignetting(const rs_rig_camera *c, double x, double y)
{
    double u = (x - c->cx) / c->fx, v = (y - c->cy) / c->fy, r2 = u * u + v * v;
    return 1 + r2 * (c->vignetting[0] + r2 * (c->vignetting[1] + r2 * c->vignetting[2]));
}

/* gain and vignetting (the mask is a file: rs_rig_load reads it). c's geometry is set. */
static int check_photometry(const char *path, int i, const rs_cv_camera *in, rs_rig_camera *c, rs_err *err)
{
#define BAD(...) rs_err_set(err, RS_ERR_INPUT, path, 0, __VA_ARGS__)
    if (in->has_gain == 2) return BAD("camera %d (%s): gain is not a number: expected observed / true", i, in->name);
    if (in->has_gain == 1 && !(in->gain >= RIG_MIN_GAIN && in->gain <= RIG_MAX_GAIN))
        return BAD("camera %d (%s): gain = %g: expected a number from %g to %g (observed / true)", i, in->name,
                   in->gain, RIG_MIN_GAIN, RIG_MAX_GAIN);
    c->gain = in->has_gain == 1 ? in->gain : 0;
    if (in->vignetting_count != 0 && in->vignetting_count != 3)
        return BAD("camera %d (%s): vignetting has %d entries: expected 3 (a1 a2 a3 of 1 + a1 r^2 + a2 r^4 + a3 r^6)",
                   i, in->name, in->vignetting_count);
    for (int j = 0; j < in->vignetting_count; j++) {
        if (!(fabs(in->vignetting[j]) <= RIG_MAX_DISTORTION))
            return BAD("camera %d (%s): vignetting entry %d is %g: expected a finite number from %g to %g", i, in->name,
                       j, in->vignetting[j], -RIG_MAX_DISTORTION, RIG_MAX_DISTORTION);
        c->vignetting[j] = in->vignetting[j];
    }
    /* The falloff along the longest radius in the image: a polynomial that turns negative or
     * grows past 2 there is a typo, not a lens. */
    double rx = fmax(c->cx, c->width - c->cx), ry = fmax(c->cy, c->height - c->cy);
    for (int k = 0; k <= 256; k++) {
        double v = rs_rig_vignetting(c, c->cx + rx * k / 256, c->cy + ry * k / 256);
        if (!(v >= 0.05 && v <= 2))
            return BAD("camera %d (%s): vignetting [%g %g %g] gives a falloff of %g at %.0f %% of the way to the "
                       "image corner: expected 0.05 to 2",
                       i, in->name, c->vignetting[0], c->vignetting[1], c->vignetting[2], v, 100.0 * k / 256);
    }
#undef BAD
    return 0;
}

static int check_camera(const char *path, int i, const rs_cv_camera *in, rs_rig_camera *c, rs_err *err)
{
    memset(c, 0, sizeof *c);
    snprintf(c->name, sizeof c->name, "%s", in->name);
#define BAD(...) rs_err_set(err, RS_ERR_INPUT, path, 0, __VA_ARGS__)
    if (check_side(path, i, in, "image_width", in->width, in->has_width, err) != 0 ||
        check_side(path, i, in, "image_height", in->height, in->has_height, err) != 0)
        return -1;
    if (strcmp(in->model, "pinhole") == 0)
        c->model = RS_LENS_PINHOLE;
    else if (strcmp(in->model, "fisheye") == 0)
        c->model = RS_LENS_FISHEYE;
    else
        return BAD("camera %d (%s): model \"%s\": expected pinhole or fisheye", i, in->name, in->model);
    if (check_matrix(path, i, in, err) != 0) return -1;
    const double *k = in->camera_matrix;
    int want = c->model == RS_LENS_PINHOLE ? 5 : 4;
    if (in->distortion_count != want && !(c->model == RS_LENS_PINHOLE && in->distortion_count == 4))
        return BAD("camera %d (%s): distortion_coefficients has %d entries: expected %s", i, in->name,
                   in->distortion_count, want == 5 ? "5 (k1 k2 p1 p2 k3)" : "4 (k1 k2 k3 k4)");
    for (int j = 0; j < in->distortion_count; j++)
        if (!(fabs(in->distortion[j]) <= RIG_MAX_DISTORTION))
            return BAD("camera %d (%s): distortion_coefficients entry %d is %g: expected a finite number from %g to %g",
                       i, in->name, j, in->distortion[j], -RIG_MAX_DISTORTION, RIG_MAX_DISTORTION);
    if (!in->has_rotation) return BAD("camera %d (%s): R_rig_cam is missing (3 x 3)", i, in->name);
    if (!all_finite(in->r_rig_cam, 9))
        return BAD("camera %d (%s): R_rig_cam holds a value that is not finite: expected a rotation", i, in->name);
    if (!rotation_ok(in->r_rig_cam))
        return BAD("camera %d (%s): R_rig_cam is not a rotation (orthonormal, det +1)", i, in->name);
    if (!in->has_translation) return BAD("camera %d (%s): t_rig_cam is missing (3 x 1, metres)", i, in->name);
    for (int j = 0; j < 3; j++)
        if (!(fabs(in->t_rig_cam[j]) <= RIG_MAX_OFFSET_M))
            return BAD("camera %d (%s): t_rig_cam entry %d is %g: expected a finite offset from the rig centre of at "
                       "most %g m",
                       i, in->name, j, in->t_rig_cam[j], RIG_MAX_OFFSET_M);
    c->width = (int)in->width;
    c->height = (int)in->height;
    c->fx = k[0];
    c->fy = k[4];
    c->cx = k[2];
    c->cy = k[5];
    for (int j = 0; j < in->distortion_count && j < 5; j++) c->dist[j] = in->distortion[j];
    memcpy(c->r_rig_cam, in->r_rig_cam, sizeof c->r_rig_cam);
    c->t_rig_cam = rs_v3_make(in->t_rig_cam[0], in->t_rig_cam[1], in->t_rig_cam[2]);
    c->max_field = usable_field(c);
    if (!(c->max_field > 0))
        return BAD("camera %d (%s): distortion_coefficients fold the image back at its centre: expected a lens "
                   "model that is one-to-one near the axis",
                   i, in->name);
#undef BAD
    return check_photometry(path, i, in, c, err);
}

int rs_rig_check(const char *path, const rs_cv_camera *cams, int n, int declared, rs_rig *rig, rs_err *err)
{
    memset(rig, 0, sizeof *rig);
    if (n <= 0)
        return rs_err_set(err, RS_ERR_INPUT, path, 0,
                          "the rig lists no cameras: expected at least one under `cameras`");
    if (declared >= 0 && declared != n)
        return rs_err_set(err, RS_ERR_INPUT, path, 0, "camera_count is %d but %d cameras are listed", declared, n);
    rig->cams = calloc((size_t)n, sizeof *rig->cams);
    if (!rig->cams) return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
    rig->count = n;
    for (int i = 0; i < n; i++)
        if (check_camera(path, i, &cams[i], &rig->cams[i], err) != 0) {
            rs_rig_release(rig);
            return -1;
        }
    return 0;
}

/* Camera i's valid_mask, named relative to the rig file's folder: any image of the camera's
 * size, a pixel valid where its first channel is above 0. */
static int load_mask(const char *rig_path, int i, const char *name, rs_rig_camera *c, rs_err *err)
{
    char path[4096];
    const char *slash = strrchr(rig_path, '/');
    if (name[0] == '/' || !slash)
        snprintf(path, sizeof path, "%s", name);
    else
        snprintf(path, sizeof path, "%.*s/%s", (int)(slash - rig_path), rig_path, name);
    rs_image *img = rs_image_read(path, err);
    if (!img) {
        char why[sizeof err->msg];
        snprintf(why, sizeof why, "%s", err->msg);
        return rs_err_set(err, err->kind, rig_path, 0, "camera %d (%s): valid_mask %s: %s", i, c->name, path, why);
    }
    if (img->width != c->width || img->height != c->height) {
        rs_err_set(err, RS_ERR_INPUT, rig_path, 0, "camera %d (%s): valid_mask %s is %d x %d: expected %d x %d", i,
                   c->name, path, img->width, img->height, c->width, c->height);
        rs_image_free(img);
        return -1;
    }
    c->mask = malloc((size_t)c->width * c->height);
    if (!c->mask) {
        rs_image_free(img);
        return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
    }
    for (int y = 0; y < c->height; y++)
        for (int x = 0; x < c->width; x++) c->mask[(size_t)y * c->width + x] = rs_image_px(img, x, y)[0] > 0;
    rs_image_free(img);
    return 0;
}

int rs_rig_load(const char *path, rs_rig *rig, rs_err *err)
{
    memset(rig, 0, sizeof *rig);
    FILE *f = fopen(path, "r");
    if (!f) return rs_err_errno(err, path, "cannot open the rig file");
    fclose(f);
    rs_cv_camera *cams = NULL;
    int n = 0, declared = -1;
    long line = 0;
    char msg[512];
    if (rs_cv_rig_read(path, &cams, &n, &declared, &line, msg, sizeof msg) != 0)
        return rs_err_set(err, RS_ERR_INPUT, path, line, "%s", msg);
    int rc = rs_rig_check(path, cams, n, declared, rig, err);
    for (int i = 0; rc == 0 && i < n; i++)
        if (cams[i].valid_mask[0]) rc = load_mask(path, i, cams[i].valid_mask, &rig->cams[i], err);
    if (rc != 0) rs_rig_release(rig);
    rs_cv_free(cams);
    return rc;
}

void rs_rig_release(rs_rig *rig)
{
    for (int i = 0; i < rig->count; i++) free(rig->cams[i].mask);
    free(rig->cams);
    rig->cams = NULL;
    rig->count = 0;
}

/* Normalised, distorted image coordinates of the ideal point (a, b) = (x/z, y/z) (pinhole) or
 * of the direction (fisheye, a and b its x and y with the angle theta off the axis). */
static void distort(const rs_rig_camera *c, double a, double b, double theta, double *xd, double *yd)
{
    const double *k = c->dist;
    if (c->model == RS_LENS_PINHOLE) {
        double r2 = a * a + b * b;
        double radial = 1 + k[0] * r2 + k[1] * r2 * r2 + k[4] * r2 * r2 * r2;
        *xd = a * radial + 2 * k[2] * a * b + k[3] * (r2 + 2 * a * a);
        *yd = b * radial + k[2] * (r2 + 2 * b * b) + 2 * k[3] * a * b;
    } else {
        double t2 = theta * theta;
        double td = theta * (1 + k[0] * t2 + k[1] * t2 * t2 + k[2] * t2 * t2 * t2 + k[3] * t2 * t2 * t2 * t2);
        double r = sqrt(a * a + b * b);
        double s = r > 1e-12 ? td / r : 1;
        *xd = a * s;
        *yd = b * s;
    }
}

int rs_rig_project(const rs_rig_camera *c, rs_v3 d, double *x, double *y, double *margin_px)
{
    double field, a, b, theta = 0;
    int in_field;
    if (c->model == RS_LENS_PINHOLE) {
        if (!(d.z > 0)) {
            *x = *y = NAN;
            if (margin_px) *margin_px = 0;
            return 0;
        }
        a = d.x / d.z;
        b = d.y / d.z;
        field = sqrt(a * a + b * b);
    } else {
        double r = sqrt(d.x * d.x + d.y * d.y);
        theta = atan2(r, d.z);
        a = d.x;
        b = d.y;
        field = theta;
    }
    in_field = field < c->max_field;
    double xd, yd;
    distort(c, a, b, theta, &xd, &yd);
    *x = c->fx * xd + c->cx;
    *y = c->fy * yd + c->cy;
    double edge = fmin(fmin(*x, c->width - 1 - *x), fmin(*y, c->height - 1 - *y));
    /* Distance to the field limit in pixels, through the local radial scale. */
    double f = 0.5 * (c->fx + c->fy);
    double field_px = (c->max_field - field) * f * fmax(radial_slope(c, field), 0.05);
    if (margin_px) *margin_px = fmin(edge, field_px);
    return in_field && edge >= 0;
}

int rs_rig_unproject(const rs_rig_camera *c, double x, double y, rs_v3 *d_cam)
{
    double xd = (x - c->cx) / c->fx, yd = (y - c->cy) / c->fy;
    /* Newton on (a, b) for the pinhole model (numeric Jacobian, the model is smooth); on theta
     * alone for the fisheye model, whose distortion is purely radial. */
    if (c->model == RS_LENS_PINHOLE) {
        double a = xd, b = yd;
        for (int it = 0; it < 50; it++) {
            double fx, fy, ax, ay, bx, by, h = 1e-7;
            distort(c, a, b, 0, &fx, &fy);
            distort(c, a + h, b, 0, &ax, &ay);
            distort(c, a, b + h, 0, &bx, &by);
            double j00 = (ax - fx) / h, j10 = (ay - fy) / h, j01 = (bx - fx) / h, j11 = (by - fy) / h;
            double det = j00 * j11 - j01 * j10;
            if (fabs(det) < 1e-12) return 0;
            double ex = fx - xd, ey = fy - yd;
            a -= (j11 * ex - j01 * ey) / det;
            b -= (-j10 * ex + j00 * ey) / det;
            if (fabs(ex) + fabs(ey) < 1e-14) break;
        }
        double px, py;
        distort(c, a, b, 0, &px, &py);
        /* Written so that a NaN from a diverged Newton step fails too. */
        if (!(fabs(px - xd) + fabs(py - yd) <= 1e-9) || !(sqrt(a * a + b * b) < c->max_field)) return 0;
        *d_cam = rs_v3_norm(rs_v3_make(a, b, 1));
        return 1;
    }
    double rd = sqrt(xd * xd + yd * yd), th = rd;
    const double *k = c->dist;
    for (int it = 0; it < 50; it++) {
        double t2 = th * th;
        double g = th * (1 + k[0] * t2 + k[1] * t2 * t2 + k[2] * t2 * t2 * t2 + k[3] * t2 * t2 * t2 * t2) - rd;
        double s = radial_slope(c, th);
        if (s <= 0) return 0;
        th -= g / s;
        if (fabs(g) < 1e-14) break;
    }
    if (!(th >= 0 && th < c->max_field)) return 0;
    double st = sin(th);
    *d_cam = rd > 1e-15 ? rs_v3_make(st * xd / rd, st * yd / rd, cos(th)) : rs_v3_make(0, 0, 1);
    return 1;
}
