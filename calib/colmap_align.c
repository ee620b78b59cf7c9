/* colmap_align: from a COLMAP model to rhoscan poses (see colmap.h): the views and control-point
 * files, the Umeyama similarity to the scan's frame with its residuals, and panorama poses. */
#include "calib/colmap.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "calib/calib_math.h"
#include "calib/colmap_text.h"

/* Grows *arr (elements of size sz) to hold n + 1; -1 when memory runs out. */
static int grow(void **arr, int n, int *cap, size_t sz)
{
    if (n < *cap) return 0;
    int c = *cap ? 2 * *cap : 16;
    void *p = realloc(*arr, (size_t)c * sz);
    if (!p) return -1;
    *arr = p;
    *cap = c;
    return 0;
}

/* |R^T R - I| <= 1e-6 entrywise and det R > 0. */
static int is_rotation(const double r[9])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double d = r[i] * r[j] + r[3 + i] * r[3 + j] + r[6 + i] * r[6 + j] - (i == j);
            if (fabs(d) > 1e-6) return 0;
        }
    double det =
        r[0] * (r[4] * r[8] - r[5] * r[7]) - r[1] * (r[3] * r[8] - r[5] * r[6]) + r[2] * (r[3] * r[7] - r[4] * r[6]);
    return det > 0;
}

int rs_colmap_views_read(const char *path, rs_colmap_view **views, int *count, rs_err *err)
{
    static const char *const rn[9] = {"R00", "R01", "R02", "R10", "R11", "R12", "R20", "R21", "R22"};
    rs_ctext c;
    *views = NULL;
    *count = 0;
    if (rs_ctext_open(&c, path, err) != 0) return -1;
    int cap = 0, rc = 0;
    while (rc == 0 && rs_ctext_next_line(&c)) {
        if (rs_ctext_blank(&c)) continue;
        if (grow((void **)views, *count, &cap, sizeof **views) != 0) {
            rc = rs_err_set(err, RS_ERR_SYSTEM, path, c.line, "out of memory");
            break;
        }
        rs_colmap_view *v = &(*views)[*count];
        memset(v, 0, sizeof *v);
        v->line = c.line;
        if (rs_ctext_name(&c, "NAME", v->name, sizeof v->name, err) != 0 ||
            rs_ctext_name(&c, "PANORAMA (a label)", v->panorama, sizeof v->panorama, err) != 0)
            rc = -1;
        for (int k = 0; rc == 0 && k < 9; k++) rc = rs_ctext_real(&c, rn[k], &v->r_local_cam[k], err);
        if (rc == 0 && rs_ctext_more(&c)) {
            if (rs_ctext_real(&c, "TX", &v->t_local_cam.x, err) != 0 ||
                rs_ctext_real(&c, "TY", &v->t_local_cam.y, err) != 0 ||
                rs_ctext_real(&c, "TZ", &v->t_local_cam.z, err) != 0)
                rc = -1;
        }
        if (rc == 0) rc = rs_ctext_end(&c, "NAME PANORAMA R00..R22 [TX TY TZ]", err);
        if (rc == 0 && !is_rotation(v->r_local_cam))
            rc = rs_err_set(err, RS_ERR_INPUT, path, c.line,
                            "view %s: R00..R22 is not a rotation (orthonormal, det "
                            "+1 to 1e-6): expected the view camera -> panorama rotation, row-major",
                            v->name);
        for (int k = 0; rc == 0 && k < *count; k++)
            if (strcmp((*views)[k].name, v->name) == 0)
                rc = rs_err_set(err, RS_ERR_INPUT, path, c.line,
                                "view %s is listed twice (also on line %ld): expected "
                                "one line per COLMAP image",
                                v->name, (*views)[k].line);
        if (rc == 0) (*count)++;
    }
    free(c.text);
    if (rc == 0 && *count == 0)
        rc = rs_err_set(err, RS_ERR_INPUT, path, 0, "no view: expected lines `NAME PANORAMA R00 .. R22 [TX TY TZ]`");
    if (rc != 0) {
        free(*views);
        *views = NULL;
        *count = 0;
    }
    return rc;
}

int rs_colmap_controls_read(const char *path, rs_colmap_control **cps, int *count, rs_err *err)
{
    rs_ctext c;
    *cps = NULL;
    *count = 0;
    if (rs_ctext_open(&c, path, err) != 0) return -1;
    int cap = 0, rc = 0;
    while (rc == 0 && rs_ctext_next_line(&c)) {
        if (rs_ctext_blank(&c)) continue;
        if (grow((void **)cps, *count, &cap, sizeof **cps) != 0) {
            rc = rs_err_set(err, RS_ERR_SYSTEM, path, c.line, "out of memory");
            break;
        }
        rs_colmap_control *p = &(*cps)[*count];
        memset(p, 0, sizeof *p);
        p->line = c.line;
        char kind[32];
        rs_ctext_token(&c, kind, sizeof kind);
        if (strcmp(kind, "image") == 0)
            p->kind = RS_COLMAP_CP_IMAGE;
        else if (strcmp(kind, "point") == 0)
            p->kind = RS_COLMAP_CP_POINT;
        else if (strcmp(kind, "panorama") == 0)
            p->kind = RS_COLMAP_CP_PANORAMA;
        else {
            rc = rs_err_set(err, RS_ERR_INPUT, path, c.line,
                            "field 1 = \"%s\": expected image, point or panorama "
                            "(then a name or id and X Y Z in metres)",
                            kind);
            break;
        }
        if (rs_ctext_name(&c, p->kind == RS_COLMAP_CP_POINT ? "a POINT3D_ID" : "a name", p->name, sizeof p->name,
                          err) != 0) {
            rc = -1;
            break;
        }
        if (p->kind == RS_COLMAP_CP_POINT) {
            char *end;
            strtol(p->name, &end, 10);
            if (end == p->name || *end) {
                rc = rs_err_set(err, RS_ERR_INPUT, path, c.line,
                                "field 2 = \"%s\": expected a POINT3D_ID (an integer "
                                "of points3D.txt)",
                                p->name);
                break;
            }
        }
        if (rs_ctext_real(&c, "X (m)", &p->world.x, err) != 0 || rs_ctext_real(&c, "Y (m)", &p->world.y, err) != 0 ||
            rs_ctext_real(&c, "Z (m)", &p->world.z, err) != 0 || rs_ctext_end(&c, "X Y Z", err) != 0) {
            rc = -1;
            break;
        }
        (*count)++;
    }
    free(c.text);
    if (rc == 0 && *count < 3)
        rc = rs_err_set(err, RS_ERR_INPUT, path, 0,
                        "%d control point%s: expected at least 3, not on one line "
                        "(`image NAME X Y Z`, `point ID X Y Z` or `panorama LABEL X Y Z`)",
                        *count, *count == 1 ? "" : "s");
    if (rc != 0) {
        free(*cps);
        *cps = NULL;
        *count = 0;
    }
    return rc;
}

/* Mean centre (COLMAP frame) of a panorama's registered views; -1 with err when it has none. */
static int panorama_centre(const rs_colmap_model *m, const rs_colmap_view *views, int nviews, const char *label,
                           rs_v3 *centre, int *used, int *listed)
{
    rs_v3 sum = {0, 0, 0};
    *used = *listed = 0;
    for (int i = 0; i < nviews; i++) {
        if (strcmp(views[i].panorama, label) != 0) continue;
        (*listed)++;
        const rs_colmap_image *im = rs_colmap_find_image(m, views[i].name);
        if (!im) continue;
        sum = rs_v3_add(sum, im->centre);
        (*used)++;
    }
    if (*used) *centre = rs_v3_scale(sum, 1.0 / *used);
    return *used ? 0 : -1;
}

int rs_colmap_controls_locate(const rs_colmap_model *m, const rs_colmap_view *views, int nviews,
                              const rs_colmap_control *cps, int count, const char *path, rs_v3 *model_xyz, rs_err *err)
{
    for (int i = 0; i < count; i++) {
        const rs_colmap_control *p = &cps[i];
        if (p->kind == RS_COLMAP_CP_IMAGE) {
            const rs_colmap_image *im = rs_colmap_find_image(m, p->name);
            if (!im)
                return rs_err_set(err, RS_ERR_INPUT, path, p->line,
                                  "image %s is not in the COLMAP model (%d images "
                                  "registered): expected the NAME of a line of images.txt",
                                  p->name, m->nimages);
            model_xyz[i] = im->centre;
        } else if (p->kind == RS_COLMAP_CP_POINT) {
            const rs_colmap_point *pt = rs_colmap_find_point(m, strtol(p->name, NULL, 10));
            if (!pt)
                return rs_err_set(err, RS_ERR_INPUT, path, p->line,
                                  "point %s is not in the COLMAP model: expected a "
                                  "POINT3D_ID of points3D.txt",
                                  p->name);
            model_xyz[i] = pt->xyz;
        } else {
            int used = 0, listed = 0;
            for (int k = 0; k < nviews; k++)
                if (strcmp(views[k].panorama, p->name) == 0 && rs_v3_len(views[k].t_local_cam) > 0)
                    return rs_err_set(err, RS_ERR_INPUT, path, p->line,
                                      "panorama %s: view %s is offset from the "
                                      "panorama's centre (views file line %ld): expected `image` control points "
                                      "for offset (rig) cameras",
                                      p->name, views[k].name, views[k].line);
            if (panorama_centre(m, views, nviews, p->name, &model_xyz[i], &used, &listed) != 0)
                return rs_err_set(err, RS_ERR_INPUT, path, p->line, "panorama %s: %s", p->name,
                                  listed ? "none of its views is in the COLMAP model (the mapper did not register "
                                           "them): expected at least one"
                                         : "no view of the views file has this label");
        }
    }
    return 0;
}

int rs_colmap_umeyama(int n, const rs_v3 *model_xyz, const rs_v3 *world, rs_colmap_similarity *sim, double *residual_m,
                      rs_err *err)
{
    if (n < 3)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                          "%d control point%s: a similarity needs at least 3 points "
                          "not on one line",
                          n, n == 1 ? "" : "s");
    /* Spread ratio below 1e-6: the points lie on one line to a part in a million of their extent,
     * and the rotation about that line is undetermined. */
    if (rs_calib_spread_ratio(n, world) < 1e-6)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                          "the %d control points lie on one line in the scan's frame: "
                          "expected at least 3 not on one line (the rotation about it is undetermined)",
                          n);
    if (rs_calib_spread_ratio(n, model_xyz) < 1e-6)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                          "the %d control points lie on one line in the COLMAP model: "
                          "expected at least 3 not on one line (the rotation about it is undetermined)",
                          n);
    if (rs_calib_align(n, model_xyz, world, 1, sim->rot, &sim->t, &sim->scale) != 0)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                          "the control points give no similarity with a positive scale: "
                          "expected the same points in the model and the scan");
    double sum = 0;
    sim->max_m = 0;
    for (int i = 0; i < n; i++) {
        rs_v3 p = rs_v3_add(rs_v3_scale(rs_m3_mul_v(sim->rot, model_xyz[i]), sim->scale), sim->t);
        double r = rs_v3_len(rs_v3_sub(p, world[i]));
        if (residual_m) residual_m[i] = r;
        sum += r * r;
        if (r > sim->max_m) sim->max_m = r;
    }
    sim->rms_m = sqrt(sum / n);
    return 0;
}

/* Chordal L2 mean of n rotations: the rotation R maximising sum_i trace(R^T R_i). It is the
 * rigid alignment of the axis vectors +-e_k onto +-R_i e_k (centroids 0), so rs_calib_align's
 * Horn solver gives it without a second eigen-solver here. */
static int mean_rotation(int n, const double *rots, double out[9])
{
    rs_v3 *src = malloc((size_t)6 * n * sizeof *src), *dst = malloc((size_t)6 * n * sizeof *dst);
    int rc = -1;
    if (src && dst) {
        for (int i = 0; i < n; i++)
            for (int k = 0; k < 3; k++) {
                rs_v3 e = rs_v3_make(k == 0, k == 1, k == 2), re = rs_m3_mul_v(rots + 9 * i, e);
                src[6 * i + 2 * k] = e;
                src[6 * i + 2 * k + 1] = rs_v3_scale(e, -1);
                dst[6 * i + 2 * k] = re;
                dst[6 * i + 2 * k + 1] = rs_v3_scale(re, -1);
            }
        rs_v3 t;
        double s;
        rc = rs_calib_align(6 * n, src, dst, 0, out, &t, &s);
    }
    free(src);
    free(dst);
    return rc;
}

int rs_colmap_pano_pose(const rs_colmap_model *m, const rs_colmap_view *views, int nviews, const char *label,
                        const rs_colmap_similarity *sim, rs_colmap_pano *out, rs_err *err)
{
    memset(out, 0, sizeof *out);
    double *rots = malloc((size_t)nviews * 9 * sizeof *rots);
    rs_v3 *centres = malloc((size_t)nviews * sizeof *centres);
    int rc = -1;
    if (!rots || !centres) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    rs_v3 sum = {0, 0, 0};
    for (int i = 0; i < nviews; i++) {
        if (strcmp(views[i].panorama, label) != 0) continue;
        out->views_listed++;
        const rs_colmap_image *im = rs_colmap_find_image(m, views[i].name);
        if (!im) continue;
        /* local -> scan world = (COLMAP world -> scan) (camera -> COLMAP world) (local -> camera). */
        double r_world_cam[9], r_cam_local[9], tmp[9], *r = rots + 9 * out->views;
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) {
                r_world_cam[3 * a + b] = im->rot_cam_world[3 * b + a];
                r_cam_local[3 * a + b] = views[i].r_local_cam[3 * b + a];
            }
        rs_calib_m3_mul(sim->rot, r_world_cam, tmp);
        rs_calib_m3_mul(tmp, r_cam_local, r);
        /* The panorama's centre: the view's centre moved back by the view's offset in the panorama. */
        rs_v3 c = rs_v3_add(rs_v3_scale(rs_m3_mul_v(sim->rot, im->centre), sim->scale), sim->t);
        centres[out->views] = rs_v3_sub(c, rs_m3_mul_v(r, views[i].t_local_cam));
        sum = rs_v3_add(sum, centres[out->views]);
        out->views++;
    }
    if (out->views == 0) {
        rs_err_set(err, RS_ERR_INPUT, NULL, 0, "panorama %s: %s", label,
                   out->views_listed ? "none of its views is in the COLMAP model (the mapper did not register them)"
                                     : "no view of the views file has this label");
        goto out;
    }
    if (mean_rotation(out->views, rots, out->pose.rot) != 0) {
        rs_err_set(err, RS_ERR_INTERNAL, NULL, 0, "panorama %s: the mean of its views' rotations failed", label);
        goto out;
    }
    out->pose.position = rs_v3_scale(sum, 1.0 / out->views);
    for (int i = 0; i < out->views; i++) {
        out->spread_deg = fmax(out->spread_deg, rs_calib_rot_angle(out->pose.rot, rots + 9 * i) * 180 / M_PI);
        out->spread_m = fmax(out->spread_m, rs_v3_len(rs_v3_sub(centres[i], out->pose.position)));
    }
    rc = 0;
out:
    free(rots);
    free(centres);
    return rc;
}
