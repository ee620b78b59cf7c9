/* test_pcd_header: rhoscan's check of a PCD header before PCL reads it (common/pcd_header.h). The
 * inputs that crashed PCL's reader while fuzzing (tests/fuzz/corpus/pcd/segv-*, oom-*, uaf-*) are
 * refused with a message, through the check and through rs_pcl_read_pcd; good headers pass. */
#include "tests/testutil.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/fileio.h"
#include "common/pcd_header.h"
#include "common/pcl_bridge.h"

static const char *corpus(const char *name)
{
    static char path[4096];
    snprintf(path, sizeof path, "%s/tests/fuzz/corpus/pcd/%s", rs_test_source_dir(), name);
    return path;
}

static void expect_refused_n(const char *data, size_t size, const char *needle)
{
    rs_err err = {0};
    assert_int_equal(rs_pcd_check(data, size, "t.pcd", &err), -1);
    if (!strstr(err.msg, needle)) fail_msg("'%s' not in '%s'", needle, err.msg);
    assert_int_equal(err.kind, RS_ERR_INPUT);
}

static void expect_refused(const char *data, const char *needle)
{
    expect_refused_n(data, strlen(data), needle);
}

#define HEAD "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"

static void test_headers(void **state)
{
    (void)state;
    rs_err err = {0};
    const char *good =
        "# .PCD v0.7\n" HEAD "WIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n";
    assert_int_equal(rs_pcd_check(good, strlen(good), "t.pcd", &err), 0);
    expect_refused("", "empty file");
    expect_refused(HEAD "WIDTH 2\nHEIGHT 1\nPOINTS 2\n", "no DATA line");
    expect_refused("VERSION 0.7\nFIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n",
                   "FIELDS has 3 names, SIZE 2 values");
    expect_refused("VERSION 0.7\nFIELDS x y z\nSIZE 4 4 3\nTYPE F F F\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n",
                   "SIZE value 3 = \"3\"");
    expect_refused("VERSION 0.7\nFIELDS x y z\nSIZE 4 4 2\nTYPE F F F\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n",
                   "TYPE F of SIZE 2");
    expect_refused(HEAD "WIDTH 2\nHEIGHT 2\nPOINTS 3\nDATA ascii\n", "WIDTH 2 x HEIGHT 2, POINTS 3");
    expect_refused(HEAD "WIDTH -1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n", "WIDTH: expected one integer");
    expect_refused(HEAD "WIDTH 4\nHEIGHT 1\nPOINTS 4\nDATA binary\n0123456789", "need 48 bytes of binary data; 10");
    expect_refused(HEAD "WIDTH 2147483647\nHEIGHT 1\nPOINTS 2147483647\nDATA ascii\n", "at most 2147483647 bytes");
    static const char compressed[] =
        HEAD "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA binary_compressed\n\x10\0\0\0\x0c\0\0\0abc";
    expect_refused_n(compressed, sizeof compressed - 1, "binary_compressed data of 16 bytes (12 uncompressed)");
    expect_refused(HEAD "WIDTH 1\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0\nPOINTS 1\nDATA ascii\n", "VIEWPOINT");
    expect_refused("VERSION 0.7\nFIELDS x y # z\n", "a '#' inside a header line");
    expect_refused("FIELDS x y z\nPOINTS 1\nSIZE 4 4 4\n", "SIZE after POINTS");
    expect_refused(HEAD "WIDTH 1\nWIDTH 1\n", "WIDTH after WIDTH");
    expect_refused(HEAD "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\nCOLUMNS a\n", "\"COLUMNS\" after the DATA line");
}

/* The fuzzing reproducers: each crashed pcl::PCDReader::read (an empty file: SIGSEGV; binary data
 * that began with FIELDS: a huge allocation; COLUMNS after DATA: a use after free). */
static void test_fuzz_findings(void **state)
{
    (void)state;
    static const char *const files[] = {"segv-empty.pcd", "oom-fields-after-data.pcd", "uaf-columns-after-data.pcd"};
    static const char *const why[] = {"empty file", "after the DATA line", "after the DATA line"};
    for (int k = 0; k < 3; k++) {
        rs_err err = {0};
        assert_int_equal(rs_pcd_check_file(corpus(files[k]), &err), -1);
        if (!strstr(err.msg, why[k])) fail_msg("%s: '%s'", files[k], err.msg);
        rs_cloud *c = rs_pcl_read_pcd(corpus(files[k]), &err);
        assert_null(c);
        assert_non_null(strstr(err.file, files[k]));
    }
    /* The committed seeds pass the check and read. */
    static const char *const seeds[] = {"ascii.pcd", "binary.pcd", "double.pcd"};
    for (int k = 0; k < 3; k++) {
        rs_err err = {0};
        rs_cloud *c = rs_pcl_read_pcd(corpus(seeds[k]), &err);
        if (!c) fail_msg("%s: %s", seeds[k], err.msg);
        assert_true(c->npoints >= 2);
        rs_cloud_free(c);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_headers), cmocka_unit_test(test_fuzz_findings)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
