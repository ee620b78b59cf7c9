/* test_e57_writer: tools/e57write's E57 files read back by the E57 reader give the PTX reader's
 * cloud bit for bit (points in the world frame through the pose, the grid, no-return points,
 * intensity, colour): the condition of the E57 playback test. Synthetic PTX files with a rotated
 * pose, and the shared reference scene's scan. */
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/cloud_format.h"
#include "common/e57.h"
#include "common/fileio.h"
#include "common/ptx.h"

static void write_e57(const char *ptx, const char *e57, const char *extra)
{
    char cmd[8192], *out = NULL;
    snprintf(cmd, sizeof cmd, "%s/e57write %s '%s' '%s'", rs_test_bin_dir(), extra ? extra : "", ptx, e57);
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) fail_msg("%s: exit %d: %s", cmd, rc, out ? out : "");
    free(out);
}

/* The two clouds are the same bytes (coordinates within tol: 0 for exact; a rotation goes
 * through the quaternion, which rounds differently from the PTX matrix). */
static void assert_same(const rs_cloud *a, const rs_cloud *b, double tol)
{
    assert_int_equal(a->npoints, b->npoints);
    assert_int_equal(a->nscans, b->nscans);
    for (int s = 0; s < a->nscans; s++) {
        assert_int_equal(a->scans[s].cols, b->scans[s].cols);
        assert_int_equal(a->scans[s].rows, b->scans[s].rows);
        assert_int_equal(a->scans[s].first, b->scans[s].first);
        assert_memory_equal(a->scans[s].position, b->scans[s].position, sizeof a->scans[s].position);
    }
    if (tol == 0) assert_memory_equal(a->xyz, b->xyz, 3 * a->npoints * sizeof *a->xyz);
    for (size_t i = 0; i < 3 * a->npoints; i++)
        if (!(fabs(a->xyz[i] - b->xyz[i]) <= tol))
            fail_msg("coordinate %zu: %.17g, expected %.17g", i, b->xyz[i], a->xyz[i]);
    assert_memory_equal(a->valid, b->valid, a->npoints);
    assert_true((a->intensity == NULL) == (b->intensity == NULL));
    if (a->intensity) assert_memory_equal(a->intensity, b->intensity, a->npoints * sizeof *a->intensity);
    assert_true((a->rgb == NULL) == (b->rgb == NULL));
    if (a->rgb) assert_memory_equal(a->rgb, b->rgb, 3 * a->npoints);
}

static void round_trip(const char *ptx, const char *dir, double tol)
{
    const char *e57 = rs_test_path(dir, "scan.e57");
    write_e57(ptx, e57, NULL);
    rs_err err = {0};
    rs_cloud *a = rs_ptx_read(ptx, &err);
    if (!a) fail_msg("%s", err.msg);
    const char *format = NULL;
    rs_cloud *b = rs_cloud_read_with(e57, NULL, &format, &err);
    if (!b) fail_msg("%s", err.msg);
    assert_string_equal(format, "E57");
    assert_same(a, b, tol);
    rs_cloud_free(a);
    rs_cloud_free(b);
}

/* Two scans, one with colour, an identity and a rotated pose (a quarter turn about z), no-return
 * points, intensities above 1. */
static void test_synthetic(void **state)
{
    const char *dir = rs_test_tmpdir("e57w");
    const char *ptx = rs_test_path(dir, "two.ptx");
    rs_test_write(ptx,
                  "3\n2\n1 2 3\n1 0 0\n0 1 0\n0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n1 2 3 1\n"
                  "0.5 0.25 -1 0.5\n0 0 0 0.5\n1.5 2.5 3.5 1.5\n-1 -2 -3 0.25\n7 8 9 0.125\n0 0 0\n"
                  "2\n2\n10 0 0\n0 1 0\n-1 0 0\n0 0 1\n0 1 0 0\n-1 0 0 0\n0 0 1 0\n10 0 0 1\n"
                  "1 0 0 0.5 255 0 10\n0 1 0 0.5 1 2 3\n0 0 1 0.5 4 5 6\n1 1 1 0.5 7 8 9\n");
    round_trip(ptx, dir, 1e-12);
    rs_test_rmtree(dir);
}

/* An identity rotation, as the reference scenes have: bit for bit. */
static void test_reference_scan(void **state)
{
    const char *ptx = rs_test_shared_file("reference/two_planes_sky/scan.ptx");
    if (!ptx) {
        if (getenv("CI") && strcmp(getenv("CI"), "true") == 0) fail_msg("the shared reference scene is missing");
        skip();
    }
    const char *dir = rs_test_tmpdir("e57w");
    round_trip(ptx, dir, 0);
    rs_test_rmtree(dir);
}

/* The bench's synthetic file: N points, read as N. */
static void test_synthetic_points(void **state)
{
    const char *dir = rs_test_tmpdir("e57w");
    const char *e57 = rs_test_path(dir, "syn.e57");
    char cmd[4096], *out = NULL;
    snprintf(cmd, sizeof cmd, "%s/e57write --synthetic 54321 '%s'", rs_test_bin_dir(), e57);
    assert_int_equal(rs_test_run(cmd, &out), 0);
    free(out);
    rs_err err = {0};
    rs_cloud *c = rs_cloud_read(e57, &err);
    if (!c) fail_msg("%s", err.msg);
    assert_int_equal(c->npoints, 54321);
    assert_int_equal(c->nscans, 0);
    assert_true(c->xyz[3 * 54320 + 2] == 54320 * 1e-4 * 0.01);
    rs_cloud_free(c);
    rs_test_rmtree(dir);
}

/* The ingest program on E57 files: a good one gives cloud.ply with its grid; a damaged one exits
 * 1 naming the file and the checksum, and writes nothing. */
static void test_ingest_program(void **state)
{
    const char *bad = rs_test_shared_file("formats/e57/bad-crc.e57");
    if (!bad) {
        if (getenv("CI") && strcmp(getenv("CI"), "true") == 0) fail_msg("the shared E57 files are missing");
        skip();
    }
    char badp[4096];
    snprintf(badp, sizeof badp, "%s", bad);
    const char *dir = rs_test_tmpdir("e57w");
    char ptx[4096], e57[4096], ini[4096], cmd[16384], text[16384], *out = NULL;
    snprintf(ptx, sizeof ptx, "%s", rs_test_path(dir, "two.ptx"));
    snprintf(e57, sizeof e57, "%s", rs_test_path(dir, "two.e57"));
    snprintf(ini, sizeof ini, "%s", rs_test_path(dir, "c.ini"));
    rs_test_write(ptx,
                  "2\n2\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n"
                  "1 0 0 0.5\n1 1 0 0.5\n1 0 1 0.5\n1 1 1 0.5\n");
    write_e57(ptx, e57, NULL);
    snprintf(text, sizeof text, "[pipeline]\nworkdir = %s/work\n[ingest]\nscan = %s\n[mesh]\nfacet_size = 0.5\n", dir,
             e57);
    rs_test_write(ini, text);
    snprintf(cmd, sizeof cmd, "%s/rhoscan-ingest '%s'", rs_test_bin_dir(), ini);
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) fail_msg("%s: %s", cmd, out);
    assert_non_null(strstr(out, "(E57): 4 points, 4 with a return, 1 scan grid(s)"));
    free(out);
    assert_true(rs_file_exists(rs_test_path(dir, "work/cloud.ply")));
    snprintf(text, sizeof text, "[pipeline]\nworkdir = %s/bad\n[ingest]\nscan = %s\n[mesh]\nfacet_size = 0.5\n", dir,
             badp);
    rs_test_write(ini, text);
    rc = rs_test_run(cmd, &out);
    assert_int_equal(rc, 1);
    if (!strstr(out, "bad-crc.e57") || !strstr(out, "page 0 fails its checksum")) fail_msg("%s", out);
    free(out);
    assert_false(rs_file_exists(rs_test_path(dir, "bad/cloud.ply")));
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_synthetic), cmocka_unit_test(test_reference_scan),
             cmocka_unit_test(test_synthetic_points), cmocka_unit_test(test_ingest_program))
