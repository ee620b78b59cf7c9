/* calib_files: the calib stage's hand-over files (see calib_files.h). A pose is a text file
 * rather than JSON so that it reads back with sscanf and stays byte-identical between runs. */
#include "pipeline/calib_files.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/fileio.h"
#include "common/json.h"
#include "pipeline/stage.h"

int rs_calib_pose_solved(const rs_config *cfg, const char *section)
{
    /* The key table has these keys for capture sections only; asking [sky] would abort. */
    if (strncmp(section, "capture", 7) != 0 || (section[7] != 0 && section[7] != '.')) return 0;
    return rs_config_has(cfg, section, "correspondences") || rs_config_has(cfg, section, "colmap_panorama") ||
        (strcmp(section, "capture") == 0 && rs_config_has(cfg, section, "refine_edges") &&
         rs_config_bool(cfg, section, "refine_edges"));
}

int rs_calib_pose_apply(const rs_config *cfg, const char *section, rs_pose *pose, rs_err *err)
{
    if (!rs_calib_pose_solved(cfg, section)) return 0;
    if (rs_config_has(cfg, section, "correspondences") && strcmp(section, "capture") != 0)
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[%s] correspondences: only [capture] can be registered from pairs so far", section);
    char path[4096];
    rs_work_path(cfg, RS_CALIB_POSE_FILE, path, sizeof path);
    if (!rs_file_exists(path))
        return rs_err_set(err, RS_ERR_INPUT, path, 0,
                          "the pose solved for [%s] (correspondences or colmap_panorama) is missing: run the calib "
                          "stage first",
                          section);
    return rs_calib_pose_read(path, section, pose, err);
}

/* The poses of a pose file, in file order. */
#define MAX_POSES 256
typedef struct {
    char section[128];
    rs_pose pose;
    int have_pos, have_rot;
} pose_entry;

static int parse_poses(const char *path, pose_entry *e, int *n, rs_err *err)
{
    char *text = NULL;
    size_t size;
    *n = 0;
    if (rs_read_file(path, &text, &size, err) != 0) return -1;
    int rc = 0, cur = -1;
    long lineno = 0;
    for (char *line = text; line && *line && rc == 0;) {
        char *next = strchr(line, '\n');
        if (next) *next++ = 0;
        lineno++;
        char name[128];
        double x, y, z, r[9];
        if (cur < 0 && line[0] != '#' && line[0] != 0 && strncmp(line, "section ", 8) != 0) {
            /* A pose with no section line before it: [capture]'s (the older one-pose format). */
            cur = (*n)++;
            memset(&e[cur], 0, sizeof e[cur]);
            snprintf(e[cur].section, sizeof e[cur].section, "capture");
        }
        if (line[0] == '#' || line[0] == 0) {
        } else if (sscanf(line, "section %127s", name) == 1) {
            if (*n == MAX_POSES)
                rc = rs_err_set(err, RS_ERR_INPUT, path, lineno, "more than %d sections", MAX_POSES);
            else {
                cur = (*n)++;
                memset(&e[cur], 0, sizeof e[cur]);
                snprintf(e[cur].section, sizeof e[cur].section, "%s", name);
            }
        } else if (sscanf(line, "position %lf %lf %lf", &x, &y, &z) == 3) {
            e[cur].pose.position = rs_v3_make(x, y, z);
            e[cur].have_pos = 1;
        } else if (sscanf(line, "rotation %lf %lf %lf %lf %lf %lf %lf %lf %lf", &r[0], &r[1], &r[2], &r[3], &r[4],
                          &r[5], &r[6], &r[7], &r[8]) == 9) {
            memcpy(e[cur].pose.rot, r, sizeof r);
            e[cur].have_rot = 1;
        } else {
            rc = rs_err_set(err, RS_ERR_INPUT, path, lineno,
                            "\"%.80s\": expected `section NAME`, `position X Y Z` or `rotation` and 9 numbers", line);
        }
        line = next;
    }
    free(text);
    for (int i = 0; rc == 0 && i < *n; i++)
        if (!(e[i].have_pos && e[i].have_rot))
            rc = rs_err_set(err, RS_ERR_INPUT, path, 0, "section %s: expected a `position` line and a `rotation` line",
                            e[i].section);
    return rc;
}

int rs_calib_pose_write(const char *path, const char *section, const rs_pose *pose, rs_err *err)
{
    pose_entry *e = calloc(MAX_POSES, sizeof *e);
    char *text = NULL;
    int n = 0, rc = -1;
    if (!e) return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
    if (rs_file_exists(path) && parse_poses(path, e, &n, err) != 0) goto out;
    int k = 0;
    while (k < n && strcmp(e[k].section, section) != 0) k++;
    if (k == MAX_POSES) {
        rs_err_set(err, RS_ERR_INPUT, path, 0, "more than %d sections", MAX_POSES);
        goto out;
    }
    if (k == n) n++;
    snprintf(e[k].section, sizeof e[k].section, "%s", section);
    e[k].pose = *pose;
    size_t cap = 160 + (size_t)n * 640, len = 0;
    text = malloc(cap);
    if (!text) {
        rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
        goto out;
    }
    len += (size_t)snprintf(text, cap, "# rhoscan calib: capture poses solved by the calib stage (pairs, COLMAP)\n");
    for (int i = 0; i < n; i++) {
        const double *r = e[i].pose.rot;
        len += (size_t)snprintf(text + len, cap - len,
                                "section %s\nposition %.17g %.17g %.17g\n"
                                "rotation %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n",
                                e[i].section, e[i].pose.position.x, e[i].pose.position.y, e[i].pose.position.z, r[0],
                                r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]);
    }
    rc = rs_write_file_atomic(path, text, len, err);
out:
    free(e);
    free(text);
    return rc;
}

int rs_calib_pose_read(const char *path, const char *section, rs_pose *pose, rs_err *err)
{
    pose_entry *e = calloc(MAX_POSES, sizeof *e);
    int n = 0, rc = -1;
    if (!e) return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
    if (parse_poses(path, e, &n, err) == 0) {
        for (int i = 0; i < n && rc != 0; i++)
            if (strcmp(e[i].section, section) == 0) {
                *pose = e[i].pose;
                rc = 0;
            }
        if (rc != 0)
            rs_err_set(err, RS_ERR_INPUT, path, 0,
                       "no pose for [%s]: expected a `section %s` block (run "
                       "the calib stage again)",
                       section, section);
    }
    free(e);
    return rc;
}

void rs_calib_pose_json(struct rs_json *o, const rs_pose *pose)
{
    rs_json *p = rs_json_set_arr(o, "position");
    rs_json_push_num(p, pose->position.x);
    rs_json_push_num(p, pose->position.y);
    rs_json_push_num(p, pose->position.z);
    rs_json *r = rs_json_set_arr(o, "rotation");
    for (int k = 0; k < 9; k++) rs_json_push_num(r, pose->rot[k]);
}
