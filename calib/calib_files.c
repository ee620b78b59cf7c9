/* calib_files: the calib stage's hand-over files (see calib_files.h). A pose is a text file
 * rather than JSON so that it reads back with sscanf and stays byte-identical between runs. */
#include "calib_files.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fileio.h"
#include "stage.h"

int rs_calib_panorama_path(const rs_config *cfg, const char *section, char *out, size_t n, rs_err *err)
{
    if (strcmp(section, "capture") != 0 || !rs_config_has(cfg, "rig", "file")) return 0;
    if (rs_config_has(cfg, "capture", "panorama"))
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "both [rig] file and [capture] panorama are set: expected one of them (the panorama "
                          "stitched from the rig's frames becomes the capture's panorama)");
    rs_work_path(cfg, RS_CALIB_PANO_FILE, out, n);
    if (!rs_file_exists(out))
        return rs_err_set(err, RS_ERR_INPUT, out, 0,
                          "the stitched panorama is missing: run the calib stage first (rhoscan run, or "
                          "rhoscan-calib CONFIG)");
    return 1;
}

int rs_calib_pose_apply(const rs_config *cfg, const char *section, rs_pose *pose, rs_err *err)
{
    if (!rs_config_has(cfg, section, "correspondences")) return 0;
    if (strcmp(section, "capture") != 0)
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[%s] correspondences: only [capture] can be registered from pairs so far", section);
    char path[4096];
    rs_work_path(cfg, RS_CALIB_POSE_FILE, path, sizeof path);
    if (!rs_file_exists(path))
        return rs_err_set(err, RS_ERR_INPUT, path, 0,
                          "the pose solved from [capture] correspondences is missing: run the calib stage first");
    return rs_calib_pose_read(path, pose, err);
}

int rs_calib_pose_write(const char *path, const rs_pose *pose, rs_err *err)
{
    char text[1024];
    const double *r = pose->rot;
    int k = snprintf(text, sizeof text,
                     "# rhoscan calib: the capture's pose solved from [capture] correspondences\n"
                     "position %.17g %.17g %.17g\n"
                     "rotation %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n",
                     pose->position.x, pose->position.y, pose->position.z, r[0], r[1], r[2], r[3], r[4], r[5],
                     r[6], r[7], r[8]);
    return rs_write_file_atomic(path, text, (size_t)k, err);
}

int rs_calib_pose_read(const char *path, rs_pose *pose, rs_err *err)
{
    char *text = NULL;
    size_t size;
    if (rs_read_file(path, &text, &size, err) != 0) return -1;
    int have_pos = 0, have_rot = 0, rc = 0;
    long lineno = 0;
    for (char *line = text; line && *line && rc == 0;) {
        char *next = strchr(line, '\n');
        if (next) *next++ = 0;
        lineno++;
        double *r = pose->rot;
        double x, y, z;
        if (line[0] == '#' || line[0] == 0) {
        } else if (sscanf(line, "position %lf %lf %lf", &x, &y, &z) == 3) {
            pose->position = rs_v3_make(x, y, z);
            have_pos = 1;
        } else if (sscanf(line, "rotation %lf %lf %lf %lf %lf %lf %lf %lf %lf", &r[0], &r[1], &r[2], &r[3], &r[4],
                          &r[5], &r[6], &r[7], &r[8]) == 9) {
            have_rot = 1;
        } else {
            rc = rs_err_set(err, RS_ERR_INPUT, path, lineno,
                            "\"%.80s\": expected `position X Y Z` or `rotation` and 9 numbers", line);
        }
        line = next;
    }
    free(text);
    if (rc == 0 && !(have_pos && have_rot))
        rc = rs_err_set(err, RS_ERR_INPUT, path, 0, "expected a `position` line and a `rotation` line");
    return rc;
}
