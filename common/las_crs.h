/* las_crs: a LAS file's coordinate reference system, read from its GeoTIFF keys (the
 * LASF_Projection VLRs 34735/34736/34737) or its OGC WKT (record 2112, a VLR or a LAS 1.4 EVLR),
 * for its name, EPSG code and linear units: rhoscan works in metres, so a projected system in
 * feet is converted (the unit's factor), a geographic one (degrees) refused by the LAS reader. */
#ifndef RS_LAS_CRS_H
#define RS_LAS_CRS_H

#include <stddef.h>
#include <stdint.h>

typedef enum { RS_LAS_CRS_NONE, RS_LAS_CRS_PROJECTED, RS_LAS_CRS_GEOGRAPHIC, RS_LAS_CRS_OTHER } rs_las_crs_kind;

typedef struct rs_las_crs {
    rs_las_crs_kind kind;
    const char *source; /* "GeoTIFF keys", "WKT" or "" */
    char name[160];     /* the system's name (WKT PROJCS/PROJCRS, GeoTIFF citation), "" if none */
    int epsg;           /* the projected (or geographic) system's EPSG code, 0 if not given */
    char unit[48];      /* the horizontal linear unit's name, "" when the file gives none (metres assumed) */
    double unit_m;      /* metres per horizontal unit (1 when none is given) */
    double vunit_m;     /* metres per vertical unit (the horizontal one when none is given) */
    int unknown_unit;   /* a unit code or name rhoscan does not know (code in unit_code) */
    int unit_code;      /* the GeoTIFF unit code (9001 metre, 9002 foot, 9003 US survey foot, ...) */
} rs_las_crs;

/* The GeoKeyDirectory (34735: n uint16 values, little-endian bytes), with its ASCII params
 * (34737, may be NULL) for the citation. Fills crs; returns 0, -1 when the directory is malformed. */
int rs_las_crs_geokeys(const uint8_t *dir, size_t nbytes, const char *ascii, size_t nascii, rs_las_crs *crs);
/* OGC WKT 1 or 2 (n bytes, NUL not needed). Returns 0, -1 when no CRS keyword is found. */
int rs_las_crs_wkt(const char *wkt, size_t n, rs_las_crs *crs);
/* One line for messages: "NAD83 / UTM zone 15N (EPSG:26915), metre, from the GeoTIFF keys". */
void rs_las_crs_describe(const rs_las_crs *crs, char *buf, size_t size);

#endif
