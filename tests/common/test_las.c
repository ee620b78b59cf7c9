/* test_las: the LAS reader on files written by tests/laswrite.h (every point format, versions,
 * extra bytes, padding, 64-bit counts, the colour rule, classes, chunk boundaries) and on broken
 * ones (each refusal names the file and the field's offset). The files other software wrote
 * are test_las_files'. */
#include "tests/testutil.h"
#include "tests/laswrite.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "common/cloud_format.h"
#include "common/las.h"

static const las_spec base = {.minor = 2, .format = 3, .scale = {0.001, 0.001, 0.001}, .offset = {500000, 5e6, 100}};

static const double pts[4][3] = {
    {500001.234, 5000002.345, 101.5}, {499999.001, 4999999.999, 99.25}, {500010, 5000020, 130}, {500000, 5e6, 100}};
static const uint16_t inten[4] = {0, 143, 65535, 7};
static const uint8_t cls[4] = {2, 6, 2, 31};

static rs_cloud *read_ok(const char *path, const uint8_t *keep)
{
    rs_err err = {0};
    rs_cloud *c = rs_las_read(path, keep, &err);
    if (!c) fail_msg("%s: %s", path, err.msg);
    return c;
}

/* Every format, every version that can hold it, with extra bytes and padding: coordinates to
 * the scale, intensity, the class (low 5 bits in formats 0-5, flags masked), colour. */
static void test_formats(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("las");
    const char *path = rs_test_path(dir, "f.las");
    uint16_t rgb[12] = {0, 128, 255, 10, 20, 30, 255, 255, 255, 1, 2, 3};
    for (int format = 0; format <= 10; format++)
        for (int minor = format >= 6 ? 4 : 0; minor <= 4; minor++) {
            las_spec s = base;
            s.format = format, s.minor = minor, s.extra = (unsigned)(format * 3) % 7, s.pad = (unsigned)minor;
            s.legacy_zero = format >= 6;
            assert_int_equal(las_write(path, &s, 4, &pts[0][0], inten, rgb, cls), 0);
            rs_cloud *c = read_ok(path, NULL);
            assert_int_equal(c->npoints, 4);
            assert_int_equal(c->nscans, 0);
            assert_true(c->normals_up);
            for (int i = 0; i < 4; i++) {
                for (int j = 0; j < 3; j++) assert_true(fabs(c->xyz[3 * i + j] - pts[i][j]) < 1e-9 + 5e-4);
                assert_int_equal((int)c->intensity[i], inten[i]);
                assert_int_equal(c->valid[i], 1);
            }
            int has_rgb = las_rgb_at[format] != 0;
            assert_int_equal(c->rgb != NULL, has_rgb);
            static const uint8_t want[12] = {0, 128, 255, 10, 20, 30, 255, 255, 255, 1, 2, 3};
            if (has_rgb) assert_memory_equal(c->rgb, want, 12);
            rs_cloud_free(c);
            /* Through the format table, by the magic bytes. */
            const char *name = NULL;
            rs_err err = {0};
            rs_cloud_read_opts opts = {0};
            uint8_t keep[256];
            assert_int_equal(rs_las_parse_classes("2 31", keep, &err), 0);
            opts.las_keep = keep;
            c = rs_cloud_read_with(path, &opts, &name, &err);
            if (!c) fail_msg("format %d, 1.%d: %s", format, minor, err.msg);
            assert_string_equal(name, "LAS");
            assert_int_equal(c->npoints, 3); /* classes 2, 2 and 31 */
            assert_true(fabs(c->xyz[3] - pts[2][0]) < 1e-6 && fabs(c->xyz[6] - pts[3][0]) < 1e-6);
            rs_cloud_free(c);
        }
    rs_test_rmtree(dir);
}

/* The colour rule: 8-bit values in the 16-bit fields are kept; 16-bit colour gives its high
 * byte, also for the points read before the first value above 255 showed it. */
static void test_colour_rule(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("las");
    const char *path = rs_test_path(dir, "c.las");
    las_spec s = base;
    uint16_t wide[12] = {0, 200, 255, 10 * 257, 20 * 257, 30 * 257, 65535, 65280, 257, 0x1234, 0x00ff, 0xff00};
    assert_int_equal(las_write(path, &s, 4, &pts[0][0], inten, wide, cls), 0);
    rs_cloud *c = read_ok(path, NULL);
    static const uint8_t want_wide[12] = {0, 0, 0, 10, 20, 30, 255, 255, 1, 0x12, 0, 0xff};
    assert_memory_equal(c->rgb, want_wide, 12);
    rs_cloud_free(c);
    /* The same file with the 16-bit point filtered out by its class: 8-bit again. */
    uint16_t narrow[12] = {0, 200, 255, 1000, 1, 1, 249, 239, 249, 5, 6, 7};
    assert_int_equal(las_write(path, &s, 4, &pts[0][0], inten, narrow, cls), 0);
    uint8_t keep[256];
    rs_err err = {0};
    assert_int_equal(rs_las_parse_classes("2 31", keep, &err), 0);
    c = read_ok(path, keep);
    assert_int_equal(c->npoints, 3);
    static const uint8_t want_narrow[9] = {0, 200, 255, 249, 239, 249, 5, 6, 7};
    assert_memory_equal(c->rgb, want_narrow, 9);
    rs_cloud_free(c);
    rs_test_rmtree(dir);
}

/* More points than one chunk (4 MiB of records): every point in order across the boundary; the
 * 64-bit count of 1.4 with the legacy one 0. */
static void test_chunks(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("las");
    const char *path = rs_test_path(dir, "big.las");
    size_t n = 250000; /* 20-byte records: 209715 per chunk */
    double *xyz = malloc(3 * n * sizeof *xyz);
    uint16_t *in = malloc(n * sizeof *in);
    uint8_t *k3 = malloc(n);
    assert_non_null(xyz), assert_non_null(in), assert_non_null(k3);
    for (size_t i = 0; i < n; i++) {
        xyz[3 * i] = 0.01 * (double)i, xyz[3 * i + 1] = -0.02 * (double)(i % 1000), xyz[3 * i + 2] = 0.5;
        in[i] = (uint16_t)i;
        k3[i] = (uint8_t)(i % 3);
    }
    las_spec s = {.minor = 4, .format = 0, .scale = {0.01, 0.01, 0.01}, .legacy_zero = 1};
    assert_int_equal(las_write(path, &s, n, xyz, in, NULL, k3), 0);
    rs_err err = {0};
    rs_las *f = rs_las_open(path, &err);
    if (!f) fail_msg("%s", err.msg);
    assert_int_equal(rs_las_info_of(f)->npoints, n);
    size_t seen = 0, chunks = 0;
    for (const rs_las_chunk *ch; (ch = rs_las_next(f, &err)) && ch->n; chunks++)
        for (size_t i = 0; i < ch->n; i++, seen++) {
            if (fabs(ch->xyz[3 * i] - xyz[3 * seen]) > 1e-9 || ch->intensity[i] != in[seen])
                fail_msg("point %zu: x %.9g intensity %u", seen, ch->xyz[3 * i], ch->intensity[i]);
        }
    assert_int_equal(seen, n);
    assert_int_equal(chunks, 2);
    rs_las_close(f);
    /* The cloud with every third point kept: in order across the chunks (decoded in place, then
     * moved down over the points not kept). */
    uint8_t keep[256];
    assert_int_equal(rs_las_parse_classes("1", keep, &err), 0);
    rs_cloud *c = rs_las_read(path, keep, &err);
    if (!c) fail_msg("%s", err.msg);
    assert_int_equal(c->npoints, (n + 1) / 3);
    for (size_t k = 0; k < c->npoints; k++) {
        size_t i = 3 * k + 1;
        if (fabs(c->xyz[3 * k] - xyz[3 * i]) > 1e-9 || fabs(c->xyz[3 * k + 1] - xyz[3 * i + 1]) > 1e-9 ||
            c->intensity[k] != (float)in[i])
            fail_msg("kept point %zu: (%.9g, %.9g), intensity %g; expected point %zu", k, c->xyz[3 * k],
                     c->xyz[3 * k + 1], c->intensity[k], i);
    }
    rs_cloud_free(c);
    free(xyz);
    free(in);
    free(k3);
    rs_test_rmtree(dir);
}

/* Writes base's 4 points, then overwrites len bytes at offset with bytes (or truncates the file
 * to offset when bytes is NULL), and expects the reader to refuse it with a message holding
 * each of the words. */
static void expect_refusal(const char *dir, const las_spec *s, long offset, const void *bytes, size_t len,
                           const char *word1, const char *word2)
{
    const char *path = rs_test_path(dir, "bad.las");
    uint16_t rgb[12] = {0};
    assert_int_equal(las_write(path, s, 4, &pts[0][0], inten, rgb, cls), 0);
    if (bytes) {
        FILE *f = fopen(path, "r+b");
        assert_non_null(f);
        assert_int_equal(fseek(f, offset, SEEK_SET), 0);
        assert_int_equal(fwrite(bytes, 1, len, f), len);
        fclose(f);
    } else {
        assert_int_equal(truncate(path, offset), 0);
    }
    rs_err err = {0};
    rs_cloud *c = rs_cloud_read(path, &err);
    if (c) fail_msg("read a broken file (%s, %s)", word1, word2);
    assert_int_equal(err.kind, RS_ERR_INPUT);
    if (!strstr(err.file, "bad.las") || !strstr(err.msg, word1) || !strstr(err.msg, word2))
        fail_msg("unexpected message: %s: %s (expected \"%s\" and \"%s\")", err.file, err.msg, word1, word2);
}

static void test_refusals(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("las");
    las_spec s = base;
    unsigned char b[8];
    expect_refusal(dir, &s, 227 + 34 * 3 + 5, NULL, 0, "4 points of 34 bytes from offset 227 need 363 bytes",
                   "the file has 334");
    expect_refusal(dir, &s, 100, NULL, 0, "100 bytes", "at least 227");
    las_put32(b, 1u << 30);
    expect_refusal(dir, &s, 107, b, 4, "1073741824 points of 34 bytes", "the file has 363");
    expect_refusal(dir, &s, 96, b, 4, "offset 96", "offset to point data 1073741824");
    las_put16(b, 200);
    expect_refusal(dir, &s, 94, b, 2, "offset 94", "header size 200");
    expect_refusal(dir, &s, 24, "\x02\x00", 2, "offset 24", "version 2.0");
    expect_refusal(dir, &s, 104, "\x0b", 1, "offset 104", "point data format 11");
    expect_refusal(dir, &s, 104, "\x83", 1, "compression bit", "laszip -i");
    las_put16(b, 30);
    expect_refusal(dir, &s, 105, b, 2, "offset 105", "record length 30");
    las_putd(b, 0.0);
    expect_refusal(dir, &s, 139, b, 8, "offset 139", "Y scale factor 0");
    las_putd(b, NAN);
    expect_refusal(dir, &s, 171, b, 8, "offset 171", "Z offset");
    las_putd(b, 1e6);
    expect_refusal(dir, &s, 131, b, 8, "point 0 (offset 227)", "coordinate x");
    /* 1.4: a 64-bit count far beyond the file, refused before anything is allocated. */
    las_spec wide = base;
    wide.minor = 4, wide.format = 6, wide.legacy_zero = 1;
    las_put64(b, (uint64_t)1 << 40);
    expect_refusal(dir, &wide, 247, b, 8, "1099511627776 points of 30 bytes", "truncated");
    /* A LAZ file whose format byte lost its bit: the laszip VLR gives it away. */
    const char *path = rs_test_path(dir, "bad.las");
    FILE *f = fopen(path, "wb");
    unsigned char h[375], vlr[54 + 4] = {0};
    double lo[3] = {0}, hi[3] = {0};
    las_spec z = base;
    z.pad = sizeof vlr;
    unsigned size = las_header(&z, 0, lo, hi, h);
    las_put32(h + 100, 1);
    memcpy(vlr + 2, "laszip encoded", 14);
    las_put16(vlr + 18, 22204), las_put16(vlr + 20, 4);
    assert_true(fwrite(h, 1, size, f) == size && fwrite(vlr, 1, sizeof vlr, f) == sizeof vlr);
    fclose(f);
    rs_err err = {0};
    assert_null(rs_cloud_read(path, &err));
    if (!strstr(err.msg, "laszip encoded") || !strstr(err.msg, "pdal translate")) fail_msg("%s", err.msg);
    rs_test_rmtree(dir);
}

static void test_classes(void **state)
{
    (void)state;
    uint8_t keep[256];
    rs_err err = {0};
    assert_int_equal(rs_las_parse_classes(" 2  6 255 ", keep, &err), 0);
    for (int k = 0; k < 256; k++) assert_int_equal(keep[k], k == 2 || k == 6 || k == 255);
    assert_int_equal(rs_las_parse_classes("2 x", keep, &err), -1);
    assert_non_null(strstr(err.msg, "\"x\" is not a class number"));
    assert_int_equal(rs_las_parse_classes("256", keep, &err), -1);
    assert_int_equal(rs_las_parse_classes("2.5", keep, &err), -1);
    assert_int_equal(rs_las_parse_classes("  ", keep, &err), -1);
    assert_non_null(strstr(err.msg, "empty"));
    /* No point kept: refused, naming the classes the file has. */
    const char *dir = rs_test_tmpdir("las");
    const char *path = rs_test_path(dir, "k.las");
    assert_int_equal(las_write(path, &base, 4, &pts[0][0], inten, NULL, cls), 0);
    assert_int_equal(rs_las_parse_classes("9", keep, &err), 0);
    assert_null(rs_las_read(path, keep, &err));
    if (!strstr(err.msg, "2 (2 points), 6 (1 points), 31 (1 points)")) fail_msg("%s", err.msg);
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_formats), cmocka_unit_test(test_colour_rule),
             cmocka_unit_test(test_chunks), cmocka_unit_test(test_refusals), cmocka_unit_test(test_classes))
