/* colmap_poses: the calib stage's [colmap] step (see colmap_poses.h): read the model, the views
 * and the control points, align by Umeyama, report residuals, write the captures' poses. */
#include "stages/calib/colmap_poses.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "pipeline/calib_files.h"
#include "calib/colmap.h"
#include "common/log.h"

#define MAX_CAPTURES 64

/* The captures that name a panorama of the views file; checks each against [colmap]. */
static int posed_captures(const rs_config *cfg, const char **posed, int *nposed, rs_err *err)
{
    const char *sections[MAX_CAPTURES];
    int n = rs_config_sections(cfg, "capture", sections, MAX_CAPTURES);
    *nposed = 0;
    for (int i = 0; i < n; i++) {
        if (!rs_config_has(cfg, sections[i], "colmap_panorama")) continue;
        if (!rs_config_has(cfg, "colmap", "model"))
            return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                              "[%s] colmap_panorama is set but [colmap] "
                              "model is not: expected the folder of a COLMAP text model",
                              sections[i]);
        if (rs_config_has(cfg, sections[i], "correspondences"))
            return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                              "[%s] has both correspondences and "
                              "colmap_panorama: expected one way to solve its pose",
                              sections[i]);
        posed[(*nposed)++] = sections[i];
    }
    return 0;
}

static void push_v3(rs_json *o, const char *key, rs_v3 v)
{
    rs_json *a = rs_json_set_arr(o, key);
    rs_json_push_num(a, v.x);
    rs_json_push_num(a, v.y);
    rs_json_push_num(a, v.z);
}

static void push_m3(rs_json *o, const char *key, const double *m)
{
    rs_json *a = rs_json_set_arr(o, key);
    for (int k = 0; k < 9; k++) rs_json_push_num(a, m[k]);
}

/* The similarity from the control points, each point's residual in the report. */
static int align(const rs_config *cfg, const rs_colmap_model *m, const rs_colmap_view *views, int nviews, rs_json *cj,
                 rs_colmap_similarity *sim, rs_err *err)
{
    static const char *const kinds[] = {"image", "point", "panorama"};
    char path[4096];
    rs_config_path(cfg, "colmap", "control_points", path, sizeof path);
    rs_colmap_control *cps = NULL;
    rs_v3 *model_xyz = NULL, *world = NULL;
    double *resid = NULL;
    int n = 0, rc = -1;
    if (rs_colmap_controls_read(path, &cps, &n, err) != 0) return -1;
    model_xyz = malloc((size_t)n * sizeof *model_xyz);
    world = malloc((size_t)n * sizeof *world);
    resid = malloc((size_t)n * sizeof *resid);
    if (!model_xyz || !world || !resid) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    if (rs_colmap_controls_locate(m, views, nviews, cps, n, path, model_xyz, err) != 0) goto out;
    for (int i = 0; i < n; i++) world[i] = cps[i].world;
    if (rs_colmap_umeyama(n, model_xyz, world, sim, resid, err) != 0) {
        rs_err_set_file(err, path);
        goto out;
    }
    rs_json_set_str(cj, "control_points_file", path);
    rs_json_set_num(cj, "scale_m_per_unit", sim->scale);
    push_m3(cj, "rotation", sim->rot);
    push_v3(cj, "translation_m", sim->t);
    rs_json_set_num(cj, "rms_m", sim->rms_m);
    rs_json_set_num(cj, "max_m", sim->max_m);
    rs_json *arr = rs_json_set_arr(cj, "control_points");
    int worst = 0;
    for (int i = 0; i < n; i++) {
        rs_json *o = rs_json_push_obj(arr);
        rs_json_set_int(o, "line", cps[i].line);
        rs_json_set_str(o, "kind", kinds[cps[i].kind]);
        rs_json_set_str(o, "name", cps[i].name);
        rs_json_set_num(o, "residual_m", resid[i]);
        if (resid[i] > resid[worst]) worst = i;
    }
    rs_log_info("calib: COLMAP model aligned by %d control points: scale %.6g m per unit, residual rms %.4f m, "
                "max %.4f m (%s line %ld)",
                n, sim->scale, sim->rms_m, sim->max_m, path, cps[worst].line);
    double limit = rs_config_real(cfg, "colmap", "max_rms_m");
    if (sim->rms_m > limit) {
        rs_err_set(err, RS_ERR_INPUT, path, cps[worst].line,
                   "the control points fit the COLMAP model with an RMS "
                   "residual of %.4f m: expected at most [colmap] max_rms_m = %g m; the worst is %s %s, %.4f m off",
                   sim->rms_m, limit, kinds[cps[worst].kind], cps[worst].name, resid[worst]);
        goto out;
    }
    rc = 0;
out:
    free(cps);
    free(model_xyz);
    free(world);
    free(resid);
    return rc;
}

int rs_calib_colmap_run(const rs_config *cfg, rs_report *rep, rs_err *err)
{
    const char *posed[MAX_CAPTURES];
    int nposed = 0;
    if (posed_captures(cfg, posed, &nposed, err) != 0) return -1;
    if (!rs_config_has(cfg, "colmap", "model")) return 0;
    if (!rs_config_has(cfg, "colmap", "control_points"))
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[colmap] model is set but control_points is "
                          "not: expected a file of at least 3 control points to place the model in the scan's frame");
    if (nposed && !rs_config_has(cfg, "colmap", "views"))
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[%s] colmap_panorama is set but [colmap] views "
                          "is not: expected the views file (tools/colmap/cut_views.py writes views.txt)",
                          posed[0]);
    char dir[4096], vpath[4096], out[4096];
    rs_config_path(cfg, "colmap", "model", dir, sizeof dir);
    rs_colmap_model m;
    rs_colmap_view *views = NULL;
    int nviews = 0, rc = -1;
    if (rs_colmap_read(dir, &m, err) != 0) return -1;
    if (rs_config_path(cfg, "colmap", "views", vpath, sizeof vpath) &&
        rs_colmap_views_read(vpath, &views, &nviews, err) != 0)
        goto out;
    rs_json *cj = rs_json_set_obj(rep->metrics, "colmap");
    rs_json_set_str(cj, "model", dir);
    rs_json_set_int(cj, "cameras", m.ncameras);
    rs_json_set_int(cj, "images", m.nimages);
    rs_json_set_int(cj, "points", m.npoints);
    rs_colmap_similarity sim;
    if (align(cfg, &m, views, nviews, cj, &sim, err) != 0) goto out;
    rs_json *caps = rs_json_set_obj(cj, "captures");
    rs_work_path(cfg, RS_CALIB_POSE_FILE, out, sizeof out);
    for (int i = 0; i < nposed; i++) {
        const char *label = rs_config_string(cfg, posed[i], "colmap_panorama");
        rs_colmap_pano pp;
        if (rs_colmap_pano_pose(&m, views, nviews, label, &sim, &pp, err) != 0) {
            rs_err_set_file(err, vpath);
            goto out;
        }
        if (rs_calib_pose_write(out, posed[i], &pp.pose, err) != 0) goto out;
        rs_json *o = rs_json_set_obj(caps, posed[i]);
        rs_json_set_str(o, "panorama", label);
        rs_json_set_int(o, "views", pp.views);
        rs_json_set_int(o, "views_listed", pp.views_listed);
        rs_json_set_num(o, "view_spread_deg", pp.spread_deg);
        rs_json_set_num(o, "view_spread_m", pp.spread_m);
        push_v3(o, "position", pp.pose.position);
        push_m3(o, "rotation", pp.pose.rot);
        if (pp.views < pp.views_listed)
            rs_report_skip(rep, "COLMAP views",
                           "[%s]: %d of the %d views of panorama %s are not in the model (the "
                           "mapper did not register them)",
                           posed[i], pp.views_listed - pp.views, pp.views_listed, label);
        rs_log_info("calib: [%s] posed by COLMAP from %d views of %s: centre (%.4f, %.4f, %.4f), views agree within "
                    "%.3f deg and %.4f m",
                    posed[i], pp.views, label, pp.pose.position.x, pp.pose.position.y, pp.pose.position.z,
                    pp.spread_deg, pp.spread_m);
    }
    if (nposed == 0)
        rs_report_skip(rep, "COLMAP poses",
                       "no [capture] section sets colmap_panorama: the model was aligned but "
                       "poses nothing");
    rc = 0;
out:
    free(views);
    rs_colmap_release(&m);
    return rc;
}
