/* test_ingest_stream: the ingest's streaming path (stages/ingest/ingest_stream.c) writes the same
 * cloud.ply as the whole-cloud path ([ingest] streaming = false) for LAS files with georeferenced
 * coordinates (recentred), 16-bit colour first seen mid-file, a class filter, withheld points,
 * exact copies (also with a coincidence table of 64 points: many passes) and a second file
 * without colour; the withheld points are dropped by default and counted, kept on request.
 * bunnyDouble.e57 (two reader chunks) streamed equals the whole-cloud path. E57 normals (testWithNormals.e57 of the shared set, skipped when absent) reach cloud.ply as nx
 * ny nz, and a PLY cloud's normals are used by the mesh stage as given (no scanner position
 * needed; faces wound to them). */
#include "tests/testutil.h"
#include "tests/laswrite.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/cloud_ply.h"
#include "common/e57.h"
#include "common/mesh.h"
#include "common/ply.h"

static char *slurp(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *b = malloc((size_t)len + 1);
    *n = fread(b, 1, (size_t)len, f);
    b[*n] = 0;
    fclose(f);
    return b;
}

static void ingest(const char *dir, const char *work, const char *sets, const char *env)
{
    char cmd[8192], *out = NULL;
    snprintf(cmd, sizeof cmd,
             "%s '%s/rhoscan' ingest '%s/configs/two_planes.ini' --set 'pipeline.workdir=%s/%s' "
             "--set 'ingest.scan=%s/a.las %s/b.las' --set ingest.outlier_neighbours=0 %s",
             env, rs_test_bin_dir(), rs_test_source_dir(), dir, work, dir, dir, sets);
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) fail_msg("exit %d: %s", rc, out);
    free(out);
}

static void same_file(const char *a, const char *b)
{
    size_t na, nb;
    char *x = slurp(a, &na), *y = slurp(b, &nb);
    assert_non_null(x);
    assert_non_null(y);
    if (na != nb || memcmp(x, y, na) != 0) fail_msg("%s and %s differ (%zu and %zu bytes)", a, b, na, nb);
    free(x);
    free(y);
}

static void write_inputs(const char *dir)
{
    enum { N = 3000 };
    double *xyz = malloc(N * 3 * sizeof *xyz);
    uint16_t *rgb = malloc(N * 3 * sizeof *rgb), *in = malloc(N * sizeof *in);
    uint8_t *cls = malloc(N), *wh = malloc(N);
    for (int k = 0; k < N; k++) {
        int q = k % 2000; /* the last 1000 repeat the first 1000: exact copies */
        xyz[3 * k] = 512000.0 + (q % 50) * 0.05, xyz[3 * k + 1] = 4100000.0 + (q / 50) * 0.05;
        xyz[3 * k + 2] = 30.0 + 0.01 * (q % 7);
        for (int j = 0; j < 3; j++) rgb[3 * k + j] = (uint16_t)(k < 700 ? (k + j) % 256 : (k * 37 + j * 1000) % 65536);
        in[k] = (uint16_t)(k * 11);
        cls[k] = k % 13 == 0 ? 7 : 2;
        wh[k] = k % 17 == 0;
    }
    las_spec s = {.minor = 4, .format = 7, .scale = {1e-3, 1e-3, 1e-3}, .offset = {512000, 4100000, 0}, .withheld = wh};
    assert_int_equal(las_write(rs_test_path(dir, "a.las"), &s, N, xyz, in, rgb, cls), 0);
    las_spec t = {.minor = 2, .format = 1, .scale = {1e-3, 1e-3, 1e-3}, .offset = {512000, 4100000, 0}};
    for (int k = 0; k < N; k++) xyz[3 * k + 2] += 5;
    assert_int_equal(las_write(rs_test_path(dir, "b.las"), &t, N / 2, xyz, in, NULL, cls), 0);
    free(xyz), free(rgb), free(in), free(cls), free(wh);
}

static void test_las_same_bytes(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("ingest_stream");
    write_inputs(dir);
    const char *variants[][2] = {
        {"", ""},
        {"--set 'ingest.las_classes=2'", ""},
        {"--set ingest.las_withheld=keep", ""},
    };
    for (size_t v = 0; v < sizeof variants / sizeof variants[0]; v++) {
        char sets[512], whole[512], few[64];
        ingest(dir, "stream", variants[v][0], "");
        snprintf(whole, sizeof whole, "%s --set ingest.streaming=false", variants[v][0]);
        ingest(dir, "whole", whole, "");
        snprintf(few, sizeof few, "RHOSCAN_INGEST_BUCKET_POINTS=64");
        snprintf(sets, sizeof sets, "%s", variants[v][0]);
        ingest(dir, "buckets", sets, few);
        same_file(rs_test_path(dir, "whole/cloud.ply"), rs_test_path(dir, "stream/cloud.ply"));
        same_file(rs_test_path(dir, "whole/cloud.ply"), rs_test_path(dir, "buckets/cloud.ply"));
        const char *keys[] = {"coincident_removed", "points_written", "points"};
        for (int k = 0; k < 3; k++) {
            double a = rs_test_json_number(rs_test_path(dir, "whole/ingest.json"), keys[k]),
                   b = rs_test_json_number(rs_test_path(dir, "stream/ingest.json"), keys[k]);
            if (a != b) fail_msg("variant %zu: %s %g (whole) vs %g (streamed)", v, keys[k], a, b);
        }
        assert_true(rs_test_json_number(rs_test_path(dir, "stream/ingest.json"), "coincident_removed") > 0);
        if (v < 2) /* a.las: 3000 points, every 17th withheld: 177 dropped (before the class filter) */
            for (int k = 0; k < 2; k++) {
                double wh = rs_test_json_number(rs_test_path(dir, k ? "stream/ingest.json" : "whole/ingest.json"),
                                                "las_withheld_dropped");
                if (wh != 177) fail_msg("variant %zu: las_withheld_dropped %g, expected 177", v, wh);
            }
    }
    rs_test_rmtree(dir);
}

/* testWithNormals.e57: (1,0,0) with a normal about (0.001, 0.001, 1) and (2,0,0) about
 * (0.001, 1, 0.001), carried through rs_cloud and cloud.ply. */
static void test_e57_normals_in_cloud_ply(void **state)
{
    (void)state;
    char src[2048];
    snprintf(src, sizeof src, "%s/formats/e57/testWithNormals.e57", rs_test_shared_dir());
    rs_err err = {0};
    rs_cloud *c = rs_e57_read(src, &err);
    if (!c) fail_msg("%s", err.msg);
    assert_non_null(c->normal);
    assert_int_equal(c->npoints, 2);
    const char *dir = rs_test_tmpdir("ingest_stream");
    assert_int_equal(rs_cloud_write_ply(c, rs_test_path(dir, "n.ply"), &err), 0);
    rs_ply *ply = rs_ply_read(rs_test_path(dir, "n.ply"), &err);
    assert_non_null(ply);
    rs_ply_element *el = rs_ply_find_element(ply, "vertex");
    assert_non_null(rs_ply_find_prop(el, "nx"));
    rs_ply_free(ply);
    rs_cloud *b = rs_cloud_read_ply(rs_test_path(dir, "n.ply"), &err);
    assert_non_null(b);
    assert_non_null(b->normal);
    const double want[2][3] = {{0.001, 0.001, 1.0}, {0.001, 1.0, 0.001}};
    for (int i = 0; i < 2; i++)
        for (int j = 0; j < 3; j++)
            if (fabs(b->normal[3 * i + j] - want[i][j]) > 2e-3 || b->normal[3 * i + j] != c->normal[3 * i + j])
                fail_msg("point %d normal %d: %g (read back) %g (E57), expected about %g", i, j, b->normal[3 * i + j],
                         c->normal[3 * i + j], want[i][j]);
    rs_cloud_free(b);
    rs_cloud_free(c);
    /* bunnyDouble.e57 (30571 points: two chunks of the E57 reader) streamed and whole */
    for (int k = 0; k < 2; k++) {
        char cmd[8192], *out = NULL;
        snprintf(cmd, sizeof cmd,
                 "'%s/rhoscan' ingest '%s/configs/two_planes.ini' --set 'pipeline.workdir=%s/%s' --set "
                 "'ingest.scan=%s/formats/e57/bunnyDouble.e57' --set ingest.outlier_neighbours=0 --set "
                 "ingest.streaming=%s",
                 rs_test_bin_dir(), rs_test_source_dir(), dir, k ? "whole" : "stream", rs_test_shared_dir(),
                 k ? "false" : "true");
        int rc = rs_test_run(cmd, &out);
        if (rc != 0) fail_msg("exit %d: %s", rc, out);
        if (!k && !strstr(out, "streamed")) fail_msg("bunnyDouble.e57 was not streamed: %s", out);
        free(out);
    }
    same_file(rs_test_path(dir, "whole/cloud.ply"), rs_test_path(dir, "stream/cloud.ply"));
    rs_test_rmtree(dir);
}

/* A PLY plane whose normals point down (-z): no scanner position, no LAS "up"; the mesh stage
 * takes the normals as given and winds its faces to them. */
static void test_mesh_uses_given_normals(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("ingest_stream");
    FILE *f = fopen(rs_test_path(dir, "plane.ply"), "w");
    assert_non_null(f);
    enum { S = 30 };
    fprintf(f,
            "ply\nformat ascii 1.0\nelement vertex %d\nproperty double x\nproperty double y\nproperty double z\n"
            "property float nx\nproperty float ny\nproperty float nz\nend_header\n",
            S * S);
    for (int i = 0; i < S; i++)
        for (int j = 0; j < S; j++)
            fprintf(f, "%.17g %.17g %.17g 0 0 -1\n", 0.1 * i + 0.013 * (j % 3), 0.1 * j, 0.002 * ((i * 7 + j) % 5));
    assert_int_equal(fclose(f), 0);
    char cmd[8192], *out = NULL;
    snprintf(cmd, sizeof cmd,
             "'%s/rhoscan' ingest '%s/configs/two_planes.ini' --set 'pipeline.workdir=%s/work' --set "
             "'ingest.scan=%s/plane.ply' && '%s/rhoscan' mesh '%s/configs/two_planes.ini' --set "
             "'pipeline.workdir=%s/work' --set mesh.surface=greedy --set mesh.fill_nadir=false",
             rs_test_bin_dir(), rs_test_source_dir(), dir, dir, rs_test_bin_dir(), rs_test_source_dir(), dir);
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) fail_msg("exit %d: %s", rc, out);
    free(out);
    rs_err err = {0};
    rs_mesh *m = rs_mesh_read(rs_test_path(dir, "work/mesh.ply"), NULL, &err);
    if (!m) fail_msg("%s", err.msg);
    assert_true(m->nfaces > 0);
    assert_true(rs_test_json_number(rs_test_path(dir, "work/mesh.json"), "faces_reconstructed") > 1000);
    assert_non_null(strstr(rs_test_read_text(rs_test_path(dir, "work/mesh.json")), "\"from the scan file\""));
    size_t down = 0;
    for (size_t k = 0; k < m->nfaces; k++) {
        rs_v3 c, n;
        rs_mesh_face(m, k, &c, &n, NULL);
        down += n.z < 0;
    }
    if (down != m->nfaces) fail_msg("%zu of %zu faces face down (the normals given)", down, m->nfaces);
    rs_mesh_free(m);
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_las_same_bytes), cmocka_unit_test(test_mesh_uses_given_normals),
             cmocka_unit_test(test_e57_normals_in_cloud_ply))
