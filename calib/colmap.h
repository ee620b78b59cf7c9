/* colmap: a COLMAP text model (cameras.txt, images.txt, points3D.txt) read and checked, the
 * views file that ties its images to panoramas, control points, and the similarity (Umeyama) that
 * takes COLMAP's frame to the scan's, so that the model poses rhoscan's captures (docs/COLMAP.md). */
#ifndef RS_COLMAP_H
#define RS_COLMAP_H

#include "common/err.h"
#include "common/pano.h"

typedef struct rs_colmap_camera {
    long id;
    char model[32];    /* COLMAP's name: PINHOLE, SIMPLE_RADIAL, OPENCV, ... */
    int width, height; /* px */
    int nparams;       /* the model's parameter count, checked against the name */
    double params[12]; /* as in cameras.txt (f, cx, cy, distortion; px) */
} rs_colmap_camera;

typedef struct rs_colmap_image {
    long id, camera_id;
    char name[256];
    double q[4];             /* QW QX QY QZ, normalised: rotation world -> camera */
    rs_v3 t;                 /* TX TY TZ: x_cam = R x_world + t, model units */
    double rot_cam_world[9]; /* R of q, row-major: world -> camera */
    rs_v3 centre;            /* camera centre -R^T t, COLMAP world frame, model units */
    int points2d;            /* 2D points listed on the image's second line */
    int points2d_with_3d;    /* of those, the ones with a 3D point (POINT3D_ID != -1) */
    long line;               /* of its first line in images.txt */
} rs_colmap_image;

typedef struct rs_colmap_point {
    long id;
    rs_v3 xyz; /* COLMAP world frame, model units */
    unsigned char rgb[3];
    double error_px; /* mean reprojection error */
    int track;       /* observations (IMAGE_ID, POINT2D_IDX pairs) */
    long line;       /* in points3D.txt */
} rs_colmap_point;

typedef struct rs_colmap_model {
    rs_colmap_camera *cameras;
    rs_colmap_image *images;
    rs_colmap_point *points; /* sorted by id */
    int ncameras, nimages, npoints;
} rs_colmap_model;

/* Reads dir/cameras.txt, dir/images.txt and dir/points3D.txt (COLMAP's model_converter
 * --output_type TXT). Checks the camera models' parameter counts, image and point ids (unique,
 * referenced ones present), quaternions (not zero) and the 2D point and track lists. Errors name
 * the file, the line, the field and what was expected. Release with rs_colmap_release. */
int rs_colmap_read(const char *dir, rs_colmap_model *m, rs_err *err);
void rs_colmap_release(rs_colmap_model *m);

/* Borrowed pointers into m, NULL when absent. */
const rs_colmap_image *rs_colmap_find_image(const rs_colmap_model *m, const char *name);
const rs_colmap_point *rs_colmap_find_point(const rs_colmap_model *m, long id);

/* Parameters of a COLMAP camera model by name (-1 when the model is unknown). */
int rs_colmap_model_params(const char *model);

/* The views file: which COLMAP images are views of which panorama (or rig), and how they sit in
 * it. Text, `#` starts a comment, one view per line:
 *     NAME PANORAMA R00 R01 R02 R10 R11 R12 R20 R21 R22 [TX TY TZ]
 * R: the view camera's frame (COLMAP's: x right, y down, z forward) -> the panorama's local frame,
 * row-major (tools/colmap/cut_views.py writes it); T: the view's centre in the panorama's frame
 * in metres (0 for views cut from the panorama; a rig camera's offset otherwise). */
typedef struct rs_colmap_view {
    char name[256];
    char panorama[64];
    double r_local_cam[9];
    rs_v3 t_local_cam; /* m */
    long line;
} rs_colmap_view;

/* Caller frees *views with free(). Errors: unreadable file, malformed lines (by line), R not a
 * rotation (|R^T R - I| > 1e-6 or det < 0), a name listed twice, no views. */
int rs_colmap_views_read(const char *path, rs_colmap_view **views, int *count, rs_err *err);

/* Control points: where something of the model is in the scan's (world) frame. Text, `#` starts a
 * comment, one point per line:
 *     image NAME X Y Z          the centre of COLMAP image NAME
 *     point ID X Y Z            COLMAP 3D point ID (points3D.txt)
 *     panorama LABEL X Y Z      the centre of a panorama of the views file (mean of its views)
 * X Y Z in metres, world frame. */
typedef enum { RS_COLMAP_CP_IMAGE, RS_COLMAP_CP_POINT, RS_COLMAP_CP_PANORAMA } rs_colmap_cp_kind;

typedef struct rs_colmap_control {
    rs_colmap_cp_kind kind;
    char name[256]; /* image name, point id as written, or panorama label */
    rs_v3 world;    /* m, scan / world frame */
    long line;
} rs_colmap_control;

/* Caller frees *cps with free(). Fewer than 3 points is an error. */
int rs_colmap_controls_read(const char *path, rs_colmap_control **cps, int *count, rs_err *err);

/* The control points' positions in COLMAP's frame (into model_xyz[count]); path names the control
 * file in errors (an image, point or panorama the model does not have, by line). views may be NULL
 * when no control point names a panorama. */
int rs_colmap_controls_locate(const rs_colmap_model *m, const rs_colmap_view *views, int nviews,
                              const rs_colmap_control *cps, int count, const char *path, rs_v3 *model_xyz, rs_err *err);

/* world = scale * rot * model + t. */
typedef struct rs_colmap_similarity {
    double scale;        /* m per model unit */
    double rot[9];       /* COLMAP world -> scan world, row-major */
    rs_v3 t;             /* m */
    double rms_m, max_m; /* residuals |world_i - (s R model_i + t)| over the points */
} rs_colmap_similarity;

/* Least-squares similarity from n >= 3 point pairs (Umeyama 1991, through rs_calib_align), and
 * each point's residual in metres into residual_m[n] (may be NULL). Errors: n < 3, either point
 * set on one line (or coincident). */
int rs_colmap_umeyama(int n, const rs_v3 *model_xyz, const rs_v3 *world, rs_colmap_similarity *sim, double *residual_m,
                      rs_err *err);

/* A panorama's pose in the scan's frame from its registered views: the rotation is the chordal
 * mean of the views' (local -> world), the centre the mean of theirs. */
typedef struct rs_colmap_pano_pose {
    rs_pose pose;            /* local -> world, centre in m */
    int views, views_listed; /* views registered in the model / listed in the views file */
    double spread_deg;       /* largest angle between one view's rotation and the mean */
    double spread_m;         /* largest distance between one view's centre and the mean */
} rs_colmap_pano;

/* Errors: the label has no view in the views file, or none of its views is in the model. */
int rs_colmap_pano_pose(const rs_colmap_model *m, const rs_colmap_view *views, int nviews, const char *label,
                        const rs_colmap_similarity *sim, rs_colmap_pano *out, rs_err *err);

#endif
