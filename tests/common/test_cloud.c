/* test_cloud: cloud.ply round trips (grids, no-return cells, colours), reading by content,
 * concatenation, PLY clouds from other software, corrupt grid descriptions, and the formats'
 * table (common/cloud_format.c): magic bytes, extensions, and the formats it refuses. */
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/cloud.h"
#include "common/cloud_format.h"
#include "common/cloud_ply.h"
#include "common/ptx.h"

/* Two scans (3 x 2 with colour and one no-return cell, 1 x 2) as PTX text. */
static const char *ptx_text = "3\n2\n1 2 3\n1 0 0\n0 1 0\n0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n1 2 3 1\n"
                              "0.1 0.2 0.3 0.5 1 2 3\n0.4 0.5 0.6 0.25 4 5 6\n0 0 0 0.5 0 0 0\n"
                              "1.1 1.2 1.3 0.125 7 8 9\n2.1 2.2 2.3 1 10 11 12\n3.1 3.2 3.3 0 13 14 15\n"
                              "1\n2\n-5 0 0.5\n1 0 0\n0 1 0\n0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n-5 0 0.5 1\n"
                              "0.123456789012345 9 8 0.5\n7 6 5 0.75\n";

static rs_cloud *sample_cloud(void)
{
    rs_err err = {0};
    rs_cloud *c = rs_ptx_read_mem(ptx_text, strlen(ptx_text), "sample.ptx", &err);
    if (!c) fail_msg("%s", err.msg);
    return c;
}

static void assert_same_cloud(const rs_cloud *a, const rs_cloud *b)
{
    assert_int_equal(a->npoints, b->npoints);
    assert_int_equal(a->nscans, b->nscans);
    for (int s = 0; s < a->nscans; s++) {
        assert_int_equal(a->scans[s].cols, b->scans[s].cols);
        assert_int_equal(a->scans[s].rows, b->scans[s].rows);
        assert_int_equal(a->scans[s].first, b->scans[s].first);
        for (int j = 0; j < 3; j++) assert_true(a->scans[s].position[j] == b->scans[s].position[j]);
    }
    for (size_t i = 0; i < a->npoints; i++) {
        assert_int_equal(a->valid[i], b->valid[i]);
        if (!a->valid[i]) continue;
        for (int j = 0; j < 3; j++) assert_true(a->xyz[3 * i + j] == b->xyz[3 * i + j]); /* doubles, exact */
        assert_float_equal(a->intensity[i], b->intensity[i], 0);
        if (a->rgb)
            for (int j = 0; j < 3; j++) assert_int_equal(a->rgb[3 * i + j], b->rgb[3 * i + j]);
    }
}

static void test_round_trip(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("cloud");
    const char *path = rs_test_path(dir, "cloud.ply");
    rs_cloud *c = sample_cloud();
    rs_err err = {0};
    assert_int_equal(rs_cloud_write_ply(c, path, &err), 0);
    rs_cloud *back = rs_cloud_read_ply(path, &err);
    if (!back) fail_msg("%s", err.msg);
    assert_same_cloud(c, back);
    /* The no-return cell stays a no-return cell, placed at its scanner. */
    assert_int_equal(back->valid[2], 0);
    assert_true(back->xyz[6] == 1 && back->xyz[7] == 2 && back->xyz[8] == 3);

    /* Only valid points are stored: 7 of 8. */
    rs_ply *ply = rs_ply_read(path, &err);
    assert_non_null(ply);
    assert_int_equal(rs_ply_find_element(ply, "vertex")->count, 7);
    assert_string_equal(rs_ply_find_comment(ply, "rhoscan_scan"), "0 3 2 1 2 3");
    rs_ply_free(ply);

    /* rs_cloud_read tells PLY from PTX by content, whatever the name says. */
    rs_cloud *again = rs_cloud_read(path, &err);
    assert_non_null(again);
    assert_same_cloud(c, again);
    const char *ptx_named_ply = rs_test_path(dir, "really_ptx.ply");
    rs_test_write(ptx_named_ply, ptx_text);
    rs_cloud *from_ptx = rs_cloud_read(ptx_named_ply, &err);
    assert_non_null(from_ptx);
    assert_same_cloud(c, from_ptx);
    rs_cloud_free(c);
    rs_cloud_free(back);
    rs_cloud_free(again);
    rs_cloud_free(from_ptx);
    rs_test_rmtree(dir);
}

/* An ascii PLY from other software: unorganized, all points valid, float colours 0..1. */
static const char *foreign_ply =
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "property float red\nproperty float green\nproperty float blue\nend_header\n"
    "0 0 0 1 0 0.5\n1 0 0 0 1 0\n0 1 0 0 0 1\n";

static void test_append_and_foreign(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("cloud");
    const char *path = rs_test_path(dir, "other.ply");
    rs_test_write(path, foreign_ply);
    rs_err err = {0};
    rs_cloud *loose = rs_cloud_read(path, &err);
    if (!loose) fail_msg("%s", err.msg);
    assert_int_equal(loose->nscans, 0);
    assert_int_equal(loose->npoints, 3);
    assert_int_equal(loose->rgb[0], 255);
    assert_int_equal(loose->rgb[2], 128);
    assert_null(loose->intensity);

    /* Organized scans first, then the loose points; arrays made to fit both. */
    rs_cloud *all = sample_cloud();
    assert_int_equal(rs_cloud_append(all, loose, &err), 0);
    assert_int_equal(all->npoints, 11);
    assert_int_equal(all->nscans, 2);
    assert_int_equal(rs_cloud_unorganized(all), 3);
    assert_float_equal(all->intensity[8], 0, 0);
    assert_true(all->xyz[3 * 9] == 1.0);

    /* And the mixture survives cloud.ply: loose points carry scan = -1. */
    const char *out = rs_test_path(dir, "cloud.ply");
    assert_int_equal(rs_cloud_write_ply(all, out, &err), 0);
    rs_cloud *back = rs_cloud_read_ply(out, &err);
    if (!back) fail_msg("%s", err.msg);
    assert_same_cloud(all, back);
    rs_cloud_free(back);

    /* A second PTX appended shifts the scan offsets. */
    rs_cloud *more = sample_cloud();
    assert_int_equal(rs_cloud_append(all, more, &err), 0);
    assert_int_equal(all->nscans, 4);
    assert_int_equal(all->scans[2].first, 11);
    assert_int_equal(all->scans[3].first, 17);
    rs_cloud_free(more);
    rs_cloud_free(all);
    rs_cloud_free(loose);
    rs_test_rmtree(dir);
}

static void expect_bad_ply(const char *dir, const char *text, const char *phrase)
{
    const char *path = rs_test_path(dir, "bad.ply");
    rs_test_write(path, text);
    rs_err err = {0};
    rs_cloud *c = rs_cloud_read_ply(path, &err);
    if (c) fail_msg("accepted: expected an error with \"%s\"", phrase);
    assert_non_null(strstr(err.file, "bad.ply"));
    if (!strstr(err.msg, phrase)) fail_msg("message \"%s\" lacks \"%s\"", err.msg, phrase);
}

#define GRID_HEADER(comment, n)                                                                                 \
    "ply\nformat ascii 1.0\ncomment " comment "\nelement vertex " #n "\nproperty double x\nproperty double y\n" \
    "property double z\nproperty int scan\nproperty int row\nproperty int col\nend_header\n"

static void test_corrupt(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("cloud");
    expect_bad_ply(dir, GRID_HEADER("rhoscan_scan 0 2 2 0 0 0", 2) "1 1 1 0 0 0\n2 2 2 0 0 0\n",
                   "holds a point already");
    expect_bad_ply(dir, GRID_HEADER("rhoscan_scan 0 2 2 0 0 0", 1) "1 1 1 0 2 0\n", "outside the grids");
    expect_bad_ply(dir, GRID_HEADER("rhoscan_scan 0 2 2 0 0 0", 1) "1 1 1 1 0 0\n", "outside the grids");
    expect_bad_ply(dir, GRID_HEADER("rhoscan_scan 0 0 2 0 0 0", 1) "1 1 1 0 0 0\n", "COLS and ROWS >= 1");
    expect_bad_ply(dir, GRID_HEADER("rhoscan_scan 3 2 2 0 0 0", 1) "1 1 1 0 0 0\n", "INDEX from 0");
    expect_bad_ply(dir, GRID_HEADER("rhoscan_scan 0 2 2 0 0 nan", 1) "1 1 1 0 0 0\n", "finite position");
    expect_bad_ply(dir, GRID_HEADER("rhoscan_scan 0 100000 100000 0 0 0", 1) "1 1 1 0 0 0\n", "corrupt");
    expect_bad_ply(dir, GRID_HEADER("rhoscan_scan 0 2 2 0 0 0", 1) "nan 1 1 0 0 0\n", "expected finite coordinates");
    expect_bad_ply(dir,
                   "ply\nformat ascii 1.0\ncomment rhoscan_scan 0 1 1 0 0 0\nelement vertex 1\nproperty double x\n"
                   "property double y\nproperty double z\nend_header\n1 1 1\n",
                   "lack scan, row and col");
    expect_bad_ply(dir, GRID_HEADER("rhoscan_origin 1 2", 1) "1 1 1 -1 -1 -1\n",
                   "comment \"rhoscan_origin 1 2\": expected three finite numbers (the offset");
    expect_bad_ply(dir, GRID_HEADER("rhoscan_viewpoint 1 2 inf", 1) "1 1 1 -1 -1 -1\n",
                   "expected three finite numbers (the scanner centre)");
    expect_bad_ply(dir, "ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
                   "no vertex element");
    rs_test_rmtree(dir);
}

static void write_bytes(const char *path, const void *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
}

/* A LAS 1.2 public header block (227 bytes), zeros but for the signature and the point data
 * format id at byte 104. */
static void write_las(const char *path, unsigned char point_format)
{
    unsigned char h[227] = "LASF";
    h[24] = 1; /* version 1.2 */
    h[25] = 2;
    h[104] = point_format;
    write_bytes(path, h, sizeof h);
}

/* rs_cloud_read refuses the file with RS_ERR_INPUT, naming it and saying phrase; *format
 * (rs_cloud_read_with) names the format refused. */
static void expect_refused(const char *path, const char *format, const char *phrase)
{
    rs_err err = {0};
    const char *got = NULL;
    assert_null(rs_cloud_read_with(path, NULL, &got, &err));
    assert_int_equal(err.kind, RS_ERR_INPUT);
    assert_string_equal(got, format);
    char buf[2048];
    rs_err_format(&err, buf, sizeof buf);
    if (!strstr(buf, path) || !strstr(buf, phrase))
        fail_msg("error '%s' should name '%s' and say '%s'", buf, path, phrase);
}

/* E57, LAS and LAZ are told by their magic bytes (E57 and LAZ refused with a message that says
 * so, LAS read by its own reader), instead of the PTX parse error they used to get. */
static void test_refused_formats(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("cloud");
    const char *e57 = rs_test_path(dir, "scan.e57");
    write_bytes(e57, "ASTM-E57\0\0\1\0\0\0\0\0", 16); /* E57 is read now (e57.h): a truncated one refused */
    expect_refused(e57, "E57", "16 bytes; an E57 file has at least one 1024-byte page");

    /* LAS and LAZ go to the LAS reader (tests/common/test_las.c), which refuses these headers. */
    const char *las = rs_test_path(dir, "scan.las");
    write_las(las, 1);
    expect_refused(las, "LAS", "offset 94: header size 0; expected at least 227");
    const char *laz7 = rs_test_path(dir, "bit7.las"), *laz6 = rs_test_path(dir, "bit6.las");
    write_las(laz7, 0x80 | 3); /* LASzip's compressed flag */
    write_las(laz6, 0x40 | 1);
    expect_refused(laz7, "LAZ", "LAZ is compressed LAS, which rhoscan cannot read yet");
    expect_refused(laz6, "LAZ", "pdal translate FILE.laz FILE.las");
    /* The name does not make a file LAZ: an uncompressed one called .laz is read as LAS. */
    const char *laz = rs_test_path(dir, "named.LAZ");
    write_las(laz, 1);
    expect_refused(laz, "LAS", "header size 0");
    /* Magic bytes before the name: a LAS called .ply, a short LAS header. */
    const char *las_named_ply = rs_test_path(dir, "really_las.ply");
    write_las(las_named_ply, 1);
    expect_refused(las_named_ply, "LAS", "header size 0");
    const char *short_las = rs_test_path(dir, "short.las");
    write_bytes(short_las, "LASF", 4);
    expect_refused(short_las, "LAS", "a LAS public header needs at least 227");

    /* Without the magic a .las is no LAS: read as PTX, whose error says what the name claimed. */
    const char *fake = rs_test_path(dir, "fake.las");
    rs_test_write(fake, "not a scan\n");
    rs_err err = {0};
    const char *got = NULL;
    assert_null(rs_cloud_read_with(fake, NULL, &got, &err));
    assert_string_equal(got, "PTX");
    assert_non_null(strstr(err.msg, "the name says LAS but the file does not start like one"));
    /* A missing file is reported as such, whatever its name. */
    assert_null(rs_cloud_read(rs_test_path(dir, "missing.ply"), &err));
    assert_int_equal(err.kind, RS_ERR_INPUT);
    assert_non_null(strstr(err.msg, "cannot open"));
    assert_null(strstr(err.msg, "the name says"));
    rs_test_rmtree(dir);
}

/* The formats without magic bytes go by extension (text with the column map, PCD), and
 * whatever else is PTX. */
static void test_formats_by_extension(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("cloud");
    rs_err err = {0};
    const char *got = NULL;
    const char *xyz = rs_test_path(dir, "points.CSV");
    rs_test_write(xyz, "x,y,z,i\n1,2,3,0.5\n4,5,6,0.25\n");
    rs_cloud_read_opts opts = {.columns = "x y z intensity"};
    rs_cloud *c = rs_cloud_read_with(xyz, &opts, &got, &err);
    if (!c) fail_msg("%s", err.msg);
    assert_string_equal(got, "text");
    assert_int_equal(c->npoints, 2);
    assert_int_equal(c->nscans, 0);
    assert_float_equal(c->intensity[1], 0.25f, 0);
    rs_cloud_free(c);

    const char *pcd = rs_test_path(dir, "points.pcd");
    rs_test_write(pcd,
                  "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\n"
                  "TYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\n"
                  "DATA ascii\n1 2 3\n4 5 6\n");
    c = rs_cloud_read_with(pcd, NULL, &got, &err);
    if (!c) fail_msg("%s", err.msg);
    assert_string_equal(got, "PCD");
    assert_int_equal(c->npoints, 2);
    assert_true(c->xyz[3] == 4.0);
    rs_cloud_free(c);

    const char *ptx = rs_test_path(dir, "scan.unknown");
    rs_test_write(ptx, ptx_text);
    c = rs_cloud_read_with(ptx, NULL, &got, &err);
    if (!c) fail_msg("%s", err.msg);
    assert_string_equal(got, "PTX");
    assert_int_equal(c->nscans, 2);
    rs_cloud_free(c);
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_round_trip), cmocka_unit_test(test_append_and_foreign),
             cmocka_unit_test(test_corrupt), cmocka_unit_test(test_refused_formats),
             cmocka_unit_test(test_formats_by_extension))
