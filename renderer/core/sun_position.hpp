#pragma once
// Where the sun is in the sky of a place at an instant (issue 15), and the
// UTC date-times the requests name that instant with. Pure: no GL, no I/O.
//
// The position is NREL's Solar Position Algorithm (SPA): I. Reda and
// A. Andreas, "Solar position algorithm for solar radiation applications",
// Solar Energy 76 (2004) 577-589, corrected in NREL/TP-560-34302 (2008).
// Its stated uncertainty is +/-0.0003 deg for the years -2000..6000, given
// the right TT - UT1 (delta T). tests/test_sun_position.cpp checks it against
// the SPA paper's own example and against PyEphem (tests/data/sun_positions.csv).
//
// Time scales: the instants here are UTC seconds since 1970-01-01T00:00:00Z
// without leap seconds (POSIX time), used as UT1. |UT1 - UTC| < 0.9 s, which
// moves the sun by less than 0.004 deg: below what a shadow map can show.
// Dates are in the proleptic Gregorian calendar (as RFC 3339 has them), also
// before 1582.

#include <optional>
#include <string>
#include <string_view>

namespace umbra {

struct SunAngles {
  // Direction of the centre of the sun's disc, measured on the observer's
  // horizon clockwise from true (geographic) north: 0 north, 90 east,
  // 180 south, 270 west. Degrees, in [0, 360). Where it is undefined (the sun
  // exactly at the zenith, an observer exactly at a pole, where every
  // direction is south or north) it is still a finite number in that range.
  double azimuth_deg;
  // Apparent elevation of the disc's centre above the horizon: the
  // topocentric (parallax-corrected) elevation plus SPA's atmospheric
  // refraction. Degrees, in [-90, 90]; negative below the horizon. As in SPA,
  // refraction is added only while the sun is not wholly below the horizon
  // (true elevation >= -0.83337 deg: the sun's semidiameter 0.26667 plus the
  // refraction at the horizon, 0.5667); lower than that the value is the
  // true (unrefracted) elevation.
  double elevation_deg;
};

// The observer's site, as SPA's refraction and parallax terms need it.
struct Atmosphere {
  // Local air pressure, hPa (= mbar), >= 0. 0 turns refraction off, which
  // gives the true (geometric, topocentric) elevation. 1010 hPa and 10 C are
  // SPA's and PyEphem's standard atmosphere.
  double pressure_hpa = 1010.0;
  // Local air temperature, degrees Celsius, > -273.
  double temperature_c = 10.0;
  // Observer's height above the reference ellipsoid (about sea level),
  // metres. Only the parallax uses it (at most 0.0024 deg at any height);
  // here so that SPA's published test point, 1830.14 m up, is reproduced.
  double elevation_m = 0.0;
};

// NREL SPA at a place and instant.
//   latitude_deg: geodetic latitude, [-90, 90], north positive.
//   longitude_deg: east positive; any value, taken modulo 360 (so -179.9 and
//     180.1 are the same meridian).
//   unix_seconds: the instant, UTC seconds since 1970-01-01T00:00:00Z (taken
//     as UT1); fractional and negative values allowed.
//   delta_t_s: TT - UT1 at that instant, seconds (delta_t_seconds() below
//     gives a model of it). Each second of error turns the sky by up to
//     0.0042 deg.
// Nothing is validated here (the request parser does that): a latitude
// outside [-90, 90] or a NaN gives meaningless angles or NaN.
SunAngles solar_position(double latitude_deg, double longitude_deg, double unix_seconds, double delta_t_s,
                         const Atmosphere& atmosphere = {});

// The same, with delta_t_seconds(decimal_year(unix_seconds)) for delta T and
// the standard atmosphere at sea level. What a request's "sun" light uses.
SunAngles solar_position(double latitude_deg, double longitude_deg, double unix_seconds);

// TT - UT1 in seconds for a decimal year (2026.5 is mid-2026). The model is
// the one PyEphem 4.1.4 (libastro deltat.c) uses, so that the test table's
// positions agree to 0.01 deg also for future years, where every model is a
// guess:
//   - before -1000: Morrison & Stephenson (2004) long-term parabola,
//     32 ((y - 1820) / 100)^2 - 20;
//   - -1000..1700: Morrison & Stephenson (2004) table, per century, linear
//     in between;
//   - 1700..2018: the yearly values of the Astronomical Almanac and IERS,
//     Bessel's interpolation (to fourth differences) in between;
//   - 2018..2118: a cubic that leaves 2018 with the table's value and its
//     slope over 2008..2018 and meets the long-term parabola, value and
//     slope, at 2118;
//   - after 2118: the long-term parabola.
// Past 2018 these are predictions: for 2026 the model says 73.8 s where the
// Earth's rotation measured about 69.1 s (IERS), i.e. the sun is 0.02 deg
// off at most; against 1950..2018 they are observations.
double delta_t_seconds(double decimal_year);

// The decimal year of an instant: y + (seconds since 1 January y) / (seconds
// in year y), y the proleptic Gregorian UTC year (as libastro's mjd_year).
double decimal_year(double unix_seconds);

// Parses an RFC 3339 date-time to unix seconds:
//   YYYY-MM-DDThh:mm:ss[.fraction](Z|+hh:mm|-hh:mm)
// 'T' and 'Z' may be lowercase; YYYY 0001..9999; the day must exist
// (Gregorian leap years: 2024-02-29 yes, 2026-02-29 and 1900-02-29 no);
// hh 00..23, mm 00..59, ss 00..59; any number of fraction digits (those past
// the ninth, below a nanosecond, are ignored); offsets up to +-23:59,
// "-00:00" meaning UTC. Refused, all deliberately:
//   - a leap second (ss = 60): unix time cannot represent it, and the sun
//     moves 0.004 deg in a second, so :59 is as good;
//   - a space or anything else in place of 'T', a missing time zone (a local
//     time without an offset names no instant), lowercase letters other than
//     't'/'z', signs or spaces inside numbers, trailing characters.
// On failure returns std::nullopt and, if why is not null, sets *why to a
// short reason naming the 1-based character or the field, e.g.
// "expected 'T' at character 11", "month 13 is out of range (01..12)".
std::optional<double> parse_utc(std::string_view text, std::string* why);

// The inverse, for showing a clock: "YYYY-MM-DDThh:mm:ssZ", the whole second
// at or before the instant (floor, so -0.5 is 1969-12-31T23:59:59Z). Years
// outside 0001..9999 come out as "0000", "-0001", "+10000" (parse_utc
// refuses them); NaN and infinities give "", and instants beyond 1e17 s
// (3 billion years) are clamped to it.
std::string format_utc(double unix_seconds);

struct SunClock;  // core/request.hpp

// Where a sun light's sun stands `time` seconds after its clock's instant:
// solar_position at clock.utc_unix_s + time, as light_at (light_math.hpp)
// places the light. For those that must not see the light math (the server:
// Umbra-Sun, Umbra-Unused-Fields).
SunAngles sun_at(const SunClock& clock, double time);

// Whether the sun's direct light arrives: its disc's centre above the
// horizon (light_at's `direct`).
inline bool above_horizon(const SunAngles& sun) { return sun.elevation_deg > 0.0; }

// "azimuth_deg=<A>; elevation_deg=<E>", each to 4 decimals: the value of the
// Umbra-Sun response header (docs/api.md). Rounded before printing, so that
// an azimuth of 359.99996 reads 0.0000 (never 360.0000) and -0.00001 reads
// 0.0000 (never -0.0000).
std::string format_sun_angles(const SunAngles& sun);

}  // namespace umbra
