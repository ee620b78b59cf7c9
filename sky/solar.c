/* solar: sun position from date, time and place (NOAA solar calculator equations, from Meeus
 * 1991, chapters 24-25 and the equation of time), see solar.h. */
#include "sky/solar.h"

#include <stdio.h>
#include <stdlib.h>

static double deg2rad(double d)
{
    return d * M_PI / 180;
}
static double rad2deg(double r)
{
    return r * 180 / M_PI;
}

/* Julian day at 0h UT of a Gregorian calendar date (Meeus 1991, eq. 7.1). */
static double julian_day_0h(int year, int month, int day)
{
    if (month <= 2) {
        year -= 1;
        month += 12;
    }
    int a = year / 100, b = 2 - a + a / 4;
    return floor(365.25 * (year + 4716)) + floor(30.6001 * (month + 1)) + day + b - 1524.5;
}

int rs_solar_parse_datetime(const char *text, double *julian_day, rs_err *err)
{
    int y, mo, d, h, mi, n = 0;
    double s = 0;
    const char *p = text;
    if (sscanf(p, "%4d-%2d-%2d%n", &y, &mo, &d, &n) != 3 || (p[n] != 'T' && p[n] != ' ')) goto bad;
    p += n + 1;
    if (sscanf(p, "%2d:%2d%n", &h, &mi, &n) != 2) goto bad;
    p += n;
    if (*p == ':') {
        char *end;
        s = strtod(p + 1, &end);
        if (end == p + 1) goto bad;
        p = end;
    }
    double zone_h = 0;
    if (*p == 'Z')
        p++;
    else if (*p == '+' || *p == '-') {
        int zh, zm;
        if (sscanf(p + 1, "%2d:%2d%n", &zh, &zm, &n) != 2) goto bad;
        zone_h = (*p == '-' ? -1 : 1) * (zh + zm / 60.0);
        p += 1 + n;
    }
    if (*p != '\0') goto bad;
    if (mo < 1 || mo > 12 || d < 1 || d > 31 || h < 0 || h > 24 || mi < 0 || mi > 59 || s < 0 || s >= 61) goto bad;
    *julian_day = julian_day_0h(y, mo, d) + (h - zone_h + mi / 60.0 + s / 3600.0) / 24.0;
    return 0;
bad:
    return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                      "[sky] datetime = \"%s\": expected YYYY-MM-DDTHH:MM[:SS][Z|+HH:MM|-HH:MM]", text);
}

void rs_solar_position(double jd, double latitude_deg, double longitude_deg, double *azimuth_deg, double *elevation_deg)
{
    double T = (jd - 2451545.0) / 36525.0;                                  /* Julian centuries since J2000 */
    double L0 = fmod(280.46646 + T * (36000.76983 + T * 0.0003032), 360.0); /* mean longitude */
    double M = 357.52911 + T * (35999.05029 - 0.0001537 * T);               /* mean anomaly */
    double e = 0.016708634 - T * (0.000042037 + 0.0000001267 * T);          /* orbit eccentricity */
    double Mr = deg2rad(M);
    double C = sin(Mr) * (1.914602 - T * (0.004817 + 0.000014 * T)) + sin(2 * Mr) * (0.019993 - 0.000101 * T) +
        sin(3 * Mr) * 0.000289; /* equation of centre */
    double omega = deg2rad(125.04 - 1934.136 * T);
    double lambda = deg2rad(L0 + C - 0.00569 - 0.00478 * sin(omega)); /* apparent longitude */
    double eps0 = 23 + (26 + (21.448 - T * (46.815 + T * (0.00059 - T * 0.001813))) / 60) / 60;
    double eps = deg2rad(eps0 + 0.00256 * cos(omega)); /* obliquity, corrected */
    double decl = asin(sin(eps) * sin(lambda));
    double yv = tan(eps / 2) * tan(eps / 2), L0r = deg2rad(L0);
    double eqtime_min = 4 *
        rad2deg(yv * sin(2 * L0r) - 2 * e * sin(Mr) + 4 * e * yv * sin(Mr) * cos(2 * L0r) -
                0.5 * yv * yv * sin(4 * L0r) - 1.25 * e * e * sin(2 * Mr));
    double day_min = fmod(jd + 0.5 - floor(jd + 0.5), 1.0) * 1440.0;     /* minutes past 0h UT */
    double tst = fmod(day_min + eqtime_min + 4 * longitude_deg, 1440.0); /* true solar time */
    if (tst < 0) tst += 1440;
    double ha = deg2rad(tst / 4 - 180); /* hour angle */
    double lat = deg2rad(latitude_deg);
    double cosz = sin(lat) * sin(decl) + cos(lat) * cos(decl) * cos(ha);
    if (cosz > 1) cosz = 1;
    if (cosz < -1) cosz = -1;
    double zen = acos(cosz);
    double az = rad2deg(atan2(sin(ha), cos(ha) * sin(lat) - tan(decl) * cos(lat))) + 180;
    double elev = 90 - rad2deg(zen);
    /* Refraction (NOAA calculator's piecewise fit of a standard atmosphere), arcseconds. */
    double refr = 0, te = tan(deg2rad(elev));
    if (elev > 85)
        refr = 0;
    else if (elev > 5)
        refr = 58.1 / te - 0.07 / (te * te * te) + 0.000086 / pow(te, 5);
    else if (elev > -0.575)
        refr = 1735 + elev * (-518.2 + elev * (103.4 + elev * (-12.79 + elev * 0.711)));
    else
        refr = -20.772 / te;
    *elevation_deg = elev + refr / 3600;
    *azimuth_deg = fmod(az + 360, 360);
}

rs_v3 rs_solar_world_dir(double azimuth_deg, double elevation_deg, double north_deg)
{
    double phi = deg2rad(north_deg - azimuth_deg), el = deg2rad(elevation_deg);
    return rs_v3_make(cos(el) * cos(phi), cos(el) * sin(phi), sin(el));
}
