/* ingest: the ingest stage. Reads the [ingest] scan files (PTX or PLY, told apart by
 * content) into one cloud and writes cloud.ply. Exports rs_ingest_run. */
#include "stages.h"

#include <stdlib.h>

#include "cloud.h"
#include "log.h"

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
                          "[ingest] scan is not set; expected one or more PTX or PLY files (or [mesh] input_mesh)");
    char dir[4096];
    if (rs_workdir(cfg, dir, sizeof dir, err) != 0) return -1;

    double t0 = rs_now();
    rs_cloud *all = calloc(1, sizeof *all);
    if (!all) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    int rc = -1;
    rs_json *files = rs_json_set_arr(rep->metrics, "files");
    for (int i = 0; i < nfiles; i++) {
        rs_config_path_at(cfg, "ingest", "scan", i, path, sizeof path);
        rs_cloud *c = rs_cloud_read(path, err);
        if (!c) goto out;
        size_t valid = 0;
        for (size_t k = 0; k < c->npoints; k++) valid += c->valid[k] != 0;
        rs_log_info("%s: %zu points, %zu with a return, %d scan grid(s)", path, c->npoints, valid, c->nscans);
        rs_json *f = rs_json_push_obj(files);
        rs_json_set_str(f, "path", path);
        rs_json_set_int(f, "points", (long long)c->npoints);
        rs_json_set_int(f, "valid", (long long)valid);
        rs_json_set_int(f, "scans", c->nscans);
        int ok = rs_cloud_append(all, c, err);
        rs_cloud_free(c);
        if (ok != 0) goto out;
    }
    rs_report_time(rep, "read", rs_now() - t0);

    size_t valid = 0;
    for (size_t k = 0; k < all->npoints; k++) valid += all->valid[k] != 0;
    rs_json_set_int(rep->metrics, "points", (long long)all->npoints);
    rs_json_set_int(rep->metrics, "valid", (long long)valid);
    rs_json_set_int(rep->metrics, "scans", all->nscans);
    rs_json_set_int(rep->metrics, "unorganized", (long long)rs_cloud_unorganized(all));
    if (valid == 0) {
        rs_err_set(err, RS_ERR_INPUT, NULL, 0, "the scans hold no point with a return (all %zu are 0 0 0); "
                   "expected a scan of the scene", all->npoints);
        goto out;
    }

    t0 = rs_now();
    if (rs_cloud_write_ply(all, rs_work_path(cfg, "cloud.ply", path, sizeof path), err) != 0) goto out;
    rs_report_time(rep, "write", rs_now() - t0);
    rc = 0;
out:
    rs_cloud_free(all);
    return rc;
}
