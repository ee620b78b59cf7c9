/* capture_e57: a capture's panorama from an E57 file's images2D (see capture_e57.h). */
#include "pipeline/capture_e57.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "calib/response.h"
#include "calib/rig.h"
#include "calib/stitch.h"
#include "common/e57.h"
#include "common/image_stb.h"
#include "common/log.h"

int rs_capture_is_e57(const char *path)
{
    FILE *fp = fopen(path, "rb");
    char head[8] = {0};
    if (!fp) return 0;
    size_t n = fread(head, 1, sizeof head, fp);
    fclose(fp);
    return n == 8 && memcmp(head, "ASTM-E57", 8) == 0;
}

static const char *projection_name(rs_e57_projection p)
{
    return p == RS_E57_SPHERICAL  ? "spherical"
        : p == RS_E57_PINHOLE     ? "pinhole"
        : p == RS_E57_CYLINDRICAL ? "cylindrical"
                                  : "visual reference";
}

/* The image [section] e57_image names, or the only spherical one. */
static int select_image(const rs_config *cfg, const char *section, rs_e57 *e, const char *path, rs_err *err)
{
    const char *want = rs_config_string(cfg, section, "e57_image");
    int n = rs_e57_image_count(e);
    if (want) {
        int digits = want[0] != 0;
        for (const char *p = want; *p; p++) digits &= isdigit((unsigned char)*p) != 0;
        for (int i = 0; i < n; i++)
            if (strcmp(rs_e57_image(e, i)->name, want) == 0) return i;
        if (digits && atoi(want) < n && strlen(want) < 9) return atoi(want);
        return rs_err_set(err, RS_ERR_INPUT, path, 0,
                          "[%s] e57_image = %s: no images2D entry of that name or index; expected one of its %d "
                          "image%s (by name, or 0 to %d)",
                          section, want, n, n == 1 ? "" : "s", n - 1);
    }
    int found = -1, count = 0;
    for (int i = 0; i < n; i++)
        if (rs_e57_image(e, i)->projection == RS_E57_SPHERICAL) found = i, count++;
    if (count == 1) return found;
    for (int i = 0; i < n && count == 0; i++)
        if (rs_e57_image(e, i)->projection == RS_E57_PINHOLE && rs_e57_image(e, i)->has_pose) return i;
    return rs_err_set(err, RS_ERR_INPUT, path, 0,
                      "[%s] e57_image is not set and the file has %d spherical images (of %d) and no posed pinhole "
                      "images; expected [%s] e57_image = NAME or INDEX",
                      section, count, n, section);
}

/* The selected image, checked to be usable as a capture's panorama (before decoding). */
static const rs_e57_image_info *usable(const rs_e57_image_info *im, int index, const char *path, rs_err *err)
{
    if (im->projection == RS_E57_CYLINDRICAL || im->projection == RS_E57_VISUAL) {
        rs_err_set(err, RS_ERR_INPUT, path, 0,
                   "image %d \"%s\" is a %s image: it cannot be a capture's panorama; expected a spherical image "
                   "(sphericalRepresentation) with a pose",
                   index, im->name, projection_name(im->projection));
        return NULL;
    }
    return im;
}

static int full_sphere(const rs_e57_image_info *im, int index, const char *path, rs_err *err)
{
    double aw = im->pixel_width * im->width, ah = im->pixel_height * im->height;
    if (im->width != 2 * im->height || fabs(aw - 2 * M_PI) > 1e-6 * 2 * M_PI || fabs(ah - M_PI) > 1e-6 * M_PI)
        return rs_err_set(err, RS_ERR_INPUT, path, 0,
                          "image %d \"%s\": %d x %d pixels of %g x %g rad cover %g x %g rad; expected a full sphere "
                          "(2 pi x pi rad, width = 2 x height) as an equirectangular panorama",
                          index, im->name, im->width, im->height, im->pixel_width, im->pixel_height, aw, ah);
    return 0;
}

/* Codes to linear radiance through the response (or sRGB); clipped pixels become NaN. */
static rs_image *linearise(const unsigned char *codes, int w, int h, const float *response, size_t *clipped,
                           const char *path, rs_err *err)
{
    rs_image *img = rs_image_new(w, h, 3);
    if (!img) {
        rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
        return NULL;
    }
    float lut[256 * 3];
    for (int i = 0; i < 256; i++)
        for (int k = 0; k < 3; k++)
            lut[3 * i + k] = response ? response[3 * i + k] : rs_srgb_to_linear((float)i / 255.0f);
    *clipped = 0;
    for (size_t p = 0; p < (size_t)w * (size_t)h; p++) {
        const unsigned char *c = codes + 3 * p;
        int clip = c[0] == 255 || c[1] == 255 || c[2] == 255;
        *clipped += (size_t)clip;
        for (int k = 0; k < 3; k++) img->data[3 * p + k] = clip ? NAN : lut[3 * c[k] + k];
    }
    return img;
}

/* The blob decoded and linearised. */
static rs_image *decode(const rs_config *cfg, const char *section, rs_e57 *e, int index, size_t *clipped,
                        const char *path, rs_err *err)
{
    const rs_e57_image_info *im = rs_e57_image(e, index);
    uint8_t *blob;
    size_t size;
    if (rs_e57_image_blob(e, index, &blob, &size, err) != 0) return NULL;
    char name[4400];
    snprintf(name, sizeof name, "%s, image %d \"%s\"", path, index, im->name);
    int w = 0, h = 0;
    rs_err why = {0};
    unsigned char *codes = rs_image_ldr_codes_mem(blob, size, name, &w, &h, &why);
    free(blob);
    if (!codes) {
        rs_err_set(err, why.kind, path, 0, "image %d \"%s\": its %s blob (%zu bytes) does not decode: %s", index,
                   im->name, im->png ? "PNG" : "JPEG", size, why.msg);
        return NULL;
    }
    if (w != im->width || h != im->height) {
        free(codes);
        rs_err_set(err, RS_ERR_INPUT, path, 0, "image %d \"%s\": the XML says %d x %d, its blob is %d x %d", index,
                   im->name, im->width, im->height, w, h);
        return NULL;
    }
    float response[256 * 3];
    char rpath[4096];
    int have = rs_config_path(cfg, section, "response_file", rpath, sizeof rpath) != NULL;
    if (have && rs_response_read(rpath, response, err) != 0) {
        free(codes);
        return NULL;
    }
    if (!have)
        rs_log_warn("%s: image \"%s\" is 8-bit and [%s] response_file is not set: linearised with the sRGB curve", path,
                    im->name, section);
    rs_image *img = linearise(codes, w, h, have ? response : NULL, clipped, path, err);
    free(codes);
    return img;
}

/* Image i as a rig camera (x right, y down, z forward, as calib/rig.h's; the pose camera to
 * world, its centre relative to centre). */
static int rig_camera(const rs_e57_image_info *im, int i, const double centre[3], rs_cv_camera *c, const char *path,
                      rs_err *err)
{
    memset(c, 0, sizeof *c);
    snprintf(c->name, sizeof c->name, "%.63s", im->name);
    snprintf(c->model, sizeof c->model, "pinhole");
    c->width = im->width, c->height = im->height;
    c->has_width = c->has_height = c->has_matrix = c->has_rotation = c->has_translation = 1;
    double fx = im->pixel_width > 0 ? im->focal_length / im->pixel_width : 0;
    /* ASTM E2807 8.4.13.6: image coordinate (0,0) is the top left corner of the top left pixel, so
     * OpenCV's principal point (pixel centres at integers) is half a pixel less. */
    double fy = im->pixel_height > 0 ? im->focal_length / im->pixel_height : 0, cx = im->principal_x - 0.5,
           cy = im->principal_y - 0.5;
    if (!(fx > 0 && fy > 0) && im->has_distortion) fx = im->fx, fy = im->fy, cx = im->cx, cy = im->cy;
    if (!(fx > 0 && fy > 0))
        return rs_err_set(err, RS_ERR_INPUT, path, 0,
                          "image %d \"%s\": focal length %g m with pixels of %g x %g m; expected a positive focal "
                          "length and pixel size (or the dist: extension's CV_FX, CV_FY)",
                          i, im->name, im->focal_length, im->pixel_width, im->pixel_height);
    if (im->has_distortion && (im->k[3] != 0 || im->k[4] != 0 || im->k[5] != 0))
        return rs_err_set(err, RS_ERR_INPUT, path, 0,
                          "image %d \"%s\": distortion CV_K4..K6 (OpenCV's rational model) are not 0; expected the "
                          "k1 k2 p1 p2 k3 model of the rig's cameras",
                          i, im->name);
    double m[9] = {fx, 0, cx, 0, fy, cy, 0, 0, 1};
    memcpy(c->camera_matrix, m, sizeof m);
    double d[5] = {im->k[0], im->k[1], im->p[0], im->p[1], im->k[2]};
    memcpy(c->distortion, d, sizeof d);
    c->distortion_count = 5;
    /* ASTM E2807 8.4.13.4-5: the E57 camera looks along -z with y up (x_image = cx - f x / z,
     * y_image = cy + f y / z for z < 0); the rig's camera is OpenCV's (x right, y down, z forward):
     * the E57 frame turned 180 degrees about x, i.e. its y and z columns negated. */
    for (int r = 0; r < 3; r++) {
        c->r_rig_cam[3 * r] = im->rotation[3 * r];
        c->r_rig_cam[3 * r + 1] = -im->rotation[3 * r + 1];
        c->r_rig_cam[3 * r + 2] = -im->rotation[3 * r + 2];
    }
    for (int k = 0; k < 3; k++) c->t_rig_cam[k] = im->translation[k] - centre[k];
    return 0;
}

/* The posed pinhole images of the selected one's scan stitched as a rig's frames are (at
 * infinite depth, gains estimated); the rig frame is the world's, centred on the cameras. */
static int stitch_pinholes(const rs_config *cfg, const char *section, rs_e57 *e, int index, rs_capture *cap,
                           size_t *clipped, rs_err *err)
{
    const rs_e57_image_info *sel = rs_e57_image(e, index);
    int n = rs_e57_image_count(e), m = 0, rc = -1;
    int *use = calloc((size_t)n, sizeof *use);
    rs_cv_camera *cams = calloc((size_t)n, sizeof *cams);
    rs_image **frames = calloc((size_t)n, sizeof *frames);
    double *gains = calloc((size_t)n, sizeof *gains), centre[3] = {0, 0, 0};
    rs_rig rig = {0};
    if (!use || !cams || !frames || !gains) {
        rs_err_set(err, RS_ERR_SYSTEM, cap->path, 0, "out of memory");
        goto out;
    }
    for (int i = 0; i < n; i++) {
        const rs_e57_image_info *im = rs_e57_image(e, i);
        if (im->projection != RS_E57_PINHOLE || strcmp(im->associated_scan, sel->associated_scan) != 0) continue;
        use[m++] = i;
        for (int k = 0; k < 3; k++) centre[k] += im->translation[k];
    }
    for (int k = 0; k < 3; k++) centre[k] /= m;
    for (int j = 0; j < m; j++) {
        size_t cl = 0;
        const rs_e57_image_info *im = rs_e57_image(e, use[j]);
        int i = use[j];
        if (!(frames[j] = decode(cfg, section, e, i, &cl, cap->path, err))) goto out;
        if (!im->has_pose) {
            rs_err_set(err, RS_ERR_INPUT, cap->path, 0,
                       "pinhole image %d \"%s\" has no pose; expected every pinhole image to be stitched to have one",
                       i, im->name);
            goto out;
        }
        if (rig_camera(im, i, centre, &cams[j], cap->path, err) != 0) goto out;
        *clipped += cl;
    }
    if (rs_rig_check(cap->path, cams, m, m, &rig, err) != 0) goto out;
    rs_stitch_opts opts = {.width = rs_stitch_default_width(&rig),
                           .feather_px = rs_config_real(cfg, "rig", "feather_px"),
                           .estimate_gain = m > 1};
    rs_stitch_stats stats;
    if (rs_stitch(&rig, frames, &opts, &cap->pano, gains, &stats, err) != 0) goto out;
    rs_log_info("%s: %d pinhole images stitched into a %d x %d panorama (%.1f %% of the sphere seen)", cap->path, m,
                cap->pano->width, cap->pano->height, 100 * stats.coverage);
    rs_gain_report_free(&stats.gain);
    cap->pose.position = rs_v3_make(centre[0], centre[1], centre[2]);
    static const double I[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    memcpy(cap->pose.rot, I, sizeof I);
    rc = 0;
out:
    for (int j = 0; frames && j < m; j++) rs_image_free(frames[j]);
    rs_rig_release(&rig);
    free(use);
    free(cams);
    free(frames);
    free(gains);
    return rc;
}

int rs_capture_load_e57(const rs_config *cfg, const char *section, rs_capture *cap, int *posed, size_t *clipped,
                        rs_err *err)
{
    *posed = 0;
    *clipped = 0;
    rs_e57 *e = rs_e57_open(cap->path, err);
    if (!e) return -1;
    int index = select_image(cfg, section, e, cap->path, err);
    const rs_e57_image_info *im = index < 0 ? NULL : usable(rs_e57_image(e, index), index, cap->path, err);
    if (im && im->projection == RS_E57_PINHOLE) {
        int rc = stitch_pinholes(cfg, section, e, index, cap, clipped, err);
        *posed = rc == 0;
        rs_e57_close(e);
        return rc;
    }
    rs_image *img = im ? decode(cfg, section, e, index, clipped, cap->path, err) : NULL;
    int rc = -1;
    if (img && full_sphere(im, index, cap->path, err) == 0) {
        cap->pano = img;
        img = NULL;
        if (im->has_pose) {
            *posed = 1;
            cap->pose.position = rs_v3_make(im->translation[0], im->translation[1], im->translation[2]);
            memcpy(cap->pose.rot, im->rotation, sizeof cap->pose.rot);
        }
        if (*clipped)
            rs_log_warn("%s: image \"%s\": %zu clipped pixels (a channel at 255) are not used", cap->path, im->name,
                        *clipped);
        rc = 0;
    }
    rs_image_free(img);
    rs_e57_close(e);
    return rc;
}

/* The width rs_stitch_default_width gives the pinhole images stitched with image index: 2 pi
 * times their largest focal length in pixels, even. */
static int stitched_width(rs_e57 *e, int index)
{
    const rs_e57_image_info *sel = rs_e57_image(e, index);
    double f = 0;
    for (int i = 0; i < rs_e57_image_count(e); i++) {
        const rs_e57_image_info *im = rs_e57_image(e, i);
        if (im->projection != RS_E57_PINHOLE || strcmp(im->associated_scan, sel->associated_scan) != 0) continue;
        double fx = im->pixel_width > 0 ? im->focal_length / im->pixel_width : 0;
        double fy = im->pixel_height > 0 ? im->focal_length / im->pixel_height : 0;
        if (!(fx > 0 && fy > 0) && im->has_distortion) fx = im->fx, fy = im->fy;
        if (isfinite(fx) && isfinite(fy)) f = fmax(f, fmax(fx, fy));
    }
    int w = (int)fmin(ceil(2 * M_PI * f), 65536);
    w += w & 1;
    return w < 16 ? 16 : w > 65536 ? 65536 : w;
}

int rs_capture_e57_width(const rs_config *cfg, const char *section, const char *path, int *width, rs_err *err)
{
    rs_e57 *e = rs_e57_open(path, err);
    if (!e) return -1;
    int index = select_image(cfg, section, e, path, err);
    if (index >= 0)
        *width = rs_e57_image(e, index)->projection == RS_E57_PINHOLE ? stitched_width(e, index)
                                                                      : rs_e57_image(e, index)->width;
    rs_e57_close(e);
    return index < 0 ? -1 : 0;
}

int rs_capture_e57_pose(const rs_config *cfg, const char *section, const char *path, rs_pose *pose)
{
    rs_err err = {0};
    rs_e57 *e = rs_e57_open(path, &err);
    if (!e) return 0;
    int index = select_image(cfg, section, e, path, &err), n = 0;
    const rs_e57_image_info *sel = index >= 0 ? rs_e57_image(e, index) : NULL;
    double sum[3] = {0, 0, 0};
    for (int i = 0; sel && i < rs_e57_image_count(e); i++) {
        const rs_e57_image_info *im = rs_e57_image(e, i);
        int same = sel->projection == RS_E57_PINHOLE
            ? im->projection == RS_E57_PINHOLE && strcmp(im->associated_scan, sel->associated_scan) == 0
            : i == index;
        if (!same || !im->has_pose) continue;
        for (int k = 0; k < 3; k++) sum[k] += im->translation[k];
        n++;
    }
    if (n) {
        static const double I[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
        /* a spherical image's own rotation; stitched pinhole images: the world's axes */
        memcpy(pose->rot, sel->projection == RS_E57_PINHOLE ? I : sel->rotation, sizeof pose->rot);
        pose->position = rs_v3_make(sum[0] / n, sum[1] / n, sum[2] / n);
    }
    rs_e57_close(e);
    return n > 0;
}
