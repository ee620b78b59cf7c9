/* irradiance_close: the occluders of the irradiance stage (see irradiance_close.h). */
#include "stages/irradiance/irradiance_close.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "common/cloud_ply.h"
#include "common/faceprop.h"
#include "common/fileio.h"
#include "common/log.h"
#include "common/pano.h"
#include "common/par.h"
#include "common/ply.h"
#include "meshing/closing.h"
#include "meshing/freespace.h"
#include "meshing/occluders_ply.h"

static int write_occluders(const char *path, const rs_mesh *occ, const uint32_t *proxy, const uint8_t *source,
                           rs_err *err)
{
    rs_ply *ply = rs_ply_new();
    double *pr = malloc(occ->nfaces * sizeof *pr), *src = malloc(occ->nfaces * sizeof *src);
    int rc = -1;
    rs_ply_element *faces = ply ? rs_mesh_to_ply(occ, ply) : NULL;
    if (!faces || !pr || !src) {
        rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory writing the occluders");
    } else {
        for (size_t f = 0; f < occ->nfaces; f++) pr[f] = proxy[f], src[f] = source ? source[f] : 1;
        if (rs_ply_add_comment(ply,
                               "rhoscan occluders: faces between known and unknown space (source 1 = "
                               "free-space map; 2, 3, 4 = a planar region's filled hole, extension, slab top or "
                               "edge); proxy = the mesh.ply facet standing for the unseen surface") == 0 &&
            rs_ply_add_scalar(faces, "proxy", RS_PLY_INT32, pr) &&
            rs_ply_add_scalar(faces, "source", RS_PLY_UINT8, src))
            rc = rs_ply_write(ply, path, 1, err);
        else
            rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory writing the occluders");
    }
    free(pr);
    free(src);
    rs_ply_free(ply);
    return rc;
}

/* The scanners' rays: every valid point of cloud.ply from its scan's position (or the
 * unorganized points' viewpoint). A missing cloud.ply (a given mesh without scans) carves
 * nothing. Returns the rays carved, -1 on a bad cloud.ply. */
static double carve_scans(const rs_config *cfg, rs_freespace *fs, rs_err *err)
{
    char path[4096];
    const char *cp = rs_work_path(cfg, "cloud.ply", path, sizeof path);
    if (!rs_file_exists(cp)) return 0;
    rs_cloud *c = rs_cloud_read_ply(cp, err);
    if (!c) return -1;
    double rays = 0;
    for (int sc = 0; sc < c->nscans; sc++) {
        const rs_scan *scan = &c->scans[sc];
        rs_v3 o = rs_v3_make(scan->position[0], scan->position[1], scan->position[2]);
        long n = (long)scan->cols * scan->rows;
#pragma omp parallel for schedule(dynamic, 4096) reduction(+ : rays)
        for (long k = 0; k < n; k++) {
            size_t q = scan->first + (size_t)k;
            if (!c->valid[q]) continue;
            rs_freespace_carve(fs, o, rs_v3_make(c->xyz[3 * q], c->xyz[3 * q + 1], c->xyz[3 * q + 2]), 0);
            rays += 1;
        }
    }
    size_t first = c->nscans
        ? c->scans[c->nscans - 1].first + (size_t)c->scans[c->nscans - 1].cols * c->scans[c->nscans - 1].rows
        : 0;
    if (c->has_viewpoint && first < c->npoints) {
        rs_v3 o = rs_v3_make(c->viewpoint[0], c->viewpoint[1], c->viewpoint[2]);
#pragma omp parallel for schedule(dynamic, 4096) reduction(+ : rays)
        for (long k = (long)first; k < (long)c->npoints; k++) {
            if (!c->valid[k]) continue;
            rs_freespace_carve(fs, o, rs_v3_make(c->xyz[3 * k], c->xyz[3 * k + 1], c->xyz[3 * k + 2]), 0);
            rays += 1;
        }
    }
    rs_cloud_free(c);
    return rays;
}

/* The camera's rays: a pixel that sees a facet is empty up to its hit on the mesh, one that sees
 * nothing of the mesh (and holds a usable value) is empty to the grid's edge. */
static double carve_camera(const rs_irradiance_state *s, rs_freespace *fs)
{
    const rs_capture *cap = &s->cap;
    int w = cap->pano->width, h = cap->pano->height;
    double rays = 0;
#pragma omp parallel for schedule(dynamic, 4) reduction(+ : rays)
    for (int r = 0; r < h; r++) {
        rs_ray ray[512];
        rs_hit hit[512];
        for (int c0 = 0; c0 < w; c0 += 512) {
            int n = w - c0 < 512 ? w - c0 : 512;
            for (int i = 0; i < n; i++) {
                ray[i].org = cap->pose.position;
                ray[i].dir = rs_pose_dir_to_world(&cap->pose, rs_pano_pixel_dir(w, h, c0 + i, r));
                ray[i].tnear = 0;
                ray[i].tfar = INFINITY;
            }
            rs_scene_intersect(s->scene, ray, hit, (size_t)n);
            for (int i = 0; i < n; i++) {
                size_t k = (size_t)r * w + c0 + i;
                rs_v3 end = rs_v3_add(ray[i].org, ray[i].dir);
                if (hit[i].face != RS_NO_HIT) {
                    end = rs_v3_add(ray[i].org, rs_v3_scale(ray[i].dir, hit[i].t));
                    rs_freespace_carve(fs, ray[i].org, end, 0);
                } else if (s->ids->data[k] < 0 && rs_capture_pixel_ok(cap->pano->data + 3 * k)) {
                    rs_freespace_carve(fs, ray[i].org, end, 1);
                } else {
                    continue;
                }
                rays += 1;
            }
        }
    }
    return rays;
}

/* The free-space map of the scans and the capture, and its faces. */
static int build_freespace(const rs_config *cfg, rs_irradiance_state *s, rs_json *fig, rs_err *err)
{
    rs_freespace_opts fo = {.cell = rs_config_real(cfg, "irradiance", "occluder_cell"),
                            .margin = rs_config_real(cfg, "irradiance", "occluder_margin"),
                            .max_cells = (size_t)rs_config_int(cfg, "irradiance", "occluder_max_cells")};
    rs_freespace fs;
    double t0 = rs_now();
    if (rs_freespace_init(&fs, s->mesh, &fo, err) != 0) return -1;
    double scan_rays = carve_scans(cfg, &fs, err);
    if (scan_rays < 0) {
        rs_freespace_release(&fs);
        return -1;
    }
    double cam_rays = carve_camera(s, &fs), t1 = rs_now();
    rs_freespace_counts cnt;
    rs_freespace_count(&fs, &cnt);
    const char *ks = rs_config_string(cfg, "irradiance", "occluder_keep");
    rs_fs_keep keep = strcmp(ks, "near") == 0 ? RS_FS_KEEP_NEAR : RS_FS_KEEP_BEHIND;
    int rc = rs_freespace_occluders(&fs, s->mesh, rs_config_real(cfg, "irradiance", "occluder_depth"), keep, &s->occ,
                                    &s->occ_proxy, err);
    rs_json_set_int(fig, "cells_unknown_opened", (long long)fs.opened);
    double t2 = rs_now();
    s->occ_cell = fs.cell;
    rs_json_set_num(fig, "cell_m", fs.cell);
    rs_json *dims = rs_json_set_arr(fig, "grid");
    for (int a = 0; a < 3; a++) rs_json_push_num(dims, fs.n[a]);
    rs_json_set_int(fig, "cells_free", (long long)cnt.free);
    rs_json_set_int(fig, "cells_occupied", (long long)cnt.occupied);
    rs_json_set_int(fig, "cells_unknown", (long long)cnt.unknown);
    rs_json_set_num(fig, "scanner_rays", scan_rays);
    rs_json_set_num(fig, "camera_rays", cam_rays);
    rs_json_set_num(fig, "grid_mb", (double)((fs.ncells + 3) / 4) / 1048576.0);
    rs_json_set_num(fig, "map_s", t1 - t0);
    rs_json_set_num(fig, "faces_s", t2 - t1);
    rs_log_info("irradiance: free-space map of %d x %d x %d cells of %.3g m (%.1f MB): %zu free, %zu occupied, %zu "
                "unknown, from %.0f scanner and %.0f camera rays in %.2f s",
                fs.n[0], fs.n[1], fs.n[2], fs.cell, (double)((fs.ncells + 3) / 4) / 1048576.0, cnt.free, cnt.occupied,
                cnt.unknown, scan_rays, cam_rays, t1 - t0);
    rs_freespace_release(&fs);
    return rc;
}

/* The points the model was seen from: every scan's position, the unorganized points' viewpoint
 * (cloud.ply, when there is one) and the camera's. *n of them into a new array; NULL with err on
 * a bad cloud.ply or out of memory. */
static rs_v3 *viewpoints(const rs_config *cfg, const rs_irradiance_state *s, size_t *n, rs_err *err)
{
    char path[4096];
    const char *cp = rs_work_path(cfg, "cloud.ply", path, sizeof path);
    rs_cloud *c = NULL;
    if (rs_file_exists(cp) && !(c = rs_cloud_read_ply(cp, err))) return NULL;
    size_t cap = (c ? (size_t)c->nscans + 1 : 0) + 1;
    rs_v3 *v = malloc(cap * sizeof *v);
    if (!v) {
        rs_cloud_free(c);
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the viewpoints");
        return NULL;
    }
    *n = 0;
    for (int sc = 0; c && sc < c->nscans; sc++)
        v[(*n)++] = rs_v3_make(c->scans[sc].position[0], c->scans[sc].position[1], c->scans[sc].position[2]);
    if (c && c->has_viewpoint) v[(*n)++] = rs_v3_make(c->viewpoint[0], c->viewpoint[1], c->viewpoint[2]);
    v[(*n)++] = s->cap.pose.position;
    rs_cloud_free(c);
    return v;
}

/* The planar closing (meshing/closing.h), appended to the occluders s holds (the free-space
 * map's, with freespace+planes); *source gets 1 for the ones before, the closing's kinds after. */
static int build_planes(const rs_config *cfg, rs_irradiance_state *s, rs_json *fig, uint8_t **source, rs_err *err)
{
    size_t nv = 0;
    double t0 = rs_now();
    rs_v3 *views = viewpoints(cfg, s, &nv, err);
    if (!views) return -1;
    rs_closing_opts o = RS_CLOSING_OPTS_DEFAULT;
    rs_closing_stats st;
    rs_mesh *pm = NULL;
    uint32_t *pp = NULL;
    uint8_t *ps = NULL;
    int rc = rs_closing_build(s->mesh, s->scene, views, nv, &o, &pm, &pp, &ps, &st, err);
    free(views);
    if (rc != 0) return -1;
    size_t n0 = s->occ ? s->occ->nfaces : 0, n1 = pm ? pm->nfaces : 0, v0 = s->occ ? s->occ->nverts : 0;
    rs_mesh *all = rs_mesh_new(v0 + (pm ? pm->nverts : 0), n0 + n1);
    uint32_t *pr = malloc((n0 + n1 + 1) * sizeof *pr);
    uint8_t *src = malloc(n0 + n1 + 1);
    if (!all || !pr || !src) {
        rs_mesh_free(all), free(pr), free(src), rs_mesh_free(pm), free(pp), free(ps);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the occluders");
    }
    if (n0) memcpy(all->verts, s->occ->verts, 3 * v0 * sizeof(float)), memcpy(all->tris, s->occ->tris, 3 * n0 * 4);
    if (n0) memcpy(pr, s->occ_proxy, n0 * sizeof *pr);
    memset(src, 1, n0);
    if (n1) {
        memcpy(all->verts + 3 * v0, pm->verts, 3 * pm->nverts * sizeof(float));
        for (size_t k = 0; k < 3 * n1; k++) all->tris[3 * n0 + k] = pm->tris[k] + (uint32_t)v0;
        memcpy(pr + n0, pp, n1 * sizeof *pr);
        memcpy(src + n0, ps, n1);
    }
    rs_mesh_free(pm), free(pp), free(ps);
    rs_mesh_free(s->occ);
    free(s->occ_proxy);
    s->occ = n0 + n1 ? all : (rs_mesh_free(all), NULL);
    s->occ_proxy = pr;
    *source = src;
    rs_json *pf = rs_json_set_obj(fig, "planes");
    rs_json_set_num(pf, "cell_m", o.cell);
    rs_json_set_int(pf, "viewpoints", (long long)nv);
    rs_json_set_int(pf, "regions", (long long)st.regions);
    rs_json_set_int(pf, "walls", (long long)st.walls);
    rs_json_set_int(pf, "ceilings", (long long)st.ceilings);
    rs_json_set_int(pf, "slabs", (long long)st.slabs);
    rs_json_set_num(pf, "hole_m2", st.hole_area);
    rs_json_set_num(pf, "extension_m2", st.extend_area);
    rs_json_set_num(pf, "slab_top_m2", st.slab_area);
    rs_json_set_int(pf, "triangles", (long long)st.faces);
    rs_json_set_num(pf, "rays", st.rays);
    rs_json_set_num(pf, "time_s", rs_now() - t0);
    rs_log_info("irradiance: %zu planar regions (%zu walls, %zu ceilings) closed: holes %.3g m^2, extensions %.3g "
                "m^2, %zu slab tops %.3g m^2, %zu faces, in %.2f s",
                st.regions, st.walls, st.ceilings, st.hole_area, st.extend_area, st.slabs, st.slab_area, st.faces,
                rs_now() - t0);
    return 0;
}

typedef struct {
    const rs_config *cfg;
    rs_irradiance_state *s;
    rs_json *fig;
    const char *mode, *occ_path;
} close_job;

/* The free-space map's faces and the planar closing, as mode asks, into s; occluders.ply. */
static int build_and_write(void *ctx, rs_err *err)
{
    close_job *j = ctx;
    uint8_t *source = NULL;
    if (strstr(j->mode, "freespace") && build_freespace(j->cfg, j->s, j->fig, err) != 0) return -1;
    if (strstr(j->mode, "planes") && build_planes(j->cfg, j->s, j->fig, &source, err) != 0) return -1;
    int rc = 0;
    if (j->s->occ)
        rc = write_occluders(j->occ_path, j->s->occ, j->s->occ_proxy, source, err);
    else if (rs_file_exists(j->occ_path))
        unlink(j->occ_path);
    free(source);
    return rc;
}

/* Collective: rank 0's occluders (faces, proxies, cell) to every rank. */
static int share_occluders(rs_irradiance_state *s, rs_err *err)
{
    if (rs_par_size() <= 1) return 0;
    uint64_t count[2] = {s->occ ? s->occ->nverts : 0, s->occ ? s->occ->nfaces : 0};
    rs_par_bcast(count, sizeof count);
    rs_par_bcast(&s->occ_cell, sizeof s->occ_cell);
    if (!count[1]) return 0;
    int failed = 0;
    if (!rs_par_is_root()) {
        s->occ = rs_mesh_new((size_t)count[0], (size_t)count[1]);
        s->occ_proxy = malloc((size_t)count[1] * sizeof *s->occ_proxy);
        failed = !s->occ || !s->occ_proxy;
    }
    if (rs_par_any(failed))
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %llu occluder faces from MPI rank 0",
                          (unsigned long long)count[1]);
    rs_par_bcast(s->occ->verts, 3 * s->occ->nverts * sizeof *s->occ->verts);
    rs_par_bcast(s->occ->tris, 3 * s->occ->nfaces * sizeof *s->occ->tris);
    rs_par_bcast(s->occ_proxy, s->occ->nfaces * sizeof *s->occ_proxy);
    return 0;
}

int rs_irradiance_close(const rs_config *cfg, rs_irradiance_state *s, rs_report *rep, rs_err *err)
{
    const char *mode = rs_config_string(cfg, "irradiance", "occluders");
    char path[4096];
    const char *occ_path = rs_work_path(cfg, "occluders.ply", path, sizeof path);
    if (strcmp(mode, "off") == 0) {
        if (rs_file_exists(occ_path)) unlink(occ_path); /* an earlier run's: nothing reads it now */
        return 0;
    }
    double t0 = rs_now();
    rs_json *fig = rs_json_set_obj(rep->metrics, "occluders");
    rs_json_set_str(fig, "mode", mode);
    s->occ_cell = rs_config_real(cfg, "irradiance", "occluder_cell");
    if (strcmp(mode, "file") == 0) {
        char given[4096];
        const char *fp = rs_config_path(cfg, "irradiance", "occluders_file", given, sizeof given);
        if (!fp)
            return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                              "[irradiance] occluders = file without occluders_file: expected the occluder PLY");
        if (rs_occluders_read(fp, s->nf, &s->occ, &s->occ_proxy, err) != 0) return -1;
        if (rs_file_exists(occ_path) && rs_par_is_root()) unlink(occ_path);
    } else {
        /* MPI: rank 0 builds them (seconds of one thread's work, cheap to send) */
        close_job job = {cfg, s, fig, mode, occ_path};
        if (rs_par_root_run(build_and_write, &job, err) != 0 || share_occluders(s, err) != 0) return -1;
    }
    double near = rs_config_real(cfg, "irradiance", "occluder_near") * s->occ_cell;
    if (s->occ && rs_scene_set_occluders(s->scene, s->occ, s->occ_proxy, near, err) != 0) return -1;
    size_t nocc = s->occ ? s->occ->nfaces : 0;
    rs_json_set_int(fig, "faces", (long long)nocc);
    rs_json_set_num(fig, "near_m", near);
    rs_report_time(rep, "occluders", rs_now() - t0);
    rs_log_info("irradiance: %zu occluder faces (%s) block rays that leave the mesh, beyond %.3g m of their origin",
                nocc, mode, near);
    return 0;
}
