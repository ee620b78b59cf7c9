/* mesh: the mesh stage. Triangulates the scan grids of cloud.ply (or takes [mesh] input_mesh
 * as it is), simplifies to the facet size and writes mesh.ply. Exports rs_mesh_run. */
#include "stages.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "cloud.h"
#include "fileio.h"
#include "grid.h"
#include "image.h"
#include "log.h"
#include "mesh.h"
#include "nadir.h"
#include "simplify.h"

/* Cells spanning more than this many angular grid steps are not surface (the seam of a
 * sweep that does not close). */
#define MAX_GAP_STEPS 2.5

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median of v[0..n) (reorders v); 0 for n = 0. */
static double median(double *v, size_t n)
{
    if (n == 0) return 0;
    qsort(v, n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* Records the mesh's size and edge lengths in the report. */
static void report_mesh(rs_report *rep, const rs_mesh *m)
{
    size_t n;
    double *len = rs_mesh_edge_lengths(m, &n), sum = 0;
    for (size_t i = 0; i < n; i++) sum += len[i];
    rs_json_set_int(rep->metrics, "vertices", (long long)m->nverts);
    rs_json_set_int(rep->metrics, "faces", (long long)m->nfaces);
    rs_json_set_num(rep->metrics, "mean_edge_m", n ? sum / (double)n : 0);
    rs_json_set_num(rep->metrics, "median_edge_m", median(len, n));
    free(len);
}

static int write_mesh(const rs_mesh *m, const char *path, const char *source, double facet_size_m,
                      const char *facet_source, rs_err *err)
{
    rs_ply *ply = rs_ply_new();
    if (!ply) return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
    int rc = -1;
    if (rs_ply_add_comment(ply, "rhoscan_generator rhoscan-mesh %s", RHOSCAN_VERSION) != 0 ||
        rs_ply_add_comment(ply, "rhoscan_source %s", source) != 0 ||
        (facet_size_m > 0 && rs_ply_add_comment(ply, "rhoscan_facet_size %.9g", facet_size_m) != 0) ||
        rs_ply_add_comment(ply, "rhoscan_facet_size_source %s", facet_source) != 0 || !rs_mesh_to_ply(m, ply)) {
        rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory building the PLY");
        goto out;
    }
    rc = rs_ply_write(ply, path, 1, err);
out:
    rs_ply_free(ply);
    return rc;
}

/* [mesh] input_mesh: checked, cleaned of zero-area faces and unused vertices, written as it is. */
static int run_input_mesh(const rs_config *cfg, const char *in_path, rs_report *rep, rs_err *err)
{
    double t0 = rs_now();
    rs_mesh *m = rs_mesh_read(in_path, NULL, err), *out = NULL;
    if (!m) return -1;
    int rc = -1;
    /* Zero area at float precision: below (1e-6 of the model's size)^2. */
    double extent = rs_mesh_extent(m), min_area = 1e-12 * extent * extent;
    size_t kept = 0;
    uint32_t *remap = malloc((m->nverts ? m->nverts : 1) * sizeof *remap);
    if (!remap) {
        rs_err_set(err, RS_ERR_SYSTEM, in_path, 0, "out of memory");
        goto out;
    }
    for (size_t v = 0; v < m->nverts; v++) remap[v] = UINT32_MAX;
    for (size_t f = 0; f < m->nfaces; f++) {
        double area;
        rs_mesh_face(m, f, NULL, NULL, &area);
        const uint32_t *t = m->tris + 3 * f;
        if (!(area > min_area) || t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
        memmove(m->tris + 3 * kept++, t, 3 * sizeof *t);
        for (int j = 0; j < 3; j++) remap[t[j]] = 0;
    }
    size_t dropped = m->nfaces - kept, nv = 0;
    if (kept == 0) {
        rs_err_set(err, RS_ERR_INPUT, in_path, 0, "[mesh] input_mesh: none of its %zu faces has a non-zero area; "
                   "expected a triangle mesh", m->nfaces);
        goto out;
    }
    for (size_t v = 0; v < m->nverts; v++)
        if (remap[v] == 0) remap[v] = (uint32_t)nv++;
    out = rs_mesh_new(nv, kept);
    if (!out) {
        rs_err_set(err, RS_ERR_SYSTEM, in_path, 0, "out of memory");
        goto out;
    }
    for (size_t v = 0; v < m->nverts; v++)
        if (remap[v] != UINT32_MAX) memcpy(out->verts + 3 * (size_t)remap[v], m->verts + 3 * v, 3 * sizeof(float));
    for (size_t k = 0; k < 3 * kept; k++) out->tris[k] = remap[m->tris[k]];
    if (dropped)
        rs_log_warn("%s: dropped %zu zero-area faces of %zu", in_path, dropped, m->nfaces);
    rs_json_set_str(rep->metrics, "source", "input_mesh");
    rs_json_set_int(rep->metrics, "faces_in", (long long)m->nfaces);
    rs_json_set_int(rep->metrics, "dropped_zero_area", (long long)dropped);
    rs_json_set_int(rep->metrics, "dropped_unused_vertices", (long long)(m->nverts - nv));
    report_mesh(rep, out);
    rs_report_time(rep, "read", rs_now() - t0);
    rs_report_skip(rep, "triangulation and simplification", "[mesh] input_mesh given");

    char path[4096];
    double t1 = rs_now();
    if (write_mesh(out, rs_work_path(cfg, "mesh.ply", path, sizeof path), "input_mesh", 0, "none (input_mesh)", err) != 0)
        goto out;
    rs_report_time(rep, "write", rs_now() - t1);
    rc = 0;
out:
    free(remap);
    rs_mesh_free(m);
    rs_mesh_free(out);
    return rc;
}

/* The facet size from the panorama: a facet spans about pixels_per_facet pixels wherever it is,
 * so its size grows with the distance from the camera (*edge_per_m: metres of edge per metre of
 * distance). *facet_m is that size at the median distance from the camera to the model. */
static int derive_facet_size(const rs_config *cfg, const rs_mesh *m, double *facet_m, double *edge_per_m,
                             rs_err *err)
{
    char pano[4096];
    if (!rs_config_path(cfg, "capture", "panorama", pano, sizeof pano))
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[mesh] facet_size is not set and there is no [capture] panorama to derive it from; "
                          "expected [mesh] facet_size = <metres> (or facets = <count>) or a [capture] panorama");
    rs_image *img = rs_image_read(pano, err);
    if (!img) return -1;
    int width = img->width;
    rs_image_free(img);
    double cam[3] = {0, 0, 0};
    rs_config_reals(cfg, "capture", "position", cam);
    double *dist = malloc((m->nverts ? m->nverts : 1) * sizeof *dist);
    if (!dist) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    for (size_t v = 0; v < m->nverts; v++) {
        rs_v3 d = rs_v3_sub(rs_mesh_vert(m, (uint32_t)v), rs_v3_make(cam[0], cam[1], cam[2]));
        dist[v] = rs_v3_len(d);
    }
    double med = median(dist, m->nverts);
    free(dist);
    double ppf = rs_config_real(cfg, "mesh", "pixels_per_facet");
    *edge_per_m = ppf * (2 * M_PI / width);
    *facet_m = *edge_per_m * med;
    if (!(*facet_m > 0))
        return rs_err_set(err, RS_ERR_INPUT, pano, 0, "cannot derive a facet size: median distance %g m from the "
                          "camera to the model; expected the camera away from the scan", med);
    rs_log_info("facet size grows with distance: %g px of a %d px panorama, %.4g m at the median distance %.3g m",
                ppf, width, *facet_m, med);
    return 0;
}

/* Adds each scan's nadir cap to the grid mesh (see nadir.h); a scan whose ground below is not
 * flat is left open and the report says why. */
static int fill_nadir(const rs_config *cfg, const rs_cloud *c, rs_mesh **grid, rs_report *rep, rs_err *err)
{
    size_t added = 0;
    for (int s = 0; s < c->nscans; s++) {
        rs_nadir_stats ns;
        rs_mesh *cap = rs_nadir_cap(c, s, rs_config_real(cfg, "mesh", "nadir_max_rms"), &ns, err);
        if (!cap) {
            if (!ns.why_not[0]) return -1;
            char what[64];
            snprintf(what, sizeof what, "nadir fill of scan %d", s);
            rs_report_skip(rep, what, "%s", ns.why_not);
            continue;
        }
        rs_mesh *merged = rs_mesh_merge_welded(*grid, cap);
        rs_mesh_free(cap);
        if (!merged) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory merging the nadir cap");
        rs_mesh_free(*grid);
        *grid = merged;
        added += ns.triangles;
        rs_log_info("scan %d: nadir hole closed by %zu triangles on the plane of its %zu-point rim (RMS %.3g m)", s,
                    ns.triangles, ns.ring_points, ns.rms_m);
    }
    rs_json_set_int(rep->metrics, "nadir_triangles", (long long)added);
    return 0;
}

/* Triangulation of cloud.ply's scan grids and simplification. */
static int run_scan(const rs_config *cfg, rs_report *rep, rs_err *err)
{
    char path[4096];
    rs_mesh *grid = NULL, *simple = NULL;
    int rc = -1;
    double t0 = rs_now();
    if (!rs_file_exists(rs_work_path(cfg, "cloud.ply", path, sizeof path)))
        return rs_err_set(err, RS_ERR_INPUT, path, 0, "not found: run the ingest stage first, or set [mesh] input_mesh");
    rs_cloud *c = rs_cloud_read_ply(path, err);
    if (!c) return -1;
    if (c->nscans == 0) {
        rs_err_set(err, RS_ERR_INPUT, path, 0, "%zu points but no scan grid: meshing needs an organized scan (PTX) or "
                   "[mesh] input_mesh; unorganized meshing comes with PCL", c->npoints);
        goto out;
    }
    size_t loose = rs_cloud_unorganized(c);
    if (loose)
        rs_report_skip(rep, "unorganized points", "%zu points belong to no scan grid; unorganized meshing comes with PCL",
                       loose);
    rs_report_time(rep, "read", rs_now() - t0);

    t0 = rs_now();
    rs_grid_opts go = {rs_config_real(cfg, "mesh", "max_depth_ratio"),
                       rs_config_real(cfg, "mesh", "max_grazing_deg") * M_PI / 180.0, MAX_GAP_STEPS};
    rs_grid_stats gs;
    grid = rs_grid_triangulate(c, &go, &gs, err);
    if (!grid) goto out;
    rs_report_time(rep, "triangulate", rs_now() - t0);
    rs_json_set_str(rep->metrics, "source", "scan grids");
    rs_json_set_int(rep->metrics, "scans", c->nscans);
    rs_json_set_int(rep->metrics, "grid_cells", (long long)gs.cells);
    rs_json_set_int(rep->metrics, "cells_no_return", (long long)gs.cells_no_return);
    rs_json_set_int(rep->metrics, "cells_dropped_gap", (long long)gs.dropped_gap);
    rs_json_set_int(rep->metrics, "triangles_dropped_depth", (long long)gs.dropped_depth);
    rs_json_set_int(rep->metrics, "triangles_dropped_grazing", (long long)gs.dropped_grazing);

    if (grid->nfaces == 0) {
        rs_err_set(err, RS_ERR_INPUT, path, 0, "no triangle survived the grid triangulation (%zu cells, %zu without "
                   "returns, %zu across depth jumps, %zu at grazing angles); expected a scan of surfaces",
                   gs.cells, gs.cells_no_return, gs.dropped_depth, gs.dropped_grazing);
        goto out;
    }

    double facet_m = 0, edge_per_m = 0;
    const char *facet_source = "config";
    if (rs_config_has(cfg, "mesh", "facet_size")) {
        facet_m = rs_config_real(cfg, "mesh", "facet_size");
    } else if (rs_config_has(cfg, "mesh", "facets")) {
        facet_source = "none ([mesh] facets)";
    } else {
        facet_source = "panorama";
        if (derive_facet_size(cfg, grid, &facet_m, &edge_per_m, err) != 0) goto out;
    }
    if (facet_m > 0) rs_json_set_num(rep->metrics, "facet_size_m", facet_m);
    rs_json_set_str(rep->metrics, "facet_size_source", facet_source);

    /* After the facet size: that is a property of what the scanner measured. */
    if (rs_config_bool(cfg, "mesh", "fill_nadir") && fill_nadir(cfg, c, &grid, rep, err) != 0) goto out;
    rs_json_set_int(rep->metrics, "faces_in", (long long)grid->nfaces);

    t0 = rs_now();
    rs_simplify_opts so;
    rs_simplify_defaults(&so);
    so.target_edge_m = edge_per_m > 0 ? 0 : facet_m;
    so.edge_per_metre = edge_per_m;
    if (edge_per_m > 0) rs_config_reals(cfg, "capture", "position", so.view_point);
    if (rs_config_has(cfg, "mesh", "facets")) so.target_faces = (size_t)rs_config_int(cfg, "mesh", "facets");
    rs_simplify_stats ss;
    simple = rs_simplify_apply(grid, &so, &ss, err);
    if (!simple) goto out;
    rs_report_time(rep, "simplify", rs_now() - t0);
    rs_json_set_int(rep->metrics, "collapses", (long long)ss.collapses);
    rs_json_set_int(rep->metrics, "rejected_topology", (long long)ss.rejected_topology);
    rs_json_set_int(rep->metrics, "rejected_flip", (long long)ss.rejected_flip);
    rs_json_set_int(rep->metrics, "rejected_quality", (long long)ss.rejected_quality);
    rs_json_set_int(rep->metrics, "rejected_size", (long long)ss.rejected_size);
    if (edge_per_m > 0) rs_json_set_num(rep->metrics, "edge_per_metre_of_distance", edge_per_m);
    rs_json_set_num(rep->metrics, "mean_edge_in_m", ss.mean_edge_in);
    report_mesh(rep, simple);
    rs_log_info("%zu grid triangles -> %zu facets (mean edge %.3g m -> %.3g m)", grid->nfaces, simple->nfaces,
                ss.mean_edge_in, ss.mean_edge_out);

    t0 = rs_now();
    if (write_mesh(simple, rs_work_path(cfg, "mesh.ply", path, sizeof path), "scan grids", facet_m, facet_source,
                   err) != 0)
        goto out;
    rs_report_time(rep, "write", rs_now() - t0);
    rc = 0;
out:
    rs_cloud_free(c);
    rs_mesh_free(grid);
    rs_mesh_free(simple);
    return rc;
}

int rs_mesh_run(const rs_config *cfg, rs_report *rep, rs_err *err)
{
    char dir[4096], in_path[4096];
    if (rs_workdir(cfg, dir, sizeof dir, err) != 0) return -1;
    if (rs_config_path(cfg, "mesh", "input_mesh", in_path, sizeof in_path)) return run_input_mesh(cfg, in_path, rep, err);
    return run_scan(cfg, rep, err);
}
