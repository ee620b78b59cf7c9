/* cv_adapter: the part of OpenCV 4.6 that calibration uses (FileStorage rig files, image files
 * stb cannot read, Debevec HDR merging), behind plain C types. Every entry catches all C++
 * exceptions and returns -1 with a message; nothing here prints, exits or throws. */
#ifndef RS_CV_ADAPTER_H
#define RS_CV_ADAPTER_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* One camera of a rig file as written (docs/DESIGN.md, section Rig file); validation is the caller's. */
typedef struct rs_cv_camera {
    char name[64];
    char model[32]; /* "pinhole", "fisheye", or what the file says */
    /* image_width and image_height as written (any number, so that a value too large for an int
     * can be named); has_width: 0 missing, 1 a number, 2 present but not a number. */
    double width, height;
    int has_width, has_height;
    int has_matrix, has_rotation, has_translation;
    double camera_matrix[9]; /* row-major */
    double distortion[8];
    int distortion_count; /* entries given (0 when missing) */
    double r_rig_cam[9];  /* camera -> rig, row-major */
    double t_rig_cam[3];  /* camera centre in the rig frame, m */
    /* Photometry, all optional: a known gain (observed = gain x true), the vignetting polynomial's
     * coefficients (a1 a2 a3), and a valid-pixel mask image (its path as written). */
    int has_gain; /* 0 missing, 1 a number, 2 present but not a number */
    double gain;
    int vignetting_count;
    double vignetting[4];
    char valid_mask[1024];
} rs_cv_camera;

/* Reads a FileStorage YAML rig file: camera_count and the cameras sequence. *cams is allocated
 * (free with rs_cv_free); *declared_count is camera_count (-1 when missing; a camera_count that
 * is not an integer from 0 to 2^31 - 1 is an error here, and so is any integer of the file that
 * does not fit 32 bits, which OpenCV would wrap). On error msg tells which field of which camera
 * was wrong and what was expected, and *line its line when known (else 0). */
int rs_cv_rig_read(const char *path, rs_cv_camera **cams, int *count, int *declared_count, long *line, char *msg,
                   size_t msg_size);

/* Reads any image OpenCV decodes (TIFF among others) as float RGB or grey, row 0 on top.
 * Integer images are scaled to [0, 1] (8-bit by 255, 16-bit by 65535) and *integer_bits set to
 * their depth (0 for float files). *data is allocated (free with rs_cv_free). */
int rs_cv_image_read(const char *path, float **data, int *width, int *height, int *channels, int *integer_bits,
                     char *msg, size_t msg_size);

/* Merges count 8-bit RGB exposures (width x height x 3, row 0 on top, same scene) taken with
 * exposure times times_s into linear radiance (float RGB into out, width x height x 3) with
 * OpenCV's CalibrateDebevec response (or the given response: 256 x 3 values, linear
 * exposure per code; NULL to calibrate) and MergeDebevec. The calibrated response goes into
 * response_out when it is not NULL (256 x 3). */
int rs_cv_merge_debevec(const unsigned char *const *images, const float *times_s, int count, int width, int height,
                        const float *response, float *out, float *response_out, char *msg, size_t msg_size);

/* cv::projectPoints (fisheye: cv::fisheye::projectPoints) of n camera-frame points (x y z each)
 * with camera_matrix (3 x 3 row-major) and dist (5 or 4 entries) into pixels (x y each): the
 * reference the C lens models (rig.c) are tested against. */
int rs_cv_project(int fisheye, const double *camera_matrix, const double *dist, int n, const double *points,
                  double *pixels, char *msg, size_t msg_size);

/* Edges of a float image (width x height, row 0 on top; e.g. log luminance) and every pixel's
 * distance to the nearest edge: Gaussian blur (sigma_px; none when 0), Sobel derivatives per
 * pixel, Canny with hysteresis thresholds lo < hi on the gradient magnitude (image units per
 * pixel, L2), then the exact Euclidean distance transform (px) into dist. edges (width x height,
 * 255 on an edge, else 0) and dist are the caller's; *edge_count is the number of edge pixels
 * (with none, dist is left unset). */
int rs_cv_edge_distance(const float *image, int width, int height, double sigma_px, double lo, double hi,
                        unsigned char *edges, float *dist, long *edge_count, char *msg, size_t msg_size);

void rs_cv_free(void *p);

#ifdef __cplusplus
}
#endif

#endif
