/* ingest: the ingest stage. Reads the [ingest] scan files (PTX, PLY, PCD, XYZ/CSV, LAS, whichever
 * common/cloud_format.h finds each to be) into one cloud, recentres georeferenced coordinates,
 * cleans unorganized points (outlier removal, voxel downsampling, PCL) and writes cloud.ply.
 * Exports rs_ingest_run. */
#include "stages/stages.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "common/cloud.h"
#include "common/cloud_format.h"
#include "common/cloud_ply.h"
#include "common/fileio.h"
#include "common/las.h"
#include "common/log.h"
#include "common/pcl_bridge.h"
#include "stages/ingest/ingest_stream.h"

/* Indices of the valid points outside every scan grid, as floats for PCL. */
static float *loose_points(const rs_cloud *c, size_t *n, size_t **index)
{
    size_t first_loose = c->npoints - rs_cloud_unorganized(c), k = 0;
    for (size_t i = first_loose; i < c->npoints; i++) k += c->valid[i] != 0;
    float *xyz = malloc((k ? k : 1) * 3 * sizeof *xyz);
    *index = malloc((k ? k : 1) * sizeof **index);
    if (!xyz || !*index) {
        free(xyz);
        free(*index);
        *index = NULL;
        return NULL;
    }
    k = 0;
    for (size_t i = first_loose; i < c->npoints; i++) {
        if (!c->valid[i]) continue;
        for (int j = 0; j < 3; j++) xyz[3 * k + j] = (float)c->xyz[3 * i + j];
        (*index)[k++] = i;
    }
    *n = k;
    return xyz;
}

/* Exact copies of an unorganized point (merged exports, a stuck sensor) dropped, the first kept:
 * PCL's kd-tree cannot split coincident points, and 200000 of them kept the outlier removal busy
 * for 214 s (a search over all of them per point). */
static int drop_coincident(rs_cloud *c, rs_report *rep, size_t *distinct, rs_err *err)
{
    size_t first = c->npoints - rs_cloud_unorganized(c), n = c->npoints - first, cap = 16, dropped = 0;
    while (cap < 2 * n) cap *= 2;
    /* Slots hold the point's offset from first in 4 bytes: the table is a quarter of the cloud's
     * 32 bytes a point (measured: 10^7 points, 1.51 -> 0.61 GB peak with cloud.ply streamed). */
    if (n >= UINT32_MAX)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "%zu unorganized points: at most %u are supported", n,
                          UINT32_MAX - 1);
    uint32_t *slot = malloc(cap * sizeof *slot);
    if (!slot) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu points' coincidence table", n);
    for (size_t k = 0; k < cap; k++) slot[k] = UINT32_MAX;
    for (size_t i = first; i < c->npoints; i++) {
        if (!c->valid[i]) continue;
        const double *p = c->xyz + 3 * i;
        uint64_t h = rs_ingest_point_hash(p);
        for (size_t k = h & (cap - 1);; k = (k + 1) & (cap - 1)) {
            if (slot[k] == UINT32_MAX) {
                slot[k] = (uint32_t)(i - first);
                break;
            }
            const double *q = c->xyz + 3 * (first + slot[k]);
            if (p[0] == q[0] && p[1] == q[1] && p[2] == q[2]) {
                c->valid[i] = 0;
                dropped++;
                break;
            }
        }
    }
    free(slot);
    rs_json_set_int(rep->metrics, "coincident_removed", (long long)dropped);
    if (dropped)
        rs_log_warn("%zu of %zu unorganized points repeat the coordinates of another point: dropped", dropped, n);
    *distinct = 0;
    for (size_t i = first; i < c->npoints; i++) *distinct += c->valid[i] != 0;
    return 0;
}

#define MIN_SPREAD RS_INGEST_MIN_SPREAD

/* 1 when the valid unorganized points lie on one line: their covariance has rank 1, i.e. the sum
 * of its 2 x 2 principal minors (about lambda1 lambda2) is below MIN_SPREAD^2 trace^2. */
static int collinear_points(const rs_cloud *c)
{
    size_t first = c->npoints - rs_cloud_unorganized(c), n = 0;
    double mean[3] = {0, 0, 0}, cov[6] = {0};
    for (size_t i = first; i < c->npoints; i++)
        if (c->valid[i]) {
            n++;
            for (int j = 0; j < 3; j++) mean[j] += (c->xyz[3 * i + j] - mean[j]) / (double)n;
        }
    for (size_t i = first; i < c->npoints; i++)
        if (c->valid[i]) {
            double d[3] = {c->xyz[3 * i] - mean[0], c->xyz[3 * i + 1] - mean[1], c->xyz[3 * i + 2] - mean[2]};
            double p[6] = {d[0] * d[0], d[1] * d[1], d[2] * d[2], d[0] * d[1], d[0] * d[2], d[1] * d[2]};
            for (int j = 0; j < 6; j++) cov[j] += p[j];
        }
    double trace = cov[0] + cov[1] + cov[2];
    double minors =
        cov[0] * cov[1] - cov[3] * cov[3] + cov[0] * cov[2] - cov[4] * cov[4] + cov[1] * cov[2] - cov[5] * cov[5];
    return !(minors > MIN_SPREAD * MIN_SPREAD * trace * trace);
}

int rs_ingest_surface_check(const rs_config *cfg, size_t npoints, size_t distinct, int collinear, rs_err *err)
{
    char scan[4096];
    const char *file = rs_config_file(cfg);
    if (rs_config_path_count(cfg, "ingest", "scan") == 1 &&
        rs_config_path_at(cfg, "ingest", "scan", 0, scan, sizeof scan))
        file = scan;
    if (distinct < 3)
        return rs_err_set(err, RS_ERR_INPUT, file, 0,
                          "[ingest] scan: the %zu unorganized points are at %zu distinct position%s: expected a scan "
                          "of a surface (at least 3 distinct points, not on one line)",
                          npoints, distinct, distinct == 1 ? "" : "s");
    if (collinear)
        return rs_err_set(err, RS_ERR_INPUT, file, 0,
                          "[ingest] scan: the %zu unorganized points lie on one line (across it they spread less "
                          "than %g of its length): expected a scan of a surface",
                          distinct, RS_INGEST_MIN_SPREAD);
    return 0;
}

/* The unorganized points must be able to carry a surface: three distinct points, not on a line. */
static int check_unorganized(const rs_config *cfg, rs_cloud *c, rs_report *rep, rs_err *err)
{
    size_t distinct = 0;
    if (drop_coincident(c, rep, &distinct, err) != 0) return -1;
    return rs_ingest_surface_check(cfg, rs_cloud_unorganized(c), distinct, distinct >= 3 && collinear_points(c), err);
}

/* Statistical outlier removal, then voxel downsampling, of the unorganized points. Scan grids
 * are left alone: the grid mesher cuts their outliers at depth jumps, and thinning a grid
 * would break it. */
static int clean(const rs_config *cfg, rs_cloud *c, rs_report *rep, rs_err *err)
{
    size_t n, *index = NULL;
    float *xyz = loose_points(c, &n, &index);
    if (!xyz) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    int rc = -1;
    uint8_t *keep = NULL;
    float *vxyz = NULL, *vin = NULL;
    uint8_t *vrgb = NULL;
    long k = rs_config_int(cfg, "ingest", "outlier_neighbours");
    size_t removed = 0;
    if (n == 0) {
        rc = 0;
        goto out;
    }
    if (k > 0 && n > (size_t)k) {
        double t0 = rs_now();
        keep = malloc(n);
        if (!keep) {
            rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
            goto out;
        }
        if (rs_pcl_outliers(xyz, n, (int)k, rs_config_real(cfg, "ingest", "outlier_std"), keep, err) != 0) goto out;
        size_t m = 0;
        for (size_t i = 0; i < n; i++) {
            if (!keep[i]) {
                c->valid[index[i]] = 0;
                removed++;
                continue;
            }
            memcpy(xyz + 3 * m, xyz + 3 * i, 3 * sizeof *xyz);
            index[m++] = index[i];
        }
        n = m;
        rs_report_time(rep, "outliers", rs_now() - t0);
        rs_log_info("statistical outlier removal (%ld neighbours, %g sigma): %zu of %zu unorganized points removed", k,
                    rs_config_real(cfg, "ingest", "outlier_std"), removed, n + removed);
    } else {
        rs_report_skip(rep, "outlier removal",
                       k > 0 ? "too few unorganized points" : "[ingest] outlier_neighbours = 0");
    }
    rs_json_set_int(rep->metrics, "outliers_removed", (long long)removed);

    if (!rs_config_has(cfg, "ingest", "voxel_size")) {
        rs_report_skip(rep, "voxel downsampling", "[ingest] voxel_size not set");
        rc = 0;
        goto out;
    }
    double t0 = rs_now(), leaf = rs_config_real(cfg, "ingest", "voxel_size");
    float *in = NULL;
    uint8_t *rgb = NULL;
    if (c->intensity && !(in = malloc((n ? n : 1) * sizeof *in))) goto nomem;
    if (c->rgb && !(rgb = malloc((n ? n : 1) * 3))) {
        free(in);
        goto nomem;
    }
    for (size_t i = 0; i < n; i++) {
        if (in) in[i] = c->intensity[index[i]];
        if (rgb) memcpy(rgb + 3 * i, c->rgb + 3 * index[i], 3);
    }
    size_t m;
    int vr = rs_pcl_voxel(xyz, in, rgb, n, leaf, &m, &vxyz, &vin, &vrgb, err);
    free(in);
    free(rgb);
    if (vr != 0) goto out;
    /* The survivors replace the unorganized part: the first m of its slots get the centroids,
     * the rest become invalid (cloud.ply writes valid points only). */
    size_t first_loose = c->npoints - rs_cloud_unorganized(c);
    for (size_t i = first_loose; i < c->npoints; i++) c->valid[i] = 0;
    for (size_t i = 0; i < m; i++) {
        size_t at = first_loose + i;
        for (int j = 0; j < 3; j++) c->xyz[3 * at + j] = vxyz[3 * i + j];
        if (c->intensity) c->intensity[at] = vin[i];
        if (c->rgb) memcpy(c->rgb + 3 * at, vrgb + 3 * i, 3);
        c->valid[at] = 1;
    }
    if (c->normal) { /* a centroid has no normal of the file's */
        free(c->normal);
        c->normal = NULL;
        rs_log_info("voxel downsampling: the file's normals are not carried (the mesh stage estimates them)");
    }
    rs_report_time(rep, "voxel", rs_now() - t0);
    rs_log_info("voxel downsampling (%g m): %zu -> %zu unorganized points", leaf, n, m);
    rs_json_set_num(rep->metrics, "voxel_size_m", leaf);
    rs_json_set_int(rep->metrics, "voxel_points_in", (long long)n);
    rs_json_set_int(rep->metrics, "voxel_points_out", (long long)m);
    rc = 0;
    goto out;
nomem:
    rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
out:
    free(xyz);
    free(index);
    free(keep);
    free(vxyz);
    free(vin);
    free(vrgb);
    return rc;
}

int rs_ingest_run(const rs_config *cfg, rs_report *rep, rs_err *err)
{
    char path[4096];
    if (rs_config_path(cfg, "mesh", "input_mesh", path, sizeof path)) {
        rs_report_skip(rep, "ingest", "[mesh] input_mesh given");
        return 0;
    }
    int nfiles = rs_config_path_count(cfg, "ingest", "scan");
    if (nfiles <= 0)
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[ingest] scan is not set; expected one or more point-cloud files (or [mesh] input_mesh)");
    char dir[4096];
    if (rs_workdir(cfg, dir, sizeof dir, err) != 0) return -1;

    if (rs_ingest_can_stream(cfg))
        return rs_ingest_stream(cfg, rep, rs_work_path(cfg, "cloud.ply", path, sizeof path), err);
    double t0 = rs_now();
    rs_cloud *all = calloc(1, sizeof *all);
    if (!all) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    int rc = -1;
    rs_json *files = rs_json_set_arr(rep->metrics, "files");
    uint8_t las_keep[256];
    const char *classes = rs_config_string(cfg, "ingest", "las_classes");
    if (classes && rs_las_parse_classes(classes, las_keep, err) != 0) {
        rs_err_set_file(err, rs_config_file(cfg));
        goto out;
    }
    int keep_withheld = strcmp(rs_config_string(cfg, "ingest", "las_withheld"), "keep") == 0;
    uint64_t withheld_total = 0;
    for (int i = 0; i < nfiles; i++) {
        rs_config_path_at(cfg, "ingest", "scan", i, path, sizeof path);
        const char *kind;
        uint64_t withheld = 0;
        rs_cloud_read_opts opts = {.columns = rs_config_string(cfg, "ingest", "columns"),
                                   .las_keep = classes ? las_keep : NULL,
                                   .las_keep_withheld = keep_withheld,
                                   .las_withheld = &withheld};
        rs_cloud *c = rs_cloud_read_with(path, &opts, &kind, err);
        if (!c) goto out;
        withheld_total += withheld;
        size_t valid = 0;
        for (size_t k = 0; k < c->npoints; k++) valid += c->valid[k] != 0;
        if (valid == 0) { /* every file must bring something: an empty one is a wrong path or export */
            rs_err_set(err, RS_ERR_INPUT, path, 0,
                       "[ingest] scan: no point with a return among its %zu (all 0 0 0 or none); expected a scan of "
                       "the scene",
                       c->npoints);
            rs_cloud_free(c);
            goto out;
        }
        rs_log_info("%s (%s): %zu points, %zu with a return, %d scan grid(s)", path, kind, c->npoints, valid,
                    c->nscans);
        rs_json *f = rs_json_push_obj(files);
        rs_json_set_str(f, "path", path);
        rs_json_set_int(f, "points", (long long)c->npoints);
        rs_json_set_int(f, "valid", (long long)valid);
        rs_json_set_int(f, "scans", c->nscans);
        int ok = 0;
        if (all->npoints == 0 && all->nscans == 0 && !c->origin[0] && !c->origin[1] && !c->origin[2]) {
            /* The first cloud becomes the whole one, uncopied (appending it to the empty one gives the
             * same values): a 10^8-point LAS is 3 GB in memory. */
            rs_cloud_free(all);
            all = c;
        } else {
            ok = rs_cloud_append(all, c, err);
            rs_cloud_free(c);
        }
        if (ok != 0) goto out;
    }
    rs_report_time(rep, "read", rs_now() - t0);
    if (withheld_total) {
        rs_json_set_int(rep->metrics, "las_withheld_dropped", (long long)withheld_total);
        rs_log_info("%llu LAS points flagged withheld: dropped ([ingest] las_withheld = keep keeps them)",
                    (unsigned long long)withheld_total);
    }
    if (rs_config_reals(cfg, "ingest", "scanner_position", all->viewpoint) == 0) all->has_viewpoint = 1;

    /* Before anything turns coordinates into floats (PCL here, the mesh later). */
    if (rs_cloud_recentre(all, rs_config_real(cfg, "ingest", "recentre_above")))
        rs_log_info("georeferenced coordinates: recentred by (%.0f, %.0f, %.0f) m, kept as rhoscan_origin in "
                    "cloud.ply and mesh.ply",
                    all->origin[0], all->origin[1], all->origin[2]);
    rs_json *origin = rs_json_set_arr(rep->metrics, "origin_m");
    for (int j = 0; j < 3; j++) rs_json_push_num(origin, all->origin[j]);

    size_t valid_in = 0;
    for (size_t k = 0; k < all->npoints; k++) valid_in += all->valid[k] != 0;
    rs_json_set_int(rep->metrics, "points", (long long)all->npoints);
    rs_json_set_int(rep->metrics, "valid", (long long)valid_in);
    rs_json_set_int(rep->metrics, "scans", all->nscans);
    rs_json_set_int(rep->metrics, "unorganized", (long long)rs_cloud_unorganized(all));
    if (valid_in == 0) {
        rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                   "the scans hold no point with a return (all %zu are 0 0 0); "
                   "expected a scan of the scene",
                   all->npoints);
        goto out;
    }
    if (rs_cloud_unorganized(all) > 0 && (check_unorganized(cfg, all, rep, err) != 0 || clean(cfg, all, rep, err) != 0))
        goto out;
    size_t valid = 0;
    for (size_t k = 0; k < all->npoints; k++) valid += all->valid[k] != 0;
    rs_json_set_int(rep->metrics, "points_written", (long long)valid);

    t0 = rs_now();
    if (rs_cloud_write_ply(all, rs_work_path(cfg, "cloud.ply", path, sizeof path), err) != 0) goto out;
    rs_report_time(rep, "write", rs_now() - t0);
    rc = 0;
out:
    rs_cloud_free(all);
    return rc;
}
