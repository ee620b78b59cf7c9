/* test_ptx: the Leica PTX reader on PDAL's test files (counts, transforms, colours; values
 * worked out by hand from the files) and on synthetic and broken input (messages, lines). */
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "common/ptx.h"

/* The PDAL folder, or NULL (the test then skips) when the shared data is absent. */
static const char *ptx_dir(void)
{
    static char dir[1024];
    const char *shared = getenv("RHOSCAN_SHARED_DIR");
    struct stat st;
    if (!shared) return NULL;
    snprintf(dir, sizeof dir, "%s/formats/ptx", shared);
    return stat(dir, &st) == 0 && S_ISDIR(st.st_mode) ? dir : NULL;
}

static rs_cloud *read_pdal(const char *name)
{
    const char *dir = ptx_dir();
    if (!dir) return NULL;
    rs_err err = {0};
    rs_cloud *c = rs_ptx_read(rs_test_path(dir, name), &err);
    if (!c) fail_msg("%s: %s", name, err.msg);
    return c;
}

static size_t count_valid(const rs_cloud *c)
{
    size_t n = 0;
    for (size_t i = 0; i < c->npoints; i++) n += c->valid[i] != 0;
    return n;
}

static void assert_point(const rs_cloud *c, size_t i, double x, double y, double z, double tol)
{
    if (fabs(c->xyz[3 * i] - x) > tol || fabs(c->xyz[3 * i + 1] - y) > tol || fabs(c->xyz[3 * i + 2] - z) > tol)
        fail_msg("point %zu: (%.9f, %.9f, %.9f), expected (%.9f, %.9f, %.9f)", i, c->xyz[3 * i], c->xyz[3 * i + 1],
                 c->xyz[3 * i + 2], x, y, z);
}

/* 15 x 71 grid, identity transform, intensity and RGB on every line, all points valid. */
static void test_pdal_with_color(void **state)
{
    (void)state;
    rs_cloud *c = read_pdal("1.2-with-color.ptx");
    if (!c) skip();
    assert_int_equal(c->nscans, 1);
    assert_int_equal(c->scans[0].cols, 15);
    assert_int_equal(c->scans[0].rows, 71);
    assert_int_equal(c->npoints, 1065);
    assert_int_equal(count_valid(c), 1065);
    assert_non_null(c->rgb);
    assert_non_null(c->intensity);
    assert_point(c, 0, 637012.24, 849028.31, 431.66, 1e-6);
    assert_float_equal(c->intensity[0], 0.034912, 1e-6);
    assert_int_equal(c->rgb[0], 68);
    assert_int_equal(c->rgb[1], 77);
    assert_int_equal(c->rgb[2], 88);
    assert_point(c, 1064, 637342.85, 853240.32, 423.92, 1e-6); /* column 14, row 70: the last line */
    assert_int_equal(c->rgb[3 * 1064], 138);
    assert_int_equal(c->rgb[3 * 1064 + 2], 136);
    for (int j = 0; j < 3; j++) assert_float_equal(c->scans[0].position[j], 0.0, 0);
    rs_cloud_free(c);
}

/* 2 x 6 grid: 8 no-return points, 4 real ones through a rotation and translation. The
 * expected coordinates are x' = x T0 + y T4 + z T8 + T12 etc. worked out from the file. */
static void test_pdal_complex_transform(void **state)
{
    (void)state;
    rs_cloud *c = read_pdal("complex-transform.ptx");
    if (!c) skip();
    assert_int_equal(c->npoints, 12);
    assert_int_equal(count_valid(c), 4);
    for (size_t i = 0; i < 12; i++) assert_int_equal(c->valid[i], i >= 4 && i < 8);
    assert_point(c, 4, -3.034407381, -3.173781036, -1.823750042, 1e-8);
    assert_point(c, 5, -3.034401372, -3.172164100, -1.823716406, 1e-8);
    assert_point(c, 6, -3.034365775, -3.168529921, -1.825114625, 1e-8);
    assert_point(c, 7, -3.034359790, -3.171403932, -1.822068350, 1e-8);
    assert_int_equal(c->rgb[3 * 4], 33);
    assert_int_equal(c->rgb[3 * 7 + 2], 23);
    /* The position line is the scanner centre in the world frame already (the matrix's
     * translation row); it must not be transformed again. */
    assert_float_equal(c->scans[0].position[0], -3.028748, 1e-12);
    assert_float_equal(c->scans[0].position[1], -3.819741, 1e-12);
    assert_float_equal(c->scans[0].position[2], -1.384333, 1e-12);
    rs_cloud_free(c);
}

/* Two scans: the first (2 x 2) is translated and scaled by 2 along z and lands exactly on the
 * second (4 x 1, identity), e.g. 15.83 * 2 + 400 = 431.66. */
static void test_pdal_multiple_and_transform(void **state)
{
    (void)state;
    rs_cloud *c = read_pdal("multiple-and-transform.ptx");
    if (!c) skip();
    assert_int_equal(c->nscans, 2);
    assert_int_equal(c->npoints, 8);
    assert_int_equal(c->scans[0].cols, 2);
    assert_int_equal(c->scans[0].rows, 2);
    assert_int_equal(c->scans[1].cols, 4);
    assert_int_equal(c->scans[1].rows, 1);
    assert_int_equal(c->scans[1].first, 4);
    assert_null(c->rgb);
    assert_point(c, 0, 637012.24, 849028.31, 431.66, 1e-6);
    assert_point(c, 3, 636699.38, 848991.01, 425.39, 1e-6);
    for (int k = 0; k < 4; k++)
        assert_point(c, (size_t)k, c->xyz[3 * (4 + k)], c->xyz[3 * (4 + k) + 1], c->xyz[3 * (4 + k) + 2], 1e-6);
    assert_float_equal(c->intensity[1], 0.004395, 1e-7);
    assert_float_equal(c->scans[0].position[0], 600000.0, 0);
    assert_float_equal(c->scans[0].position[1], 800000.0, 0);
    assert_float_equal(c->scans[0].position[2], 400.0, 0);
    assert_float_equal(c->scans[1].position[0], 0.0, 0);
    rs_cloud_free(c);
}

static void test_pdal_no_color(void **state)
{
    (void)state;
    rs_cloud *c = read_pdal("no-color.ptx");
    if (!c) skip();
    assert_int_equal(c->nscans, 1);
    assert_int_equal(c->scans[0].cols, 15);
    assert_int_equal(c->scans[0].rows, 1);
    assert_int_equal(count_valid(c), 15);
    assert_null(c->rgb);
    assert_point(c, 14, 635795.24, 849310.43, 426.61, 1e-6);
    assert_float_equal(c->intensity[13], 0.000244, 1e-7);
    rs_cloud_free(c);
}

/* A 2-column, 1-row scan with a 90 degree turn about z, scale 0.5 and a translation; blank
 * lines and CRLF line ends are tolerated; the second scan has colour and the first does not. */
static const char *two_scans =
    "2\r\n1\r\n10 20 30\r\n0 1 0\r\n-1 0 0\r\n0 0 1\r\n"
    "0 0.5 0 0\r\n-0.5 0 0 0\r\n0 0 0.5 0\r\n10 20 30 1\r\n"
    "2 4 6 0.25\r\n\r\n0 0 0 0.5\r\n"
    "\n1\n1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n1.5 -2.5 3e2 0.75 10 20 255\n";

static void test_synthetic_two_scans(void **state)
{
    (void)state;
    rs_err err = {0};
    rs_cloud *c = rs_ptx_read_mem(two_scans, strlen(two_scans), "two.ptx", &err);
    if (!c) fail_msg("%s", err.msg);
    assert_int_equal(c->nscans, 2);
    assert_int_equal(c->npoints, 3);
    /* (2, 4, 6): x' = 2*0 + 4*(-0.5) + 6*0 + 10 = 8, y' = 2*0.5 + 20 = 21, z' = 6*0.5 + 30 = 33. */
    assert_point(c, 0, 8, 21, 33, 1e-12);
    assert_int_equal(c->valid[0], 1);
    assert_int_equal(c->valid[1], 0); /* 0 0 0: no return, placed at the scanner */
    assert_point(c, 1, 10, 20, 30, 0);
    assert_point(c, 2, 1.5, -2.5, 300, 0);
    assert_non_null(c->rgb);
    assert_int_equal(c->rgb[0], 0); /* the first scan had no colour */
    assert_int_equal(c->rgb[6], 10);
    assert_int_equal(c->rgb[8], 255);
    assert_float_equal(c->intensity[2], 0.75, 1e-7);
    assert_int_equal(c->scans[1].first, 2);
    rs_cloud_free(c);
}

/* Reads text that must fail and checks the file name, the line and a phrase of the message. */
static void expect_error(const char *text, long line, const char *phrase)
{
    rs_err err = {0};
    rs_cloud *c = rs_ptx_read_mem(text, strlen(text), "bad.ptx", &err);
    if (c) fail_msg("accepted: expected an error with \"%s\"", phrase);
    assert_string_equal(err.file, "bad.ptx");
    if (err.line != line) fail_msg("line %ld, expected %ld: %s", err.line, line, err.msg);
    if (!strstr(err.msg, phrase)) fail_msg("message \"%s\" lacks \"%s\"", err.msg, phrase);
    assert_int_equal(err.kind, RS_ERR_INPUT);
}

#define HEADER_1x2 "1\n2\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n"

static void test_errors(void **state)
{
    (void)state;
    expect_error(HEADER_1x2 "1 2 3 0.5\n", 12, "ends after 1 of 2 points");
    expect_error(HEADER_1x2 "1 2 3 0.5\n1 2 x 0.5\n", 12, "token 3 \"x\" is not a number");
    expect_error(HEADER_1x2 "1 2 3 0.5\n1 2 3 0.5 7\n", 12, "found 5 numbers; expected 4");
    expect_error(HEADER_1x2 "1 2 3\n1 2 3 0.5\n", 11, "found 3 numbers");
    expect_error(HEADER_1x2 "1 2 nan 0.5\n1 2 3 0.5\n", 11, "not finite");
    expect_error(HEADER_1x2 "1 2 1e999 0.5\n1 2 3 0.5\n", 11, "not finite");
    expect_error(HEADER_1x2 "1 2 3 0.5 1 2 300\n1 2 3 0.5\n", 11, "expected 0 to 255");
    /* Beyond the cloud's range, in the file or only after the scan's transform (a scale or a
     * translation); an intensity beyond float. */
    expect_error(HEADER_1x2 "1 2 3e9 0.5\n1 2 3 0.5\n", 11, "after the scan's transform");
    expect_error("1\n1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1e6 0 0 0\n0 1e6 0 0\n0 0 1e6 0\n0 0 0 1\n5555 0 0 0.5\n", 11,
                 "coordinate 5.555e+09 after the scan's transform");
    expect_error("1\n1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 2e9 1\n1 1 1 0.5\n", 11,
                 "after the scan's transform");
    expect_error(HEADER_1x2 "1 2 3 1e300\n1 2 3 0.5\n", 11, "intensity 1e+300");
    expect_error("2\n", 2, "the file ends");
    expect_error("abc\n", 1, "not a number");
    expect_error("0\n5\n", 1, "expected an integer from 1");
    expect_error("2.5\n5\n", 1, "expected an integer from 1");
    expect_error("1\n2\n0 0\n", 3, "scanner position: found 2 tokens; expected 3");
    expect_error("1\n1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 0 0\n0 0 0 0\n0 0 0 0\n0 0 0 1\n1 1 1 1\n", 7, "singular");
    /* Counts that would need terabytes: refused before any allocation, no overflow. */
    expect_error("2000000000\n2000000000\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n1 2 3 4\n",
                 10, "truncated or the counts are wrong");
    expect_error("99999999999999999999\n1\n", 1, "expected an integer from 1");
    expect_error("", 0, "no scan found");
    expect_error(" \n\n", 0, "no scan found");
    /* A second scan that breaks off after its header. */
    expect_error(HEADER_1x2 "1 2 3 0.5\n1 2 3 0.5\n1\n", 14, "the file ends");
}

/* Every prefix of a valid file either parses or fails cleanly (run under the sanitizers, this
 * catches reads past the end of the buffer: the copy below has no terminating NUL). */
static void test_every_truncation(void **state)
{
    (void)state;
    size_t n = strlen(two_scans);
    int ok = 0;
    for (size_t len = 0; len <= n; len++) {
        char *copy = malloc(len ? len : 1);
        memcpy(copy, two_scans, len);
        rs_err err = {0};
        rs_cloud *c = rs_ptx_read_mem(copy, len, "cut.ptx", &err);
        if (c)
            ok++;
        else
            assert_true(err.msg[0] != 0);
        rs_cloud_free(c);
        free(copy);
    }
    assert_true(ok >= 1); /* at least the whole file */
}

static void test_read_file(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("ptx");
    const char *path = rs_test_path(dir, "scan.ptx");
    rs_test_write(path, two_scans);
    rs_err err = {0};
    rs_cloud *c = rs_ptx_read(path, &err);
    assert_non_null(c);
    assert_int_equal(c->npoints, 3);
    rs_cloud_free(c);
    assert_null(rs_ptx_read(rs_test_path(dir, "missing.ptx"), &err));
    assert_non_null(strstr(err.file, "missing.ptx"));
    rs_test_rmtree(dir);
}

/* The reference scans: full size, and fast (strtod on a buffer, not fscanf). */
static void test_reference_scans(void **state)
{
    (void)state;
    const char *path = rs_test_shared_file("reference/step_park/scan.ptx");
    if (!path) skip();
    rs_err err = {0};
    rs_cloud *c = rs_ptx_read(path, &err);
    if (!c) fail_msg("%s", err.msg);
    assert_int_equal(c->scans[0].cols, 1440);
    assert_int_equal(c->scans[0].rows, 500);
    /* truth.json: scanner_position [4.5, -7.5, 1.8] */
    assert_float_equal(c->scans[0].position[0], 4.5, 1e-9);
    assert_float_equal(c->scans[0].position[1], -7.5, 1e-9);
    assert_float_equal(c->scans[0].position[2], 1.8, 1e-6);
    /* First line "1.0375 0.0000 -1.7969": a ground point below the scanner. */
    assert_point(c, 0, 4.5 + 1.0375, -7.5, 1.8 - 1.7969, 1e-9);
    rs_cloud_free(c);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_pdal_with_color), cmocka_unit_test(test_pdal_complex_transform),
             cmocka_unit_test(test_pdal_multiple_and_transform), cmocka_unit_test(test_pdal_no_color),
             cmocka_unit_test(test_synthetic_two_scans), cmocka_unit_test(test_errors),
             cmocka_unit_test(test_every_truncation), cmocka_unit_test(test_read_file),
             cmocka_unit_test(test_reference_scans))
