/* edge_pose: [capture] refine_edges in the calib stage (see edge_pose.h). Runs after the pairs
 * and COLMAP steps, so that a pose they solved is the start; alone, the config's pose is. */
#include "stages/calib/edge_pose.h"

#include <stdio.h>
#include <string.h>
#include "pipeline/calib_files.h"
#include "pipeline/panorama.h"
#include "calib/edge_refine.h"
#include "common/fileio.h"
#include "common/log.h"
#include "common/scene.h"

/* An error of the refinement, re-worded to name the config key that asked for it. */
static int keyed_error(const rs_config *cfg, rs_err *err)
{
    char msg[sizeof err->msg];
    snprintf(msg, sizeof msg, "%s", err->msg);
    snprintf(err->msg, sizeof err->msg, "[capture] refine_edges = true: %.*s", (int)sizeof err->msg - 40, msg);
    if (!err->file[0]) rs_err_set_file(err, rs_config_file(cfg));
    return -1;
}

/* The pose to start from: the one solved earlier in this run, else the config's. */
static int start_pose(const rs_config *cfg, rs_pose *pose, rs_err *err)
{
    char path[4096];
    rs_work_path(cfg, RS_CALIB_POSE_FILE, path, sizeof path);
    if ((rs_config_has(cfg, "capture", "correspondences") || rs_config_has(cfg, "capture", "colmap_panorama")) &&
        rs_file_exists(path))
        return rs_calib_pose_read(path, "capture", pose, err);
    if (rs_capture_config_pose(cfg, pose) != 0) /* [capture] position and rotation, or an E57 image's pose */
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[capture] refine_edges = true but [capture] "
                          "position is not set and no pose was solved: expected a rough centre (m, world frame) to "
                          "start from, or [capture] correspondences");
    return 0;
}

int rs_calib_edge_pose_run(const rs_config *cfg, rs_report *rep, rs_err *err)
{
    const char *names[64];
    int nsec = rs_config_sections(cfg, "capture", names, 64);
    for (int i = 0; i < nsec && i < 64; i++)
        if (strcmp(names[i], "capture") != 0 && rs_config_has(cfg, names[i], "refine_edges") &&
            rs_config_bool(cfg, names[i], "refine_edges"))
            return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                              "[%s] refine_edges = true: only [capture] "
                              "can be refined by edges so far",
                              names[i]);
    /* No default: an unset key leaves the section's text, and so the fingerprints, as they were. */
    if (!rs_config_has(cfg, "capture", "refine_edges") || !rs_config_bool(cfg, "capture", "refine_edges")) return 0;
    char mesh_path[4096], pano_path[4096], pose_path[4096];
    rs_mesh *mesh = NULL;
    rs_scene *scene = NULL;
    rs_image *pano = NULL;
    int rc = -1;
    rs_pose start;
    if (start_pose(cfg, &start, err) != 0) return -1;
    rs_work_path(cfg, "mesh.ply", mesh_path, sizeof mesh_path);
    if (!rs_file_exists(mesh_path))
        return rs_err_set(err, RS_ERR_INPUT, mesh_path, 0,
                          "[capture] refine_edges = true needs the model: run the "
                          "mesh stage first (rhoscan run, or rhoscan-mesh CONFIG)");
    int found = rs_capture_panorama_path(cfg, "capture", pano_path, sizeof pano_path, err);
    if (found < 0) return -1;
    if (!found)
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[capture] refine_edges = true but there is no "
                          "panorama: expected [capture] panorama or [rig] file and frames");
    double t0 = rs_now();
    if (!(mesh = rs_mesh_read(mesh_path, NULL, err))) goto out;
    if (!(scene = rs_scene_new(mesh, err))) goto out;
    if (!(pano = rs_image_read(pano_path, err))) goto out;
    rs_edge_refine_opts opts;
    rs_edge_refine_defaults(&opts);
    opts.levels = (int)rs_config_int(cfg, "calib", "edge_levels");
    opts.max_width = (int)rs_config_int(cfg, "calib", "edge_max_width");
    rs_edge_refine_result res;
    if (rs_edge_refine(scene, pano, &start, &opts, &res, err) != 0) {
        if (!err->file[0]) rs_err_set_file(err, pano_path);
        keyed_error(cfg, err);
        goto out;
    }
    double seconds = rs_now() - t0;
    rs_report_time(rep, "edge_refinement", seconds);
    if (rs_calib_pose_write(rs_work_path(cfg, RS_CALIB_POSE_FILE, pose_path, sizeof pose_path), "capture", &res.pose,
                            err) != 0)
        goto out;
    rs_json *o = rs_json_set_obj(rep->metrics, "edge_refinement");
    rs_json_set_str(o, "panorama", pano_path);
    rs_json_set_int(o, "finest_width", res.finest_width);
    rs_json_set_int(o, "levels", opts.levels);
    rs_json_set_int(o, "model_edge_pixels", res.model_edges);
    rs_json_set_int(o, "image_edge_pixels", res.image_edges);
    rs_json_set_num(o, "cost_before", res.cost_before);
    rs_json_set_num(o, "cost_after", res.cost_after);
    rs_json_set_num(o, "median_px_before", res.median_px_before);
    rs_json_set_num(o, "median_px_after", res.median_px_after);
    rs_json_set_int(o, "iterations", res.iterations);
    rs_json_set_num(o, "turn_deg", res.turn_deg);
    rs_json_set_num(o, "shift_m", res.shift_m);
    rs_calib_pose_json(o, &res.pose);
    rs_log_info("calib: edges refined the pose by %.3f deg and %.3f m in %d iterations (%.1f s): median chamfer "
                "%.2f -> %.2f px at %d px wide, %ld model edge pixels",
                res.turn_deg, res.shift_m, res.iterations, seconds, res.median_px_before, res.median_px_after,
                res.finest_width, res.model_edges);
    rc = 0;
out:
    rs_image_free(pano);
    rs_scene_free(scene);
    rs_mesh_free(mesh);
    return rc;
}
