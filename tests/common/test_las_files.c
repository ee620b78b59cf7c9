/* test_las_files: every LAS/LAZ file of the shared reference set (written by TerraScan,
 * LAStools, libLAS, Global Mapper, PDAL and RS Survey) read through the format table: the point
 * count, the bounding box of the decoded points and the first point to 0.5 mm (the README's
 * three decimals), intensity and colour as its README documents them, or the refusal it gives
 * (simple.laz: LAZ). Skips when the shared set is absent (fails under CI=true). */
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/cloud_format.h"
#include "common/las.h"

typedef struct las_case {
    const char *name;
    size_t count;
    double lo[3], hi[3], first[3];
    int intensity;         /* of the first point; -1: not documented */
    int rgb[3], rgbmax[3]; /* first colour and the maximum per channel; -1: no colour */
    int version_minor, format, record_length, offset;
} las_case;

#define NO_RGB     \
    {-1, -1, -1},  \
    {              \
        -1, -1, -1 \
    }
static const las_case cases[] = {
    {"1.0_0.las",
     1,
     {470692.440, 4602888.900, 16.000},
     {470692.440, 4602888.900, 16.000},
     {470692.440, 4602888.900, 16.000},
     -1,
     NO_RGB,
     0,
     0,
     20,
     1007},
    {"simple1_1.las",
     1065,
     {635619.850, 848899.700, 406.590},
     {638982.550, 853535.430, 586.380},
     {637012.240, 849028.310, 431.660},
     143,
     NO_RGB,
     1,
     1,
     28,
     227},
    {"point10.las",
     1065,
     {493994.870, 4877429.620, 123.930},
     {494993.680, 4878817.020, 178.730},
     {494428.610, 4877455.580, 131.570},
     143,
     NO_RGB,
     2,
     0,
     20,
     1207},
    {"autzen.las",
     106,
     {635616.310, 848977.790, 407.350},
     {638864.600, 853362.370, 536.840},
     {636083.300, 849398.650, 407.350},
     65,
     NO_RGB,
     2,
     1,
     28,
     1994},
    {"point-color.las",
     1065,
     {493994.870, 4877429.620, 123.930},
     {494993.680, 4878817.020, 178.730},
     {494428.610, 4877455.580, 131.570},
     -1,
     {68, 77, 88},
     {249, 239, 249},
     2,
     2,
     26,
     1207},
    {"1.2-with-color.las",
     1065,
     {635619.850, 848899.700, 406.590},
     {638982.550, 853535.430, 586.380},
     {637012.240, 849028.310, 431.660},
     143,
     {68, 77, 88},
     {-2, -2, -2},
     2,
     3,
     34,
     229},
    {"vegetation_1_3.las",
     10683,
     {-98451.205, -55975.417, -81460.091},
     {-98447.447, -55969.405, -81455.203},
     {-98449.688, -55970.553, -81458.594},
     3341,
     NO_RGB,
     3,
     1,
     28,
     235},
    {"test1_4.las",
     1000,
     {1694038.446, 1816492.706, 5592.750},
     {1694539.677, 1816497.976, 5599.070},
     {1694510.387, 1816497.966, 5598.360},
     41,
     NO_RGB,
     4,
     6,
     30,
     2305},
    {"v4d8.las",
     10,
     {150.340, 90.730, 7.700},
     {999.120, 802.410, 947.760},
     {999.120, 153.600, 630.490},
     0,
     {0, 0, 0},
     {0, 0, 0},
     4,
     8,
     38,
     1673},
    {"extrabytes.las",
     1065,
     {635619.850, 848899.700, 406.590},
     {638982.550, 853535.430, 586.380},
     {637012.240, 849028.310, 431.660},
     143,
     {68, 77, 88},
     {-2, -2, -2},
     4,
     3,
     61,
     1389},
};
enum { NCASES = sizeof cases / sizeof cases[0] };

#define TOL 5e-4 + 1e-9

/* Metres per file unit: the README gives the files' own values, the reader converts feet. */
static double unit_of(const char *name)
{
    if (strcmp(name, "autzen.las") == 0) return 0.3048;            /* GeoTIFF 3076 = 9002, foot */
    if (strcmp(name, "test1_4.las") == 0) return 0.30480060960122; /* WKT UNIT["US survey foot"] */
    return 1;
}

static const char *las_path(const char *name)
{
    static char path[4][2048];
    static int next;
    char *p = path[next++ % 4];
    snprintf(p, sizeof path[0], "%s/formats/las/%s", rs_test_shared_dir(), name);
    return p;
}

static void check_case(const las_case *k)
{
    const char *path = las_path(k->name), *format = NULL;
    rs_err err = {0};
    rs_las *f = rs_las_open(path, &err);
    if (!f) fail_msg("%s: %s", k->name, err.msg);
    const rs_las_info *in = rs_las_info_of(f);
    if (in->version_minor != k->version_minor || in->format != k->format ||
        (int)in->record_length != k->record_length || (int)in->offset_to_points != k->offset)
        fail_msg("%s: LAS 1.%d format %d record %u offset %u", k->name, in->version_minor, in->format,
                 in->record_length, in->offset_to_points);
    rs_las_close(f);
    rs_cloud *c = rs_cloud_read_with(path, NULL, &format, &err);
    if (!c) fail_msg("%s: %s", k->name, err.msg);
    assert_string_equal(format, "LAS");
    if (c->npoints != k->count) fail_msg("%s: %zu points, expected %zu", k->name, c->npoints, k->count);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    int mx[3] = {0, 0, 0};
    for (size_t i = 0; i < c->npoints; i++)
        for (int j = 0; j < 3; j++) {
            lo[j] = fmin(lo[j], c->xyz[3 * i + j]), hi[j] = fmax(hi[j], c->xyz[3 * i + j]);
            if (c->rgb && c->rgb[3 * i + j] > mx[j]) mx[j] = c->rgb[3 * i + j];
        }
    double u = unit_of(k->name);
    for (int j = 0; j < 3; j++)
        if (fabs(lo[j] - u * k->lo[j]) > TOL || fabs(hi[j] - u * k->hi[j]) > TOL ||
            fabs(c->xyz[j] - u * k->first[j]) > TOL)
            fail_msg("%s axis %d: bbox %.4f .. %.4f, first %.4f; expected %.3f .. %.3f, first %.3f (x %.9g m)", k->name,
                     j, lo[j], hi[j], c->xyz[j], u * k->lo[j], u * k->hi[j], u * k->first[j], u);
    if (k->intensity >= 0 && c->intensity[0] != (float)k->intensity)
        fail_msg("%s: intensity %g, expected %d", k->name, c->intensity[0], k->intensity);
    assert_int_equal(c->rgb != NULL, k->rgb[0] >= 0);
    for (int j = 0; j < 3 && c->rgb; j++) {
        if (c->rgb[j] != k->rgb[j])
            fail_msg("%s: first colour channel %d = %d, expected %d", k->name, j, c->rgb[j], k->rgb[j]);
        if (k->rgbmax[j] >= 0 && mx[j] != k->rgbmax[j])
            fail_msg("%s: colour maximum channel %d = %d, expected %d", k->name, j, mx[j], k->rgbmax[j]);
    }
    assert_true(c->normals_up && !c->has_viewpoint && c->nscans == 0);
    rs_cloud_free(c);
}

static void test_documented_values(void **state)
{
    (void)state;
    for (int k = 0; k < NCASES; k++) check_case(&cases[k]);
}

/* extrabytes.las is 1.2-with-color.las with 27 extra bytes per record: the same points. */
static void test_extra_bytes_same_points(void **state)
{
    (void)state;
    rs_err err = {0};
    rs_cloud *a = rs_cloud_read(las_path("1.2-with-color.las"), &err),
             *b = rs_cloud_read(las_path("extrabytes.las"), &err);
    if (!a || !b) fail_msg("%s", err.msg);
    assert_int_equal(a->npoints, b->npoints);
    assert_memory_equal(a->xyz, b->xyz, 3 * a->npoints * sizeof *a->xyz);
    assert_memory_equal(a->intensity, b->intensity, a->npoints * sizeof *a->intensity);
    assert_memory_equal(a->rgb, b->rgb, 3 * a->npoints);
    rs_cloud_free(a);
    rs_cloud_free(b);
}

/* The refusals and the empty file: LAZ names the file and how to decompress it; no-points.las
 * reads as 0 points (the ingest then refuses it, tests/stages/test_las_ingest). */
static void test_laz_and_empty(void **state)
{
    (void)state;
    rs_err err = {0};
    const char *format = NULL;
    assert_null(rs_cloud_read_with(las_path("simple.laz"), NULL, &format, &err));
    assert_string_equal(format, "LAZ");
    assert_int_equal(err.kind, RS_ERR_INPUT);
    if (!strstr(err.file, "simple.laz") || !strstr(err.msg, "LAZ is compressed LAS") || !strstr(err.msg, "laszip -i") ||
        !strstr(err.msg, "pdal translate"))
        fail_msg("%s: %s", err.file, err.msg);
    rs_cloud *c = rs_cloud_read(las_path("no-points.las"), &err);
    if (!c) fail_msg("%s", err.msg);
    assert_int_equal(c->npoints, 0);
    rs_cloud_free(c);
}

/* Classes: 1.0_0.las's one point is class 2, vegetation_1_3.las's are all 11. */
static void test_classes(void **state)
{
    (void)state;
    uint8_t keep[256];
    rs_err err = {0};
    assert_int_equal(rs_las_parse_classes("2 6", keep, &err), 0);
    rs_cloud *c = rs_las_read(las_path("1.0_0.las"), keep, &err);
    if (!c) fail_msg("%s", err.msg);
    assert_int_equal(c->npoints, 1);
    rs_cloud_free(c);
    assert_null(rs_las_read(las_path("vegetation_1_3.las"), keep, &err));
    if (!strstr(err.msg, "classes: 11 (10683 points)")) fail_msg("%s", err.msg);
    assert_int_equal(rs_las_parse_classes("11", keep, &err), 0);
    c = rs_las_read(las_path("vegetation_1_3.las"), keep, &err);
    if (!c) fail_msg("%s", err.msg);
    assert_int_equal(c->npoints, 10683);
    rs_cloud_free(c);
}

/* The coordinate systems the files carry (GeoTIFF keys in the libLAS and TerraScan files, WKT in
 * Global Mapper's and PDAL's), as their VLRs give them. */
static void test_coordinate_systems(void **state)
{
    (void)state;
    static const struct {
        const char *file, *source, *name, *unit;
        int epsg;
        double unit_m;
    } want[] = {
        {"1.0_0.las", "GeoTIFF keys", "NAD83 / UTM zone 15N", "metre", 26915, 1},
        {"point10.las", "GeoTIFF keys", "NAD83 / UTM zone 10N", "metre", 26910, 1},
        {"autzen.las", "GeoTIFF keys", "NAD83(HARN) / Oregon Lambert (ft)", "foot", 2994, 0.3048},
        {"test1_4.las", "WKT", "NAD83(HARN) / New Mexico Central (ftUS)", "US survey foot", 0, 1200.0 / 3937.0},
        {"v4d8.las", "WKT", "JGD2011 / Japan Plane Rectangular CS VIII", "metre", 6676, 1},
        {"simple1_1.las", "", "", "", 0, 1},
    };
    for (size_t k = 0; k < sizeof want / sizeof want[0]; k++) {
        rs_err err = {0};
        rs_las *f = rs_las_open(las_path(want[k].file), &err);
        if (!f) fail_msg("%s: %s", want[k].file, err.msg);
        const rs_las_crs *crs = &rs_las_info_of(f)->crs;
        if (strcmp(crs->source, want[k].source) != 0 || strcmp(crs->name, want[k].name) != 0 ||
            strcmp(crs->unit, want[k].unit) != 0 || (want[k].epsg && crs->epsg != want[k].epsg) ||
            fabs(crs->unit_m - want[k].unit_m) > 1e-9 || fabs(rs_las_info_of(f)->unit_m[2] - want[k].unit_m) > 1e-9)
            fail_msg("%s: \"%s\" from \"%s\", EPSG %d, unit \"%s\" = %.15g m", want[k].file, crs->name, crs->source,
                     crs->epsg, crs->unit, crs->unit_m);
        assert_int_equal(crs->kind, want[k].source[0] ? RS_LAS_CRS_PROJECTED : RS_LAS_CRS_NONE);
        rs_las_close(f);
    }
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_documented_values), cmocka_unit_test(test_extra_bytes_same_points),
             cmocka_unit_test(test_laz_and_empty), cmocka_unit_test(test_classes),
             cmocka_unit_test(test_coordinate_systems))
