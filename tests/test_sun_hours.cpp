// Sun hours (POST /api/sun-hours) without GL: the samples, the grid, the
// tally, the body's parser and the answers, and the ray cast against
// analytic cases (a wall's shadow at the equator on the equinox, a pole's
// shadow length against the sun's elevation) and PyEphem's sun-up time.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

#include <glm/trigonometric.hpp>
#include <nlohmann/json.hpp>

#include "core/light_math.hpp"
#include "core/mesh_instance.hpp"
#include "core/model.hpp"
#include "core/model_shells.hpp"
#include "core/builtin_models.hpp"
#include "core/shapes/shape.hpp"
#include "core/sun_hours.hpp"
#include "reference/ray_cast.hpp"
#include "reference/sun_hours_footprints.hpp"
#include "reference/sun_hours_ray_cast.hpp"
#include "service/request_cost.hpp"
#include "sun_hours_answer.hpp"
#include "sun_hours_parser.hpp"
#include "model_support.hpp"

namespace umbra {
namespace {

using json = nlohmann::json;

constexpr double kDay = 86400.0;
const double kEquinox2026 = *parse_utc("2026-03-20T00:00:00Z", nullptr);

SunHoursRequest parsed(const json& body) {
  const ParsedSunHours p = parse_sun_hours_request(body.dump());
  EXPECT_TRUE(p.ok()) << p.error.field << ": " << p.error.message;
  return p.ok() ? *p.request : SunHoursRequest{};
}

json body_with(const std::string& path, const json& value) {
  json body = {{"site", {{"latitude", 51.5}, {"longitude", -0.12}}},
               {"period", {{"start", "2026-03-21T00:00:00Z"}, {"end", "2026-03-22T00:00:00Z"}}},
               {"grid", {{"size", {4, 2}}, {"spacing", 0.5}}}};
  if (!path.empty()) body[json::json_pointer(path)] = value;
  return body;
}

RequestError refusal(const json& body) {
  const ParsedSunHours p = parse_sun_hours_request(body.dump());
  EXPECT_FALSE(p.ok()) << body.dump();
  return p.error;
}

// Runs the ray cast over the request's grid and period, as the service does.
SunHoursResult cast(const SunHoursRequest& q) {
  SunHoursResult result;
  result.step_minutes = q.period.step_minutes;
  result.samples = sun_samples(q.site, q.period, *sample_count(q.period));
  const RayScene rays(q.view.scene);
  ray_cast_sun_hours(rays, q.grid, result.samples, result);
  return result;
}

TEST(SunHours, SamplesStandForTheMiddleOfTheirSteps) {
  SunPeriod day{kEquinox2026, kEquinox2026 + kDay, 10.0};
  ASSERT_EQ(sample_count(day), std::size_t(144));
  EXPECT_DOUBLE_EQ(sample_time(day, 0), kEquinox2026 + 300.0);
  EXPECT_DOUBLE_EQ(sample_time(day, 143), kEquinox2026 + kDay - 300.0);
  day.step_minutes = 7.0;  // 1440 / 7 is not whole
  EXPECT_FALSE(sample_count(day));
  day.step_minutes = 0.5;
  EXPECT_EQ(sample_count(day), std::size_t(2880));
}

TEST(SunHours, ProbesDoNotAliasWithTheDay) {
  // Periods whose probes' stretches are whole days: the middle of each
  // stretch fell at one time of day (all midnight from a noon start: sun-up
  // share 0, and a year's job priced at 1 % of its cost). The share the
  // probes see must be the period's own, measured here at 97-minute steps
  // (prime to the day: every time of day is taken).
  const SunSite london{51.5, -0.12, 0.0};
  for (const double start_hour : {0.0, 12.0})
    for (const double step : {1.0, 2.0, 10.0}) {
      const double start = kEquinox2026 + start_hour * 3600.0;
      const SunPeriod period{start, start + 512.0 * kDay, step};
      const std::size_t count = *sample_count(period);
      const double seen = sun_up_share(probe_samples(london, period, count));
      const SunPeriod steady{start, start + 7600.0 * 97.0 * 60.0, 97.0};
      const double truth = sun_up_share(sun_samples(london, steady, *sample_count(steady)));
      EXPECT_NEAR(seen, truth, 0.05) << "start " << start_hour << " h, step " << step << " min";
    }
}

TEST(SunHours, TheGridIsTheCentresOfItsCells) {
  const SunHoursRequest q = parsed(body_with("/grid", {{"center", {1, 2, 3}}, {"size", {4, 2}}, {"spacing", 0.5}}));
  EXPECT_EQ(q.grid.columns, 8);
  EXPECT_EQ(q.grid.rows, 4);
  EXPECT_EQ(q.grid.points(), std::size_t(32));
  EXPECT_EQ(q.grid.origin(), glm::dvec3(-0.75, 2.0, 2.25));
  EXPECT_EQ(q.grid.point(9), glm::dvec3(-0.25, 2.0, 2.75));  // column 1, row 1
  EXPECT_EQ(q.grid.point(31), glm::dvec3(2.75, 2.0, 3.75));  // the last: the far corner's cell
}

TEST(SunHours, ATallyCountsLitSamplesAndTheLongestRun) {
  PointTally t;
  for (bool lit : {true, true, false, true, true, true, false, true}) t.record(lit);
  EXPECT_EQ(t.lit, 6u);
  EXPECT_EQ(t.longest, 3u);
  SunHoursResult r;
  r.step_minutes = 10.0;
  r.tally = {PointTally{12, 0, 12}, PointTally{11, 0, 11}, PointTally{13, 0, 5}, PointTally{0, 0, 0}};
  EXPECT_DOUBLE_EQ(r.hours(0), 2.0);
  EXPECT_DOUBLE_EQ(r.longest_run_hours(2), 5.0 / 6.0);
  EXPECT_DOUBLE_EQ(r.pass_share(2.0), 0.5);  // 12 x 10 minutes is exactly 2 hours: it passes
  EXPECT_DOUBLE_EQ(r.pass_share(0.0), 1.0);
}

TEST(SunHoursParser, DefaultsAndEveryField) {
  SunHoursRequest q = parsed(body_with("", nullptr));
  EXPECT_EQ(q.site.north_deg, 0.0);
  EXPECT_EQ(q.period.step_minutes, 10.0);
  EXPECT_EQ(q.grid.center, glm::dvec3(0.0));
  EXPECT_TRUE(q.exact);
  EXPECT_FALSE(q.include_samples);
  EXPECT_FALSE(q.require_hours);
  EXPECT_EQ(q.view.scene.objects.size(), 2u);  // cube-on-plane, as /api/render's default
  json body = body_with("/site/north_deg", -30);
  body["require_hours"] = 2;
  body["exact"] = false;
  body["include_samples"] = true;
  body["period"]["step_minutes"] = 15;
  body["scene"] = "three-cubes";
  q = parsed(body);
  EXPECT_EQ(q.site.north_deg, -30.0);
  EXPECT_EQ(q.require_hours, 2.0);
  EXPECT_FALSE(q.exact);
  EXPECT_TRUE(q.include_samples);
  EXPECT_EQ(sample_count(q.period), std::size_t(96));
  EXPECT_EQ(q.view.scene.objects.size(), 4u);
}

TEST(SunHoursParser, BadInputIs400NamingTheField) {
  struct Case {
    std::string path;
    json value;
    std::string field, says;
  };
  const std::vector<Case> cases = {
      {"/period/end", "2026-03-20T00:00:00Z", "period.end", "not after period.start"},
      {"/period/end", "2026-03-21T00:00:00Z", "period.end", "not after period.start"},
      {"/period/step_minutes", 0, "period.step_minutes", "out of range"},
      {"/period/step_minutes", 7, "period.step_minutes", "whole number of steps"},
      // 10^9 samples: a thousand years at half-minute steps.
      {"/period/end", "3026-03-21T00:00:00Z", "period.step_minutes", "over the limit"},
      {"/period/start", "2026-03-21 00:00:00Z", "period.start", "RFC 3339"},
      {"/period/start", 0, "period.start", "string"},
      // 10^12 points.
      {"/grid/size", {1e6, 1e6}, "grid.spacing", "over the limit"},
      {"/grid/size", {4, 2.2}, "grid.spacing", "whole number of cells"},
      {"/grid/size", {4, 0}, "grid.size[1]", "out of range"},
      {"/grid/spacing", -1, "grid.spacing", "out of range"},
      {"/grid/center", {0, 1}, "grid.center", "[x, y, z]"},
      {"/site/latitude", 91, "site.latitude", "out of range"},
      {"/site/longitude", "east", "site.longitude", "number"},
      {"/site/height", 1, "site.height", "unknown field"},
      {"/require_hours", -1, "require_hours", "out of range"},
      {"/exact", "yes", "exact", "true or false"},
      {"/shadow", json::object(), "shadow", "unknown field"},
      {"/width", 0, "width", ""},
      {"/scene", "no-such-scene", "scene", "no-such-scene"},
      {"/scene", json::parse(R"({"objects": [{"type": "box", "size": -1}]})"), "scene.objects[0].size", ""},
  };
  for (const Case& c : cases) {
    const RequestError e = refusal(body_with(c.path, c.value));
    EXPECT_EQ(e.field, c.field) << c.path << " = " << c.value.dump() << ": " << e.message;
    EXPECT_NE(e.message.find(c.says), std::string::npos) << e.message;
  }
  json body = body_with("", nullptr);
  body.erase("site");
  EXPECT_EQ(refusal(body).field, "site");
  body = body_with("", nullptr);
  body["grid"].erase("spacing");
  EXPECT_EQ(refusal(body).field, "grid.spacing");
  EXPECT_EQ(parse_sun_hours_request("{\"site\": ").error.message.find("malformed JSON"), 0u);
  EXPECT_EQ(parse_sun_hours_request("[1]").error.message, "must be an object, not an array");
}

TEST(SunHoursAnswer, AcceptChoosesJsonOrCsv) {
  EXPECT_EQ(sun_hours_format(""), SunHoursFormat::Json);
  EXPECT_EQ(sun_hours_format("*/*"), SunHoursFormat::Json);
  EXPECT_EQ(sun_hours_format("application/json"), SunHoursFormat::Json);
  EXPECT_EQ(sun_hours_format("text/csv"), SunHoursFormat::Csv);
  EXPECT_EQ(sun_hours_format("Text/CSV; charset=utf-8"), SunHoursFormat::Csv);
  EXPECT_EQ(sun_hours_format("text/*"), SunHoursFormat::Csv);
  EXPECT_EQ(sun_hours_format("application/json;q=0.5, text/csv"), SunHoursFormat::Csv);
  EXPECT_EQ(sun_hours_format("text/csv;q=0.2, */*;q=0.5"), SunHoursFormat::Json);
  EXPECT_EQ(sun_hours_format("text/csv;q=0, */*"), SunHoursFormat::Json);
  EXPECT_EQ(sun_hours_format("image/png"), SunHoursFormat::Png);
  EXPECT_EQ(sun_hours_format("image/*"), SunHoursFormat::Png);
  EXPECT_EQ(sun_hours_format("image/png, application/json;q=0.9"), SunHoursFormat::Png);
  EXPECT_FALSE(sun_hours_format("application/xml"));
  EXPECT_FALSE(sun_hours_format("text/csv;q=0"));
}

TEST(SunHoursAnswer, MalformedWeightsAreUnacceptable) {
  // A weight outside RFC 9110's qvalue grammar must not outrank the others:
  // NaN survived std::max and chose the picture for a grid-only job (500).
  for (const char* bad : {"nan", "NaN", "-1", "2", "1.5", "0.5e1", "inf", "0.1234", "1.", "", "x"})
    EXPECT_EQ(sun_hours_format(std::string("image/png;q=") + bad + ", application/json;q=0.1", false),
              SunHoursFormat::Json)
        << bad;
  EXPECT_EQ(sun_hours_format("application/json;q=nan, text/csv;q=0.001"), SunHoursFormat::Csv);
  EXPECT_FALSE(sun_hours_format("application/json;q=nan"));
  EXPECT_EQ(sun_hours_format("text/csv;q=1.000, application/json;q=0.999"), SunHoursFormat::Csv);
  EXPECT_EQ(sun_hours_format("text/csv;q=0.5, application/json;q=0.50"), SunHoursFormat::Json);
}

TEST(SunHoursAnswer, InstantsKeepTheirFraction) {
  EXPECT_EQ(sun_hours_utc(0.0), "1970-01-01T00:00:00Z");
  EXPECT_EQ(sun_hours_utc(22.5), "1970-01-01T00:00:22.5Z");
  EXPECT_EQ(sun_hours_utc(kEquinox2026 + 300.0), "2026-03-20T00:05:00Z");
}

TEST(SunHoursAnswer, JsonAndCsvHoldEveryPoint) {
  json body = body_with("/grid/center", {0, -0.49, 0});
  body["require_hours"] = 2;
  body["include_samples"] = true;
  const SunHoursRequest q = parsed(body);
  const SunHoursResult r = cast(q);
  const json answer = json::parse(sun_hours_json(q, r));
  EXPECT_EQ(answer["grid"]["columns"], 8);
  EXPECT_EQ(answer["grid"]["rows"], 4);
  EXPECT_EQ(answer["grid"]["origin"], json({-1.75, -0.49, -0.75}));
  ASSERT_EQ(answer["hours"].size(), 32u);
  ASSERT_EQ(answer["longest_run_hours"].size(), 32u);
  EXPECT_EQ(answer["samples_count"], 144);
  EXPECT_EQ(answer["samples"].size(), 144u);
  EXPECT_EQ(answer["samples"][0]["utc"], "2026-03-21T00:05:00Z");
  EXPECT_EQ(answer["path"], "ray_cast");
  EXPECT_EQ(answer["exact"], true);
  EXPECT_EQ(answer["pairs"], answer["pairs_ray_cast"]);
  EXPECT_EQ(answer["pairs"], 32 * answer["samples_up"].get<int>());
  EXPECT_DOUBLE_EQ(answer["pass_share"].get<double>(), r.pass_share(2.0));
  // Points inside the cube (-0.5..0.5) never see the sun; others do.
  EXPECT_EQ(answer["hours"][q.grid.columns + 3], 0.0);
  // The south row (+Z) is never in the cube's shadow at noon in March.
  EXPECT_DOUBLE_EQ(answer["hours"][31].get<double>(), r.samples_up * 10.0 / 60.0);
  const std::string csv = sun_hours_csv(q, r);
  std::istringstream lines(csv);
  std::string line;
  std::getline(lines, line);
  EXPECT_EQ(line, "x,y,z,hours,longest_run_hours");
  std::size_t count = 0;
  while (std::getline(lines, line)) ++count;
  EXPECT_EQ(count, 32u);
  EXPECT_NE(csv.find("\n-1.75,-0.49,-0.75,"), std::string::npos) << csv.substr(0, 200);
  body.erase("require_hours");
  body.erase("include_samples");
  const json plain = json::parse(sun_hours_json(parsed(body), r));
  EXPECT_FALSE(plain.contains("pass_share"));
  EXPECT_FALSE(plain.contains("samples"));
}

// A north-south wall at the equator on the equinox: the sun rises due east,
// climbs through the zenith and sets due west, so a point west of the wall
// at distance d is in its shadow each morning until the sun stands
// atan(h / d) high: about atan(h / d) / 15 degrees an hour of it.
TEST(SunHoursRayCast, AWallsShadowAtTheEquatorOnTheEquinox) {
  const double h = 4.0, half_thickness = 0.1, y0 = 0.01;
  json wall = {{"type", "box"}, {"center", {0, h / 2, 0}}, {"size", {2 * half_thickness, h, 4000}}};
  json body = {{"scene", {{"objects", json::array({wall})}}},
               {"site", {{"latitude", 0}, {"longitude", 0}}},
               {"period", {{"start", "2026-03-20T00:00:00Z"}, {"end", "2026-03-21T00:00:00Z"}, {"step_minutes", 2}}},
               // Points west of the wall at d = 1..8 from its middle.
               {"grid", {{"center", {-4.5, y0, 0}}, {"size", {8, 1}}, {"spacing", 1}}}};
  const SunHoursRequest q = parsed(body);
  const SunHoursResult r = cast(q);
  std::size_t up = 0;
  for (const SunSample& s : r.samples) up += s.up() ? 1 : 0;
  for (std::size_t i = 0; i < q.grid.points(); ++i) {
    const glm::dvec3 p = q.grid.point(i);
    // Independent of the ray caster: the ray p + t D enters the wall's slab
    // at x = -half_thickness, below its top, while the sun is east (D.x > 0).
    std::uint32_t lit = 0;
    for (const SunSample& s : r.samples) {
      if (!s.up()) continue;
      const glm::dvec3& D = s.direction;
      const bool blocked = D.x > 0.0 && p.y + (-half_thickness - p.x) / D.x * D.y < h;
      lit += blocked ? 0 : 1;
    }
    EXPECT_EQ(r.tally[i].lit, lit) << "point " << i;
    // The closed form, within two steps (the sun's declination and
    // refraction move it by minutes).
    const double d = -p.x - half_thickness;
    const double shaded_hours = glm::degrees(std::atan((h - y0) / d)) / 15.0;
    EXPECT_NEAR(r.hours(i), double(up) * 2.0 / 60.0 - shaded_hours, 2 * 2.0 / 60.0) << "d = " << d;
    // The shadow is one morning stretch: the sun is seen in one unbroken run.
    EXPECT_EQ(r.tally[i].longest, r.tally[i].lit) << "point " << i;
  }
  EXPECT_GT(r.hours(0), r.hours(7));  // nearer the wall (point 7), less sun
}

// A pole in the sun: the points along its shadow are dark out to
// r + (h - y0) / tan(elevation), lit beyond, at every elevation.
TEST(SunHoursRayCast, APolesShadowLengthFollowsTheSunsElevation) {
  const double h = 2.0, radius = 0.05, y0 = 0.001, spacing = 0.01;
  for (const char* instant : {"2026-06-21T05:00:00Z", "2026-06-21T06:30:00Z", "2026-06-21T08:00:00Z",
                              "2026-06-21T12:00:00Z"}) {
    const double t = *parse_utc(instant, nullptr);
    // One sample, at the instant: a period of one step around it.
    const SunAngles sun = solar_position(51.5, -0.12, t);
    ASSERT_GT(sun.elevation_deg, 3.0) << instant;
    // North turned so that the sun stands due -X: the shadow falls along +X.
    const double north = std::fmod(270.0 - sun.azimuth_deg, 360.0);
    const double length = radius + (h - y0) / std::tan(glm::radians(sun.elevation_deg));
    const double reach = std::ceil((length + 1.0) / spacing) * spacing;
    json pole = {{"type", "cylinder"}, {"center", {0, h / 2, 0}}, {"radius", radius}, {"height", h}};
    json body = {{"scene", {{"objects", json::array({pole})}}},
                 {"site", {{"latitude", 51.5}, {"longitude", -0.12}, {"north_deg", north}}},
                 {"period", {{"start", format_utc(t - 30)}, {"end", format_utc(t + 30)}, {"step_minutes", 1}}},
                 {"grid", {{"center", {reach / 2, y0, 0}}, {"size", {reach, spacing}}, {"spacing", spacing}}}};
    const SunHoursRequest q = parsed(body);
    const SunHoursResult r = cast(q);
    ASSERT_EQ(r.samples.size(), 1u);
    EXPECT_NEAR(r.samples[0].direction.z, 0.0, 1e-9);
    EXPECT_LT(r.samples[0].direction.x, 0.0);
    // Every point short of the length is dark, every one past it lit.
    std::size_t dark = 0;
    for (std::size_t i = 0; i < q.grid.points(); ++i) {
      const double x = q.grid.point(i).x;
      if (r.tally[i].lit == 0) ++dark;
      if (x < length - spacing) {
        EXPECT_EQ(r.tally[i].lit, 0u) << instant << " x = " << x;
      } else if (x > length + spacing) {
        EXPECT_EQ(r.tally[i].lit, 1u) << instant << " x = " << x;
      }
    }
    EXPECT_NEAR(double(dark) * spacing, length, 2 * spacing) << instant << ", elevation " << sun.elevation_deg;
  }
}

}  // namespace
}  // namespace umbra

namespace umbra {
namespace {

SunHoursResult cast_by_footprints(const SunHoursRequest& q) {
  SunHoursResult result;
  result.step_minutes = q.period.step_minutes;
  result.samples = sun_samples_on_all_cores(q.site, q.period, *sample_count(q.period));
  const RayScene rays(q.view.scene);
  footprint_sun_hours(rays, q.view.scene, q.grid, result.samples, result);
  return result;
}

void expect_same_tallies(const SunHoursResult& a, const SunHoursResult& b, const std::string& what) {
  ASSERT_EQ(a.tally.size(), b.tally.size());
  std::size_t differ = 0;
  for (std::size_t i = 0; i < a.tally.size(); ++i)
    differ += a.tally[i].lit != b.tally[i].lit || a.tally[i].longest != b.tally[i].longest ? 1 : 0;
  EXPECT_EQ(differ, 0u) << what;
  EXPECT_EQ(a.pairs, b.pairs) << what;
}

// The footprints settle most pairs without a ray and give the pure ray
// cast's tally at every point: over random scenes of boxes (turned),
// spheres, cylinders, thin poles, plates just above the grid and a model,
// at sites from the equator to the polar circle, over days and a week.
TEST(SunHoursFootprints, EveryPointEqualsThePureRayCast) {
  std::uint64_t seed = 12345;
  const auto uniform = [&](double lo, double hi) {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return lo + (hi - lo) * double(seed >> 11) / double(1ull << 53);
  };
  std::uint64_t by_maps = 0, pairs = 0;
  for (int scene = 0; scene < 24; ++scene) {
    const double y0 = uniform(-0.2, 0.3);
    json objects = json::array();
    objects.push_back({{"type", "plane"}, {"center", {0, uniform(-0.5, y0), 0}}, {"size", {40, 40}}});
    const int n = 1 + scene % 7;
    for (int k = 0; k < n; ++k) {
      const json at = {uniform(-6, 6), uniform(0, 2), uniform(-6, 6)};
      switch (k % 5) {
        case 0:
          objects.push_back({{"type", "box"}, {"center", at}, {"size", {uniform(0.1, 2), uniform(0.1, 3), uniform(0.1, 2)}},
                             {"rotation_y_deg", uniform(0, 90)}});
          break;
        case 1: objects.push_back({{"type", "sphere"}, {"center", at}, {"radius", uniform(0.1, 1.5)}}); break;
        case 2:
          objects.push_back({{"type", "cylinder"}, {"center", at}, {"radius", uniform(0.01, 0.05)}, {"height", uniform(1, 5)}});
          break;
        case 3:  // a plate just above the grid's plane
          objects.push_back({{"type", "box"}, {"center", {at[0], y0 + uniform(1e-4, 0.05), at[2]}},
                             {"size", {uniform(0.5, 3), 0.01, uniform(0.5, 3)}}});
          break;
        default:
          objects.push_back({{"type", "mesh"}, {"model", "teapot"}, {"position", at}, {"scale", uniform(0.3, 1)}});
      }
    }
    const double latitude = std::vector<double>{0, 23.4, 51.5, 66.5, -33.9, 70}[std::size_t(scene % 6)];
    const int days = scene % 4 == 3 ? 7 : 1;
    const std::string start = scene % 2 ? "2026-06-21T00:00:00Z" : "2026-12-03T00:00:00Z";
    json body = {{"scene", {{"objects", objects}}},
                 {"site", {{"latitude", latitude}, {"longitude", uniform(-180, 180)}, {"north_deg", uniform(-180, 180)}}},
                 {"period", {{"start", start}, {"end", format_utc(*parse_utc(start, nullptr) + days * kDay)},
                             {"step_minutes", days == 1 ? 5 : 30}}},
                 {"grid", {{"center", {0, y0, 0}}, {"size", {16, 16}}, {"spacing", 0.25}}}};
    const SunHoursRequest q = parsed(body);
    const SunHoursResult exact = cast(q), footprints = cast_by_footprints(q);
    expect_same_tallies(footprints, exact, "scene " + std::to_string(scene) + ": " + body.dump().substr(0, 400));
    EXPECT_EQ(footprints.pairs_by_maps + footprints.pairs_ray_cast, footprints.pairs);
    by_maps += footprints.pairs_by_maps;
    pairs += footprints.pairs;
  }
  // Most pairs are settled without a ray (the grid is mostly in the sun).
  EXPECT_GT(double(by_maps), 0.5 * double(pairs));
}

// A small grid (a garden) among objects near and far: those whose shadows
// never reach it are not drawn, and those far away whose long low-sun
// shadows do still are: every point as the pure ray cast's.
TEST(SunHoursFootprints, AGardenAmongFarObjectsKeepsTheLongShadows) {
  json objects = json::array({{{"type", "plane"}, {"center", {0, -0.5, 0}}, {"size", {400, 400}}}});
  for (int k = 0; k < 40; ++k) {
    const double angle = k * 0.61, distance = 1.5 + 2.0 * k;
    const json at = {distance * std::cos(angle), 1.0 + 0.1 * k, distance * std::sin(angle)};
    if (k % 3 == 0)
      objects.push_back({{"type", "box"}, {"center", at}, {"size", {0.8, 3.0 + 0.2 * k, 0.8}}, {"rotation_y_deg", 7 * k}});
    else if (k % 3 == 1)
      objects.push_back({{"type", "cylinder"}, {"center", at}, {"radius", 0.1}, {"height", 3.0 + 0.2 * k}});
    else
      objects.push_back({{"type", "sphere"}, {"center", at}, {"radius", 0.5}});
  }
  const json body = {{"scene", {{"objects", objects}}},
                     {"site", {{"latitude", 64}, {"longitude", 10}}},
                     {"period", {{"start", "2026-02-10T00:00:00Z"}, {"end", "2026-02-12T00:00:00Z"}, {"step_minutes", 2}}},
                     {"grid", {{"center", {0.3, -0.49, -0.2}}, {"size", {2, 2}}, {"spacing", 0.05}}}};
  const SunHoursRequest q = parsed(body);
  const SunHoursResult exact = cast(q), footprints = cast_by_footprints(q);
  expect_same_tallies(footprints, exact, "garden");
  std::uint64_t dark = 0;
  for (const PointTally& t : exact.tally) dark += exact.samples_up - t.lit;
  EXPECT_GT(dark, exact.pairs / 10) << "the far objects' shadows reach the garden";
}

// Points in a core's shadow are counted when they enter and leave it, not
// at every sample: wide boxes whose shadows cross, overlap and part over
// two days of minutes (rows entering one shadow as they leave another, a
// shadow held through sunset) still give every point the pure ray cast's
// lit samples and longest run.
TEST(SunHoursFootprints, PointsCountedAsTheyEnterAndLeaveCoreShadows) {
  json body = {{"scene", {{"objects", json::array({
                   {{"type", "plane"}, {"center", {0, -0.5, 0}}, {"size", {60, 60}}},
                   {{"type", "box"}, {"center", {-2, 1.5, 0}}, {"size", {3, 4, 2}}, {"rotation_y_deg", 20}},
                   {{"type", "box"}, {"center", {2.5, 1, 1}}, {"size", {2, 3, 3}}},
                   {{"type", "box"}, {"center", {0, 3, -4}}, {"size", {6, 0.5, 2}}},
               })}}},
               {"site", {{"latitude", 51.5}, {"longitude", 0}, {"north_deg", 30}}},
               {"period", {{"start", "2026-03-20T00:00:00Z"}, {"end", "2026-03-22T00:00:00Z"}, {"step_minutes", 1}}},
               {"grid", {{"center", {0, -0.49, 0}}, {"size", {20, 20}}, {"spacing", 0.2}}}};
  const SunHoursRequest q = parsed(body);
  const SunHoursResult exact = cast(q), footprints = cast_by_footprints(q);
  expect_same_tallies(footprints, exact, body.dump());
}

// A grid wholly under a roof, a grid on the floor's own plane, and a sun
// grazing the horizon at the polar circle: the footprints still agree.
TEST(SunHoursFootprints, RoofsFloorsAndGrazingSuns) {
  const std::vector<json> scenes = {
      json::parse(R"({"objects": [{"type": "box", "center": [0, 3, 0], "size": [30, 0.2, 30]}]})"),
      json::parse(R"({"objects": [{"type": "plane", "center": [0, 0, 0], "size": [30, 30]},
                                  {"type": "box", "center": [0, 1, 0], "size": [1, 2, 1]}]})"),
  };
  for (const json& scene : scenes) {
    for (double latitude : {0.0, 66.0, 80.0}) {
      json body = {{"scene", scene},
                   {"site", {{"latitude", latitude}, {"longitude", 10}}},
                   {"period", {{"start", "2026-03-18T00:00:00Z"}, {"end", "2026-03-21T00:00:00Z"}, {"step_minutes", 2}}},
                   {"grid", {{"center", {0, 0, 0}}, {"size", {20, 20}}, {"spacing", 0.5}}}};
      const SunHoursRequest q = parsed(body);
      expect_same_tallies(cast_by_footprints(q), cast(q), body.dump());
    }
  }
}

}  // namespace
}  // namespace umbra

namespace umbra {
namespace {

// A point above everything sees the sun whenever it is up: over a year at
// one-minute steps its hours are the sun-up time that PyEphem gives
// (tests/data/sun_up_hours.csv, scripts/make-sun-up-table.py). SPA's
// refraction at the horizon is 14.9" more than PyEphem's, so SPA's sun
// rises 1 to 64 s earlier and sets as much later (most at the polar
// circles' grazing days): over a year 0.25 to 0.85 h more, plus up to a
// minute a day of sampling that does not average out (each day's rise
// falls near the same point of its minute). A day: within one step.
TEST(SunHoursRayCast, AYearsHoursAreTheSunUpTimeOfPyEphem) {
  std::ifstream table(UMBRA_SUN_UP_TABLE_CSV);
  ASSERT_TRUE(table) << UMBRA_SUN_UP_TABLE_CSV;
  std::string line;
  int rows = 0, years = 0;
  while (std::getline(table, line)) {
    if (line.empty() || line[0] == '#' || line.rfind("name,", 0) == 0) continue;
    std::vector<std::string> cell;
    std::stringstream fields(line);
    for (std::string c; std::getline(fields, c, ',');) cell.push_back(c);
    ASSERT_EQ(cell.size(), 6u) << line;
    const json body = {{"scene", "cube-on-plane"},
                       {"site", {{"latitude", std::stod(cell[1])}, {"longitude", std::stod(cell[2])}}},
                       {"period", {{"start", cell[3]}, {"end", cell[4]}, {"step_minutes", 1}}},
                       {"grid", {{"center", {0.3, 10, -0.2}}, {"size", {1, 1}}, {"spacing", 1}}}};
    const SunHoursRequest q = parsed(body);
    const SunHoursResult r = cast_by_footprints(q);
    const double ephem = std::stod(cell[5]), hours = r.hours(0);
    EXPECT_EQ(r.tally[0].lit, r.samples_up) << line;
    // The samples on all cores are the samples one by one.
    for (std::size_t k = 0; k < r.samples.size(); k += 997)
      ASSERT_EQ(sun_sample(q.site, q.period, k).direction, r.samples[k].direction) << line << " sample " << k;
    const bool year = q.period.end_unix_s - q.period.start_unix_s > 300 * kDay;
    if (year) {
      EXPECT_GE(hours - ephem, 0.0) << line << ": " << hours;
      EXPECT_LE(hours - ephem, 1.0) << line << ": " << hours;
      ++years;
    } else {
      EXPECT_NEAR(hours, ephem, 1.0 / 60.0 + 5.0 / 3600.0) << line;
      // Polar day and night are whole.
      if (ephem == 0.0 || ephem == 24.0) {
        EXPECT_EQ(hours, ephem) << line;
      }
    }
    ++rows;
  }
  EXPECT_EQ(rows, 24);
  EXPECT_EQ(years, 6);
}

}  // namespace
}  // namespace umbra

namespace umbra {
namespace {

// ShapeKind::surely_meets is a proof: whenever it says yes, the exact
// intersection finds a hit in (0, infinity). Rays from everywhere (inside,
// outside, grazing the shrunk surface) at boxes (turned) and spheres; and
// it does say yes through the middle, and no for rays that only pass
// within the margin of the surface.
TEST(SunHoursFootprints, ASureHitIsAHitOfTheExactTest) {
  std::uint64_t seed = 99;
  const auto uniform = [&](double lo, double hi) {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return lo + (hi - lo) * double(seed >> 11) / double(1ull << 53);
  };
  SceneObject box;
  box.type = SceneObject::Type::Box;
  box.center = {1, 2, -3};
  box.size = {2, 1, 0.5};
  box.rotation_y_deg = 37;
  SceneObject sphere;
  sphere.type = SceneObject::Type::Sphere;
  sphere.center = {-2, 1, 4};
  sphere.radius = 1.5;
  SceneObject pole;  // thin and tall, as the bench's poles
  pole.type = SceneObject::Type::Cylinder;
  pole.center = {0.5, 1.5, 2};
  pole.radius = 0.05;
  pole.size.y = 3.0;
  SceneObject column;
  column.type = SceneObject::Type::Cylinder;
  column.center = {-1, 0, -1};
  column.radius = 1.2;
  column.size.y = 0.8;
  const double margin = 1e-3;
  int sure = 0;
  for (const SceneObject* o : {&box, &sphere, &pole, &column}) {
    const ShapeKind& kind = shape_kind(o->type);
    ASSERT_NE(kind.surely_meets, nullptr) << kind.name;
    for (int i = 0; i < 200000; ++i) {
      const glm::dvec3 origin = o->center + glm::dvec3(uniform(-4, 4), uniform(-4, 4), uniform(-4, 4));
      // Aim near the surface: a point on the object's bounds, jittered.
      const Aabb b = object_bounds(*o);
      const glm::dvec3 aim = glm::mix(b.min, b.max, glm::dvec3(uniform(-0.05, 1.05), uniform(-0.05, 1.05), uniform(-0.05, 1.05)));
      const glm::dvec3 dir = glm::normalize(aim - origin);
      if (!kind.surely_meets(*o, origin, dir, margin)) continue;
      ++sure;
      glm::dvec3 normal;
      const double t = kind.intersect(*o, origin, dir, 0.0, std::numeric_limits<double>::infinity(), normal);
      ASSERT_TRUE(t > 0.0 && t < std::numeric_limits<double>::infinity()) << kind.name << " ray " << i;
    }
  }
  EXPECT_GT(sure, 100000);
  // A point inside the object shrunk by twice the margin surely meets it
  // in every direction (ShapeKind::contains).
  int inside = 0;
  for (const SceneObject* o : {&box, &sphere, &pole, &column}) {
    const ShapeKind& kind = shape_kind(o->type);
    ASSERT_NE(kind.contains, nullptr) << kind.name;
    const Aabb b = object_bounds(*o);
    for (int i = 0; i < 20000; ++i) {
      const glm::dvec3 p = glm::mix(b.min, b.max, glm::dvec3(uniform(0, 1), uniform(0, 1), uniform(0, 1)));
      if (!kind.contains(*o, p, 2.0 * margin)) continue;
      ++inside;
      for (int j = 0; j < 8; ++j) {
        const glm::dvec3 dir = glm::normalize(glm::dvec3(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1)));
        ASSERT_TRUE(kind.surely_meets(*o, p, dir, margin)) << kind.name << " point " << i;
        glm::dvec3 normal;
        const double t = kind.intersect(*o, p, dir, 0.0, std::numeric_limits<double>::infinity(), normal);
        ASSERT_TRUE(t > 0.0 && t < std::numeric_limits<double>::infinity()) << kind.name;
      }
    }
  }
  EXPECT_GT(inside, 5000);
  // Just inside the surface (within twice the margin): not contained.
  EXPECT_FALSE(shape_kind(sphere.type).contains(sphere, sphere.center + glm::dvec3(1.5 - margin, 0, 0), 2.0 * margin));
  EXPECT_TRUE(shape_kind(sphere.type).contains(sphere, sphere.center + glm::dvec3(1.5 - 3 * margin, 0, 0), 2.0 * margin));
  // Through the middle: yes, from outside and from inside.
  EXPECT_TRUE(shape_kind(box.type).surely_meets(box, box.center + glm::dvec3(0, 0, 5), {0, 0, -1}, margin));
  EXPECT_TRUE(shape_kind(box.type).surely_meets(box, box.center, {0, 1, 0}, margin));
  EXPECT_TRUE(shape_kind(sphere.type).surely_meets(sphere, sphere.center, {1, 0, 0}, margin));
  // Within the margin of the surface, or behind the origin: no.
  EXPECT_FALSE(shape_kind(sphere.type).surely_meets(sphere, sphere.center + glm::dvec3(-5, 1.5 - margin / 2, 0), {1, 0, 0}, margin));
  EXPECT_FALSE(shape_kind(sphere.type).surely_meets(sphere, sphere.center + glm::dvec3(5, 0, 0), {1, 0, 0}, margin));
  EXPECT_FALSE(shape_kind(box.type).surely_meets(box, box.center + glm::dvec3(0, 0.5 - margin / 2, 9), {0, 0, -1}, margin));
  // Leaving the surface from just inside, the exit nearer than the margin: no.
  EXPECT_FALSE(shape_kind(box.type).surely_meets(box, box.center + glm::dvec3(0, 0.5 - margin / 4, 0), {0, 1, 0}, margin));
}

}  // namespace
}  // namespace umbra

namespace umbra {
namespace {

// The core's shadow is a proof for whole rows at once: every grid point
// that core_spans hands out has a ray that surely_meets the object and the
// exact intersection hits, for turned boxes, spheres and cylinders under
// random suns, on grids near the origin and kilometres from it (where the
// slack, not the cell, bounds the rounding). And it is no empty proof: for
// a box it takes nearly every point surely_meets takes one by one.
TEST(SunHoursFootprints, TheCoresShadowIsASureHitForEveryPointItTakes) {
  std::uint64_t seed = 4242;
  const auto uniform = [&](double lo, double hi) {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return lo + (hi - lo) * double(seed >> 11) / double(1ull << 53);
  };
  std::size_t taken = 0, box_taken = 0, box_sure = 0;
  for (int round = 0; round < 300; ++round) {
    const double far = round % 3 == 0 ? 0.0 : (round % 3 == 1 ? 3.0e3 : 2.0e5);
    SunGrid grid;
    grid.spacing = std::vector<double>{0.05, 0.25, 1.0}[std::size_t(round % 5) % 3];
    grid.columns = grid.rows = 120;
    grid.size_x = grid.size_z = grid.spacing * 120;
    grid.center = {far + uniform(-1, 1), uniform(-1, 1), -far + uniform(-1, 1)};
    SceneObject o;
    const glm::dvec3 at = grid.center + glm::dvec3(uniform(-0.3, 0.3), 0, uniform(-0.3, 0.3)) * grid.size_x;
    switch (round % 3) {
      case 0:
        o.type = SceneObject::Type::Box;
        o.size = glm::dvec3(uniform(0.2, 0.4), uniform(0.1, 0.5), uniform(0.2, 0.4)) * grid.size_x;
        o.rotation_y_deg = uniform(-180, 180);
        o.center = at + glm::dvec3(0, uniform(-0.4, 0.6) * o.size.y, 0);
        break;
      case 1:
        o.type = SceneObject::Type::Sphere;
        o.radius = uniform(0.05, 0.2) * grid.size_x;
        o.center = at + glm::dvec3(0, uniform(-0.5, 2) * o.radius, 0);
        break;
      default:
        o.type = SceneObject::Type::Cylinder;
        o.radius = uniform(0.05, 0.2) * grid.size_x;
        o.size.y = uniform(0.1, 0.6) * grid.size_x;
        o.center = at + glm::dvec3(0, uniform(-0.4, 0.6) * o.size.y, 0);
    }
    const ShapeKind& kind = shape_kind(o.type);
    const double margin = 1e-5 * (1.0 + std::abs(far) + grid.size_x);
    const std::vector<SolidCore> cores = solid_cores(o, grid.center.y, margin);
    ASSERT_LE(cores.size(), 1u);
    const SolidCore core = cores.empty() ? SolidCore{} : cores[0];
    const double elevation = glm::radians(uniform(1, 89)), azimuth = uniform(0, 2 * 3.14159265358979);
    const glm::dvec3 d{std::cos(elevation) * std::sin(azimuth), std::sin(elevation), std::cos(elevation) * std::cos(azimuth)};
    std::vector<std::uint8_t> in_core(grid.points(), 0);
    core_spans(core, d, grid, 0, grid.rows, [&](int r, int c0, int c1) {
      for (int c = c0; c <= c1; ++c) in_core[std::size_t(r) * std::size_t(grid.columns) + std::size_t(c)] = 1;
    });
    for (std::size_t i = 0; i < grid.points(); ++i) {
      const glm::dvec3 p = grid.point(i);
      const bool sure = kind.surely_meets(o, p, d, margin);
      if (o.type == SceneObject::Type::Box) box_sure += sure ? 1 : 0, box_taken += in_core[i];
      if (!in_core[i]) continue;
      ++taken;
      ASSERT_TRUE(sure) << kind.name << " round " << round << " point " << i;
      glm::dvec3 normal;
      const double t = kind.intersect(o, p, d, 0.0, std::numeric_limits<double>::infinity(), normal);
      ASSERT_TRUE(t > 0.0 && t < std::numeric_limits<double>::infinity()) << kind.name << " round " << round;
    }
  }
  EXPECT_GT(taken, 100000u);
  EXPECT_GT(double(box_taken), 0.95 * double(box_sure));
}

// A mesh's footprints are drawn from clusters of its triangles: every
// triangle lies inside one cluster's box, there are at most as many as
// asked, and two buildings far apart in one model leave the street
// between them out.
TEST(SunHoursFootprints, AMeshsClustersHoldEveryTriangleAndLeaveTheGaps) {
  const auto city = test::city_model(5, 12.0f, 6.0f);
  std::uint32_t shells = 0;
  const std::vector<std::uint32_t> shell_of = triangle_shells(*city, shells);
  EXPECT_EQ(shells, 25u);
  ASSERT_EQ(shell_of.size(), 25u * 12u);
  // 25 shells (buildings) of 12 triangles: at most `most` boxes (a power
  // of 2 below the shells), a building each, or split to `fewest`.
  for (const auto& [fewest, most, expected] : std::vector<std::array<int, 3>>{
           {1, 1, 1}, {1, 2, 2}, {1, 8, 8}, {1, 16, 16}, {1, 32, 25}, {32, 1024, 32}, {300, 1024, 300}, {400, 1024, 300}}) {
    const std::vector<Aabb> boxes = shell_clusters(*city, shell_of, shells, fewest, most);
    EXPECT_EQ(boxes.size(), std::size_t(expected)) << fewest << " " << most;
    const ModelPart& part = city->parts[0];
    for (std::size_t t = 0; t < part.triangle_count(); ++t) {
      bool held = false;
      for (const Aabb& b : boxes) {
        bool all = true;
        for (int c = 0; c < 3; ++c) {
          const glm::dvec3 p(part.positions[part.indices[3 * t + std::size_t(c)]]);
          all = all && p.x >= b.min.x && p.x <= b.max.x && p.y >= b.min.y && p.y <= b.max.y && p.z >= b.min.z &&
                p.z <= b.max.z;
        }
        held = held || all;
      }
      ASSERT_TRUE(held) << "triangle " << t << ", fewest " << fewest << ", most " << most;
    }
  }
  // Two buildings 100 m apart: the point between them is in no box (one
  // box each, and split further: still none over the street).
  const auto pair = test::city_model(2, 100.0f, 4.0f);
  const std::vector<std::uint32_t> pair_shells = triangle_shells(*pair, shells);
  EXPECT_EQ(shells, 4u);
  for (const Aabb& b : shell_clusters(*pair, pair_shells, shells, 32, 1024)) {
    const glm::dvec3 street(50, 1, 50);
    EXPECT_FALSE(street.x >= b.min.x && street.x <= b.max.x && street.z >= b.min.z && street.z <= b.max.z);
  }
  const TriangleModel empty;
  EXPECT_TRUE(shell_clusters(empty, triangle_shells(empty, shells), shells, 32, 1024).empty());
  EXPECT_EQ(shells, 0u);
}

// Rays whose lines pass through `cores` (model space) of `model`, placed
// turned and stretched as the footprints draw them in the world, from
// anywhere along the line before the core point (outside, inside another
// building, or in the core itself), rising: each is dark in Embree's own
// test (the proof the footprints take a core for).
void expect_rays_through_cores_dark(const std::shared_ptr<const TriangleModel>& model, const std::vector<Aabb>& cores,
                                    std::uint64_t seed) {
  ASSERT_FALSE(cores.empty());
  Scene scene;
  SceneObject mesh;
  mesh.type = SceneObject::Type::Mesh;
  mesh.model = model;
  mesh.model_id = "model";
  mesh.center = {3, -1, 2};
  mesh.rotation_deg = {0, 27, 0};
  mesh.mesh_scale = {1.5, 0.8, 1.2};
  scene.objects.push_back(mesh);
  const RayScene rays(scene);
  const glm::dmat4 to_world = mesh_transform(mesh);
  const auto uniform = [&](double lo, double hi) {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return lo + (hi - lo) * double(seed >> 11) / double(1ull << 53);
  };
  for (int i = 0; i < 20000; ++i) {
    const Aabb& core = cores[std::size_t(i) % cores.size()];
    const glm::dvec3 in_core = glm::mix(core.min, core.max, glm::dvec3(uniform(0, 1), uniform(0, 1), uniform(0, 1)));
    const glm::dvec3 through(to_world * glm::dvec4(in_core, 1.0));
    const glm::dvec3 d = glm::normalize(glm::dvec3(uniform(-1, 1), uniform(0.02, 1), uniform(-1, 1)));
    const glm::dvec3 origin = through - uniform(0.0, 60.0) * d;
    ASSERT_FALSE(sees_sun(rays, origin, d)) << "ray " << i;
  }
}

// A closed model's shell cores are inside its shells: one per building of
// a city in one mesh, none for an open box or the open teapot; and every
// ray whose line passes through a core meets the model in Embree's own
// test (the proof the footprints take it for), from outside, from inside
// another building and from inside the core itself, turned and scaled.
TEST(SunHoursFootprints, AClosedModelsShellCoresAreSureHits) {
  const auto city = test::city_model(4, 10.0f, 5.0f);
  ASSERT_TRUE(city->closed);
  const std::vector<Aabb> cores = shell_cores(*city, 1e-3);
  ASSERT_EQ(cores.size(), 16u);
  for (const Aabb& core : cores) {
    // Buildings are 5 wide: the core takes most of each.
    EXPECT_GT(core.extent().x, 4.0);
    EXPECT_GT(core.extent().y, 1.5);
  }
  EXPECT_TRUE(shell_cores(*test::box_model({1, 1, 1}, /*with_bottom=*/false), 1e-3).empty());
  // An open model's shells that close up have cores; the open ones none:
  // a city file with one building not watertight keeps the others' proofs.
  {
    auto mixed = std::make_shared<TriangleModel>();
    ModelPart part = test::box_model({1, 1, 1}, /*with_bottom=*/false)->parts[0];
    const auto closed_box = test::box_model({1, 1, 1});
    const ModelPart& box = closed_box->parts[0];
    std::vector<glm::vec3> moved;
    for (const glm::vec3& p : box.positions) moved.push_back(p + glm::vec3(10, 0, 0));
    part.append(moved, box.normals, box.indices);
    mixed->parts.push_back(part);
    finish_model(*mixed);
    ASSERT_FALSE(mixed->closed);
    const std::vector<Aabb> mixed_cores = shell_cores(*mixed, 1e-3);
    ASSERT_EQ(mixed_cores.size(), 1u);
    EXPECT_GT(mixed_cores[0].min.x, 8.0);  // the closed box's, not the open one's
  }
  // A pitched roof over a box: a closed house whose middle is not its
  // bounds' middle; its core stands on its floor.
  auto house = std::make_shared<TriangleModel>();
  {
    ModelPart part;
    part.positions = {{-2, 0, -3}, {2, 0, -3}, {2, 0, 3}, {-2, 0, 3}, {-2, 3, -3}, {2, 3, -3}, {2, 3, 3}, {-2, 3, 3},
                      {0, 6, -3}, {0, 6, 3}};
    part.normals.assign(part.positions.size(), glm::vec3(0, 1, 0));
    part.indices = {0, 1, 2, 0, 2, 3,  // floor (seen from below)
                    0, 5, 1, 0, 4, 5,  // front wall (z = -3) and its gable
                    4, 8, 5,           //
                    3, 2, 6, 3, 6, 7,  // back wall (z = 3) and its gable
                    7, 6, 9,           //
                    0, 3, 7, 0, 7, 4,  // left wall
                    1, 5, 6, 1, 6, 2,  // right wall
                    4, 7, 9, 4, 9, 8,  // left roof
                    5, 8, 9, 5, 9, 6};  // right roof
    house->parts.push_back(part);
    finish_model(*house);
    ASSERT_TRUE(house->closed);
    const std::vector<Aabb> house_cores = shell_cores(*house, 1e-3);
    ASSERT_EQ(house_cores.size(), 1u);
    EXPECT_LT(house_cores[0].max.y, 6.0);
    EXPECT_GT(house_cores[0].extent().x * house_cores[0].extent().y * house_cores[0].extent().z, 0.25 * 4 * 3 * 6);
  }
  // Rays through the cores, as the footprints draw them in the world.
  expect_rays_through_cores_dark(city, shell_cores(*city, 1e-3), 77);
  expect_rays_through_cores_dark(house, shell_cores(*house, 1e-3), 77);
}

// Triangles wound to face `out`, as a modeller's export writes them.
struct MeshBuilder {
  ModelPart part;
  void triangle(glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 out) {
    if (glm::dot(glm::cross(b - a, c - a), out) < 0.0f) std::swap(b, c);
    const auto first = std::uint32_t(part.positions.size());
    for (const glm::vec3& p : {a, b, c}) part.positions.push_back(p), part.normals.push_back(out);
    part.indices.insert(part.indices.end(), {first, first + 1, first + 2});
  }
  std::shared_ptr<TriangleModel> finish() {
    auto model = std::make_shared<TriangleModel>();
    model->parts.push_back(part);
    finish_model(*model);
    return model;
  }
};

// An arch (20 wide, 10 tall, a 16 x 8 tunnel through it along z, 20
// long), its top face at model y = 0 written with `top_zero` (-0.0f is the
// same position in other bits, as exporters write it).
std::shared_ptr<TriangleModel> arch_model(float top_zero) {
  const float s = 10.0f, length = 10.0f;
  const std::vector<glm::vec2> outline = {{-1, -1}, {-0.8f, -1}, {-0.8f, -0.2f}, {0.8f, -0.2f},
                                          {0.8f, -1}, {1, -1},    {1, 0},         {-1, 0}};
  const int caps[6][3] = {{0, 1, 2}, {0, 2, 7}, {7, 2, 3}, {7, 3, 6}, {6, 3, 4}, {6, 4, 5}};
  MeshBuilder b;
  for (const float z : {length, -length})
    for (const auto& t : caps)
      b.triangle(glm::vec3(outline[t[0]] * s, z), glm::vec3(outline[t[1]] * s, z), glm::vec3(outline[t[2]] * s, z),
                 glm::vec3(0, 0, z > 0 ? 1 : -1));
  for (std::size_t i = 0; i < outline.size(); ++i) {
    const glm::vec2 p = outline[i] * s, q = outline[(i + 1) % outline.size()] * s;
    const glm::vec3 out(q.y - p.y, -(q.x - p.x), 0);
    glm::vec3 a(p, -length), c(q, -length), d(q, length), e(p, length);
    if (i == 6) a.y = c.y = d.y = e.y = top_zero;  // the top face
    b.triangle(a, c, d, out);
    b.triangle(a, d, e, out);
  }
  return b.finish();
}

// Corners weld as numbers, -0 as 0 (the red-team pass: an arch whose top
// face was written with -0 split into two open shells, whose parity put a
// "core" in the tunnel: 563 points differed from the pure ray cast). And
// a triangle with two equal corners (closedness ignores it) costs no core.
TEST(SunHoursFootprints, ShellsWeldAsNumbersAndIgnoreDegenerateTriangles) {
  for (const float top : {0.0f, -0.0f}) {
    const auto arch = arch_model(top);
    ASSERT_TRUE(arch->closed) << top;
    std::uint32_t shells = 0;
    triangle_shells(*arch, shells);
    EXPECT_EQ(shells, 1u) << std::signbit(top);
    for (const Aabb& core : shell_cores(*arch, 1e-3))  // inside the arch's top, above the tunnel
      EXPECT_GT(core.min.y, -2.0) << std::signbit(top);
    json body = json::parse(R"({"scene": {"objects": [
        {"type": "mesh", "model": "arch", "position": [0, 10, 0]}]},
        "site": {"latitude": 51.5, "longitude": -0.12},
        "period": {"start": "2026-06-20T00:00:00Z", "end": "2026-06-21T00:00:00Z", "step_minutes": 10},
        "grid": {"center": [0, 0.5, 0], "size": [40, 40], "spacing": 0.5}})");
    const ParsedSunHours p =
        parse_sun_hours_request(body.dump(), test::lookup_of({{"sha256:arch", arch}}, {{"arch", "sha256:arch"}}));
    ASSERT_TRUE(p.request) << p.error.message;
    expect_same_tallies(cast_by_footprints(*p.request), cast(*p.request), std::signbit(top) ? "-0 top" : "+0 top");
  }
  auto cube = std::make_shared<TriangleModel>(*test::box_model({1, 1, 1}));
  ASSERT_EQ(shell_cores(*cube, 1e-3).size(), 1u);
  cube->parts[0].indices.insert(cube->parts[0].indices.end(), {0, 1, 1});
  finish_model(*cube);
  ASSERT_TRUE(cube->closed);
  EXPECT_EQ(shell_cores(*cube, 1e-3).size(), 1u);
}

// A thousand instances of a model of 4900 buildings would draw 10 million
// clusters and cores each sample, and the plan ran before any budget: past
// 65,536 in all each model is one box again (the red-team pass measured
// 31 s and 1.6 GB of planning before).
TEST(SunHoursFootprints, ManyInstancesOfManyShellsDrawABoundedNumber) {
  const auto city = test::city_model(70, 2.0f, 1.0f);
  json objects = json::array();
  for (int i = 0; i < 1000; ++i)
    objects.push_back({{"type", "mesh"}, {"model", "city"}, {"position", {(i % 40) * 3.0, 0, (i / 40) * 3.0}}});
  const json body = {{"scene", {{"objects", objects}}},
                     {"site", {{"latitude", 51.5}, {"longitude", -0.12}}},
                     {"period", {{"start", "2026-06-20T00:00:00Z"}, {"end", "2026-06-21T00:00:00Z"}, {"step_minutes", 10}}},
                     {"grid", {{"center", {0, 0.5, 0}}, {"size", {20, 20}}, {"spacing", 0.25}}}};
  const ParsedSunHours p =
      parse_sun_hours_request(body.dump(), test::lookup_of({{"sha256:city", city}}, {{"city", "sha256:city"}}));
  ASSERT_TRUE(p.request) << p.error.message;
  const FootprintShares shares =
      footprint_shares(p.request->view.scene, p.request->grid, {glm::normalize(glm::dvec3(0.3, 0.5, 0.2))});
  EXPECT_EQ(shares.hulls, 1000.0);  // one box an instance
  EXPECT_EQ(shares.model_triangles, 70.0 * 70.0 * 12.0);  // the model's triangles once
  // A few instances keep their buildings (1024 clusters of 4900 each, and
  // the buildings' cores).
  json few = body;
  few["scene"]["objects"] = json::array({objects[0], objects[1]});
  const ParsedSunHours q =
      parse_sun_hours_request(few.dump(), test::lookup_of({{"sha256:city", city}}, {{"city", "sha256:city"}}));
  ASSERT_TRUE(q.request);
  EXPECT_EQ(footprint_shares(q.request->view.scene, q.request->grid, {glm::normalize(glm::dvec3(0.3, 0.5, 0.2))}).hulls,
            2.0 * (1024 + 4900));
}

// A model's clusters and cores are found once and kept for the next
// request on it (the plan's, then its walk's, then the next request's):
// found, they are priced; kept, not. Placed elsewhere (another margin) or
// another model, found again.
TEST(SunHoursFootprints, AModelsClustersAndCoresAreKeptForTheNextRequest) {
  const auto city = test::city_model(6, 10.0f, 5.0f);
  const auto body_at = [&](double x) {
    return json{{"scene", {{"objects", json::array({{{"type", "mesh"}, {"model", "city"}, {"position", {x, 0, 0}}}})}}},
                {"site", {{"latitude", 51.5}, {"longitude", -0.12}}},
                {"period", {{"start", "2026-06-20T00:00:00Z"}, {"end", "2026-06-21T00:00:00Z"}, {"step_minutes", 10}}},
                {"grid", {{"center", {0, 0.5, 0}}, {"size", {20, 20}}, {"spacing", 0.25}}}};
  };
  const auto shares_of = [&](const json& body) {
    const ParsedSunHours p =
        parse_sun_hours_request(body.dump(), test::lookup_of({{"sha256:city", city}}, {{"city", "sha256:city"}}));
    EXPECT_TRUE(p.request) << p.error.message;
    return footprint_shares(p.request->view.scene, p.request->grid, {glm::normalize(glm::dvec3(0.3, 0.5, 0.2))});
  };
  const double triangles = double(city->triangle_count());
  EXPECT_EQ(shares_of(body_at(0)).model_triangles, triangles);
  const FootprintShares again = shares_of(body_at(0));
  EXPECT_EQ(again.model_triangles, 0.0);
  EXPECT_EQ(again.hulls, 2.0 * 36);  // its 36 buildings' clusters and cores, as found
  // A larger margin (5 m, a building's width): no cores, so the model's
  // exact shadow is found too, and priced as much again.
  EXPECT_EQ(shares_of(body_at(5e5)).model_triangles, 2.0 * triangles);
  EXPECT_EQ(shares_of(body_at(0)).model_triangles, 0.0);
}

// A city of 25 buildings in one mesh, as a CityJSON or glTF file brings
// it: the footprints path equals the pure ray cast at every point, and
// casts far fewer rays than one box around the whole city would leave to
// the query (nearly every pair under it).
TEST(SunHoursFootprints, ACityInOneMeshIsDrawnBuildingByBuilding) {
  json body = json::parse(R"({"scene": {"objects": [{"type": "plane", "center": [0, 0, 0], "size": [200, 200]},
      {"type": "mesh", "model": "city", "position": [-30, 0, -30], "rotation_deg": [0, 20, 0]}]},
      "site": {"latitude": 51.5, "longitude": -0.12},
      "period": {"start": "2026-03-20T00:00:00Z", "end": "2026-03-21T00:00:00Z", "step_minutes": 10},
      "grid": {"center": [0, 0.5, 0], "size": [80, 80], "spacing": 0.5}})");
  const ParsedSunHours p = parse_sun_hours_request(
      body.dump(), test::lookup_of({{"sha256:city", test::city_model(5, 14.0f, 8.0f)}}, {{"city", "sha256:city"}}));
  ASSERT_TRUE(p.request) << p.error.message;
  const SunHoursRequest& q = *p.request;
  const SunHoursResult exact = cast(q), footprints = cast_by_footprints(q);
  expect_same_tallies(footprints, exact, "city in one mesh");
  EXPECT_LT(double(footprints.pairs_ray_cast), 0.35 * double(footprints.pairs));
}

// Buildings without their ground faces (as city files often write them)
// are shells open only at their floor: closed by it, they have cores for
// rising rays, so a city of them is drawn with proofs of dark, as a closed
// one is. Proved, not guessed: every rising ray through such a core is dark
// in Embree's own test; a shell open anywhere else, or along edges at more
// than one height, has none; and an instance that does not keep up up
// (turned about x) does without them, its hours still the pure ray cast's.
TEST(SunHoursFootprints, ShellsOpenOnlyAtTheirFloorHaveCoresForRisingRays) {
  const auto open_box = test::box_model({1, 1, 1}, /*with_bottom=*/false);
  EXPECT_TRUE(shell_cores(*open_box, 1e-3).empty());
  const std::vector<Aabb> open_box_cores = shell_cores(*open_box, 1e-3, /*open_floors=*/true);
  ASSERT_EQ(open_box_cores.size(), 1u);
  // At least twice the margin above the open floor: rising rays from it
  // pass the open edges far above Embree's rounding there.
  EXPECT_GE(open_box_cores[0].min.y, -1.0 + 2e-3);
  for (const Aabb& core : shell_cores(*test::city_model(2, 10.0f, 5.0f, false), 1e-3, true)) EXPECT_GE(core.min.y, 2e-3);
  // Upside down: open at its top.
  {
    auto flipped = std::make_shared<TriangleModel>(*open_box);
    for (glm::vec3& p : flipped->parts[0].positions) p.y = -p.y;
    finish_model(*flipped);
    EXPECT_TRUE(shell_cores(*flipped, 1e-3, true).empty());
  }
  // One corner of its open rim raised: open along edges at two heights.
  {
    auto raised = std::make_shared<TriangleModel>(*open_box);
    for (glm::vec3& p : raised->parts[0].positions)
      if (p == glm::vec3(1, -1, 1)) p.y = -0.9f;
    finish_model(*raised);
    EXPECT_TRUE(shell_cores(*raised, 1e-3, true).empty());
  }
  // Rays through the cores of a floorless city, turned about y and
  // stretched, from anywhere along the line before the core point.
  const auto city = test::city_model(4, 10.0f, 5.0f, /*with_floors=*/false);
  ASSERT_FALSE(city->closed);
  const std::vector<Aabb> cores = shell_cores(*city, 1e-3, true);
  ASSERT_EQ(cores.size(), 16u);
  expect_rays_through_cores_dark(city, cores, 78);
  // The sun hours of a floorless city: as the pure ray cast's, and by
  // proofs (few rays); turned about x it keeps no cores, and its exact
  // shadows (MeshGridShadow) settle it as well.
  for (const bool upright : {true, false}) {
    json body = json::parse(R"({"scene": {"objects": [{"type": "plane", "center": [0, 0, 0], "size": [200, 200]},
        {"type": "mesh", "model": "city", "position": [-30, 0, -30], "rotation_deg": [0, 20, 0]}]},
        "site": {"latitude": 51.5, "longitude": -0.12},
        "period": {"start": "2026-03-20T00:00:00Z", "end": "2026-03-21T00:00:00Z", "step_minutes": 10},
        "grid": {"center": [0, 0.5, 0], "size": [80, 80], "spacing": 0.5}})");
    if (!upright) body["scene"]["objects"][1]["rotation_deg"] = {0.5, 20, 0};
    const ParsedSunHours p = parse_sun_hours_request(
        body.dump(), test::lookup_of({{"sha256:city", test::city_model(5, 14.0f, 8.0f, false)}}, {{"city", "sha256:city"}}));
    ASSERT_TRUE(p.request) << p.error.message;
    const SunHoursResult exact = cast(*p.request), footprints = cast_by_footprints(*p.request);
    expect_same_tallies(footprints, exact, upright ? "floorless city" : "floorless city, turned about x");
    EXPECT_LT(double(footprints.pairs_ray_cast), 0.01 * double(footprints.pairs));
  }
}

// A fine grid (a micrometre apart) and an object kilometres away: its
// footprint lies billions of rows off the grid, past any int (the red-team
// pass found this crash and hang). Both paths agree, and nothing is cast.
TEST(SunHoursFootprints, AFootprintBillionsOfCellsAwayIsNoCrash) {
  for (const char* center : {"[0, 0.5, 3000]", "[5000, 0.5, 3000]", "[3000, 0, 0]", "[-3000, 0, -3000]"}) {
    const json body = json::parse(std::string(R"({"scene": {"objects": [{"type": "box", "center": )") + center +
                                  R"(, "size": [10, 1, 10]}]}, "site": {"latitude": 51.5, "longitude": 0},
        "period": {"start": "2026-03-21T00:00:00Z", "end": "2026-03-22T00:00:00Z", "step_minutes": 10},
        "grid": {"center": [0, 0, 0], "size": [1e-4, 1e-4], "spacing": 1e-6}})");
    const SunHoursRequest q = parsed(body);
    const SunHoursResult footprints = cast_by_footprints(q);
    expect_same_tallies(footprints, cast(q), center);
    EXPECT_EQ(footprints.pairs_ray_cast, 0u) << center;
    const FootprintShares shares = footprint_shares(q.view.scene, q.grid, {glm::normalize(glm::dvec3(0.3, 0.2, 0.9))});
    EXPECT_EQ(shares.queried, 0.0) << center;
    EXPECT_EQ(shares.depth, 0.0) << center;
  }
}

}  // namespace
}  // namespace umbra

namespace umbra {
namespace {

// One sample over a grid under a stack of thin turned boxes: the work of
// one sample is long, and a stop must be seen within it (the red-team pass
// measured one sample running 135 s past an 8 s watchdog, when the stop
// was asked only between samples). stop_requested answers true from its
// second call: asked only between samples, this single-sample cast would
// finish and never throw.
json stacked_spokes(int boxes, double spacing) {
  json objects = json::array();
  for (int i = 0; i < boxes; ++i)
    objects.push_back({{"type", "box"}, {"center", {0, 1, 0}}, {"size", {10, 0.05, 0.002}}, {"rotation_y_deg", 45}});
  return {{"scene", {{"objects", objects}}},
          {"site", {{"latitude", 51.5}, {"longitude", 0}}},
          {"period", {{"start", "2026-03-21T12:00:00Z"}, {"end", "2026-03-21T12:10:00Z"}, {"step_minutes", 10}}},
          {"grid", {{"center", {0, 0, 0}}, {"size", {6.4, 6.4}}, {"spacing", spacing}}}};
}

// Samples more than six minutes apart over more than a day draw their
// mesh shadows from a memory per time of day: as many as a day holds
// steps, where it holds a whole number of at least 32.
TEST(SunHoursFootprints, AYearsMeshShadowsKeepAMemoryPerTimeOfDay) {
  EXPECT_EQ(mesh_memory_day_slots(600.0, 52560), 144u);  // a year at ten minutes
  EXPECT_EQ(mesh_memory_day_slots(600.0, 144), 0u);      // one day: none a day later
  EXPECT_EQ(mesh_memory_day_slots(300.0, 105120), 0u);   // five minutes: a memory from the last sample
  EXPECT_EQ(mesh_memory_day_slots(420.0, 10000), 0u);    // seven: a day is not a whole number of steps
  EXPECT_EQ(mesh_memory_day_slots(2700.0, 1000), 32u);   // 45 minutes: 32 a day
  EXPECT_EQ(mesh_memory_day_slots(3600.0, 1000), 0u);    // an hour: fewer than a block's
  // Teapots (open: their exact shadows) over four days at ten minutes,
  // in memories per time of day on every thread: the pure ray cast's
  // tally at every point.
  const json body = {
      {"scene",
       {{"objects",
         {{{"type", "plane"}, {"center", {0, 0, 0}}, {"size", {40, 40}}},
          {{"type", "mesh"}, {"model", "teapot"}, {"position", {-1.5, 0, 0.5}}, {"scale", 0.5}},
          {{"type", "mesh"}, {"model", "teapot"}, {"position", {1.5, 0, -0.5}}, {"rotation_deg", {0, 120, 0}}, {"scale", 0.4}}}}}},
      {"site", {{"latitude", 51.5}, {"longitude", -0.12}}},
      {"period", {{"start", "2026-05-01T00:00:00Z"}, {"end", "2026-05-05T00:00:00Z"}, {"step_minutes", 10}}},
      {"grid", {{"center", {0, 0.01, 0}}, {"size", {10, 10}}, {"spacing", 0.1}}}};
  const SunHoursRequest q = parsed(body);
  const SunHoursResult exact = cast(q), footprints = cast_by_footprints(q);
  expect_same_tallies(footprints, exact, "teapots over four days at ten minutes");
  EXPECT_LT(double(footprints.pairs_ray_cast), 0.05 * double(footprints.pairs));
}

TEST(SunHoursStop, IsAskedWithinOneSample) {
  const SunHoursRequest q = parsed(stacked_spokes(50, 0.025));  // 256 x 256 points, 50 boxes
  SunHoursResult result;
  result.step_minutes = q.period.step_minutes;
  result.samples = sun_samples(q.site, q.period, 1);
  ASSERT_TRUE(result.samples[0].up());
  const RayScene rays(q.view.scene);
  const std::uint64_t pairs = q.grid.points();
  for (const bool by_footprints : {true, false}) {
    int calls = 0;
    const std::function<bool()> stop = [&] { return ++calls > 1; };
    std::atomic<std::uint64_t> done{0};
    if (by_footprints)
      EXPECT_THROW(footprint_sun_hours(rays, q.view.scene, q.grid, result.samples, result, stop, &done), CastStopped);
    else
      EXPECT_THROW(ray_cast_sun_hours(rays, q.grid, result.samples, result, stop, &done), CastStopped);
    EXPECT_LT(done.load(), pairs) << (by_footprints ? "footprints" : "ray cast");
  }
}

// The cost of a ray is the objects whose bounds it passes: a thousand
// teapots at one spot (open models: every pair in their footprints is a
// ray) cost a thousand tests a ray, not log2(1000) (the estimate was 160
// times under the time taken).
TEST(SunHoursCost, OverlappingObjectsArePricedByTheirDepth) {
  json stacked_body = stacked_spokes(1000, 0.2);
  for (int i = 0; i < 1000; ++i)
    stacked_body["scene"]["objects"][std::size_t(i)] = {
        {"type", "mesh"}, {"model", "teapot"}, {"position", {0, 1, 0}}, {"scale", 2}};
  const SunHoursRequest stacked = parsed(stacked_body);
  json spread_body = stacked_body;
  for (int i = 0; i < 1000; ++i)  // small, far apart: no ray meets two
    spread_body["scene"]["objects"][std::size_t(i)] = {{"type", "mesh"},
                                                       {"model", "teapot"},
                                                       {"position", {1000.0 + 10.0 * (i % 40), 1, 1000.0 + 10.0 * (i / 40)}},
                                                       {"scale", 0.02}};
  const SunHoursRequest spread = parsed(spread_body);
  const SunHoursPlan a = plan_sun_hours(stacked), b = plan_sun_hours(spread);
  EXPECT_GT(a.estimate.ray_cast_ms, 30.0 * b.estimate.ray_cast_ms);
  // 32 x 32 points, one sample, up to 1000 objects each: about 10^6 tests.
  EXPECT_GT(a.estimate.cost.total_ms, 1e6 * 1.0e-5);
}

// The plan runs before any budget: its time must not grow with rows x
// objects (a 1 x 4M grid under 20 kilometre-long boxes took 64 s).
TEST(SunHoursCost, ThePlanVisitsABoundedLattice) {
  json body = stacked_spokes(0, 0.25);
  json objects = json::array();
  for (int i = 0; i < 20; ++i)
    objects.push_back({{"type", "box"}, {"center", {0, 0.5, 0}}, {"size", {0.1 + 0.001 * i, 1, 999999}}});
  body["scene"]["objects"] = objects;
  body["grid"] = {{"center", {0, 0, 0}}, {"size", {0.25, 1048576}}, {"spacing", 0.25}};
  const SunHoursRequest q = parsed(body);
  ASSERT_EQ(q.grid.points(), std::size_t(4194304));
  std::vector<glm::dvec3> directions;
  for (int i = 0; i < 32; ++i) directions.push_back(glm::normalize(glm::dvec3(0.3, 0.2 + 0.02 * i, 0.9)));
  // The rows each footprint is walked over: the lattice's, not the grid's.
  std::size_t rows = 0;
  for (const SceneObject& o : q.view.scene.objects)
    footprint_spans(reachable_bounds(object_bounds(o), 0.0, 524288.0), directions[0], q.grid, 0, q.grid.rows,
                    [&](int, int, int) { ++rows; }, 32768);
  EXPECT_LE(rows, 20u * 130u);
  const FootprintShares shares = footprint_shares(q.view.scene, q.grid, directions);
  EXPECT_GT(shares.depth, 10.0);  // every point lies under the 20 boxes
}

}  // namespace
}  // namespace umbra
