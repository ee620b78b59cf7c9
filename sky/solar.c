/* solar: sun position from date, time and place (NOAA solar calculator equations, from Meeus
 * 1991, chapters 24-25 and the equation of time), see solar.h. */
#include "sky/solar.h"

#include <stdarg.h>
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

/* n decimal digits at p into *v; 0 when any is not a digit. */
static int digits(const char *p, int n, int *v)
{
    *v = 0;
    for (int k = 0; k < n; k++) {
        if (p[k] < '0' || p[k] > '9') return 0;
        *v = 10 * *v + (p[k] - '0');
    }
    return 1;
}

static int days_in_month(int year, int month)
{
    static const int days[12] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
    int leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
    return month == 2 && leap ? 29 : days[month - 1];
}

static const char *const month_name[12] = {"January", "February", "March",     "April",   "May",      "June",
                                           "July",    "August",   "September", "October", "November", "December"};

#define DATETIME_FORM "YYYY-MM-DDTHH:MM[:SS[.s]][Z|+HH:MM|-HH:MM] (ISO 8601)"

/* "[sky] datetime = "TEXT": why" (the config file is the caller's to add). */
static int bad_datetime(rs_err *err, const char *text, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int bad_datetime(rs_err *err, const char *text, const char *fmt, ...)
{
    char why[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(why, sizeof why, fmt, ap);
    va_end(ap);
    return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "[sky] datetime = \"%.80s\": %s", text, why);
}

int rs_solar_parse_datetime(const char *text, double *julian_day, rs_err *err)
{
#define BAD(...) bad_datetime(err, text, __VA_ARGS__)
    int y, mo, d, h, mi;
    double s = 0;
    const char *p = text;
    /* The fields by position, digits only: sscanf would take "+7", " 7" or a 5-digit year. */
    if (!digits(p, 4, &y) || p[4] != '-' || !digits(p + 5, 2, &mo) || p[7] != '-' || !digits(p + 8, 2, &d) ||
        (p[10] != 'T' && p[10] != ' ') || !digits(p + 11, 2, &h) || p[13] != ':' || !digits(p + 14, 2, &mi))
        return BAD("expected " DATETIME_FORM);
    p += 16;
    if (*p == ':') {
        /* SS[.s]: two digits and an optional decimal fraction, read by strtod as before. */
        const char *q = p + 1;
        int ss;
        if (!digits(q, 2, &ss)) return BAD("the seconds are not two digits: expected " DATETIME_FORM);
        q += 2;
        if (*q == '.' || *q == ',') {
            q++;
            if (*q < '0' || *q > '9') return BAD("the seconds' fraction has no digit: expected " DATETIME_FORM);
            while (*q >= '0' && *q <= '9') q++;
        }
        char sec[64];
        snprintf(sec, sizeof sec, "%.*s", (int)(q - p - 1) < 63 ? (int)(q - p - 1) : 63, p + 1);
        for (char *c = sec; *c; c++)
            if (*c == ',') *c = '.';
        s = strtod(sec, NULL);
        p = q;
    }
    double zone_h = 0;
    if (*p == 'Z')
        p++;
    else if (*p == '+' || *p == '-') {
        int zh, zm = 0;
        if (!digits(p + 1, 2, &zh)) return BAD("the time zone is not +HH:MM or -HH:MM: expected " DATETIME_FORM);
        const char *q = p + 3;
        if (*q == ':' && digits(q + 1, 2, &zm))
            q += 3;
        else if (digits(q, 2, &zm))
            q += 2;
        if (zm > 59 || zh * 60 + zm > 14 * 60)
            return BAD("time zone %.*s: expected an offset from UTC of at most 14 hours (-14:00 to +14:00)",
                       (int)(q - p), p);
        zone_h = (*p == '-' ? -1 : 1) * (zh + zm / 60.0);
        p = q;
    }
    if (*p != '\0') return BAD("\"%.20s\" after the time: expected " DATETIME_FORM, p);
    if (mo < 1 || mo > 12) return BAD("month %02d: expected 01 to 12", mo);
    if (d < 1 || d > days_in_month(y, mo))
        return BAD("day %02d: %s %04d has %d days", d, month_name[mo - 1], y, days_in_month(y, mo));
    if (h > 23 || mi > 59) return BAD("time %02d:%02d: expected hours 00 to 23 and minutes 00 to 59", h, mi);
    /* 60 is a leap second. */
    if (!(s >= 0 && s < 61)) return BAD("seconds %g: expected 00 to 60.999", s);
    *julian_day = julian_day_0h(y, mo, d) + (h - zone_h + mi / 60.0 + s / 3600.0) / 24.0;
    return 0;
#undef BAD
}

void rs_solar_position(double jd, double latitude_deg, double longitude_deg, double *azimuth_deg, double *elevation_deg)
{
    /* Nothing below loops, but a NaN would reach the sky map and its samplers: say so at once. */
    if (!isfinite(jd) || !isfinite(latitude_deg) || !isfinite(longitude_deg)) {
        *azimuth_deg = *elevation_deg = NAN;
        return;
    }
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
