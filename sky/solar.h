/* solar: where the sun stands for a date, time and place (NOAA solar calculator, after Meeus,
 * "Astronomical Algorithms", 1991), and the world direction toward it. Exports rs_solar_*. */
#ifndef RS_SOLAR_H
#define RS_SOLAR_H

#include "common/err.h"
#include "common/vec.h"

/* Julian day (UT) of an ISO 8601 date and time "YYYY-MM-DDTHH:MM[:SS[.s]][Z|+HH:MM|-HH:MM]"
 * (a space may replace the T; no zone means UTC; +HHMM and +HH are read too). The date must exist
 * in the Gregorian calendar (no 30 February), hours 00-23, minutes 00-59, seconds 00-60.999
 * (digits only: no NaN), the offset at most 14 hours. Returns 0, or -1 with err naming the text,
 * the field at fault and what was expected. */
int rs_solar_parse_datetime(const char *text, double *julian_day, rs_err *err);

/* Apparent sun position (with the standard atmospheric refraction of the NOAA calculator) at
 * julian_day (UT) seen from latitude_deg (north positive), longitude_deg (east positive):
 * azimuth clockwise from geographic north and elevation above the horizon, degrees.
 * Accuracy about 0.01 degrees for years 1800-2100 (NOAA); the refraction term is a standard
 * atmosphere's. NaN for both when an input is not finite. */
void rs_solar_position(double julian_day, double latitude_deg, double longitude_deg, double *azimuth_deg,
                       double *elevation_deg);

/* World direction (unit, Z up) toward a sun at compass azimuth (clockwise from north) and
 * elevation, given the world azimuth of north: north_deg = atan2(y, x) of geographic north in
 * the world frame, degrees (90 when +Y is north, as in an ENU frame). */
rs_v3 rs_solar_world_dir(double azimuth_deg, double elevation_deg, double north_deg);

#endif
