/* test_ply: PLY round trips (ascii, binary), big-endian and foreign files, and every way a
 * file can be bad: each error must name the file, the place and what was expected. */
#include "tests/testutil.h"

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "common/fileio.h"
#include "common/ply.h"

/* ---- helpers ---- */

static rs_ply *read_text(const char *text, rs_err *err)
{
    return rs_ply_read_mem(text, strlen(text), "bad.ply", err);
}

/* The read must fail, and the formatted message must hold each of the given parts. */
static void expect_fail_mem(const char *data, size_t size, const char *part1, const char *part2)
{
    rs_err err;
    char msg[2048];
    rs_err_clear(&err);
    rs_ply *ply = rs_ply_read_mem(data, size, "bad.ply", &err);
    rs_err_format(&err, msg, sizeof msg);
    if (ply || !strstr(msg, "bad.ply") || (part1 && !strstr(msg, part1)) || (part2 && !strstr(msg, part2)))
        fail_msg("expected failure with '%s' and '%s', got %s: '%s'", part1 ? part1 : "", part2 ? part2 : "",
                 ply ? "success" : "failure", msg);
    assert_int_equal(err.kind, RS_ERR_INPUT);
}

static void expect_fail(const char *text, const char *part1, const char *part2)
{
    expect_fail_mem(text, strlen(text), part1, part2);
}

static char *slurp(const char *path, size_t *size)
{
    char *data = NULL;
    rs_err err;
    assert_int_equal(rs_read_file(path, &data, size, &err), 0);
    return data;
}

/* Big-endian encoders for the hand-made file. */
static size_t be16(unsigned char *p, uint16_t v)
{
    p[0] = (unsigned char)(v >> 8);
    p[1] = (unsigned char)v;
    return 2;
}
static size_t be32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(v >> (24 - 8 * i));
    return 4;
}
static size_t be32f(unsigned char *p, float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    return be32(p, u);
}
static size_t be64d(unsigned char *p, double d)
{
    uint64_t u;
    memcpy(&u, &d, 8);
    for (int i = 0; i < 8; i++) p[i] = (unsigned char)(u >> (56 - 8 * i));
    return 8;
}

/* ---- round trips ---- */

#define NV 4
static const double xs[NV] = {0.1, -2.5, 1e-7, 3.0e38};
static const double ws[NV] = {0.1, -1e300, 1.0 / 3.0, 12345.6789};
static const double u8s[NV] = {0, 255, 17, 128};
static const double i8s[NV] = {-128, 127, -1, 0};
static const double i16s[NV] = {-32768, 32767, -5, 7};
static const double u16s[NV] = {0, 65535, 1, 2};
static const double i32s[NV] = {-2147483648.0, 2147483647.0, -1, 42};
static const double u32s[NV] = {0, 4294967295.0, 1, 123456789};
static const double tris[6] = {0, 1, 2, 2, 3, 0};

static rs_ply *mixed_mesh(void)
{
    rs_ply *ply = rs_ply_new();
    assert_non_null(ply);
    assert_int_equal(rs_ply_add_comment(ply, "made by %s", "test_ply"), 0);
    assert_int_equal(rs_ply_add_comment(ply, "input_hash 0123abcd"), 0);
    rs_ply_element *v = rs_ply_add_element(ply, "vertex", NV);
    assert_non_null(v);
    assert_non_null(rs_ply_add_scalar(v, "x", RS_PLY_FLOAT32, xs));
    assert_non_null(rs_ply_add_scalar(v, "w", RS_PLY_FLOAT64, ws));
    assert_non_null(rs_ply_add_scalar(v, "red", RS_PLY_UINT8, u8s));
    assert_non_null(rs_ply_add_scalar(v, "s8", RS_PLY_INT8, i8s));
    assert_non_null(rs_ply_add_scalar(v, "s16", RS_PLY_INT16, i16s));
    assert_non_null(rs_ply_add_scalar(v, "u16", RS_PLY_UINT16, u16s));
    assert_non_null(rs_ply_add_scalar(v, "s32", RS_PLY_INT32, i32s));
    assert_non_null(rs_ply_add_scalar(v, "u32", RS_PLY_UINT32, u32s));
    rs_ply_element *f = rs_ply_add_element(ply, "face", 2);
    assert_non_null(f);
    assert_non_null(rs_ply_add_list_fixed(f, "vertex_indices", RS_PLY_UINT8, RS_PLY_INT32, 3, tris));
    const float albedo[2] = {0.25f, 0.7f};
    assert_non_null(rs_ply_add_scalar_f(f, "albedo_r", RS_PLY_FLOAT32, albedo));
    return ply;
}

static void check_prop(const rs_ply_element *el, const char *name, rs_ply_type type, const double *expect, int as_float)
{
    rs_ply_prop *p = rs_ply_find_prop(el, name);
    assert_non_null(p);
    assert_int_equal(p->type, type);
    assert_false(p->is_list);
    for (size_t k = 0; k < el->count; k++) {
        double want = as_float ? (double)(float)expect[k] : expect[k];
        if (p->data[k] != want) fail_msg("%s[%zu] = %.17g, expected %.17g", name, k, p->data[k], want);
    }
}

static void roundtrip(int binary)
{
    const char *dir = rs_test_tmpdir("ply");
    const char *path = rs_test_path(dir, binary ? "mesh_bin.ply" : "mesh_ascii.ply");
    rs_err err;
    rs_ply *ply = mixed_mesh();
    assert_int_equal(rs_ply_write(ply, path, binary, &err), 0);
    rs_ply_free(ply);

    ply = rs_ply_read(path, &err);
    if (!ply) fail_msg("read failed: %s", err.msg);
    assert_int_equal(ply->nelements, 2);
    assert_int_equal(ply->ncomments, 2);
    assert_string_equal(ply->comments[0], "made by test_ply");
    assert_string_equal(ply->comments[1], "input_hash 0123abcd");
    assert_string_equal(rs_ply_find_comment(ply, "input_hash"), "0123abcd");
    assert_null(rs_ply_find_comment(ply, "input"));

    rs_ply_element *v = rs_ply_find_element(ply, "vertex");
    assert_non_null(v);
    assert_int_equal(v->count, NV);
    assert_int_equal(v->nprops, 8);
    assert_string_equal(v->props[0].name, "x"); /* order kept */
    check_prop(v, "x", RS_PLY_FLOAT32, xs, 1);
    check_prop(v, "w", RS_PLY_FLOAT64, ws, 0);
    check_prop(v, "red", RS_PLY_UINT8, u8s, 0);
    check_prop(v, "s8", RS_PLY_INT8, i8s, 0);
    check_prop(v, "s16", RS_PLY_INT16, i16s, 0);
    check_prop(v, "u16", RS_PLY_UINT16, u16s, 0);
    check_prop(v, "s32", RS_PLY_INT32, i32s, 0);
    check_prop(v, "u32", RS_PLY_UINT32, u32s, 0);

    rs_ply_element *f = rs_ply_find_element(ply, "face");
    assert_non_null(f);
    assert_int_equal(f->count, 2);
    rs_ply_prop *vi = rs_ply_find_prop(f, "vertex_indices");
    assert_non_null(vi);
    assert_true(vi->is_list);
    assert_int_equal(vi->count_type, RS_PLY_UINT8);
    assert_int_equal(vi->type, RS_PLY_INT32);
    assert_int_equal(vi->offsets[0], 0);
    assert_int_equal(vi->offsets[1], 3);
    assert_int_equal(vi->offsets[2], 6);
    for (int i = 0; i < 6; i++) assert_true(vi->data[i] == tris[i]);
    rs_ply_prop *a = rs_ply_find_prop(f, "albedo_r");
    assert_true(a->data[0] == 0.25 && a->data[1] == (double)0.7f);
    rs_ply_free(ply);
    rs_test_rmtree(dir);
}

static void test_roundtrip_ascii(void **state)
{
    roundtrip(0);
}
static void test_roundtrip_binary(void **state)
{
    roundtrip(1);
}

/* The exact ascii text: header names and enough digits to round-trip. */
static void test_ascii_text(void **state)
{
    const char *dir = rs_test_tmpdir("ply");
    const char *path = rs_test_path(dir, "t.ply");
    rs_err err;
    rs_ply *ply = rs_ply_new();
    rs_ply_add_comment(ply, "hello\nworld");
    rs_ply_element *v = rs_ply_add_element(ply, "vertex", 1);
    const double x = 0.1, c = 7;
    rs_ply_add_scalar(v, "x", RS_PLY_FLOAT32, &x);
    rs_ply_add_scalar(v, "y", RS_PLY_FLOAT64, &x);
    rs_ply_add_scalar(v, "c", RS_PLY_UINT8, &c);
    assert_int_equal(rs_ply_write(ply, path, 0, &err), 0);
    rs_ply_free(ply);
    size_t size;
    char *text = slurp(path, &size);
    assert_string_equal(text,
                        "ply\nformat ascii 1.0\ncomment hello world\nelement vertex 1\n"
                        "property float x\nproperty double y\nproperty uchar c\nend_header\n"
                        "0.100000001 0.10000000000000001 7\n");
    free(text);
    rs_test_rmtree(dir);
}

/* Integers are rounded half away from zero and saturated; NaN becomes 0; floats saturate. */
static void test_convert_saturate(void **state)
{
    const double in_u8[5] = {-5, 2.5, 300, NAN, 254.49};
    const double out_u8[5] = {0, 3, 255, 0, 254};
    const double in_i8[4] = {-200, -2.5, 1e10, 0.5};
    const double out_i8[4] = {-128, -3, 127, 1};
    const double in_u32[3] = {-1, 5e9, 4294967294.6};
    const double out_u32[3] = {0, 4294967295.0, 4294967295.0};
    const double in_f[3] = {1e39, -1e39, 1.5};
    const double out_f[3] = {FLT_MAX, -FLT_MAX, 1.5};
    const char *dir = rs_test_tmpdir("ply");
    for (int binary = 0; binary < 2; binary++) {
        const char *path = rs_test_path(dir, "sat.ply");
        rs_err err;
        rs_ply *ply = rs_ply_new();
        rs_ply_element *a = rs_ply_add_element(ply, "a", 5);
        rs_ply_add_scalar(a, "u8", RS_PLY_UINT8, in_u8);
        rs_ply_element *b = rs_ply_add_element(ply, "b", 4);
        rs_ply_add_scalar(b, "i8", RS_PLY_INT8, in_i8);
        rs_ply_element *c = rs_ply_add_element(ply, "c", 3);
        rs_ply_add_scalar(c, "u32", RS_PLY_UINT32, in_u32);
        rs_ply_add_scalar(c, "f", RS_PLY_FLOAT32, in_f);
        assert_int_equal(rs_ply_write(ply, path, binary, &err), 0);
        rs_ply_free(ply);
        ply = rs_ply_read(path, &err);
        assert_non_null(ply);
        check_prop(rs_ply_find_element(ply, "a"), "u8", RS_PLY_UINT8, out_u8, 0);
        check_prop(rs_ply_find_element(ply, "b"), "i8", RS_PLY_INT8, out_i8, 0);
        check_prop(rs_ply_find_element(ply, "c"), "u32", RS_PLY_UINT32, out_u32, 0);
        check_prop(rs_ply_find_element(ply, "c"), "f", RS_PLY_FLOAT32, out_f, 0);
        rs_ply_free(ply);
    }
    rs_test_rmtree(dir);
}

/* A big-endian file written byte by byte. */
static void test_big_endian(void **state)
{
    const char *header = "ply\nformat binary_big_endian 1.0\ncomment big\n"
                         "element vertex 2\nproperty float x\nproperty short s\nproperty uint u\n"
                         "property double d\nelement face 1\nproperty list ushort int vertex_indices\n"
                         "end_header\n";
    unsigned char buf[512];
    size_t n = strlen(header);
    memcpy(buf, header, n);
    n += be32f(buf + n, 1.5f);
    n += be16(buf + n, (uint16_t)-2);
    n += be32(buf + n, 0x01020304u);
    n += be64d(buf + n, 2.0);
    n += be32f(buf + n, -0.125f);
    n += be16(buf + n, 300);
    n += be32(buf + n, 4000000000u);
    n += be64d(buf + n, -1e-300);
    n += be16(buf + n, 3);
    n += be32(buf + n, 0);
    n += be32(buf + n, 1);
    n += be32(buf + n, (uint32_t)-7);
    rs_err err;
    rs_ply *ply = rs_ply_read_mem((const char *)buf, n, "be.ply", &err);
    if (!ply) fail_msg("%s", err.msg);
    assert_string_equal(ply->comments[0], "big");
    rs_ply_element *v = rs_ply_find_element(ply, "vertex");
    const double x[2] = {1.5, -0.125}, s[2] = {-2, 300}, u[2] = {16909060, 4000000000.0}, d[2] = {2.0, -1e-300};
    check_prop(v, "x", RS_PLY_FLOAT32, x, 0);
    check_prop(v, "s", RS_PLY_INT16, s, 0);
    check_prop(v, "u", RS_PLY_UINT32, u, 0);
    check_prop(v, "d", RS_PLY_FLOAT64, d, 0);
    rs_ply_prop *vi = rs_ply_find_prop(rs_ply_find_element(ply, "face"), "vertex_indices");
    assert_int_equal(vi->count_type, RS_PLY_UINT16);
    assert_int_equal(vi->offsets[1], 3);
    assert_true(vi->data[0] == 0 && vi->data[1] == 1 && vi->data[2] == -7);
    rs_ply_free(ply);
    /* One byte short must fail, naming the face. */
    expect_fail_mem((const char *)buf, n - 1, "element 'face' 0", "data ends after 0 of 1");
}

/* The header style of other software: CRLF, obj_info, intN type names, vertex_index,
 * lists of varying length, odd spacing, trailing garbage. */
static void test_foreign_header(void **state)
{
    const char *text = "ply\r\nformat ascii 1.0\r\ncomment made by OtherSoft 2.1\r\n"
                       "obj_info num_cols 10\r\n\r\nelement vertex 4\r\nproperty float32 x\r\n"
                       "property float32 y\r\nproperty float32 z\r\nproperty uint8 red\r\n"
                       "element face 2\r\nproperty list uchar int vertex_index\r\n"
                       "end_header  \r\n"
                       "0 0 0 255\r\n1 0 0 0\r\n  1 1 0\t12\r\n0 1 0 7\r\n"
                       "4 0 1 2 3\r\n3 0 2 3\r\nsome trailing garbage \x01\x02";
    rs_err err;
    rs_ply *ply = read_text(text, &err);
    if (!ply) fail_msg("%s", err.msg);
    assert_int_equal(ply->ncomments, 2);
    assert_string_equal(ply->comments[0], "made by OtherSoft 2.1");
    assert_string_equal(ply->comments[1], "num_cols 10");
    rs_ply_element *v = rs_ply_find_element(ply, "vertex");
    const double red[4] = {255, 0, 12, 7}, x[4] = {0, 1, 1, 0};
    check_prop(v, "red", RS_PLY_UINT8, red, 0);
    check_prop(v, "x", RS_PLY_FLOAT32, x, 0);
    rs_ply_prop *vi = rs_ply_find_prop(rs_ply_find_element(ply, "face"), "vertex_index");
    assert_non_null(vi);
    assert_int_equal(vi->offsets[0], 0);
    assert_int_equal(vi->offsets[1], 4);
    assert_int_equal(vi->offsets[2], 7);
    const double items[7] = {0, 1, 2, 3, 0, 2, 3};
    for (int i = 0; i < 7; i++) assert_true(vi->data[i] == items[i]);
    rs_ply_free(ply);
}

/* ---- errors ---- */

#define HDR  "ply\nformat ascii 1.0\n"
#define BHDR "ply\nformat binary_little_endian 1.0\n"

static void test_header_errors(void **state)
{
    expect_fail("PLY\nformat ascii 1.0\nend_header\n", "bad.ply:1", "expected 'ply'");
    expect_fail_mem("", 0, "expected 'ply'", NULL);
    expect_fail_mem(NULL, 0, "expected 'ply'", NULL);
    expect_fail("ply", "no 'end_header'", NULL);
    expect_fail(HDR "element vertex 1\nproperty float x\n0.5\n", "no 'end_header'", NULL);
    expect_fail("ply\nformat binary_middle_endian 1.0\nend_header\n", "bad.ply:2",
                "unknown format 'binary_middle_endian' (expected ascii");
    expect_fail("ply\nformat ascii 2.0\nend_header\n", "bad.ply:2", "version '2.0'");
    expect_fail("ply\nformat ascii\nend_header\n", "bad.ply:2", "expected 'format");
    expect_fail("ply\nelement vertex 1\nend_header\n", "bad.ply:3", "no 'format' line");
    expect_fail(HDR "format ascii 1.0\nend_header\n", "bad.ply:3", "second 'format'");
    expect_fail(HDR "element vertex 1\nproperty flaot x\nend_header\n", "bad.ply:4",
                "unknown type 'flaot' (expected char, uchar");
    expect_fail(HDR "element face 1\nproperty list float int vi\nend_header\n", "bad.ply:4",
                "count type 'float' is not an integer type");
    expect_fail(HDR "element face 1\nproperty list uchar int\nend_header\n", "bad.ply:4",
                "expected 'property <type> <name>'");
    expect_fail(HDR "property float x\nend_header\n", "bad.ply:3", "before any 'element'");
    expect_fail(HDR "element vertex -3\nend_header\n", "bad.ply:3", "not a non-negative integer");
    expect_fail(HDR "element vertex 99999999999999999999999\nend_header\n", "bad.ply:3", "not a non-negative integer");
    expect_fail(HDR "element vertex 1 2\nend_header\n", "bad.ply:3", "expected 'element <name>");
    expect_fail(HDR "element v 1\nproperty int a\nproperty float a\nend_header\n", "bad.ply:5",
                "property 'a' declared twice");
    expect_fail(HDR "element v 1\nelement v 1\nend_header\n", "bad.ply:4", "declared twice");
    expect_fail(HDR "elephant v 1\nend_header\n", "bad.ply:3", "unknown header line 'elephant'");
    expect_fail_mem(HDR "comment a\0b\nend_header\n", sizeof(HDR "comment a\0b\nend_header\n") - 1, "bad.ply:3",
                    "NUL byte");
}

static void test_ascii_data_errors(void **state)
{
    expect_fail(HDR "element vertex 2\nproperty float x\nproperty float y\nend_header\n"
                    "1 2\n3 abc\n",
                "bad.ply:8", "element 'vertex' 1, property 'y': expected a number (float), found 'abc'");
    expect_fail(HDR "element vertex 1\nproperty uchar c\nend_header\n300\n", "bad.ply:6",
                "expected an integer in 0..255 (uchar), found '300'");
    expect_fail(HDR "element vertex 1\nproperty int c\nend_header\n1.5\n", "bad.ply:6", "expected an integer");
    expect_fail(HDR "element vertex 3\nproperty float x\nproperty float y\nend_header\n1 2\n3 4\n5",
                "element 'vertex' 2, property 'y'", "data ends after 2 of 3 'vertex' elements (truncated file?)");
    /* A count far beyond the data: fails once the tokens run out, without a huge allocation. */
    expect_fail(HDR "element vertex 1000000000000\nproperty float x\nend_header\n1 2 3\n",
                "data ends after 3 of 1000000000000", NULL);
    expect_fail(HDR "element face 1\nproperty list char int vi\nend_header\n-1 4\n", "element 'face' 0, list 'vi'",
                "negative item count -1");
    expect_fail(HDR "element face 1\nproperty list uchar int vi\nend_header\n-1 4\n",
                "list count: expected an integer in 0..255", NULL);
    expect_fail(HDR "element face 1\nproperty list uint int vi\nend_header\n4000000000 1 2 3\n",
                "4000000000 items announced", NULL);
    expect_fail(HDR "element face 2\nproperty list uchar int vi\nend_header\n3 0 1 2\n3 0 1\n", "element 'face' 1",
                "data ends after 1 of 2");
    expect_fail(HDR "element face 1\nproperty list uchar int vi\nend_header\n3 0 x 2\n",
                "list item: expected an integer", "found 'x'");
}

static void test_binary_data_errors(void **state)
{
    /* A count that would need exabytes: fails after the two records there are. */
    const char huge[] = BHDR "element vertex 18446744073709551615\nproperty float x\nend_header\n"
                             "\0\0\0\0\0\0\x80?";
    expect_fail_mem(huge, sizeof huge - 1, "element 'vertex' 2",
                    "data ends after 2 of 18446744073709551615 'vertex' elements");
    const char neg[] = BHDR "element face 1\nproperty list char int vi\nend_header\n\xff\0\0\0\0";
    expect_fail_mem(neg, sizeof neg - 1, "element 'face' 0, list 'vi'", "negative item count -1");
    const char big[] = BHDR "element face 1\nproperty list uint int vi\nend_header\n"
                            "\xf0\xff\xff\xff\0\0\0\0\0\0\0\0\0\0\0\0";
    expect_fail_mem(big, sizeof big - 1, "4294967280 items announced", NULL);
    const char none[] = BHDR "element vertex 1\nproperty double x\nend_header\n";
    expect_fail_mem(none, sizeof none - 1, "data ends after 0 of 1 'vertex'", NULL);
}

/* Every prefix of a binary mesh fails with a message (none crashes); the faces' one names the
 * face being read. */
static void test_truncated_binary(void **state)
{
    const char *dir = rs_test_tmpdir("ply");
    const char *path = rs_test_path(dir, "five.ply");
    rs_err err;
    rs_ply *ply = rs_ply_new();
    rs_ply_element *v = rs_ply_add_element(ply, "vertex", 3);
    rs_ply_add_scalar(v, "x", RS_PLY_FLOAT32, NULL);
    rs_ply_element *f = rs_ply_add_element(ply, "face", 5);
    double items[15] = {0};
    rs_ply_add_list_fixed(f, "vertex_indices", RS_PLY_UINT8, RS_PLY_INT32, 3, items);
    assert_int_equal(rs_ply_write(ply, path, 1, &err), 0);
    rs_ply_free(ply);
    size_t size;
    char *data = slurp(path, &size);
    /* Each face is 13 bytes: cut inside face 2. */
    expect_fail_mem(data, size - 13 * 3 + 5, "element 'face' 2, list 'vertex_indices'",
                    "data ends after 2 of 5 'face' elements");
    expect_fail_mem(data, size - 13 * 3, "element 'face' 2, property 'vertex_indices'",
                    "data ends after 2 of 5 'face' elements (truncated file?)");
    for (size_t n = 0; n < size; n++) {
        rs_err_clear(&err);
        char *copy = malloc(n ? n : 1); /* exact size so that ASan sees any over-read */
        memcpy(copy, data, n);
        rs_ply *p = rs_ply_read_mem(copy, n, "bad.ply", &err);
        if (p) fail_msg("prefix of %zu of %zu bytes was accepted", n, size);
        assert_true(err.msg[0] != '\0');
        free(copy);
    }
    ply = rs_ply_read_mem(data, size, "ok.ply", &err);
    assert_non_null(ply);
    rs_ply_free(ply);
    free(data);
    rs_test_rmtree(dir);
}

/* Random byte changes in valid files: reading may succeed or fail, but must never crash. */
static void test_mutations(void **state)
{
    const char *dir = rs_test_tmpdir("ply");
    rs_err err;
    uint32_t seed = 12345;
    for (int binary = 0; binary < 2; binary++) {
        const char *path = rs_test_path(dir, "m.ply");
        rs_ply *ply = mixed_mesh();
        assert_int_equal(rs_ply_write(ply, path, binary, &err), 0);
        rs_ply_free(ply);
        size_t size;
        char *data = slurp(path, &size);
        char *copy = malloc(size);
        for (int round = 0; round < 3000; round++) {
            memcpy(copy, data, size);
            for (int m = 0; m < 1 + round % 4; m++) {
                seed = seed * 1664525u + 1013904223u;
                copy[(seed >> 8) % size] = (char)(seed >> 24);
            }
            seed = seed * 1664525u + 1013904223u;
            size_t n = round % 3 ? size : (seed >> 8) % size;
            rs_ply_free(rs_ply_read_mem(copy, n, "m.ply", &err));
        }
        free(copy);
        free(data);
    }
    rs_test_rmtree(dir);
}

/* ---- builders, writer errors ---- */

static void test_builders(void **state)
{
    rs_ply_free(NULL);
    rs_ply *ply = rs_ply_new();
    char long_name[80];
    memset(long_name, 'a', sizeof long_name - 1);
    long_name[sizeof long_name - 1] = '\0';
    assert_null(rs_ply_add_element(ply, long_name, 1));
    assert_null(rs_ply_add_element(ply, "", 1));
    rs_ply_element *v = rs_ply_add_element(ply, "vertex", 2);
    assert_non_null(v);
    assert_null(rs_ply_add_element(ply, "vertex", 2));
    assert_non_null(rs_ply_add_scalar(v, "x", RS_PLY_FLOAT32, NULL));
    assert_null(rs_ply_add_scalar(v, "x", RS_PLY_FLOAT32, NULL));
    assert_true(rs_ply_find_prop(v, "x")->data[1] == 0.0);
    assert_null(rs_ply_add_list_fixed(v, "l", RS_PLY_FLOAT32, RS_PLY_INT32, 3, NULL));
    assert_null(rs_ply_add_list_fixed(v, "l", RS_PLY_UINT8, RS_PLY_INT32, 256, NULL));
    assert_null(rs_ply_find_prop(v, "y"));
    assert_null(rs_ply_find_element(ply, "face"));
    rs_ply_add_comment(ply, "key");
    rs_ply_add_comment(ply, "key2 b");
    rs_ply_add_comment(ply, "key   spaced value");
    assert_string_equal(rs_ply_find_comment(ply, "key"), "");
    assert_string_equal(rs_ply_find_comment(ply, "key2"), "b");
    assert_null(rs_ply_find_comment(ply, "ke"));
    rs_ply_free(ply);
}

static void test_write_errors(void **state)
{
    const char *dir = rs_test_tmpdir("ply");
    const char *path = rs_test_path(dir, "over.ply");
    rs_err err;
    char msg[2048];
    rs_ply *ply = rs_ply_new();
    rs_ply_element *f = rs_ply_add_element(ply, "face", 1);
    rs_ply_prop *p = rs_ply_add_list_fixed(f, "vi", RS_PLY_UINT8, RS_PLY_INT32, 3, NULL);
    /* Make face 0 a 300-item list, more than a uchar count can say. */
    double *items = calloc(300, sizeof(double));
    free(p->data);
    p->data = items;
    p->offsets[1] = 300;
    assert_int_equal(rs_ply_write(ply, path, 1, &err), -1);
    rs_err_format(&err, msg, sizeof msg);
    assert_non_null(strstr(msg, "over.ply"));
    assert_non_null(strstr(msg, "300 items, more than its count type uchar"));
    assert_false(rs_file_exists(path));
    assert_int_equal(rs_ply_write(ply, "/nonexistent-dir/x/y.ply", 0, &err), -1);
    assert_null(rs_ply_read("/nonexistent-dir/x/y.ply", &err));
    assert_true(err.msg[0] != '\0');
    rs_ply_free(ply);
    rs_test_rmtree(dir);
}

/* A mesh of a million faces: binary round trip, and the read must be fast. */
static void test_large_binary(void **state)
{
    const size_t nv = 500000, nf = 1000000;
    const char *dir = rs_test_tmpdir("ply");
    const char *path = rs_test_path(dir, "big.ply");
    rs_err err;
    rs_ply *ply = rs_ply_new();
    rs_ply_element *v = rs_ply_add_element(ply, "vertex", nv);
    const char *axes[3] = {"x", "y", "z"};
    for (int a = 0; a < 3; a++) {
        rs_ply_prop *p = rs_ply_add_scalar(v, axes[a], RS_PLY_FLOAT32, NULL);
        for (size_t k = 0; k < nv; k++) p->data[k] = (double)(float)(k * 0.001 + a);
    }
    rs_ply_element *f = rs_ply_add_element(ply, "face", nf);
    rs_ply_prop *vi = rs_ply_add_list_fixed(f, "vertex_indices", RS_PLY_UINT8, RS_PLY_INT32, 3, NULL);
    for (size_t k = 0; k < 3 * nf; k++) vi->data[k] = (double)(k % nv);
    rs_ply_add_scalar(f, "albedo_r", RS_PLY_FLOAT32, NULL);
    assert_int_equal(rs_ply_write(ply, path, 1, &err), 0);
    rs_ply_free(ply);

    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    ply = rs_ply_read(path, &err);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double secs = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    print_message("read %zu faces in %.3f s\n", nf, secs);
    assert_non_null(ply);
    f = rs_ply_find_element(ply, "face");
    vi = rs_ply_find_prop(f, "vertex_indices");
    assert_int_equal(f->count, nf);
    assert_int_equal(vi->offsets[nf], 3 * nf);
    assert_true(vi->data[3 * nf - 1] == (double)((3 * nf - 1) % nv));
    assert_true(rs_ply_find_prop(rs_ply_find_element(ply, "vertex"), "z")->data[nv - 1] ==
                (double)(float)((nv - 1) * 0.001 + 2));
    /* Speed is measured in bench/, not asserted here: tests check correctness. */
    rs_ply_free(ply);
    rs_test_rmtree(dir);
}

/* The reference scene's truth mesh, when the shared data is there. */
static void test_shared_truth(void **state)
{
    const char *shared = getenv("RHOSCAN_SHARED_DIR");
    struct stat st;
    if (!shared || stat(shared, &st) != 0 || !S_ISDIR(st.st_mode)) skip();
    char path[4096];
    snprintf(path, sizeof path, "%s/reference/two_planes_sky/truth.ply", shared);
    rs_err err;
    rs_ply *ply = rs_ply_read(path, &err);
    if (!ply) fail_msg("%s", err.msg);
    rs_ply_element *v = rs_ply_find_element(ply, "vertex");
    rs_ply_element *f = rs_ply_find_element(ply, "face");
    assert_non_null(v);
    assert_non_null(f);
    assert_int_equal(v->count, 16);
    assert_int_equal(f->count, 24);
    const char *names[4] = {"red", "green", "blue", "part"};
    for (int i = 0; i < 4; i++) {
        rs_ply_prop *p = rs_ply_find_prop(f, names[i]);
        assert_non_null(p);
        assert_int_equal(p->type, i < 3 ? RS_PLY_FLOAT32 : RS_PLY_INT32);
        for (size_t k = 0; k < f->count; k++)
            assert_true(i < 3 ? p->data[k] >= 0.0 && p->data[k] <= 1.0 : p->data[k] >= 0.0);
    }
    rs_ply_prop *vi = rs_ply_find_prop(f, "vertex_indices");
    assert_non_null(vi);
    for (size_t k = 0; k < f->count; k++) {
        assert_int_equal(vi->offsets[k + 1] - vi->offsets[k], 3);
        for (size_t j = vi->offsets[k]; j < vi->offsets[k + 1]; j++) assert_true(vi->data[j] >= 0 && vi->data[j] < 16);
    }
    rs_ply_free(ply);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_roundtrip_ascii), cmocka_unit_test(test_roundtrip_binary),
             cmocka_unit_test(test_ascii_text), cmocka_unit_test(test_convert_saturate),
             cmocka_unit_test(test_big_endian), cmocka_unit_test(test_foreign_header),
             cmocka_unit_test(test_header_errors), cmocka_unit_test(test_ascii_data_errors),
             cmocka_unit_test(test_binary_data_errors), cmocka_unit_test(test_truncated_binary),
             cmocka_unit_test(test_mutations), cmocka_unit_test(test_builders), cmocka_unit_test(test_write_errors),
             cmocka_unit_test(test_large_binary), cmocka_unit_test(test_shared_truth))
