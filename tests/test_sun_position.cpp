// renderer/sun_position: NREL SPA against its paper's example and against
// PyEphem (tests/data/sun_positions.csv, written by scripts/make-sun-table.py
// and checked to be ephem's output by the ctest sun_table_is_ephem_output),
// the delta T model, and RFC 3339 parsing and formatting.
#include "core/sun_position.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#ifndef UMBRA_SUN_TABLE_CSV
#error "UMBRA_SUN_TABLE_CSV: the path of tests/data/sun_positions.csv (tests/CMakeLists.txt)"
#endif

namespace {

using umbra::Atmosphere;
using umbra::SunAngles;

// Issue 15's tolerances: 0.01 deg, 0.05 deg for the apparent elevation
// within 5 deg of the horizon (where refraction models differ).
constexpr double kTolerance = 0.01;
constexpr double kNearHorizonTolerance = 0.05;
// SPA adds refraction only above this true elevation (sun_position.hpp).
constexpr double kSpaRefractionFloor = -(0.26667 + 0.5667);

struct Row {
  double unix_seconds;
  std::string utc;
  double latitude, longitude, delta_t_s, azimuth, elevation, true_elevation;
};

std::vector<Row> load_table() {
  std::ifstream in(UMBRA_SUN_TABLE_CSV);
  EXPECT_TRUE(in) << "cannot open " << UMBRA_SUN_TABLE_CSV;
  std::vector<Row> rows;
  std::string line;
  bool header = true;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    if (header) {
      EXPECT_EQ(line, "unix_seconds,utc,latitude,longitude,delta_t_s,azimuth,elevation,true_elevation");
      header = false;
      continue;
    }
    std::istringstream fields(line);
    std::string f[8];
    for (std::string& s : f) std::getline(fields, s, ',');
    rows.push_back({std::stod(f[0]), f[1], std::stod(f[2]), std::stod(f[3]), std::stod(f[4]), std::stod(f[5]),
                    std::stod(f[6]), std::stod(f[7])});
  }
  EXPECT_GT(rows.size(), 3000u) << UMBRA_SUN_TABLE_CSV;
  return rows;
}

const std::vector<Row>& table() {
  static const std::vector<Row> rows = load_table();
  return rows;
}

// |a - b| for azimuths: 359.99 and 0.01 are 0.02 apart.
double azimuth_difference(double a, double b) { return std::fabs(std::remainder(a - b, 360.0)); }

// The largest error seen in one category, with the row it was seen at.
struct Worst {
  Worst(const char* n, double t) : name(n), tolerance(t) {}
  const char* name;
  double tolerance;
  double error = 0.0;
  int count = 0;
  int failures = 0;
  std::string where;
  void add(double e, const Row& r) {
    ++count;
    if (e > tolerance) ++failures;
    if (e > error) {
      error = e;
      char buf[160];
      std::snprintf(buf, sizeof buf, "%s lat %.4f lon %.4f (ephem az %.4f el %.4f)", r.utc.c_str(), r.latitude,
                    r.longitude, r.azimuth, r.elevation);
      where = buf;
    }
  }
  void report() const {
    std::printf("  %-58s %5d rows, max error %.5f deg (tolerance %.2f) at %s\n", name, count, error, tolerance,
                where.c_str());
    EXPECT_EQ(failures, 0) << name << ": " << failures << " of " << count << " rows off by more than " << tolerance
                           << " deg; worst " << error << " at " << where;
  }
};

// Compares positions from `position` (the row -> our angles, with SPA's
// refraction or with none) against ephem's, category by category.
template <typename Position>
void compare_with_ephem(Position position) {
  Worst azimuth{"azimuth, observer off the poles, sun < 89 deg", kTolerance};
  Worst zenith_azimuth{"azimuth within 1 deg of the zenith, times cos(elevation)", kTolerance};
  double zenith_raw = 0.0;
  Worst true_elevation{"true (unrefracted) elevation, every row", kTolerance};
  Worst high{"apparent elevation, ephem >= 5 deg", kTolerance};
  Worst horizon{"apparent elevation within 5 deg of the horizon, both refract", kNearHorizonTolerance};
  Worst deep{"apparent elevation, sun < -5 deg, neither refracts", kTolerance};
  Worst only_ephem{"below the horizon, only ephem refracts: true elevation", kTolerance};
  double only_ephem_refraction = 0.0;
  for (const Row& r : table()) {
    const SunAngles ours = position(r, Atmosphere{});
    Atmosphere airless;
    airless.pressure_hpa = 0.0;
    const SunAngles ours_true = position(r, airless);
    true_elevation.add(std::fabs(ours_true.elevation_deg - r.true_elevation), r);
    // Azimuth is undefined at the poles (every direction is north, or
    // south: those rows are left out) and at the zenith, and ill-conditioned
    // near it: a difference d in position moves the azimuth by up to
    // d / cos(elevation), e.g. 0.0002 deg of sky is 0.05 deg of azimuth at
    // 89.96 deg. Within 1 deg of the zenith the azimuth difference is
    // therefore compared as the angle it makes on the sky, times
    // cos(elevation), at the same tolerance; the raw one is printed.
    const double daz = azimuth_difference(ours.azimuth_deg, r.azimuth);
    if (std::fabs(r.latitude) < 90.0) {
      if (r.elevation < 89.0) {
        azimuth.add(daz, r);
      } else {
        zenith_azimuth.add(daz * std::cos(r.elevation * (3.14159265358979323846 / 180.0)), r);
        zenith_raw = std::max(zenith_raw, daz);
      }
    }
    const double e = std::fabs(ours.elevation_deg - r.elevation);
    const bool ephem_refracts = r.elevation != r.true_elevation;
    const bool spa_refracts = ours_true.elevation_deg >= kSpaRefractionFloor;
    if (r.elevation >= 5.0) {
      high.add(e, r);
    } else if (spa_refracts) {
      horizon.add(e, r);
    } else if (!ephem_refracts) {
      deep.add(e, r);
    } else {
      // The sun is wholly below the horizon (true elevation < -0.83 deg):
      // SPA adds no refraction there, libastro's formula still does, down
      // to about -8 deg true (up to 1.5 deg, a refraction nobody sees:
      // for a sea-level observer that light comes from inside the Earth).
      // The position itself must still agree: our (unrefracted) apparent
      // elevation against ephem's true one.
      only_ephem.add(std::fabs(ours.elevation_deg - r.true_elevation), r);
      only_ephem_refraction = std::max(only_ephem_refraction, r.elevation - r.true_elevation);
    }
  }
  for (const Worst* w : {&azimuth, &zenith_azimuth, &true_elevation, &high, &horizon, &deep, &only_ephem}) w->report();
  std::printf("  (near the zenith the raw azimuth difference reaches %.4f deg)\n", zenith_raw);
  std::printf("  (ephem's refraction in the last category: up to %.3f deg; SPA's: none)\n", only_ephem_refraction);
  EXPECT_GT(high.count, 1000);
  EXPECT_GT(horizon.count, 100);
  EXPECT_GT(deep.count, 1000);
  EXPECT_GT(zenith_azimuth.count, 10);
}

TEST(SunPosition, ReproducesTheSpaPapersExample) {
  // Reda & Andreas, table A5.1 (and spa_tester.c): 2003-10-17 12:30:30
  // local time at UTC-7, 39.742476 N 105.1786 W, 1830.14 m, 820 mbar, 11 C,
  // delta T 67 s -> zenith 50.11162 deg, azimuth 194.34024 deg (printed to
  // 5 decimals).
  const std::optional<double> t = umbra::parse_utc("2003-10-17T12:30:30-07:00", nullptr);
  ASSERT_TRUE(t);
  Atmosphere site;
  site.pressure_hpa = 820.0;
  site.temperature_c = 11.0;
  site.elevation_m = 1830.14;
  const SunAngles s = umbra::solar_position(39.742476, -105.1786, *t, 67.0, site);
  EXPECT_NEAR(90.0 - s.elevation_deg, 50.11162, 0.000005);
  EXPECT_NEAR(s.azimuth_deg, 194.34024, 0.000005);
}

TEST(SunPosition, AgreesWithEphemGivenEphemsDeltaT) {
  // The algorithms alone: each row's instant with the delta T ephem used.
  compare_with_ephem([](const Row& r, const Atmosphere& a) {
    return umbra::solar_position(r.latitude, r.longitude, r.unix_seconds, r.delta_t_s, a);
  });
}

TEST(SunPosition, AgreesWithEphemEndToEnd) {
  // What a request gets: our own delta T model.
  compare_with_ephem([](const Row& r, const Atmosphere& a) {
    return umbra::solar_position(r.latitude, r.longitude, r.unix_seconds,
                                 umbra::delta_t_seconds(umbra::decimal_year(r.unix_seconds)), a);
  });
  for (const Row& r : table()) {
    const SunAngles a = umbra::solar_position(r.latitude, r.longitude, r.unix_seconds);
    const SunAngles b = umbra::solar_position(r.latitude, r.longitude, r.unix_seconds,
                                              umbra::delta_t_seconds(umbra::decimal_year(r.unix_seconds)));
    ASSERT_EQ(a.azimuth_deg, b.azimuth_deg);
    ASSERT_EQ(a.elevation_deg, b.elevation_deg);
  }
}

TEST(SunPosition, AtThePolesTheElevationAgreesAndTheAzimuthIsInRange) {
  int rows = 0;
  for (const Row& r : table()) {
    if (std::fabs(r.latitude) != 90.0) continue;
    ++rows;
    const SunAngles s = umbra::solar_position(r.latitude, r.longitude, r.unix_seconds, r.delta_t_s);
    const double tolerance = std::fabs(r.elevation) < 5.0 ? kNearHorizonTolerance : kTolerance;
    // (Where only ephem refracts, see compare_with_ephem, the true elevations are compared.)
    const bool same_refraction = s.elevation_deg >= kSpaRefractionFloor || r.elevation == r.true_elevation;
    const double theirs = same_refraction ? r.elevation : r.true_elevation;
    EXPECT_NEAR(s.elevation_deg, theirs, same_refraction ? tolerance : kTolerance) << r.utc << " lat " << r.latitude;
    EXPECT_GE(s.azimuth_deg, 0.0);
    EXPECT_LT(s.azimuth_deg, 360.0);
  }
  EXPECT_GT(rows, 100);
  // Half a year of night and day: the sun is up at the north pole at the
  // June solstice, down at the December one, and the other way round south.
  const double june = *umbra::parse_utc("2026-06-21T12:00:00Z", nullptr);
  const double december = *umbra::parse_utc("2026-12-21T12:00:00Z", nullptr);
  EXPECT_NEAR(umbra::solar_position(90.0, 0.0, june).elevation_deg, 23.44, 0.1);
  EXPECT_NEAR(umbra::solar_position(90.0, 0.0, december).elevation_deg, -23.44, 0.1);
  EXPECT_NEAR(umbra::solar_position(-90.0, 0.0, december).elevation_deg, 23.44, 0.1);
}

TEST(SunDeltaT, MatchesEphemsModel) {
  // Same model (libastro's), our own interpolation: the difference is in
  // the rounding and in the last two tabulated years, where libastro takes
  // a missing difference as zero.
  double worst = 0.0, at = 0.0;
  for (const Row& r : table()) {
    const double d = std::fabs(umbra::delta_t_seconds(umbra::decimal_year(r.unix_seconds)) - r.delta_t_s);
    if (d > worst) worst = d, at = umbra::decimal_year(r.unix_seconds);
  }
  std::printf("  delta T: max difference from ephem %.5f s (year %.3f)\n", worst, at);
  // 0.01 s turns the sky by 0.00004 deg.
  EXPECT_LT(worst, 0.01);
}

TEST(SunDeltaT, FollowsThePublishedValues) {
  // Table values at the start of a year (Astronomical Almanac / IERS).
  EXPECT_NEAR(umbra::delta_t_seconds(1950.0), 29.15, 1e-9);
  EXPECT_NEAR(umbra::delta_t_seconds(2000.0), 63.83, 1e-9);
  EXPECT_NEAR(umbra::delta_t_seconds(2018.0), 68.97, 1e-9);
  // Morrison & Stephenson's parabola from 2118 on, and its table before 1700.
  EXPECT_NEAR(umbra::delta_t_seconds(2200.0), 32.0 * 3.8 * 3.8 - 20.0, 1e-9);
  EXPECT_NEAR(umbra::delta_t_seconds(1000.0), 1570.0, 1e-9);
  EXPECT_NEAR(umbra::delta_t_seconds(1650.0), (120.0 + 9.0) / 2.0, 1e-9);
  // Continuous where the pieces meet (within a second's worth of change).
  for (double y : {1700.0, 2018.0, 2118.0})
    EXPECT_NEAR(umbra::delta_t_seconds(y - 1e-6), umbra::delta_t_seconds(y + 1e-6), 0.01) << y;
  EXPECT_TRUE(std::isnan(umbra::delta_t_seconds(std::nan(""))));
}

TEST(SunAzimuth, FollowsTheCompass) {
  const auto at = [](const char* utc) { return *umbra::parse_utc(utc, nullptr); };
  // Equator, March equinox: the sun rises due east and sets due west.
  const SunAngles morning = umbra::solar_position(0.0, 0.0, at("2026-03-20T07:00:00Z"));
  EXPECT_NEAR(morning.azimuth_deg, 90.0, 1.0);
  EXPECT_GT(morning.elevation_deg, 10.0);
  const SunAngles evening = umbra::solar_position(0.0, 0.0, at("2026-03-20T17:00:00Z"));
  EXPECT_NEAR(evening.azimuth_deg, 270.0, 1.0);
  // Paris at (solar) noon in December, 11:50 UTC: low in the southern sky.
  const SunAngles paris = umbra::solar_position(48.85, 2.35, at("2026-12-21T12:50:00+01:00"));
  EXPECT_NEAR(paris.azimuth_deg, 180.0, 5.0);
  EXPECT_NEAR(paris.elevation_deg, 90.0 - 48.85 - 23.44, 0.2);
  // Sydney at (solar) noon, 01:53 UTC, in any month: the northern sky.
  const SunAngles sydney = umbra::solar_position(-33.87, 151.21, at("2026-12-21T12:53:00+11:00"));
  EXPECT_NEAR(sydney.elevation_deg, 90.0 - 33.87 + 23.44, 0.2);
  EXPECT_NEAR(std::remainder(sydney.azimuth_deg, 360.0), 0.0, 5.0);
  const SunAngles sydney_june = umbra::solar_position(-33.87, 151.21, at("2026-06-21T11:53:00+10:00"));
  EXPECT_NEAR(std::remainder(sydney_june.azimuth_deg, 360.0), 0.0, 5.0);
  // The issue's example: Paris, 2026-12-21 14:00 UTC, afternoon: south-west.
  const SunAngles issue = umbra::solar_position(48.85, 2.35, at("2026-12-21T14:00:00Z"));
  EXPECT_GT(issue.azimuth_deg, 200.0);
  EXPECT_LT(issue.azimuth_deg, 240.0);
  EXPECT_GT(issue.elevation_deg, 5.0);
  // The same meridian by any name.
  const double t = at("2026-12-21T14:00:00Z");
  const SunAngles east = umbra::solar_position(10.0, 180.1, t), west = umbra::solar_position(10.0, -179.9, t);
  EXPECT_NEAR(std::remainder(east.azimuth_deg - west.azimuth_deg, 360.0), 0.0, 1e-9);
  EXPECT_NEAR(east.elevation_deg, west.elevation_deg, 1e-9);
}

struct Accepted {
  const char* text;
  double unix_seconds;
};

TEST(SunUtc, ParsesRfc3339) {
  const Accepted cases[] = {
      {"1970-01-01T00:00:00Z", 0.0},
      {"2026-12-21T14:00:00Z", 1797861600.0},
      {"2026-12-21t14:00:00z", 1797861600.0},
      {"2026-12-21T15:00:00+01:00", 1797861600.0},
      {"2026-12-21T04:30:00-09:30", 1797861600.0},
      {"2026-12-21T14:00:00-00:00", 1797861600.0},
      {"2026-12-21T15:00:00.5+01:00", 1797861600.5},
      {"2026-12-21T14:00:00.250Z", 1797861600.25},
      {"2026-12-21T14:00:00.0000000000001Z", 1797861600.0},
      {"2024-02-29T00:00:00Z", 1709164800.0},
      {"2000-02-29T12:00:00Z", 951825600.0},
      {"1969-12-31T23:59:59Z", -1.0},
      {"1950-01-01T00:00:00Z", -631152000.0},
      {"2100-12-31T23:59:59Z", 4133980799.0},
      {"0001-01-01T00:00:00Z", -62135596800.0},
      {"9999-12-31T23:59:59Z", 253402300799.0},
      {"0001-01-01T00:30:00+01:00", -62135596800.0 - 1800.0},  // the UTC instant is in year 0: fine
      {"2026-01-01T00:00:00+23:59", 1767225600.0 - 86340.0},
  };
  for (const Accepted& c : cases) {
    std::string why;
    const std::optional<double> t = umbra::parse_utc(c.text, &why);
    ASSERT_TRUE(t) << c.text << ": " << why;
    EXPECT_DOUBLE_EQ(*t, c.unix_seconds) << c.text;
  }
}

struct Refused {
  const char* text;
  const char* why;
};

TEST(SunUtc, RefusesWithAReason) {
  const Refused cases[] = {
      {"", "empty: expected a date-time such as 2026-12-21T14:00:00Z"},
      {"2026-02-29T00:00:00Z", "2026 is not a leap year: February has 28 days"},
      {"1900-02-29T00:00:00Z", "1900 is not a leap year: February has 28 days"},
      {"2026-02-30T00:00:00Z", "day 30 is out of range (01..28 in month 02)"},
      {"2026-04-31T00:00:00Z", "day 31 is out of range (01..30 in month 04)"},
      {"2026-12-00T00:00:00Z", "day 00 is out of range (01..31 in month 12)"},
      {"2026-13-01T00:00:00Z", "month 13 is out of range (01..12)"},
      {"2026-00-01T00:00:00Z", "month 00 is out of range (01..12)"},
      {"0000-01-01T00:00:00Z", "year 0000 is out of range (0001..9999)"},
      {"2026-12-21T24:00:00Z", "hour 24 is out of range (00..23)"},
      {"2026-12-21T14:60:00Z", "minute 60 is out of range (00..59)"},
      {"2026-12-31T23:59:60Z", "second 60 (a leap second) cannot be represented in unix time: use 59"},
      {"2026-12-31T23:59:61Z", "second 61 is out of range (00..59)"},
      {"2026-12-21 14:00:00Z", "expected 'T' at character 11, found a space"},
      {"2026-12-21X14:00:00Z", "expected 'T' at character 11, found 'X'"},
      {"2026-12-21T14:00:00", "no time zone: end with Z or +hh:mm"},
      {"2026-12-21T14:00Z", "expected ':' at character 17, found 'Z'"},
      {"2026-12-21", "text ends where 'T' was expected"},
      {"2026-12-21T14:00:00.Z", "expected a digit after '.' at character 21, found 'Z'"},
      {"2026-12-21T14:00:00.", "text ends after '.': expected fraction digits"},
      {"2026-12-21T14:00:00Zjunk", "unexpected 'j' at character 21 after the time zone"},
      {"2026-12-21T14:00:00Z ", "unexpected a space at character 21 after the time zone"},
      {"2026-12-21T14:00:00+01", "text ends where ':' was expected"},
      {"2026-12-21T14:00:00+0100", "expected ':' at character 23, found '0'"},
      {"2026-12-21T14:00:00+24:00", "offset hours 24 are out of range (00..23)"},
      {"2026-12-21T14:00:00+01:60", "offset minutes 60 are out of range (00..59)"},
      {"2026-12-21T14:00:00UTC", "expected a time zone (Z, +hh:mm or -hh:mm) at character 20, found 'U'"},
      {"26-12-21T14:00:00Z", "expected a digit of the year at character 3, found '-'"},
      {"+2026-12-21T14:00:00Z", "expected a digit of the year at character 1, found '+'"},
      {"99999-12-21T14:00:00Z", "expected '-' at character 5, found '9'"},
      {"2026-1-21T14:00:00Z", "expected a digit of the month at character 7, found '-'"},
      {"2026-12-21T14:00:00.99999999999999999999999999999999999999999999x",
       "expected a time zone (Z, +hh:mm or -hh:mm) at character 65, found 'x'"},
      {"2026-12-21T14:00:00+99:99", "offset hours 99 are out of range (00..23)"},
      {"sunrise", "expected a digit of the year at character 1, found 's'"},
      {"1797861600", "expected '-' at character 5, found '8'"},
  };
  for (const Refused& c : cases) {
    std::string why = "(not set)";
    EXPECT_FALSE(umbra::parse_utc(c.text, &why)) << c.text;
    EXPECT_EQ(why, c.why) << c.text;
    EXPECT_FALSE(umbra::parse_utc(c.text, nullptr)) << c.text;  // why is optional
  }
  const std::string nul_inside("2026-12-21T14:00:00Z\0", 21);
  // A NUL is a character like any other (string_view, not C string).
  std::string why;
  EXPECT_FALSE(umbra::parse_utc(nul_inside, &why));
  EXPECT_EQ(why, "unexpected byte 0x00 at character 21 after the time zone");
}

TEST(SunUtc, FormatsAndRoundTrips) {
  EXPECT_EQ(umbra::format_utc(0.0), "1970-01-01T00:00:00Z");
  EXPECT_EQ(umbra::format_utc(1797861600.0), "2026-12-21T14:00:00Z");
  EXPECT_EQ(umbra::format_utc(1797861600.999), "2026-12-21T14:00:00Z");  // floor, not round
  EXPECT_EQ(umbra::format_utc(-0.5), "1969-12-31T23:59:59Z");
  EXPECT_EQ(umbra::format_utc(1709164800.0), "2024-02-29T00:00:00Z");
  EXPECT_EQ(umbra::format_utc(-62135596800.0), "0001-01-01T00:00:00Z");
  EXPECT_EQ(umbra::format_utc(253402300799.0), "9999-12-31T23:59:59Z");
  EXPECT_EQ(umbra::format_utc(-62135596801.0), "0000-12-31T23:59:59Z");
  EXPECT_EQ(umbra::format_utc(253402300800.0), "+10000-01-01T00:00:00Z");
  EXPECT_EQ(umbra::format_utc(std::nan("")), "");
  EXPECT_EQ(umbra::format_utc(HUGE_VAL), "");
  // Every row's instant: format_utc against Python's datetime, and back.
  for (const Row& r : table()) {
    ASSERT_EQ(umbra::format_utc(r.unix_seconds), r.utc);
    const std::optional<double> back = umbra::parse_utc(r.utc, nullptr);
    ASSERT_TRUE(back) << r.utc;
    ASSERT_EQ(*back, r.unix_seconds);
  }
  // A day's worth of seconds across a year end, and whole days over 10000 years.
  for (double t = 1798761600.0 - 43200; t < 1798761600.0 + 43200; t += 1.0)
    ASSERT_EQ(*umbra::parse_utc(umbra::format_utc(t), nullptr), t);
  for (double t = -62135596800.0; t < 253402300800.0; t += 86400.0 * 7 + 3601)
    ASSERT_EQ(*umbra::parse_utc(umbra::format_utc(t), nullptr), t);
}

TEST(SunUtc, DecimalYear) {
  EXPECT_DOUBLE_EQ(umbra::decimal_year(0.0), 1970.0);
  EXPECT_DOUBLE_EQ(umbra::decimal_year(*umbra::parse_utc("2024-07-02T00:00:00Z", nullptr)), 2024.0 + 183.0 / 366.0);
  EXPECT_DOUBLE_EQ(umbra::decimal_year(*umbra::parse_utc("2026-07-02T12:00:00Z", nullptr)), 2026.0 + 182.5 / 365.0);
}

}  // namespace

namespace {

TEST(SunHeader, FourDecimalsWithNoMinusZeroAndNo360) {
  EXPECT_EQ(umbra::format_sun_angles({210.55966, 12.07044}), "azimuth_deg=210.5597; elevation_deg=12.0704");
  EXPECT_EQ(umbra::format_sun_angles({359.99996, -0.00001}), "azimuth_deg=0.0000; elevation_deg=0.0000");
  EXPECT_EQ(umbra::format_sun_angles({359.99994, -12.5}), "azimuth_deg=359.9999; elevation_deg=-12.5000");
  EXPECT_EQ(umbra::format_sun_angles({0.0, 90.0}), "azimuth_deg=0.0000; elevation_deg=90.0000");
}

}  // namespace
