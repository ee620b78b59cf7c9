/* rig: a Ladybug-style camera rig (docs/DESIGN.md, section Rig file) and its lens models: OpenCV's pinhole
 * model with k1 k2 p1 p2 k3 and OpenCV's fisheye model with k1..k4, each used only inside the
 * field of view where it is one-to-one (the radial polynomial folds back at large radii). */
#ifndef RS_RIG_H
#define RS_RIG_H

#include "calib/cv_adapter.h"
#include "common/err.h"
#include "common/vec.h"

typedef enum { RS_LENS_PINHOLE, RS_LENS_FISHEYE } rs_lens_model;

typedef struct rs_rig_camera {
    char name[64];
    int width, height; /* px */
    rs_lens_model model;
    double fx, fy, cx, cy; /* px; pixel centres at integer coordinates (OpenCV) */
    double dist[5];        /* pinhole: k1 k2 p1 p2 k3; fisheye: k1 k2 k3 k4 (dist[4] = 0) */
    double r_rig_cam[9];   /* camera -> rig rotation, row-major */
    rs_v3 t_rig_cam;       /* camera centre in the rig frame, m */
    double max_field;      /* pinhole: largest usable tan of the angle off the axis;
                                  fisheye: largest usable angle off the axis (rad) */
    /* Photometry (docs/DESIGN.md, section Rig file), each optional: */
    double gain;          /* known gain, observed = gain x true; 0 when the stitcher estimates it */
    double vignetting[3]; /* a1 a2 a3: observed = true x (1 + a1 r^2 + a2 r^4 + a3 r^6), r the distance from
                                  the principal point in focal lengths; all 0 without */
    unsigned char *mask;  /* width x height, row 0 on top, 0 where the pixel is not to be used (the rig's
                                  own housing, a lens hood, a dead column); NULL: every pixel valid */
} rs_rig_camera;

typedef struct rs_rig {
    int count;
    rs_rig_camera *cams;
} rs_rig;

/* Reads and checks a rig file (through OpenCV's FileStorage). Errors name the file, the camera
 * and the field, what was found and what was expected: image_width and image_height not integers
 * from 1 to 65536; a camera matrix that is not [fx 0 cx; 0 fy cy; 0 0 1] of finite numbers with
 * 1 <= fx, fy <= 1e7 px and the principal point inside the image (0 <= cx <= width, 0 <= cy <=
 * height); an unknown model; a distortion vector of the wrong length or with an entry that is not
 * finite or beyond +/-1000, or one that folds the image back at its centre; a rotation that is
 * not finite, orthonormal with det +1; a translation not finite or beyond 100 m; a camera_count
 * different from the cameras listed; a gain not a number from 1e-3 to 1e3; vignetting not 3
 * finite coefficients or one that makes the falloff leave 0.05 to 2 inside the image; a
 * valid_mask (relative to the rig file's folder) that cannot be read or is not the camera's
 * size. Release with rs_rig_release. */
int rs_rig_load(const char *path, rs_rig *rig, rs_err *err);
/* The checks of rs_rig_load on cameras already parsed (n of them; declared: camera_count, -1 when
 * the file has none); path names the file in errors. */
int rs_rig_check(const char *path, const rs_cv_camera *cams, int n, int declared, rs_rig *rig, rs_err *err);
void rs_rig_release(rs_rig *rig);

/* The vignetting falloff of camera c at pixel (x, y): observed / true (1 without vignetting). */
double rs_rig_vignetting(const rs_rig_camera *c, double x, double y);

/* Pixel (x, y) of a direction in the camera frame (x right, y down, z forward; need not be unit).
 * Returns 1 when the direction lies inside the lens model's usable field and the pixel inside
 * the image (0 <= x <= width - 1, same for y), else 0 (x, y still set when finite). *margin_px
 * (may be NULL) is the distance in pixels to the nearest edge of that usable region. */
int rs_rig_project(const rs_rig_camera *c, rs_v3 d_cam, double *x, double *y, double *margin_px);

/* The inverse: the unit camera-frame direction of pixel (x, y), by Newton iteration on the
 * distortion. Returns 0 when it does not converge inside the usable field. */
int rs_rig_unproject(const rs_rig_camera *c, double x, double y, rs_v3 *d_cam);

#endif
