/* test_las_crs: the LAS coordinate-system parsers (common/las_crs.c) on WKT 1 and 2 texts and
 * GeoTIFF key directories: names, EPSG codes, units (feet converted, vertical units of a
 * compound system), geographic systems and unknown unit codes flagged for refusal. */
#include "tests/testutil.h"

#include <math.h>
#include <string.h>

#include "common/las_crs.h"

static void test_wkt(void **state)
{
    (void)state;
    rs_las_crs c;
    const char *geo = "GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\",6378137,298.257223563]],"
                      "UNIT[\"degree\",0.0174532925199433],AUTHORITY[\"EPSG\",\"4326\"]]";
    assert_int_equal(rs_las_crs_wkt(geo, strlen(geo), &c), 0);
    assert_int_equal(c.kind, RS_LAS_CRS_GEOGRAPHIC);
    assert_string_equal(c.name, "WGS 84");
    const char *compd = "COMPD_CS[\"x\",PROJCS[\"NAD83 / UTM zone 15N\",GEOGCS[\"NAD83\",UNIT[\"degree\",0.01745]],"
                        "UNIT[\"metre\",1,AUTHORITY[\"EPSG\",\"9001\"]],AUTHORITY[\"EPSG\",\"26915\"]],"
                        "VERT_CS[\"NAVD88 height (ftUS)\",UNIT[\"US survey foot\",0.304800609601219]]]";
    assert_int_equal(rs_las_crs_wkt(compd, strlen(compd), &c), 0);
    assert_int_equal(c.kind, RS_LAS_CRS_PROJECTED);
    assert_int_equal(c.epsg, 26915);
    assert_string_equal(c.unit, "metre");
    assert_true(c.unit_m == 1 && fabs(c.vunit_m - 0.304800609601219) < 1e-15);
    const char *wkt2 = "PROJCRS[\"NAD83 / Oregon (ft)\",BASEGEOGCRS[\"NAD83\",ANGLEUNIT[\"degree\",0.0174]],"
                       "CONVERSION[\"x\",METHOD[\"Lambert\"]],CS[Cartesian,2],"
                       "AXIS[\"easting\",east,LENGTHUNIT[\"foot\",0.3048]],AXIS[\"northing\",north,"
                       "LENGTHUNIT[\"foot\",0.3048]],ID[\"EPSG\",2994]]";
    assert_int_equal(rs_las_crs_wkt(wkt2, strlen(wkt2), &c), 0);
    assert_int_equal(c.kind, RS_LAS_CRS_PROJECTED);
    assert_int_equal(c.epsg, 2994);
    assert_string_equal(c.unit, "foot");
    assert_true(c.unit_m == 0.3048 && c.vunit_m == 0.3048);
    assert_int_equal(rs_las_crs_wkt("nothing here", 12, &c), -1);
    /* An authority code that is no EPSG code (too large for int, or fractional) is ignored, not cast. */
    const char *huge = "PROJCS[\"x\",UNIT[\"metre\",1],AUTHORITY[\"EPSG\",\"9e99\"]]";
    assert_int_equal(rs_las_crs_wkt(huge, strlen(huge), &c), 0);
    assert_int_equal(c.epsg, 0);
    const char *frac = "PROJCS[\"x\",UNIT[\"metre\",1],ID[\"EPSG\",2994.5]]";
    assert_int_equal(rs_las_crs_wkt(frac, strlen(frac), &c), 0);
    assert_int_equal(c.epsg, 0);
}

static void put_keys(uint8_t *d, const unsigned *v, int n)
{
    for (int i = 0; i < n; i++) d[2 * i] = (uint8_t)v[i], d[2 * i + 1] = (uint8_t)(v[i] >> 8);
}

static void test_geokeys(void **state)
{
    (void)state;
    uint8_t d[64];
    rs_las_crs c;
    const unsigned feet[] = {1, 1, 0, 3, 1024, 0, 1, 1, 3072, 0, 1, 2994, 3076, 0, 1, 9002};
    put_keys(d, feet, 16);
    assert_int_equal(rs_las_crs_geokeys(d, 32, NULL, 0, &c), 0);
    assert_true(c.kind == RS_LAS_CRS_PROJECTED && c.epsg == 2994 && c.unit_m == 0.3048 && !c.unknown_unit);
    const unsigned odd[] = {1, 1, 0, 3, 1024, 0, 1, 1, 3072, 0, 1, 2994, 3076, 0, 1, 9999};
    put_keys(d, odd, 16);
    assert_int_equal(rs_las_crs_geokeys(d, 32, NULL, 0, &c), 0);
    assert_true(c.unknown_unit && c.unit_code == 9999);
    const unsigned geo[] = {1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4269};
    put_keys(d, geo, 12);
    assert_int_equal(rs_las_crs_geokeys(d, 24, NULL, 0, &c), 0);
    assert_true(c.kind == RS_LAS_CRS_GEOGRAPHIC && c.epsg == 4269);
    const unsigned lies[] = {1, 1, 0, 9, 1024, 0, 1, 1}; /* 9 keys announced, 1 present */
    put_keys(d, lies, 8);
    assert_int_equal(rs_las_crs_geokeys(d, 16, NULL, 0, &c), -1);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_wkt), cmocka_unit_test(test_geokeys))
