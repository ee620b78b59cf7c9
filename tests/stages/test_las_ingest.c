/* test_las_ingest: the whole pipeline on a LAS file. The sample two_planes scan is written as a
 * LAS (floor class 2, wall class 6, plus noise points of class 7 high above) and read with
 * [ingest] las_classes = 2 6 and the scanner position: the ingest keeps exactly the floor and
 * wall points, the albedo meets the sample's own bound (rhoscan-eval with max_mean_rel_error of
 * sample_data/two_planes/expected.json), and cloud.ply and albedo.ply are byte for byte those of
 * the same points given as a PLY cloud. The same scan georeferenced
 * (moved to (500000, 5400000, 300)) with the scanner position in that frame is recentred, the
 * scanner with it. Without a scanner position the floor alone meshes with every facet facing
 * up; LAZ and empty LAS files are refused by the programs naming the file. */
#include "tests/testutil.h"
#include "tests/laswrite.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "common/cloud_ply.h"
#include "common/mesh.h"
#include "common/ply.h"
#include "common/ptx.h"

static const double local[3] = {0, 0, 0}, geo[3] = {500000, 5400000, 300}, near_geo[3] = {5000, 4000, 30};
#define NOISE 40

/* The sample's scan moved by geo into dir/scan.las; returns the floor + wall count, *origin the
 * shift the ingest will make when georeferenced (whole metres of the kept points' bounding box
 * centre), *scanner its position in the file's frame. */
static size_t write_scan(const char *dir, const double geo[3], double origin[3], double scanner[3])
{
    char path[2048];
    snprintf(path, sizeof path, "%s/sample_data/two_planes/scan.ptx", rs_test_source_dir());
    rs_err err = {0};
    rs_cloud *c = rs_ptx_read(path, &err);
    if (!c) fail_msg("%s", err.msg);
    double *xyz = malloc((c->npoints + NOISE) * 3 * sizeof *xyz);
    uint8_t *cls = malloc(c->npoints + NOISE);
    uint16_t *in = calloc(c->npoints + NOISE, sizeof *in);
    assert_true(xyz && cls && in);
    size_t n = 0;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    las_spec s = {.minor = 4, .format = 6, .scale = {1e-4, 1e-4, 1e-4}, .offset = {geo[0], geo[1], geo[2]}};
    for (size_t i = 0; i < c->npoints; i++) {
        if (!c->valid[i]) continue;
        for (int j = 0; j < 3; j++) {
            /* As the file will hold it: on the scale's grid. */
            double v = c->xyz[3 * i + j] + geo[j];
            v = llround((v - s.offset[j]) / s.scale[j]) * s.scale[j] + s.offset[j];
            xyz[3 * n + j] = v, lo[j] = fmin(lo[j], v), hi[j] = fmax(hi[j], v);
        }
        cls[n++] = c->xyz[3 * i + 2] < 0.05 ? 2 : 6;
    }
    for (int j = 0; j < 3; j++) {
        origin[j] = floor(0.5 * (lo[j] + hi[j]) + 0.5);
        scanner[j] = c->scans[0].position[j] + geo[j];
    }
    for (size_t k = 0; k < NOISE; k++, n++) { /* birds: far above, class 7 (low noise) */
        for (int j = 0; j < 3; j++) xyz[3 * n + j] = geo[j] + (j == 2 ? 40 : (double)k);
        cls[n] = 7;
    }
    snprintf(path, sizeof path, "%s/scan.las", dir);
    assert_int_equal(las_write(path, &s, n, xyz, in, NULL, cls), 0);
    /* The floor and wall points as an ASCII PLY (exact doubles), intensity 0 as in the LAS. */
    snprintf(path, sizeof path, "%s/scan.ply", dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f,
            "ply\nformat ascii 1.0\nelement vertex %zu\nproperty double x\nproperty double y\nproperty double z\n"
            "property float intensity\nend_header\n",
            n - NOISE);
    for (size_t i = 0; i < n - NOISE; i++)
        fprintf(f, "%.17g %.17g %.17g 0\n", xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    assert_int_equal(fclose(f), 0);
    free(xyz);
    free(cls);
    free(in);
    rs_cloud_free(c);
    return n - NOISE;
}

static int run(const char *cmd, char **out)
{
    int rc = rs_test_run(cmd, out);
    if (rc != 0 && rc != 1) print_message("exit %d: %s\n", rc, *out);
    return rc;
}

static void test_pipeline(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("las_ingest");
    double origin[3], scanner[3];
    size_t kept = write_scan(dir, local, origin, scanner);
    char cmd[8192], *out = NULL;
    snprintf(cmd, sizeof cmd,
             "'%s/rhoscan' run '%s/configs/two_planes.ini' --force --set 'pipeline.workdir=%s/work' "
             "--set 'ingest.scan=%s/scan.las' --set 'ingest.las_classes=2 6' "
             "--set 'ingest.scanner_position=%.4f %.4f %.4f'",
             rs_test_bin_dir(), rs_test_source_dir(), dir, dir, scanner[0], scanner[1], scanner[2]);
    int rc = run(cmd, &out);
    assert_int_equal(rc, 0);
    free(out);
    assert_int_equal((size_t)rs_test_json_number(rs_test_path(dir, "work/ingest.json"), "points"), kept);
    /* The sample's bound on the albedo error per truth part. */
    char expected[2048];
    snprintf(expected, sizeof expected, "%s/sample_data/two_planes/expected.json", rs_test_source_dir());
    double bound = rs_test_json_number(expected, "max_mean_rel_error");
    snprintf(cmd, sizeof cmd, "'%s/rhoscan-eval' '%s/sample_data/two_planes' '%s/work' --out '%s/eval' --max-error %g",
             rs_test_bin_dir(), rs_test_source_dir(), dir, dir, bound);
    rc = run(cmd, &out);
    if (rc != 0) fail_msg("rhoscan-eval exit %d: %s", rc, out);
    free(out);
    /* The same points as a PLY cloud (the unorganized path before LAS): the same albedo.ply. */
    snprintf(cmd, sizeof cmd,
             "'%s/rhoscan' run '%s/configs/two_planes.ini' --force --set 'pipeline.workdir=%s/work_ply' "
             "--set 'ingest.scan=%s/scan.ply' --set 'ingest.scanner_position=%.4f %.4f %.4f'",
             rs_test_bin_dir(), rs_test_source_dir(), dir, dir, scanner[0], scanner[1], scanner[2]);
    assert_int_equal(run(cmd, &out), 0);
    free(out);
    snprintf(cmd, sizeof cmd,
             "cmp '%s/work/cloud.ply' '%s/work_ply/cloud.ply' && cmp '%s/work/albedo.ply' '%s/work_ply/albedo.ply'",
             dir, dir, dir, dir);
    rc = run(cmd, &out);
    if (rc != 0) fail_msg("the LAS and PLY runs differ: %s", out);
    free(out);
    rs_test_rmtree(dir);
}

/* Georeferenced: the ingest recentres by the whole metres of the points' centre, and moves the
 * scanner position (given in the file's frame) with them. */
static void test_georeferenced(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("las_ingest");
    double origin[3], scanner[3];
    size_t kept = write_scan(dir, geo, origin, scanner);
    char cmd[8192], *out = NULL;
    snprintf(cmd, sizeof cmd,
             "'%s/rhoscan' run '%s/configs/two_planes.ini' --force --only ingest --set 'pipeline.workdir=%s/work' "
             "--set 'ingest.scan=%s/scan.las' --set 'ingest.las_classes=2 6' "
             "--set 'ingest.scanner_position=%.4f %.4f %.4f'",
             rs_test_bin_dir(), rs_test_source_dir(), dir, dir, scanner[0], scanner[1], scanner[2]);
    assert_int_equal(run(cmd, &out), 0);
    free(out);
    const char *ingest = rs_test_path(dir, "work/ingest.json");
    assert_int_equal((size_t)rs_test_json_number(ingest, "points"), kept);
    double o[3];
    rs_test_json_vec3(rs_test_json_file(ingest), "origin_m", o);
    rs_err err = {0};
    rs_cloud *c = rs_cloud_read_ply(rs_test_path(dir, "work/cloud.ply"), &err);
    if (!c) fail_msg("%s", err.msg);
    assert_true(c->has_viewpoint && !c->normals_up);
    for (int j = 0; j < 3; j++) {
        assert_true(o[j] == origin[j] && c->origin[j] == origin[j]);
        assert_true(fabs(c->viewpoint[j] - (scanner[j] - origin[j])) < 1e-9);
    }
    rs_cloud_free(c);
    rs_test_rmtree(dir);
}

/* A georeferenced run to the end (a shift the truth's float vertices can still hold; the capture's
 * position given in the recentred frame, as the mesh stage asks): albedo.ply
 * carries rhoscan_origin, and rhoscan-eval, which moves the facets back by it, matches them to a
 * truth moved the same way and finds the sample's bound met. */
static void test_georeferenced_albedo(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("las_ingest");
    double origin[3], scanner[3];
    write_scan(dir, near_geo, origin, scanner);
    char cmd[8192], *out = NULL;
    snprintf(cmd, sizeof cmd,
             "'%s/rhoscan' run '%s/configs/two_planes.ini' --force --set 'pipeline.workdir=%s/work' "
             "--set 'ingest.scan=%s/scan.las' --set 'ingest.las_classes=2 6' --set ingest.recentre_above=1000 "
             "--set 'ingest.scanner_position=%.4f %.4f %.4f' --set 'capture.position=%.4f %.4f %.4f'",
             rs_test_bin_dir(), rs_test_source_dir(), dir, dir, scanner[0], scanner[1], scanner[2],
             near_geo[0] - origin[0], near_geo[1] - 9 - origin[1], near_geo[2] + 4 - origin[2]);
    int rc = run(cmd, &out);
    if (rc != 0) fail_msg("exit %d: %s", rc, out);
    free(out);
    rs_err err = {0};
    rs_ply *alb = rs_ply_read(rs_test_path(dir, "work/albedo.ply"), &err);
    if (!alb) fail_msg("%s", err.msg);
    const char *o = rs_ply_find_comment(alb, "rhoscan_origin");
    double oo[3] = {0, 0, 0};
    if (!o || sscanf(o, "%lf %lf %lf", &oo[0], &oo[1], &oo[2]) != 3) fail_msg("albedo.ply has no rhoscan_origin");
    for (int j = 0; j < 3; j++) assert_true(oo[j] == origin[j]);
    rs_ply_free(alb);
    /* The truth moved by near_geo, its images as they are. */
    char src[2048];
    snprintf(src, sizeof src, "%s/sample_data/two_planes", rs_test_source_dir());
    assert_int_equal(mkdir(rs_test_path(dir, "truth"), 0755), 0);
    static const char *const images[] = {"pano.exr", "pano_diffcol.exr", "pano_diffdir.exr", "pano_diffind.exr"};
    for (int k = 0; k < 4; k++) {
        char from[4096], to[4096];
        snprintf(from, sizeof from, "%s/%s", src, images[k]);
        snprintf(to, sizeof to, "%s/truth/%s", dir, images[k]);
        assert_int_equal(symlink(from, to), 0);
    }
    snprintf(cmd, sizeof cmd, "%s/truth.ply", src);
    rs_ply *truth = rs_ply_read(cmd, &err);
    if (!truth) fail_msg("%s", err.msg);
    rs_ply_element *v = rs_ply_find_element(truth, "vertex");
    static const char *const axes[3] = {"x", "y", "z"};
    for (int j = 0; j < 3; j++) {
        rs_ply_prop *p = rs_ply_find_prop(v, axes[j]);
        assert_non_null(p);
        for (size_t i = 0; i < v->count; i++) p->data[i] += near_geo[j];
    }
    if (rs_ply_write(truth, rs_test_path(dir, "truth/truth.ply"), 1, &err) != 0) fail_msg("%s", err.msg);
    rs_ply_free(truth);
    char expected[4096];
    snprintf(expected, sizeof expected, "%s/expected.json", src);
    double bound = rs_test_json_number(expected, "max_mean_rel_error");
    snprintf(cmd, sizeof cmd, "'%s/rhoscan-eval' '%s/truth' '%s/work' --out '%s/eval' --max-error %g",
             rs_test_bin_dir(), dir, dir, dir, bound);
    rc = run(cmd, &out);
    if (rc != 0) fail_msg("rhoscan-eval exit %d: %s", rc, out);
    free(out);
    const char *ej = rs_test_path(dir, "eval/eval.json");
    double matched = rs_test_json_number(ej, "matched"), total = rs_test_json_number(ej, "facets_total");
    print_message("georeferenced: %.0f of %.0f facets matched to the moved truth\n", matched, total);
    assert_true(matched > 0.95 * total);
    rs_test_rmtree(dir);
}

/* No scanner position: the floor (class 2) meshes with its facets facing up (+Z). */
static void test_upward(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("las_ingest");
    double origin[3], scanner[3];
    write_scan(dir, local, origin, scanner);
    char cmd[8192], *out = NULL;
    snprintf(cmd, sizeof cmd,
             "'%s/rhoscan' run '%s/configs/two_planes.ini' --force --only ingest --set 'pipeline.workdir=%s/work' "
             "--set 'ingest.scan=%s/scan.las' --set ingest.las_classes=2 && '%s/rhoscan' mesh "
             "'%s/configs/two_planes.ini' --set 'pipeline.workdir=%s/work' --set mesh.facet_size=0.5",
             rs_test_bin_dir(), rs_test_source_dir(), dir, dir, rs_test_bin_dir(), rs_test_source_dir(), dir);
    int rc = run(cmd, &out);
    assert_int_equal(rc, 0);
    free(out);
    rs_err err = {0};
    rs_mesh *m = rs_mesh_read(rs_test_path(dir, "work/mesh.ply"), NULL, &err);
    if (!m) fail_msg("%s", err.msg);
    assert_true(m->nfaces > 10);
    size_t down = 0;
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 c, nrm;
        double area;
        rs_mesh_face(m, f, &c, &nrm, &area);
        down += nrm.z <= 0;
    }
    if (down) fail_msg("%zu of %zu floor facets face down", down, m->nfaces);
    rs_mesh_free(m);
    rs_cloud *c = rs_cloud_read_ply(rs_test_path(dir, "work/cloud.ply"), &err);
    if (!c) fail_msg("%s", err.msg);
    assert_true(c->normals_up && !c->has_viewpoint); /* the comment rhoscan_normals_up */
    rs_cloud_free(c);
    rs_test_rmtree(dir);
}

/* Coincident points (a merged export, a stuck sensor) are dropped by the ingest, the first of
 * each kept: 1000 distinct points on a plane, 300 repeats of them, and one point at x = -0 that
 * repeats one at +0 (LAS stores both as the integer 0). */
static void test_coincident(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("las_ingest");
    enum { DISTINCT = 1000, REPEATS = 300 };
    double *xyz = malloc((DISTINCT + REPEATS + 2) * 3 * sizeof *xyz);
    assert_non_null(xyz);
    size_t n = 0;
    for (int k = 0; k < DISTINCT; k++, n++)
        xyz[3 * n] = (k % 40) * 0.1, xyz[3 * n + 1] = (k / 40) * 0.1 + 0.1, xyz[3 * n + 2] = 0.01 * (k % 7);
    for (int k = 0; k < REPEATS; k++, n++)
        for (int j = 0; j < 3; j++) xyz[3 * n + j] = xyz[3 * (size_t)(k * 3 % DISTINCT) + j];
    xyz[3 * n] = 0, xyz[3 * n + 1] = 0, xyz[3 * n + 2] = 0, n++; /* +0 and its -0 twin */
    xyz[3 * n] = -0.0, xyz[3 * n + 1] = 0, xyz[3 * n + 2] = 0, n++;
    las_spec s = {.minor = 2, .format = 0, .scale = {1e-3, 1e-3, 1e-3}};
    assert_int_equal(las_write(rs_test_path(dir, "dup.las"), &s, n, xyz, NULL, NULL, NULL), 0);
    free(xyz);
    char cmd[8192], *out = NULL;
    snprintf(cmd, sizeof cmd,
             "'%s/rhoscan' ingest '%s/configs/two_planes.ini' --set 'pipeline.workdir=%s/work' "
             "--set 'ingest.scan=%s/dup.las' --set ingest.outlier_neighbours=0",
             rs_test_bin_dir(), rs_test_source_dir(), dir, dir);
    int rc = run(cmd, &out);
    if (rc != 0) fail_msg("exit %d: %s", rc, out);
    free(out);
    const char *ingest = rs_test_path(dir, "work/ingest.json");
    assert_int_equal((size_t)rs_test_json_number(ingest, "coincident_removed"), REPEATS + 1);
    rs_err err = {0};
    rs_cloud *c = rs_cloud_read_ply(rs_test_path(dir, "work/cloud.ply"), &err);
    if (!c) fail_msg("%s", err.msg);
    assert_int_equal(c->npoints, DISTINCT + 1);
    rs_cloud_free(c);
    rs_test_rmtree(dir);
}

/* The programs refuse a LAZ file and a LAS without points (exit 1, the file named). */
static void test_refused(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("las_ingest");
    las_spec s = {.minor = 2, .format = 1, .scale = {0.01, 0.01, 0.01}};
    const double p[3] = {1, 2, 3};
    assert_int_equal(las_write(rs_test_path(dir, "empty.las"), &s, 0, p, NULL, NULL, NULL), 0);
    s.format = 3; /* then the compressed flag set on its format byte */
    assert_int_equal(las_write(rs_test_path(dir, "c.laz"), &s, 1, p, NULL, NULL, NULL), 0);
    FILE *f = fopen(rs_test_path(dir, "c.laz"), "r+b");
    assert_non_null(f);
    assert_int_equal(fseek(f, 104, SEEK_SET), 0);
    assert_int_equal(fputc(0x83, f), 0x83);
    fclose(f);
    const char *names[2] = {"empty.las", "c.laz"}, *words[2] = {"no point with a return among its 0", "laszip -i"};
    for (int k = 0; k < 2; k++) {
        char cmd[8192], *out = NULL;
        snprintf(cmd, sizeof cmd,
                 "'%s/rhoscan' ingest '%s/configs/two_planes.ini' --set 'pipeline.workdir=%s/work' "
                 "--set 'ingest.scan=%s/%s'",
                 rs_test_bin_dir(), rs_test_source_dir(), dir, dir, names[k]);
        int rc = rs_test_run(cmd, &out);
        assert_int_equal(rc, 1);
        if (!strstr(out, names[k]) || !strstr(out, words[k])) fail_msg("unexpected message: %s", out);
        free(out);
    }
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_pipeline), cmocka_unit_test(test_georeferenced),
             cmocka_unit_test(test_georeferenced_albedo), cmocka_unit_test(test_coincident),
             cmocka_unit_test(test_upward), cmocka_unit_test(test_refused))
