/* panorama: which file is a capture's panorama (see panorama.h). */
#include "pipeline/panorama.h"

#include <string.h>
#include "calib/rig.h"
#include "calib/stitch.h"
#include "common/fileio.h"
#include "common/image.h"
#include "pipeline/calib_files.h"
#include "pipeline/capture_e57.h"
#include "pipeline/stage.h"

int rs_capture_panorama_check(const rs_config *cfg, rs_err *err)
{
    if (rs_config_has(cfg, "rig", "file") && rs_config_has(cfg, "capture", "panorama"))
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "both [rig] file and [capture] panorama are set: expected one of them (the panorama "
                          "stitched from the rig's frames becomes the capture's panorama)");
    return 0;
}

int rs_capture_panorama_path(const rs_config *cfg, const char *section, char *out, size_t n, rs_err *err)
{
    if (strcmp(section, "capture") == 0 && rs_config_has(cfg, "rig", "file")) {
        if (rs_capture_panorama_check(cfg, err) != 0) return -1;
        rs_work_path(cfg, RS_CALIB_PANO_FILE, out, n);
        if (!rs_file_exists(out))
            return rs_err_set(err, RS_ERR_INPUT, out, 0,
                              "the stitched panorama is missing: run the calib stage first (rhoscan run, or "
                              "rhoscan-calib CONFIG)");
        return 1;
    }
    return rs_config_path(cfg, section, "panorama", out, n) ? 1 : 0;
}

int rs_capture_panorama_width(const rs_config *cfg, int *width, char *from, size_t n, rs_err *err)
{
    if (rs_capture_panorama_check(cfg, err) != 0) return -1;
    if (rs_config_path(cfg, "capture", "panorama", from, n)) {
        if (rs_capture_is_e57(from)) return rs_capture_e57_width(cfg, "capture", from, width, err) == 0 ? 1 : -1;
        rs_image *img = rs_image_read(from, err);
        if (!img) return -1;
        *width = img->width;
        rs_image_free(img);
        return 1;
    }
    if (rs_config_path(cfg, "rig", "file", from, n)) {
        /* The calib stage stitches the panorama after meshing: its width follows from the rig. */
        rs_rig rig;
        if (rs_rig_load(from, &rig, err) != 0) return -1;
        *width = rs_stitch_width(&rig, (int)rs_config_int(cfg, "rig", "width"));
        rs_rig_release(&rig);
        return 1;
    }
    return 0;
}

int rs_capture_config_pose(const rs_config *cfg, rs_pose *pose)
{
    char path[4096];
    if (rs_config_path(cfg, "capture", "panorama", path, sizeof path) && rs_capture_is_e57(path) &&
        rs_capture_e57_pose(cfg, "capture", path, pose))
        return 0;
    double pos[3];
    if (rs_config_reals(cfg, "capture", "position", pos) != 0) return -1;
    pose->position = rs_v3_make(pos[0], pos[1], pos[2]);
    rs_config_reals(cfg, "capture", "rotation", pose->rot);
    return 0;
}

int rs_capture_position(const rs_config *cfg, double pos[3])
{
    rs_pose pose;
    if (rs_capture_config_pose(cfg, &pose) != 0) return -1;
    pos[0] = pose.position.x, pos[1] = pose.position.y, pos[2] = pose.position.z;
    return 0;
}
