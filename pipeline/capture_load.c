/* capture_load: loading a posed panorama from a config section (see capture_load.h); an E57
 * file's spherical image through pipeline/capture_e57.h. */
#include "pipeline/capture_load.h"

#include <string.h>
#include "pipeline/calib_files.h"
#include "pipeline/capture_e57.h"
#include "pipeline/panorama.h"

int rs_capture_load(const rs_config *cfg, const char *section, rs_capture *cap, rs_err *err)
{
    memset(cap, 0, sizeof *cap);
    int found = rs_capture_panorama_path(cfg, section, cap->path, sizeof cap->path, err);
    if (found < 0) return -1;
    if (!found)
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[%s] panorama is not set: expected an equirectangular EXR or HDR file", section);
    int posed = 0, e57 = rs_capture_is_e57(cap->path);
    size_t clipped = 0;
    if (e57 && rs_capture_load_e57(cfg, section, cap, &posed, &clipped, err) != 0) return -1;
    rs_image *img = e57 ? cap->pano : rs_image_read(cap->path, err);
    cap->pano = NULL; /* set again below, once checked */
    if (!img) return -1;
    if (img->width != 2 * img->height) {
        rs_err_set(err, RS_ERR_INPUT, cap->path, 0,
                   "panorama is %d x %d: expected an equirectangular image with width = 2 x height", img->width,
                   img->height);
        rs_image_free(img);
        return -1;
    }
    if (img->channels == 1) {
        rs_image *rgb = rs_image_new(img->width, img->height, 3);
        if (!rgb) {
            rs_image_free(img);
            return rs_err_set(err, RS_ERR_SYSTEM, cap->path, 0, "out of memory");
        }
        for (size_t k = 0; k < (size_t)img->width * img->height; k++)
            rgb->data[3 * k] = rgb->data[3 * k + 1] = rgb->data[3 * k + 2] = img->data[k];
        rs_image_free(img);
        img = rgb;
    }
    cap->pano = img;
    for (size_t k = 0; k < (size_t)img->width * img->height; k++) {
        const float *px = img->data + 3 * k;
        if (!(isfinite(px[0]) && isfinite(px[1]) && isfinite(px[2])))
            cap->nonfinite++;
        else if (px[0] < 0 || px[1] < 0 || px[2] < 0)
            cap->negative++;
    }
    /* With [capture] correspondences or colmap_panorama, the pose the calib stage solved is the
     * capture's pose (position and rotation only seeded it, so position is not required then).
     * Only capture sections have those keys: [sky] panorama is posed by its position and rotation. */
    if (rs_calib_pose_solved(cfg, section)) {
        if (rs_calib_pose_apply(cfg, section, &cap->pose, err) != 0) {
            rs_capture_release(cap);
            return -1;
        }
        return 0;
    }
    if (posed) return 0; /* the E57 image's pose */
    double pos[3];
    if (rs_config_reals(cfg, section, "position", pos) != 0) {
        rs_capture_release(cap);
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[%s] position is not set: expected the camera centre as three numbers (m, world frame)",
                          section);
    }
    cap->pose.position = rs_v3_make(pos[0], pos[1], pos[2]);
    rs_config_reals(cfg, section, "rotation", cap->pose.rot);
    return 0;
}
