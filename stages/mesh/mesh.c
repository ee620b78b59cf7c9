/* mesh: the mesh stage. Triangulates the scan grids of cloud.ply (one sheet where scans
 * overlap) or reconstructs its unorganized points (PCL), or takes [mesh] input_mesh as it is;
 * simplifies to the facet size, measures the result and writes mesh.ply. Exports rs_mesh_run. */
#include "stages/stages.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/cloud.h"
#include "common/cloud_ply.h"
#include "meshing/denoise.h"
#include "common/fileio.h"
#include "meshing/grid.h"
#include "common/log.h"
#include "common/mesh.h"
#include "pipeline/panorama.h"
#include "meshing/meshreport.h"
#include "meshing/nadir.h"
#include "meshing/overlap.h"
#include "meshing/refine.h"
#include "meshing/simplify.h"
#include "meshing/unorganized.h"

/* Cells spanning more than this many angular grid steps are not surface (the seam of a
 * sweep that does not close). */
#define MAX_GAP_STEPS 2.5

/* The [mesh] keys, and the [capture] position and [pipeline] threads it uses, read once.
 * (The panorama that sets the facet size by default is looked up by derive_facet_size.) */
typedef struct {
    const char *config_file; /* for messages */
    int has_input_mesh;      /* [mesh] input_mesh replaces the meshing: */
    char input_mesh[4096];
    int has_facet_size; /* [mesh] facet_size (m) */
    double facet_size_m;
    int has_facets; /* [mesh] facets: the facet budget */
    long facets;
    int fill_nadir;
    double nadir_max_rms;
    double overlap_tolerance;
    rs_unorg_opts unorg; /* unorganized points */
    rs_grid_opts grid;   /* scan grids, with the budget's target */
    size_t report_points;
    int denoise;
    rs_denoise_opts denoise_opts;
    int has_camera; /* [capture] position */
    double camera[3];
} mesh_opts;

static void mesh_opts_read(const rs_config *cfg, mesh_opts *o)
{
    memset(o, 0, sizeof *o);
    o->config_file = rs_config_file(cfg);
    o->has_input_mesh = rs_config_path(cfg, "mesh", "input_mesh", o->input_mesh, sizeof o->input_mesh) != NULL;
    o->has_facet_size = rs_config_has(cfg, "mesh", "facet_size");
    o->facet_size_m = o->has_facet_size ? rs_config_real(cfg, "mesh", "facet_size") : 0;
    o->has_facets = rs_config_has(cfg, "mesh", "facets");
    o->facets = o->has_facets ? rs_config_int(cfg, "mesh", "facets") : 0;
    o->fill_nadir = rs_config_bool(cfg, "mesh", "fill_nadir");
    o->nadir_max_rms = rs_config_real(cfg, "mesh", "nadir_max_rms");
    o->overlap_tolerance = rs_config_real(cfg, "mesh", "overlap_tolerance");
    o->unorg = (rs_unorg_opts){strcmp(rs_config_string(cfg, "mesh", "surface"), "poisson") == 0,
                               (int)rs_config_int(cfg, "mesh", "normal_neighbours"),
                               rs_config_has(cfg, "mesh", "max_edge") ? rs_config_real(cfg, "mesh", "max_edge") : 0,
                               (int)rs_config_int(cfg, "mesh", "poisson_depth"),
                               (int)rs_config_int(cfg, "pipeline", "threads")};
    o->grid = (rs_grid_opts){rs_config_real(cfg, "mesh", "max_depth_ratio"),
                             rs_config_real(cfg, "mesh", "max_grazing_deg") * M_PI / 180.0, MAX_GAP_STEPS, 0, 0};
    /* A budget far below the grid's cells: every k-th row and column (grid.h). */
    if (o->has_facets)
        o->grid.target_faces = (size_t)o->facets;
    else if (o->has_facet_size)
        o->grid.target_edge_m = o->facet_size_m;
    o->report_points = (size_t)rs_config_int(cfg, "mesh", "report_points");
    o->denoise = rs_config_bool(cfg, "mesh", "denoise");
    rs_denoise_defaults(&o->denoise_opts);
    o->denoise_opts.normal_iterations = (int)rs_config_int(cfg, "mesh", "denoise_iterations");
    o->denoise_opts.vertex_iterations = (int)rs_config_int(cfg, "mesh", "denoise_vertex_iterations");
    o->denoise_opts.sigma_r_deg = rs_config_real(cfg, "mesh", "denoise_sigma_r_deg");
    o->denoise_opts.sigma_s_edges = rs_config_real(cfg, "mesh", "denoise_sigma_s");
    o->denoise_opts.max_move_m = rs_config_real(cfg, "mesh", "denoise_max_move");
    o->has_camera = rs_capture_position(cfg, o->camera) == 0;
}

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
                      const char *facet_source, const double origin[3], rs_err *err)
{
    rs_ply *ply = rs_ply_new();
    if (!ply) return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
    int rc = -1;
    if (rs_ply_add_comment(ply, "rhoscan_generator rhoscan-mesh %s", RHOSCAN_VERSION) != 0 ||
        rs_ply_add_comment(ply, "rhoscan_source %s", source) != 0 ||
        (facet_size_m > 0 && rs_ply_add_comment(ply, "rhoscan_facet_size %.9g", facet_size_m) != 0) ||
        rs_ply_add_comment(ply, "rhoscan_facet_size_source %s", facet_source) != 0 ||
        (origin && (origin[0] != 0 || origin[1] != 0 || origin[2] != 0) &&
         rs_ply_add_comment(ply, "rhoscan_origin %.17g %.17g %.17g", origin[0], origin[1], origin[2]) != 0) ||
        !rs_mesh_to_ply(m, ply)) {
        rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory building the PLY");
        goto out;
    }
    rc = rs_ply_write(ply, path, 1, err);
out:
    rs_ply_free(ply);
    return rc;
}

static int derive_facet_size(const rs_config *cfg, const rs_mesh *m, double *facet_m, double *edge_per_m, rs_err *err);

/* [mesh] input_refine: the input's long edges split down to the facet size a scan would get
 * ([mesh] facet_size, else the panorama's, growing with the distance from the camera), so that a
 * model of a few large triangles per wall (CAD, BIM, a closed truth mesh) gets facets a panorama
 * resolves. Without either size it stays as it is, and the report says why. */
static int refine_input(const rs_config *cfg, rs_mesh **mesh, rs_report *rep, rs_err *err)
{
    if (!rs_config_bool(cfg, "mesh", "input_refine")) {
        rs_report_skip(rep, "input mesh refinement", "[mesh] input_refine = false");
        return 0;
    }
    rs_refine_opts ro = {0};
    if (rs_config_has(cfg, "mesh", "facet_size")) {
        ro.edge_m = rs_config_real(cfg, "mesh", "facet_size");
    } else {
        char pano[4096];
        int width = 0;
        int found = rs_capture_panorama_width(cfg, &width, pano, sizeof pano, err);
        if (found < 0) return -1;
        if (!found) {
            rs_report_skip(rep, "input mesh refinement", "no [mesh] facet_size and no panorama to derive it from");
            return 0;
        }
        double facet_m = 0;
        if (derive_facet_size(cfg, *mesh, &facet_m, &ro.edge_per_metre, err) != 0) return -1;
        rs_capture_position(cfg, ro.view_point);
    }
    rs_refine_stats st;
    rs_mesh *fine = rs_mesh_refine(*mesh, &ro, &st, err);
    if (!fine) return -1;
    rs_mesh_free(*mesh);
    *mesh = fine;
    rs_log_info("input mesh refined: %zu -> %zu faces in %d passes (%zu edges split)", st.faces_in, st.faces_out,
                st.passes, st.edges_split);
    rs_json_set_int(rep->metrics, "refined_faces_in", (long long)st.faces_in);
    rs_json_set_int(rep->metrics, "refined_edges_split", (long long)st.edges_split);
    if (ro.edge_m > 0) rs_json_set_num(rep->metrics, "refine_edge_m", ro.edge_m);
    if (ro.edge_per_metre > 0) rs_json_set_num(rep->metrics, "refine_edge_per_metre_of_distance", ro.edge_per_metre);
    return 0;
}

/* Input meshes from this many faces show the progress of their checks. */
#define INPUT_PROGRESS_FACES 1000000

/* [mesh] input_mesh: checked, cleaned of degenerate faces and unused vertices, written as it is. */
static int run_input_mesh(const rs_config *cfg, const char *in_path, rs_report *rep, rs_err *err)
{
    double t0 = rs_now();
    rs_mesh *m = rs_mesh_read(in_path, NULL, err), *out = NULL;
    if (!m) return -1;
    int rc = -1;
    /* Zero area at float precision: below (1e-6 of the model's size)^2. */
    double extent = rs_mesh_extent(m), min_area = 1e-12 * extent * extent;
    size_t kept = 0;
    rs_mesh_degenerate deg;
    uint32_t *remap = malloc((m->nverts ? m->nverts : 1) * sizeof *remap);
    uint8_t *drop = calloc(m->nfaces ? m->nfaces : 1, 1);
    rs_progress *prog = m->nfaces >= INPUT_PROGRESS_FACES
        ? rs_progress_start("mesh: checking the input mesh's faces", 2 * m->nfaces)
        : NULL;
    int marked = remap && drop ? rs_mesh_mark_degenerate(m, min_area, drop, &deg, prog) : -1;
    if (prog) rs_progress_end(prog);
    if (marked != 0) {
        rs_err_set(err, RS_ERR_SYSTEM, in_path, 0, "out of memory checking %zu faces", m->nfaces);
        goto out;
    }
    for (size_t v = 0; v < m->nverts; v++) remap[v] = UINT32_MAX;
    for (size_t f = 0; f < m->nfaces; f++) {
        const uint32_t *t = m->tris + 3 * f;
        if (drop[f]) continue;
        memmove(m->tris + 3 * kept++, t, 3 * sizeof *t);
        for (int j = 0; j < 3; j++) remap[t[j]] = 0;
    }
    size_t dropped = deg.zero_area, nv = 0;
    if (kept == 0) {
        rs_err_set(err, RS_ERR_INPUT, in_path, 0,
                   "[mesh] input_mesh: none of its %zu faces is a usable triangle (%zu of zero area, %zu with "
                   "collinear corners); expected a triangle mesh with some area",
                   m->nfaces, deg.zero_area, deg.collinear);
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
    if (dropped) rs_log_warn("%s: dropped %zu zero-area faces of %zu", in_path, dropped, m->nfaces);
    if (deg.collinear)
        rs_log_warn("%s: dropped %zu faces of %zu whose corners are collinear (to float precision)", in_path,
                    deg.collinear, m->nfaces);
    if (deg.coincident)
        rs_log_warn("%s: dropped %zu faces of %zu that repeat the corners of another face (coincident duplicates)",
                    in_path, deg.coincident, m->nfaces);
    if (refine_input(cfg, &out, rep, err) != 0) goto out;
    rs_json_set_str(rep->metrics, "source", "input_mesh");
    rs_json_set_int(rep->metrics, "faces_in", (long long)m->nfaces);
    rs_json_set_int(rep->metrics, "dropped_zero_area", (long long)dropped);
    rs_json_set_int(rep->metrics, "dropped_collinear", (long long)deg.collinear);
    rs_json_set_int(rep->metrics, "dropped_coincident", (long long)deg.coincident);
    rs_json_set_int(rep->metrics, "dropped_unused_vertices", (long long)(m->nverts - nv));
    report_mesh(rep, out);
    rs_report_time(rep, "read", rs_now() - t0);
    rs_report_skip(rep, "triangulation and simplification", "[mesh] input_mesh given");

    char path[4096];
    double t1 = rs_now();
    if (write_mesh(out, rs_work_path(cfg, "mesh.ply", path, sizeof path), "input_mesh", 0, "none (input_mesh)", NULL,
                   err) != 0)
        goto out;
    rs_report_time(rep, "write", rs_now() - t1);
    rc = 0;
out:
    free(remap);
    free(drop);
    rs_mesh_free(m);
    rs_mesh_free(out);
    return rc;
}

/* The facet size from the panorama: a facet spans about pixels_per_facet pixels wherever it is,
 * so its size grows with the distance from the camera (*edge_per_m: metres of edge per metre of
 * distance). *facet_m is that size at the median distance from the camera to the model. */
static int derive_facet_size(const rs_config *cfg, const rs_mesh *m, double *facet_m, double *edge_per_m, rs_err *err)
{
    char pano[4096];
    int width = 0;
    int found = rs_capture_panorama_width(cfg, &width, pano, sizeof pano, err);
    if (found < 0) return -1;
    if (!found)
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[mesh] facet_size is not set and there is no [capture] panorama or [rig] file to derive it "
                          "from; expected [mesh] facet_size = <metres> (or facets = <count>) or a panorama");
    double cam[3] = {0, 0, 0};
    rs_capture_position(cfg, cam);
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
        return rs_err_set(err, RS_ERR_INPUT, pano, 0,
                          "cannot derive a facet size: median distance %g m from the "
                          "camera to the model; expected the camera away from the scan",
                          med);
    rs_log_info("facet size grows with distance: %g px of a %d px panorama, %.4g m at the median distance %.3g m", ppf,
                width, *facet_m, med);
    return 0;
}

/* The nadir cap's vertex spacing: a third of the facet edge the budget asks for ([mesh]
 * facet_size, or from [mesh] facets and the area of grid as equilateral facets), so that the
 * simplifier still has some triangles per facet there; 0 (the grid's own steps) otherwise: a
 * size derived from the panorama shrinks near the camera, and the ground below is near. */
static double cap_spacing(const mesh_opts *o, const rs_mesh *grid)
{
    double facet_m = 0;
    if (o->has_facet_size) facet_m = o->facet_size_m;
    if (!(facet_m > 0) && o->has_facets && o->facets > 0) {
        double area = 0;
        for (size_t f = 0; f < grid->nfaces; f++) {
            const uint32_t *t = grid->tris + 3 * f;
            rs_v3 a = rs_mesh_vert(grid, t[0]), b = rs_mesh_vert(grid, t[1]), c = rs_mesh_vert(grid, t[2]);
            area += 0.5 * rs_v3_len(rs_v3_cross(rs_v3_sub(b, a), rs_v3_sub(c, a)));
        }
        facet_m = sqrt(4 * area / (sqrt(3) * (double)o->facets));
    }
    return facet_m > 0 ? facet_m / 3 : 0;
}

/* Adds each scan's nadir cap to the grid mesh (see nadir.h) on the grid's lattice (stride),
 * coarse when there is a budget; a scan whose ground below is not flat is left open and the
 * report says why. */
static int fill_nadir(const mesh_opts *o, const rs_cloud *c, int stride, rs_mesh **grid, rs_report *rep, rs_err *err)
{
    size_t added = 0;
    double spacing = cap_spacing(o, *grid);
    for (int s = 0; s < c->nscans; s++) {
        rs_nadir_stats ns;
        rs_mesh *cap = rs_nadir_cap_coarse(c, s, o->nadir_max_rms, stride, spacing, &ns, err);
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

/* Scan s of c triangulated alone (its figures added to gs) and, with [mesh] fill_nadir, its
 * nadir cap welded on at the grid's own spacing: the overlap test keeps or drops whole cap
 * faces, and coarse ones left duplicated sheets where another station saw the ground.
 * *nreal: the grid's own faces, which come first. NULL with err set on failure. */
static rs_mesh *scan_sheet(const mesh_opts *o, const rs_cloud *c, int s, rs_grid_stats *gs, size_t *nreal,
                           rs_report *rep, rs_err *err)
{
    rs_cloud one = *c; /* a view of scan s alone: the grid indexes the shared arrays */
    one.nscans = 1;
    one.scans = &c->scans[s];
    rs_grid_stats g1;
    rs_mesh *grid = rs_grid_triangulate(&one, &o->grid, &g1, err);
    if (!grid) return NULL;
    gs->cells += g1.cells;
    gs->cells_no_return += g1.cells_no_return;
    gs->dropped_gap += g1.dropped_gap;
    gs->dropped_depth += g1.dropped_depth;
    gs->dropped_grazing += g1.dropped_grazing;
    *nreal = grid->nfaces;
    gs->stride = g1.stride;
    if (!o->fill_nadir) return grid;
    rs_nadir_stats ns;
    rs_mesh *cap = rs_nadir_cap_coarse(c, s, o->nadir_max_rms, g1.stride, 0, &ns, err);
    if (!cap && !ns.why_not[0]) {
        rs_mesh_free(grid);
        return NULL;
    }
    if (!cap) {
        char what[64];
        snprintf(what, sizeof what, "nadir fill of scan %d", s);
        rs_report_skip(rep, what, "%s", ns.why_not);
        return grid;
    }
    rs_mesh *merged = rs_mesh_merge_welded(grid, cap);
    rs_mesh_free(cap);
    rs_mesh_free(grid);
    if (!merged) rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory merging %d scans", c->nscans);
    return merged;
}

/* Drops the faces of all whose surface another scan saw better (overlap.h); owner and guess:
 * per face, the scan it comes from and whether it is nadir fill. */
static int resolve_overlaps(const mesh_opts *o, const rs_cloud *c, rs_mesh *all, const int *owner, const uint8_t *guess,
                            rs_report *rep, rs_err *err)
{
    double t0 = rs_now();
    uint8_t *drop = malloc(all->nfaces ? all->nfaces : 1);
    if (!drop) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory merging %d scans", c->nscans);
    rs_overlap_stats os;
    if (rs_overlap_resolve(all, owner, guess, c->scans, c->nscans, o->overlap_tolerance, drop, &os, err) != 0) {
        free(drop);
        return -1;
    }
    rs_report_time(rep, "overlap", rs_now() - t0);
    rs_json_set_int(rep->metrics, "overlap_faces_dropped", (long long)os.dropped);
    rs_json_set_int(rep->metrics, "overlap_nadir_faces_dropped", (long long)os.dropped_guess);
    rs_log_info("%d scans: %zu of %zu faces dropped where another scan saw the surface better (%zu of them nadir "
                "fill)",
                c->nscans, os.dropped, all->nfaces, os.dropped_guess);
    size_t kept = 0;
    for (size_t f = 0; f < all->nfaces; f++)
        if (!drop[f]) memmove(all->tris + 3 * kept++, all->tris + 3 * f, 3 * sizeof *all->tris);
    all->nfaces = kept;
    free(drop);
    return 0;
}

/* Several scans: each grid triangulated alone with its nadir cap, then the faces whose
 * surface another scan saw better dropped (overlap.h), so that one sheet remains. */
static rs_mesh *multi_scan(const mesh_opts *o, const rs_cloud *c, rs_grid_stats *gs, rs_report *rep, rs_err *err)
{
    rs_mesh *all = rs_mesh_new(0, 0), *out = NULL;
    int *owner = NULL;
    uint8_t *guess = NULL;
    size_t caps = 0;
    if (!all) goto nomem;
    memset(gs, 0, sizeof *gs);
    for (int s = 0; s < c->nscans; s++) {
        size_t nreal;
        rs_mesh *grid = scan_sheet(o, c, s, gs, &nreal, rep, err);
        if (!grid) goto fail;
        size_t f0 = all->nfaces;
        rs_mesh *merged = rs_mesh_merge_welded(all, grid);
        int *ow = realloc(owner, (merged ? merged->nfaces : 1) * sizeof *ow);
        uint8_t *gu = realloc(guess, merged ? merged->nfaces : 1);
        if (ow) owner = ow;
        if (gu) guess = gu;
        if (!merged || !ow || !gu) {
            rs_mesh_free(merged);
            rs_mesh_free(grid);
            goto nomem;
        }
        for (size_t f = f0; f < merged->nfaces; f++) {
            owner[f] = s;
            guess[f] = f - f0 >= nreal; /* the cap's faces come after the grid's */
        }
        caps += grid->nfaces - nreal;
        rs_mesh_free(grid);
        rs_mesh_free(all);
        all = merged;
    }
    rs_json_set_int(rep->metrics, "nadir_triangles", (long long)caps);
    if (resolve_overlaps(o, c, all, owner, guess, rep, err) != 0) goto fail;
    out = all;
    all = NULL;
    goto done;
nomem:
    rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory merging %d scans", c->nscans);
fail:
done:
    rs_mesh_free(all);
    free(owner);
    free(guess);
    return out;
}

static void report_unorganized(rs_report *rep, const char *source, int poisson, const rs_unorg_stats *us)
{
    rs_json_set_str(rep->metrics, "source", source);
    rs_json_set_int(rep->metrics, "points", (long long)us->points);
    rs_json_set_num(rep->metrics, "spacing_median_m", us->spacing_median_m);
    rs_json_set_num(rep->metrics, "spacing_p90_m", us->spacing_p90_m);
    rs_json_set_int(rep->metrics, "points_no_normal", (long long)us->points_no_normal);
    if (us->normals_given) rs_json_set_str(rep->metrics, "normals", "from the scan file");
    rs_json_set_int(rep->metrics, "faces_reconstructed", (long long)us->faces_raw);
    if (poisson) {
        rs_json_set_num(rep->metrics, "poisson_cell_m", us->cell_m);
        rs_json_set_int(rep->metrics, "faces_trimmed", (long long)us->faces_trimmed);
        rs_json_set_int(rep->metrics, "faces_small_pieces", (long long)us->faces_pieces);
    } else
        rs_json_set_num(rep->metrics, "max_edge_m", us->max_edge_m);
}

static void report_grid(rs_report *rep, int nscans, const rs_grid_stats *gs)
{
    rs_json_set_str(rep->metrics, "source", "scan grids");
    rs_json_set_int(rep->metrics, "scans", nscans);
    rs_json_set_int(rep->metrics, "grid_cells", (long long)gs->cells);
    rs_json_set_int(rep->metrics, "grid_stride", gs->stride);
    rs_json_set_int(rep->metrics, "cells_no_return", (long long)gs->cells_no_return);
    rs_json_set_int(rep->metrics, "cells_dropped_gap", (long long)gs->dropped_gap);
    rs_json_set_int(rep->metrics, "triangles_dropped_depth", (long long)gs->dropped_depth);
    rs_json_set_int(rep->metrics, "triangles_dropped_grazing", (long long)gs->dropped_grazing);
}

/* Unorganized points (no scan grid): the surface reconstructed by PCL. */
static rs_mesh *reconstruct(const mesh_opts *o, const rs_cloud *c, const char **source, rs_report *rep, rs_err *err)
{
    double t0 = rs_now();
    rs_unorg_stats us;
    rs_mesh *m = rs_unorg_mesh(c, &o->unorg, &us, err);
    if (!m) return NULL;
    *source = o->unorg.poisson ? "unorganized points (Poisson)" : "unorganized points (greedy projection)";
    rs_report_time(rep, "reconstruct", rs_now() - t0);
    report_unorganized(rep, *source, o->unorg.poisson, &us);
    rs_log_info("%zu unorganized points (spacing median %.3g m, p90 %.3g m): %zu triangles", us.points,
                us.spacing_median_m, us.spacing_p90_m, m->nfaces);
    return m;
}

/* The surface of cloud.ply before simplification: its scan grids triangulated (nadir holes
 * closed: *nadir_done), or its unorganized points reconstructed. */
static rs_mesh *build_surface(const mesh_opts *o, const rs_cloud *c, int *nadir_done, int *stride, const char **source,
                              rs_report *rep, rs_err *err)
{
    double t0 = rs_now();
    *nadir_done = 0;
    *stride = 1;
    if (c->nscans == 0) return reconstruct(o, c, source, rep, err);
    size_t loose = rs_cloud_unorganized(c);
    if (loose)
        rs_report_skip(rep, "unorganized points", "%zu points belong to no scan grid; the grids are meshed", loose);
    rs_grid_stats gs;
    rs_mesh *grid;
    if (c->nscans == 1) {
        grid = rs_grid_triangulate(c, &o->grid, &gs, err);
    } else {
        grid = multi_scan(o, c, &gs, rep, err);
        *nadir_done = 1;
    }
    if (!grid) return NULL;
    *stride = gs.stride;
    *source = "scan grids";
    rs_report_time(rep, "triangulate", rs_now() - t0);
    report_grid(rep, c->nscans, &gs);
    if (gs.stride > 1)
        rs_log_info("grid triangulated every %d rows and columns: the budget is over %g times below the cells",
                    gs.stride, RS_GRID_MARGIN);
    if (grid->nfaces == 0) {
        rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                   "no triangle survived the grid triangulation (%zu cells, %zu without "
                   "returns, %zu across depth jumps, %zu at grazing angles); expected a scan of surfaces",
                   gs.cells, gs.cells_no_return, gs.dropped_depth, gs.dropped_grazing);
        rs_mesh_free(grid);
        return NULL;
    }
    return grid;
}

/* The quality report of the final mesh against the cloud's valid points. */
static int report_quality(const mesh_opts *o, const rs_cloud *c, const rs_mesh *m, rs_report *rep, rs_err *err)
{
    double t0 = rs_now();
    size_t n = 0;
    for (size_t i = 0; i < c->npoints; i++) n += c->valid[i] != 0;
    double *pts = malloc((n ? n : 1) * 3 * sizeof *pts);
    if (!pts) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    size_t k = 0;
    for (size_t i = 0; i < c->npoints; i++)
        if (c->valid[i]) memcpy(pts + 3 * k++, c->xyz + 3 * i, 3 * sizeof *pts);
    rs_mesh_quality q;
    int rc = rs_mesh_quality_measure(m, pts, n, o->report_points, 1.0, &q, err);
    free(pts);
    if (rc != 0) return -1;
    rs_mesh_quality_json(&q, rs_json_set_obj(rep->metrics, "quality"));
    rs_report_time(rep, "report", rs_now() - t0);
    rs_log_info("mesh: %zu facets, edges %.3g m mean (%.3g .. %.3g m, p5 .. p95), %zu boundary loops, %zu non-manifold "
                "edges",
                q.faces, q.edge_mean_m, q.edge_p5_m, q.edge_p95_m, q.boundary_loops, q.nonmanifold_edges);
    if (q.points_tested)
        rs_log_info("scan points to the mesh: mean %.4g m, p95 %.4g m, %.1f %% within 2 cm (%zu points)", q.dist_mean_m,
                    q.dist_p95_m, 100 * q.within_2cm, q.points_tested);
    return 0;
}

/* Positions that later stages read from the config ([capture] position, the calib stage's
 * correspondences) are in the frame of cloud.ply and mesh.ply: the world frame minus
 * rhoscan_origin when the ingest recentred a georeferenced scan (the ingest's own
 * [ingest] scanner_position is read before that, in the world frame). A [capture] position
 * nearer the model's world place than its recentred one was given in the world frame: every
 * ray from it would miss the model, so this stops with the position to give instead. */
static int check_capture_frame(const mesh_opts *o, const rs_cloud *c, rs_err *err)
{
    if ((c->origin[0] == 0 && c->origin[1] == 0 && c->origin[2] == 0) || !o->has_camera) return 0;
    const double *cam = o->camera;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < c->npoints; i++)
        if (c->valid[i])
            for (int j = 0; j < 3; j++) {
                lo[j] = fmin(lo[j], c->xyz[3 * i + j]);
                hi[j] = fmax(hi[j], c->xyz[3 * i + j]);
            }
    double d_local = 0, d_world = 0;
    for (int j = 0; j < 3; j++) {
        double centre = lo[j] <= hi[j] ? 0.5 * (lo[j] + hi[j]) : 0;
        d_local += (cam[j] - centre) * (cam[j] - centre);
        d_world += (cam[j] - centre - c->origin[j]) * (cam[j] - centre - c->origin[j]);
    }
    if (d_world < d_local)
        return rs_err_set(err, RS_ERR_INPUT, o->config_file, 0,
                          "[capture] position %.10g %.10g %.10g is in the georeferenced frame, but the scan was "
                          "recentred by rhoscan_origin %.10g %.10g %.10g (cloud.ply): expected the position in the "
                          "recentred frame, %.10g %.10g %.10g",
                          cam[0], cam[1], cam[2], c->origin[0], c->origin[1], c->origin[2], cam[0] - c->origin[0],
                          cam[1] - c->origin[1], cam[2] - c->origin[2]);
    return 0;
}

/* [mesh] denoise: the simplified mesh's normals filtered with its creases kept, the vertices
 * moved to follow them within denoise_max_move (denoise.h); a low sun turns the scan's normal
 * noise into E_sky error (docs/ACCURACY.md). The moves go to mesh.json. */
static int denoise_mesh(const mesh_opts *o, rs_mesh *m, rs_report *rep, rs_err *err)
{
    rs_json *d = rs_json_set_obj(rep->metrics, "denoise");
    rs_json_set_bool(d, "on", o->denoise);
    if (!o->denoise) return 0;
    double t0 = rs_now();
    rs_denoise_stats ds;
    if (rs_denoise_apply(m, &o->denoise_opts, &ds, err) != 0) {
        if (!err->file[0]) rs_err_set_file(err, o->config_file);
        return -1;
    }
    rs_report_time(rep, "denoise", rs_now() - t0);
    rs_json_set_int(d, "vertices_moved", (long long)ds.moved);
    rs_json_set_int(d, "vertices_at_max_move", (long long)ds.clamped);
    rs_json_set_num(d, "rms_move_m", ds.rms_move_m);
    rs_json_set_num(d, "max_move_m", ds.max_move_m);
    rs_json_set_num(d, "sigma_s_m", ds.sigma_s_m);
    rs_log_info("denoise: %zu of %zu vertices moved, RMS %.3g m, max %.3g m (%zu held at %g m)", ds.moved, m->nverts,
                ds.rms_move_m, ds.max_move_m, ds.clamped, o->denoise_opts.max_move_m);
    return 0;
}

/* The facet size the simplifier aims at: [mesh] facet_size, none with only [mesh] facets, else
 * from the panorama (growing with the distance: edge_per_m). */
typedef struct {
    double facet_m;     /* m, 0: none */
    double edge_per_m;  /* m of edge per m of distance from the camera, 0: a fixed size */
    const char *source; /* rhoscan_facet_size_source */
} facet_size;

static int choose_facet_size(const rs_config *cfg, const mesh_opts *o, const rs_mesh *grid, facet_size *fs, rs_err *err)
{
    fs->facet_m = 0;
    fs->edge_per_m = 0;
    fs->source = "config";
    if (o->has_facet_size) {
        fs->facet_m = o->facet_size_m;
    } else if (o->has_facets) {
        fs->source = "none ([mesh] facets)";
    } else {
        fs->source = "panorama";
        if (derive_facet_size(cfg, grid, &fs->facet_m, &fs->edge_per_m, err) != 0) return -1;
    }
    return 0;
}

static void report_simplify(rs_report *rep, const rs_simplify_stats *ss, double edge_per_m, const rs_mesh *simple)
{
    rs_json_set_int(rep->metrics, "collapses", (long long)ss->collapses);
    rs_json_set_int(rep->metrics, "rejected_topology", (long long)ss->rejected_topology);
    rs_json_set_int(rep->metrics, "rejected_flip", (long long)ss->rejected_flip);
    rs_json_set_int(rep->metrics, "rejected_quality", (long long)ss->rejected_quality);
    rs_json_set_int(rep->metrics, "rejected_size", (long long)ss->rejected_size);
    if (edge_per_m > 0) rs_json_set_num(rep->metrics, "edge_per_metre_of_distance", edge_per_m);
    rs_json_set_num(rep->metrics, "mean_edge_in_m", ss->mean_edge_in);
    report_mesh(rep, simple);
}

/* The grid simplified to the facet size or budget (simplify.h). */
static rs_mesh *simplify_to_facets(const mesh_opts *o, const rs_mesh *grid, const facet_size *fs, rs_report *rep,
                                   rs_err *err)
{
    double t0 = rs_now();
    rs_simplify_opts so;
    rs_simplify_defaults(&so);
    so.target_edge_m = fs->edge_per_m > 0 ? 0 : fs->facet_m;
    so.edge_per_metre = fs->edge_per_m;
    if (fs->edge_per_m > 0 && o->has_camera) memcpy(so.view_point, o->camera, sizeof so.view_point);
    if (o->has_facets) so.target_faces = (size_t)o->facets;
    rs_simplify_stats ss;
    rs_mesh *simple = rs_simplify_apply(grid, &so, &ss, err);
    if (!simple) return NULL;
    rs_report_time(rep, "simplify", rs_now() - t0);
    report_simplify(rep, &ss, fs->edge_per_m, simple);
    rs_log_info("%zu triangles -> %zu facets (mean edge %.3g m -> %.3g m)", grid->nfaces, simple->nfaces,
                ss.mean_edge_in, ss.mean_edge_out);
    return simple;
}

/* Several scans: the facets where two scans' simplified sheets still overlap are dropped.
 * Dropping a facet can uncover another pair behind it: a few passes. */
static int drop_overlapping_sheets(const mesh_opts *o, rs_mesh *simple, rs_report *rep, rs_err *err)
{
    size_t removed = 0, r1 = 1;
    for (int pass = 0; pass < 3 && r1 > 0; pass++) {
        if (rs_overlap_dedup(simple, o->overlap_tolerance, &r1, err) != 0) return -1;
        removed += r1;
    }
    rs_json_set_int(rep->metrics, "overlap_facets_dropped_after_simplify", (long long)removed);
    rs_json_set_int(rep->metrics, "faces", (long long)simple->nfaces);
    if (removed) rs_log_info("%zu facets dropped where two scans' simplified sheets still overlapped", removed);
    return 0;
}

/* Meshing of cloud.ply (grids or unorganized points), simplification, report. */
static int run_scan(const rs_config *cfg, const mesh_opts *o, rs_report *rep, rs_err *err)
{
    char path[4096];
    rs_mesh *grid = NULL, *simple = NULL;
    int rc = -1;
    double t0 = rs_now();
    if (!rs_file_exists(rs_work_path(cfg, "cloud.ply", path, sizeof path)))
        return rs_err_set(err, RS_ERR_INPUT, path, 0,
                          "not found: run the ingest stage first, or set [mesh] input_mesh");
    rs_cloud *c = rs_cloud_read_ply(path, err);
    if (!c) return -1;
    rs_report_time(rep, "read", rs_now() - t0);
    rs_json *origin = rs_json_set_arr(rep->metrics, "origin_m");
    for (int j = 0; j < 3; j++) rs_json_push_num(origin, c->origin[j]);
    if (check_capture_frame(o, c, err) != 0) goto out;

    int nadir_done, stride;
    const char *source = "scan grids";
    grid = build_surface(o, c, &nadir_done, &stride, &source, rep, err);
    if (!grid) {
        if (!err->file[0]) rs_err_set_file(err, path);
        goto out;
    }
    facet_size fs;
    if (choose_facet_size(cfg, o, grid, &fs, err) != 0) goto out;
    if (fs.facet_m > 0) rs_json_set_num(rep->metrics, "facet_size_m", fs.facet_m);
    rs_json_set_str(rep->metrics, "facet_size_source", fs.source);

    /* After the facet size: that is a property of what the scanner measured. */
    if (!nadir_done && c->nscans > 0 && o->fill_nadir && fill_nadir(o, c, stride, &grid, rep, err) != 0) goto out;
    rs_json_set_int(rep->metrics, "faces_in", (long long)grid->nfaces);
    if (!(simple = simplify_to_facets(o, grid, &fs, rep, err))) goto out;
    /* Before the overlap dedup: filtered normals make two scans' leftover sheets parallel. */
    if (denoise_mesh(o, simple, rep, err) != 0) goto out;
    if (c->nscans > 1 && drop_overlapping_sheets(o, simple, rep, err) != 0) goto out;
    if (report_quality(o, c, simple, rep, err) != 0) goto out;

    t0 = rs_now();
    if (write_mesh(simple, rs_work_path(cfg, "mesh.ply", path, sizeof path), source, fs.facet_m, fs.source, c->origin,
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
    char dir[4096];
    if (rs_workdir(cfg, dir, sizeof dir, err) != 0) return -1;
    mesh_opts o;
    mesh_opts_read(cfg, &o);
    if (o.has_input_mesh) return run_input_mesh(cfg, o.input_mesh, rep, err);
    return run_scan(cfg, &o, rep, err);
}
