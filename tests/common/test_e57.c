/* test_e57: the E57 reader on the files other software wrote (the shared reference set's
 * formats/e57, values from its README: counts, bounding boxes to 1 mm, first points, images),
 * and on damaged copies of them (a wrong CRC, XML that lies about counts, offsets or
 * coordinates, truncation): each read or refused with its reason. */
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/cloud_format.h"
#include "common/e57.h"

/* The shared file, or NULL after skip() (a failure under CI=true). */
static const char *e57_file(const char *name)
{
    char rel[256];
    snprintf(rel, sizeof rel, "formats/e57/%s", name);
    const char *p = rs_test_shared_file(rel);
    if (!p && getenv("CI") && strcmp(getenv("CI"), "true") == 0) fail_msg("%s is missing (CI=true requires it)", rel);
    return p;
}

static rs_e57 *open_shared(const char *name)
{
    const char *p = e57_file(name);
    if (!p) return NULL;
    rs_err err = {0};
    rs_e57 *e = rs_e57_open(p, &err);
    if (!e) fail_msg("%s: %s", name, err.msg);
    return e;
}

static rs_cloud *read_shared(const char *name)
{
    const char *p = e57_file(name);
    if (!p) return NULL;
    rs_err err = {0};
    const char *format = NULL;
    rs_cloud *c = rs_cloud_read_with(p, NULL, &format, &err);
    if (!c) fail_msg("%s: %s", name, err.msg);
    assert_string_equal(format, "E57");
    return c;
}

static size_t count_valid(const rs_cloud *c)
{
    size_t n = 0;
    for (size_t i = 0; i < c->npoints; i++) n += c->valid[i] != 0;
    return n;
}

/* The valid points' bounding box equals lo..hi (per axis) to 1 mm (README values are rounded
 * to 3 decimals: within 0.5 mm of them). */
static void assert_bbox(const rs_cloud *c, const double lo[3], const double hi[3])
{
    double a[3] = {INFINITY, INFINITY, INFINITY}, b[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < c->npoints; i++)
        if (c->valid[i])
            for (int j = 0; j < 3; j++) {
                a[j] = fmin(a[j], c->xyz[3 * i + j]);
                b[j] = fmax(b[j], c->xyz[3 * i + j]);
            }
    for (int j = 0; j < 3; j++)
        if (fabs(a[j] - lo[j]) > 0.0005 + 1e-9 || fabs(b[j] - hi[j]) > 0.0005 + 1e-9)
            fail_msg("axis %d: bbox [%.6f, %.6f], expected [%.3f, %.3f]", j, a[j], b[j], lo[j], hi[j]);
}

static void assert_xyz(const double *p, double x, double y, double z, double tol)
{
    if (fabs(p[0] - x) > tol || fabs(p[1] - y) > tol || fabs(p[2] - z) > tol)
        fail_msg("point (%.7f, %.7f, %.7f), expected (%.7f, %.7f, %.7f)", p[0], p[1], p[2], x, y, z);
}

/* The first chunk of scan i. */
static rs_e57_points first_chunk(rs_e57 *e, int i)
{
    rs_err err = {0};
    rs_e57_points p = {0};
    if (rs_e57_scan_begin(e, i, &err) != 0 || rs_e57_scan_next(e, &p, &err) != 1) fail_msg("scan %d: %s", i, err.msg);
    return p;
}

static void test_pump_grid(void **state)
{
    rs_e57 *e = open_shared("pumpAVisualReferenceImage.e57");
    if (!e) skip();
    assert_int_equal(rs_e57_scan_count(e), 1);
    const rs_e57_scan_info *s = rs_e57_scan(e, 0);
    assert_string_equal(s->name, "pumpA");
    assert_int_equal(s->records, 155201);
    assert_true(s->grid && !s->has_pose && s->has_rgb && s->has_intensity);
    assert_int_equal(s->row_max - s->row_min + 1, 1074);
    assert_int_equal(s->col_max - s->col_min + 1, 345);
    rs_e57_points p = first_chunk(e, 0);
    assert_xyz(p.xyz, 1.702286, -3.193588, -1.841843, 1e-6);
    assert_int_equal(p.rgb[0], 51);
    assert_int_equal(p.rgb[1], 65);
    assert_int_equal(p.rgb[2], 49);
    assert_int_equal(p.row[0], 267);
    assert_int_equal(p.col[0], 0);
    assert_true(fabs(p.intensity[0] - 0.456557) < 1e-5);
    assert_int_equal(rs_e57_image_count(e), 1);
    const rs_e57_image_info *im = rs_e57_image(e, 0);
    assert_string_equal(im->name, "pumpVisual");
    assert_int_equal(im->projection, RS_E57_VISUAL);
    assert_int_equal(im->width, 3072);
    assert_int_equal(im->height, 2304);
    assert_int_equal(im->blob_length, 1504576);
    assert_false(im->png || im->has_pose);
    uint8_t *blob;
    size_t n;
    rs_err err = {0};
    assert_int_equal(rs_e57_image_blob(e, 0, &blob, &n, &err), 0);
    assert_int_equal(n, 1504576);
    assert_true(blob[0] == 0xff && blob[1] == 0xd8); /* a JPEG's SOI marker */
    free(blob);
    rs_e57_close(e);

    /* As a cloud: the 1074 x 345 grid, column by column, the stored cells valid. */
    rs_cloud *c = read_shared("pumpAVisualReferenceImage.e57");
    assert_int_equal(c->nscans, 1);
    assert_int_equal(c->scans[0].rows, 1074);
    assert_int_equal(c->scans[0].cols, 345);
    assert_int_equal(c->npoints, 1074 * 345);
    assert_int_equal(count_valid(c), 155201);
    assert_true(c->valid[267]);
    assert_xyz(c->xyz + 3 * 267, 1.702286, -3.193588, -1.841843, 1e-6);
    float lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < c->npoints; i++)
        if (c->valid[i]) lo = fminf(lo, c->intensity[i]), hi = fmaxf(hi, c->intensity[i]);
    assert_true(fabs(lo - 0.384) <= 0.0005 && fabs(hi - 0.698) <= 0.0005);
    assert_bbox(c, (double[]){-2.904, -5.301, -1.900}, (double[]){1.722, -0.793, 1.843});
    rs_cloud_free(c);
}

/* The same bunny as doubles, 32-bit and 19-bit scaled integers (values across byte, word and
 * packet boundaries). */
static void test_bunnies(void **state)
{
    const char *names[] = {"bunnyDouble.e57", "bunnyInt32.e57", "bunnyInt19.e57"};
    for (int k = 0; k < 3; k++) {
        rs_cloud *c = read_shared(names[k]);
        if (!c) skip();
        assert_int_equal(c->npoints, 30571);
        assert_int_equal(count_valid(c), 30571);
        assert_int_equal(c->nscans, 0);
        assert_xyz(c->xyz, -0.070630, 0.040150, 0.001226, 1.5e-6);
        assert_bbox(c, (double[]){-0.095, 0.040, -0.062}, (double[]){0.061, 0.187, 0.059});
        rs_cloud_free(c);
    }
}

static void test_cubes(void **state)
{
    const char *names[] = {"ColouredCubeFloat.e57", "ColouredCubeDouble.e57"};
    for (int k = 0; k < 2; k++) {
        rs_cloud *c = read_shared(names[k]);
        if (!c) skip();
        assert_int_equal(c->npoints, 7680);
        assert_non_null(c->rgb);
        assert_xyz(c->xyz, -0.5, -0.499056, 0.071363, 1e-6);
        assert_int_equal(c->rgb[0], 0);
        assert_int_equal(c->rgb[1], 0);
        assert_int_equal(c->rgb[2], 255);
        assert_bbox(c, (double[]){-0.5, -0.5, -0.5}, (double[]){0.5, 0.5, 0.5});
        rs_cloud_free(c);
    }
}

/* las2e57: data3D before formatName, the las: extension, 16-bit colour (65280 of 0..65535). */
static void test_las2e57_colour(void **state)
{
    rs_cloud *c = read_shared("ColourRepresentation.e57");
    if (!c) skip();
    assert_int_equal(c->npoints, 153);
    assert_xyz(c->xyz, -0.5, -0.015, -0.432, 1e-9);
    assert_int_equal(c->rgb[2], 254); /* 65280 / 65535 * 255 = 254.0 */
    for (size_t i = 0; i < 3 * c->npoints; i++) assert_true(c->rgb[i] == 0 || c->rgb[i] == 254);
    assert_bbox(c, (double[]){-0.5, -0.5, -0.5}, (double[]){0.5, 0.5, 0.5});
    rs_cloud_free(c);
}

static void test_two_prototypes(void **state)
{
    rs_e57 *e = open_shared("A_B_different_dims.e57");
    if (!e) skip();
    assert_int_equal(rs_e57_scan_count(e), 2);
    assert_string_equal(rs_e57_scan(e, 0)->name, "no-color");
    assert_true(rs_e57_scan(e, 0)->has_intensity && !rs_e57_scan(e, 0)->has_rgb);
    assert_true(rs_e57_scan(e, 1)->has_rgb && !rs_e57_scan(e, 1)->has_intensity);
    rs_e57_points p = first_chunk(e, 0);
    assert_int_equal(p.n, 1);
    assert_xyz(p.xyz, 84.174, 537.270, 4.629, 0.0005);
    assert_true(fabs(p.intensity[0] - 0.760) < 0.0005);
    p = first_chunk(e, 1);
    assert_int_equal(p.n, 1);
    assert_xyz(p.xyz, 83.198, 538.468, 4.590, 0.0005);
    assert_int_equal(p.rgb[0], 74);
    assert_int_equal(p.rgb[1], 92);
    assert_int_equal(p.rgb[2], 54);
    rs_e57_close(e);
    rs_cloud *c = read_shared("A_B_different_dims.e57");
    assert_int_equal(c->npoints, 2);
    assert_non_null(c->rgb);
    assert_non_null(c->intensity);
    rs_cloud_free(c);
}

/* A pose with a translation and no rotation (identity): points in the world frame. */
static void test_translation_only(void **state)
{
    rs_e57 *e = open_shared("translationWithoutRotation.e57");
    if (!e) skip();
    const rs_e57_scan_info *s = rs_e57_scan(e, 0);
    assert_true(s->has_pose && !s->grid); /* indexBounds but no row or column fields */
    assert_true(s->translation[0] == 4 && s->translation[1] == 5 && s->translation[2] == 6);
    assert_true(s->rotation[0] == 1 && s->rotation[4] == 1 && s->rotation[8] == 1 && s->rotation[1] == 0);
    rs_e57_close(e);
    rs_cloud *c = read_shared("translationWithoutRotation.e57");
    assert_int_equal(c->npoints, 4);
    assert_xyz(c->xyz + 9, 5, 6, 6, 1e-12);
    assert_bbox(c, (double[]){4, 5, 6}, (double[]){5, 6, 6});
    assert_true(c->has_viewpoint && c->viewpoint[0] == 4 && c->viewpoint[2] == 6);
    rs_cloud_free(c);
}

static void test_normals(void **state)
{
    rs_e57 *e = open_shared("testWithNormals.e57");
    if (!e) skip();
    assert_true(rs_e57_scan(e, 0)->has_normals);
    rs_e57_points p = first_chunk(e, 0);
    assert_int_equal(p.n, 2);
    assert_false(rs_e57_scan_next(e, &p, NULL)); /* the end of the scan */
    p = first_chunk(e, 0);                       /* and read again from its start */
    assert_xyz(p.xyz, 1, 0, 0, 1e-7);
    assert_xyz(p.xyz + 3, 2, 0, 0, 1e-7);
    double n0[3] = {p.normal[0], p.normal[1], p.normal[2]}, n1[3] = {p.normal[3], p.normal[4], p.normal[5]};
    assert_xyz(n0, 0.001, 0.001, 1.0, 0.0006);
    assert_xyz(n1, 0.001, 1.0, 0.001, 0.0006);
    rs_e57_close(e);
}

/* Spherical coordinates only, with an invalid state on odd points. */
static void test_spherical(void **state)
{
    rs_cloud *c = read_shared("tiny_spherical.e57");
    if (!c) skip();
    assert_int_equal(c->npoints, 180);
    assert_int_equal(count_valid(c), 180);
    double a = 2 * 3.14 / 360; /* point 2, the second valid one */
    assert_xyz(c->xyz + 3, cos(a) * cos(a), cos(a) * sin(a), sin(a), 1e-12);
    assert_bbox(c, (double[]){0, -0.5, 0}, (double[]){1, 0.5, 1});
    rs_cloud_free(c);
}

static void test_images(void **state)
{
    rs_cloud *c = read_shared("tiny_pc_and_images.e57");
    if (!c) skip();
    assert_int_equal(c->npoints, 2);
    assert_xyz(c->xyz, 0, 0, 0, 1e-7);
    assert_xyz(c->xyz + 3, 1, 1, 1, 1e-7);
    rs_cloud_free(c);
    rs_e57 *e = open_shared("tiny_pc_and_images.e57");
    assert_int_equal(rs_e57_scan(e, 0)->records, 2);
    assert_int_equal(rs_e57_image_count(e), 4);
    const rs_e57_projection proj[4] = {RS_E57_VISUAL, RS_E57_SPHERICAL, RS_E57_PINHOLE, RS_E57_CYLINDRICAL};
    for (int i = 0; i < 4; i++) {
        const rs_e57_image_info *im = rs_e57_image(e, i);
        assert_int_equal(im->projection, proj[i]);
        assert_int_equal(im->width, 100);
        assert_int_equal(im->height, 100);
        assert_int_equal(im->has_pose, i == 1);
    }
    const rs_e57_image_info *sph = rs_e57_image(e, 1);
    assert_string_equal(sph->name, "spherical");
    assert_true(sph->png);
    assert_int_equal(sph->blob_length, 1073);
    assert_true(fabs(sph->pixel_width - 0.0314) < 1e-12);
    assert_string_equal(sph->associated_scan, rs_e57_scan(e, 0)->guid);
    /* (0.5, 1, 0, 0) normalised: a rotation about x by 2 atan(2). */
    double ang = 2 * atan2(1, 0.5);
    assert_true(fabs(sph->rotation[4] - cos(ang)) < 1e-12 && fabs(sph->rotation[7] - sin(ang)) < 1e-12);
    assert_true(sph->translation[0] == 1 && sph->translation[1] == 2 && sph->translation[2] == 3);
    const rs_e57_image_info *pin = rs_e57_image(e, 2);
    assert_true(pin->focal_length == 123 && pin->pixel_width == 0.044 && pin->pixel_height == 0.033);
    assert_true(pin->principal_x == 23 && pin->principal_y == 42);
    assert_true(rs_e57_image(e, 3)->radius == 666);
    uint8_t *blob;
    size_t n;
    rs_err err = {0};
    assert_int_equal(rs_e57_image_blob(e, 1, &blob, &n, &err), 0);
    assert_true(n == 1073 && memcmp(blob, "\x89PNG", 4) == 0);
    free(blob);
    assert_int_equal(rs_e57_image_blob(e, 2, &blob, &n, &err), 0);
    size_t nonzero = 0;
    for (size_t i = 0; i < n; i++) nonzero += blob[i] != 0;
    assert_int_equal(nonzero, 0); /* the blob README says is all zeros */
    free(blob);
    rs_e57_close(e);
}

/* No scans, three pinhole images, two with the Leica dist: extension. */
static void test_pinhole_distortion(void **state)
{
    rs_e57 *e = open_shared("PinholeImageWithDistortionParameters.e57");
    if (!e) skip();
    assert_int_equal(rs_e57_scan_count(e), 0);
    assert_int_equal(rs_e57_image_count(e), 3);
    int with = 0;
    for (int i = 0; i < 3; i++) {
        const rs_e57_image_info *im = rs_e57_image(e, i);
        assert_int_equal(im->projection, RS_E57_PINHOLE);
        assert_true(im->width == 1 && im->height == 1 && !im->has_pose && im->blob_length == 375);
        assert_true(im->focal_length == 0);
        with += im->has_distortion;
    }
    assert_int_equal(with, 2);
    assert_false(rs_e57_image(e, 2)->has_distortion);
    const rs_e57_image_info *d = rs_e57_image(e, 0);
    assert_true(fabs(d->k[0] - 1.01) < 1e-6 && fabs(d->k[5] - 6.06) < 1e-6 && fabs(d->p[1] - 12.12) < 1e-5);
    assert_true(fabs(d->cx - 21.21) < 1e-5 && fabs(d->fy - 32.32) < 1e-5);
    rs_e57_close(e);
    /* Valid as an image source, refused as a cloud. */
    rs_err err = {0};
    assert_null(rs_cloud_read(e57_file("PinholeImageWithDistortionParameters.e57"), &err));
    assert_non_null(strstr(err.msg, "no points"));
}

/* Refused with their reason: no points, a checksum. */
static void test_refusals(void **state)
{
    const char *p = e57_file("bad-crc.e57");
    if (!p) skip();
    rs_err err = {0};
    assert_null(rs_e57_open(p, &err));
    assert_int_equal(err.kind, RS_ERR_INPUT);
    assert_non_null(strstr(err.msg, "checksum"));
    assert_non_null(strstr(err.msg, "page 0"));
    assert_null(rs_cloud_read(p, &err));
    assert_non_null(strstr(err.file, "bad-crc.e57"));
    const char *none[] = {"empty.e57", "ZeroPoints.e57"};
    for (int k = 0; k < 2; k++) {
        rs_e57 *e = open_shared(none[k]);
        assert_int_equal(rs_e57_scan_count(e), k);
        assert_int_equal(rs_e57_image_count(e), 0);
        rs_e57_close(e);
        assert_null(rs_cloud_read(e57_file(none[k]), &err));
        assert_int_equal(err.kind, RS_ERR_INPUT);
        assert_non_null(strstr(err.msg, "no points"));
    }
}

/* A copy of a shared file in memory with `from` replaced by `to` (same length) in its XML and
 * the pages' CRCs recomputed, so that only the lie is left. */
static uint8_t *patched(const char *name, const char *from, const char *to, size_t *size)
{
    const char *p = e57_file(name);
    if (!p) return NULL;
    FILE *fp = fopen(p, "rb");
    assert_non_null(fp);
    fseek(fp, 0, SEEK_END);
    *size = (size_t)ftell(fp);
    rewind(fp);
    uint8_t *d = malloc(*size);
    assert_int_equal(fread(d, 1, *size, fp), *size);
    fclose(fp);
    assert_int_equal(strlen(from), strlen(to));
    size_t n = strlen(from), hits = 0;
    for (size_t i = 0; from[0] && i + n <= *size; i++)
        if (memcmp(d + i, from, n) == 0) memcpy(d + i, to, n), hits++;
    assert_true(hits > 0 || !from[0]);
    for (size_t pg = 0; pg + 1024 <= *size; pg += 1024) {
        uint32_t c = rs_e57_crc32c(d + pg, 1020);
        d[pg + 1020] = (uint8_t)(c >> 24), d[pg + 1021] = (uint8_t)(c >> 16);
        d[pg + 1022] = (uint8_t)(c >> 8), d[pg + 1023] = (uint8_t)c;
    }
    return d;
}

/* Each lie refused with the file, where, and what was expected. */
static void expect_refusal(const char *from, const char *to, size_t cut, const char *words)
{
    size_t size;
    uint8_t *d = patched("bunnyInt19.e57", from, to, &size);
    if (!d) skip();
    rs_err err = {0};
    rs_cloud *c = rs_e57_read_mem(d, size - cut, "lie.e57", &err);
    if (c) fail_msg("%s -> %s (cut %zu): read", from, to, cut);
    assert_int_equal(err.kind, RS_ERR_INPUT);
    assert_string_equal(err.file, "lie.e57");
    if (!strstr(err.msg, words)) fail_msg("%s -> %s: \"%s\" lacks \"%s\"", from, to, err.msg, words);
    free(d);
}

static void test_lies(void **state)
{
    /* The unpatched copy reads (the CRCs are recomputed the way the writer made them). */
    size_t size;
    uint8_t *d = patched("bunnyInt19.e57", "", "", &size);
    if (!d) skip();
    rs_err err = {0};
    rs_cloud *c = rs_e57_read_mem(d, size, "copy.e57", &err);
    assert_non_null(c);
    assert_int_equal(c->npoints, 30571);
    rs_cloud_free(c);
    free(d);
    expect_refusal("recordCount=\"30571\"", "recordCount=\"30572\"", 0, "recordCount is 30572");
    expect_refusal("recordCount=\"30571\"", "recordCount=\"90571\"", 0, "recordCount");
    expect_refusal("fileOffset=\"48\"", "fileOffset=\"40\"", 0, "section id");
    expect_refusal("fileOffset=\"48\"", "fileOffset=\"99\"", 0, "");
    expect_refusal("<cartesianX ", "<cartesianQ ", 0, "no coordinates; expected cartesianX/Y/Z");
    expect_refusal("minimum=\"-262144\"", "minimum=\"-262145\"", 0, "recordCount 30571 of 61 bits"); /* 20 bits */
    expect_refusal("", "", 1024, "filePhysicalLength");
    expect_refusal("</e57Root>", "</e57Roox>", 0, "XML");
}

/* A truncated copy (pages cut, the header's length fixed) and a wrong CRC past the XML. */
static void test_truncated_and_crc(void **state)
{
    size_t size;
    uint8_t *d = patched("bunnyDouble.e57", "", "", &size);
    if (!d) skip();
    rs_err err = {0};
    /* A point's byte in page 200: pages are checked 128 at a time as they are read, so the XML
     * (pages 0 and 723) reads and the points fail. */
    d[200 * 1024 + 10] ^= 1;
    rs_e57 *e = rs_e57_open_mem(d, size, "flip.e57", &err);
    if (!e) fail_msg("%s", err.msg);
    rs_e57_close(e);
    assert_null(rs_e57_read_mem(d, size, "flip.e57", &err));
    assert_non_null(strstr(err.msg, "page 200 fails its checksum"));
    d[200 * 1024 + 10] ^= 1;
    for (size_t cut = 1024; cut < size; cut += 100 * 1024) {
        uint64_t len = size - cut;
        memcpy(d + 16, &len, 8); /* filePhysicalLength (little-endian machine, as the reader) */
        uint32_t c = rs_e57_crc32c(d, 1020);
        d[1020] = (uint8_t)(c >> 24), d[1021] = (uint8_t)(c >> 16), d[1022] = (uint8_t)(c >> 8), d[1023] = (uint8_t)c;
        assert_null(rs_e57_read_mem(d, (size_t)len, "cut.e57", &err));
        assert_int_equal(err.kind, RS_ERR_INPUT);
    }
    free(d);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_pump_grid), cmocka_unit_test(test_bunnies), cmocka_unit_test(test_cubes),
             cmocka_unit_test(test_las2e57_colour), cmocka_unit_test(test_two_prototypes),
             cmocka_unit_test(test_translation_only), cmocka_unit_test(test_normals), cmocka_unit_test(test_spherical),
             cmocka_unit_test(test_images), cmocka_unit_test(test_pinhole_distortion), cmocka_unit_test(test_refusals),
             cmocka_unit_test(test_lies), cmocka_unit_test(test_truncated_and_crc))
