/* parallax: the model and the rig's pose for the stitcher's parallax correction (see
 * parallax.h). The mesh stage runs before calib, so mesh.ply is there in a full run. */
#include "stages/calib/parallax.h"

#include <stdio.h>
#include <string.h>
#include "pipeline/calib_files.h"
#include "common/fileio.h"
#include "pipeline/stage.h"

#define MESH_FILE "mesh.ply"

int rs_calib_parallax_wanted(const rs_config *cfg)
{
    char path[4096];
    return rs_config_bool(cfg, "rig", "parallax") && rs_file_exists(rs_work_path(cfg, MESH_FILE, path, sizeof path));
}

int rs_calib_parallax_load(const rs_config *cfg, int pose_solved, rs_parallax_model *m, rs_err *err)
{
    char path[4096];
    memset(m, 0, sizeof *m);
    rs_m3_identity(m->pose.rot);
    if (!rs_config_bool(cfg, "rig", "parallax")) {
        snprintf(m->why, sizeof m->why, "[rig] parallax = false");
        return 0;
    }
    rs_work_path(cfg, MESH_FILE, path, sizeof path);
    if (!rs_file_exists(path)) {
        snprintf(m->why, sizeof m->why, "no %s in the work folder (the mesh stage makes it)", MESH_FILE);
        return 0;
    }
    if (rs_calib_pose_solved(cfg, "capture")) {
        if (!pose_solved) {
            snprintf(m->why, sizeof m->why, "the capture's pose is not solved yet");
            return 0;
        }
        if (rs_calib_pose_apply(cfg, "capture", &m->pose, err) != 0) return -1;
    } else {
        double pos[3];
        if (rs_config_reals(cfg, "capture", "position", pos) != 0) {
            snprintf(m->why, sizeof m->why, "no [capture] position: the rig centre in the model is unknown");
            return 0;
        }
        m->pose.position = rs_v3_make(pos[0], pos[1], pos[2]);
        rs_config_reals(cfg, "capture", "rotation", m->pose.rot);
    }
    m->mesh = rs_mesh_read(path, NULL, err);
    if (!m->mesh) return -1;
    m->scene = rs_scene_new(m->mesh, err);
    if (!m->scene) {
        rs_mesh_free(m->mesh);
        m->mesh = NULL;
        return -1;
    }
    return 1;
}

void rs_calib_parallax_release(rs_parallax_model *m)
{
    rs_scene_free(m->scene);
    rs_mesh_free(m->mesh);
    m->scene = NULL;
    m->mesh = NULL;
}
