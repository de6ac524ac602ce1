// umbra-sun-hours-bench: POST /api/sun-hours' footprints path against the
// pure ray cast (bench/results/sun-hours.md).
//
// The footprints path (reference/sun_hours_footprints) settles a (point,
// sample) pair without a ray where the point lies outside every object's
// footprint along the sun, and casts the pure ray cast's own query
// (sees_sun) for the rest, so its hours must equal the pure ray cast's at
// every point. This program measures both, in one run on one machine:
//
//  1. Hard scenes (cube-on-plane, three-cubes, a city of 12 x 12 blocks, 200
//     thin poles, the 1M-triangle teapots, a grazing sun at Tromso), each
//     over a day at 1-minute steps and the year 2026 at 10-minute steps, on
//     a 1000 x 1000 grid: footprint_sun_hours itself over the whole grid
//     (wall clock, all threads), and the pure ray cast (sees_sun per pair,
//     the points walking the samples in order, all threads) over a subset
//     of the same grid's points (every 50th row), each of whose tallies
//     (lit samples and longest run) is compared with the footprints path's
//     at that point. Where that would not fit about ten minutes on two
//     cores, a coarser grid over the same area and fewer pure points
//     (plan_for), said in the report's `shrunk` column.
//  2. Seeded random scenes on small grids where the pure ray cast
//     (ray_cast_sun_hours itself) covers the whole grid: every point is
//     compared.
//
// Exit status 1 when any compared point differs (or a request is refused).
//
//   umbra-sun-hours-bench [--quick] [--seed 1] [--random 30] [--out DIR]
//                         [--only NAME]... [--period day|year] [--coarsen N] [--pure-column-step N]
//                         [--inject-difference]
//
// --quick: 100 x 100 grids, 10- and 360-minute steps, 6 random scenes (the
// smoke test). --only/--period/--coarsen/--pure-column-step: one case, or a
// coarser grid, by hand. --inject-difference: corrupts one pure tally, so
// that the run must fail (the smoke test of the check itself).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "machine.hpp"
#include "core/model.hpp"
#include "core/sun_hours.hpp"
#include "reference/ray_cast.hpp"
#include "reference/sun_hours_footprints.hpp"
#include "reference/sun_hours_ray_cast.hpp"
#include "service/request_cost.hpp"
#include "sun_hours_parser.hpp"

using umbra::bench::cpu_model_and_threads;
using umbra::bench::utc_now;

namespace {

std::string machine() {
  return cpu_model_and_threads() + "; the benchmark uses " + std::to_string(std::thread::hardware_concurrency());
}

using json = nlohmann::json;
using umbra::PointTally;
using umbra::SunGrid;
using umbra::SunHoursRequest;
using umbra::SunHoursResult;
using umbra::SunSample;
using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

std::string fmt(const char* pattern, double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, pattern, value);
  return buffer;
}

// Three significant figures with a k / M / G suffix (pairs, pairs/s).
std::string si(double v) {
  if (!std::isfinite(v)) return "-";
  const char* suffix[] = {"", " k", " M", " G", " T"};
  int k = 0;
  while (std::abs(v) >= 1000.0 && k < 4) v /= 1000.0, ++k;
  return fmt(std::abs(v) >= 100 ? "%.0f" : std::abs(v) >= 10 ? "%.1f" : "%.2f", v) + suffix[k];
}

// A seeded generator (PCG-style LCG, as the tests use): the same scenes on
// every machine and standard library.
struct Random {
  std::uint64_t state;
  explicit Random(std::uint64_t seed) : state(seed * 0x9E3779B97F4A7C15ull + 1442695040888963407ull) {}
  double uniform(double lo, double hi) {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return lo + (hi - lo) * double(state >> 11) / double(1ull << 53);
  }
  int below(int n) { return std::min(n - 1, int(uniform(0.0, double(n)))); }
};

// ------------------------------------------------------------ the hard scenes

struct Place {
  const char* name;
  double latitude, longitude;
};
constexpr Place kLondon{"London 51.5 N, 0.12 W", 51.5, -0.12};
constexpr Place kTromso{"Tromso 69.65 N, 18.96 E", 69.65, 18.96};

struct Period {
  std::string label;  // "day" or "year"
  std::string start, end;
  double step_minutes;
};

struct HardScene {
  std::string name;
  std::string what;  // one line for the report
  json scene;        // the request's "scene"
  Place place;
  std::string day_start;  // the day period's start (UTC midnight)
  // The 1000 x 1000 grid: centre and side (square), spacing = side / 1000.
  double grid_y = 0.0, grid_side = 1.0;
};

json scene_file_objects(const std::string& name) {
  const std::string path = std::string(UMBRA_SCENES_DIR) + "/" + name + ".json";
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path);
  return json::parse(in).at("scene");
}

// 12 x 12 blocks on a 300 m site: 25 m plots, footprints 8-20 m each way
// placed in their plot so that every street is at least 5 m wide, heights
// 3-60 m uniform, on a 400 x 400 m ground.
json city(std::uint64_t seed) {
  Random r(seed * 7 + 1);
  json objects = json::array();
  objects.push_back({{"type", "plane"}, {"center", {0, 0, 0}}, {"size", {400, 400}}});
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 12; ++j) {
      const double wx = r.uniform(8, 20), wz = r.uniform(8, 20), h = r.uniform(3, 60);
      const double jx = r.uniform(-1, 1) * (25 - wx - 5) / 2, jz = r.uniform(-1, 1) * (25 - wz - 5) / 2;
      objects.push_back({{"type", "box"},
                         {"center", {-137.5 + 25 * i + jx, h / 2, -137.5 + 25 * j + jz}},
                         {"size", {wx, h, wz}}});
    }
  return {{"objects", objects}};
}

// The city's blocks as one closed model, as a city model file brings them
// (each block a closed box of 6 faces, counter-clockwise seen from
// outside): the footprints are drawn from clusters of its triangles and
// the proofs of dark are its shells' cores (mesh_cluster_bounds,
// shell_cores), not the analytic boxes'.
// Without floors, each block lacks its ground face (as many city files
// write buildings): shells open only at their floor.
std::shared_ptr<const umbra::TriangleModel> city_model(std::uint64_t seed, bool floors) {
  umbra::ModelPart part;
  const json blocks = city(seed);
  for (const json& o : blocks["objects"]) {
    if (o["type"] != "box") continue;
    const glm::vec3 centre(o["center"][0].get<float>(), o["center"][1].get<float>(), o["center"][2].get<float>());
    const glm::vec3 half(o["size"][0].get<float>() / 2, o["size"][1].get<float>() / 2, o["size"][2].get<float>() / 2);
    for (int k = 0; k < 3; ++k)
      for (const float sign : {1.0f, -1.0f}) {
        if (k == 1 && sign < 0.0f && !floors) continue;
        glm::vec3 n(0.0f), u(0.0f), v(0.0f);
        n[k] = sign;
        const int iu = (k + 1) % 3, iv = (k + 2) % 3;
        u[iu] = half[iu];
        v[iv] = half[iv] * sign;
        const glm::vec3 face = centre + n * half[k];
        const auto first = std::uint32_t(part.positions.size());
        for (const glm::vec3& p : {face - u - v, face + u - v, face + u + v, face - u + v}) {
          part.positions.push_back(p);
          part.normals.push_back(n);
        }
        part.indices.insert(part.indices.end(), {first, first + 1, first + 2, first, first + 2, first + 3});
      }
  }
  auto model = std::make_shared<umbra::TriangleModel>();
  model->parts.push_back(std::move(part));
  umbra::finish_model(*model);
  return model;
}

json city_mesh(std::uint64_t seed, bool floors = true) {
  return {{"objects", {{{"type", "plane"}, {"center", {0, 0, 0}}, {"size", {400, 400}}},
                       {{"type", "mesh"}, {"model", std::string(floors ? "bench-city-" : "bench-city-open-") +
                                                        std::to_string(seed)}}}}};
}

// The models the cases name (city_mesh's), for the parser.
std::optional<umbra::FoundModel> find_bench_model(const std::string& name) {
  const std::string prefix = "bench-city-", open = "bench-city-open-";
  if (name.rfind(prefix, 0) != 0) return std::nullopt;
  const bool floors = name.rfind(open, 0) != 0;
  const std::uint64_t seed = std::stoull(name.substr((floors ? prefix : open).size()));
  static std::mutex mutex;
  static std::map<std::pair<std::uint64_t, bool>, std::shared_ptr<const umbra::TriangleModel>> models;
  std::lock_guard<std::mutex> lock(mutex);
  auto& model = models[{seed, floors}];
  if (!model) model = city_model(seed, floors);
  return umbra::FoundModel{"sha256:" + name, model};
}

// 200 poles, radius 3-10 cm, 2-8 m tall, standing on the ground over a 50 x
// 50 m grid.
json poles(std::uint64_t seed) {
  Random r(seed * 7 + 2);
  json objects = json::array();
  objects.push_back({{"type", "plane"}, {"center", {0, 0, 0}}, {"size", {60, 60}}});
  for (int k = 0; k < 200; ++k) {
    const double h = r.uniform(2, 8);
    objects.push_back({{"type", "cylinder"},
                       {"center", {r.uniform(-25, 25), h / 2, r.uniform(-25, 25)}},
                       {"radius", r.uniform(0.03, 0.1)},
                       {"height", h}});
  }
  return {{"objects", objects}};
}

// Five buildings, 3-12 m tall, turned, near the middle of a 300 m site:
// with the sun 1-2 degrees up their shadows run hundreds of metres.
json grazing(std::uint64_t seed) {
  Random r(seed * 7 + 3);
  json objects = json::array();
  objects.push_back({{"type", "plane"}, {"center", {0, 0, 0}}, {"size", {400, 400}}});
  for (int k = 0; k < 5; ++k) {
    const double h = r.uniform(3, 12);
    objects.push_back({{"type", "box"},
                       {"center", {r.uniform(-60, 60), h / 2, r.uniform(-60, 60)}},
                       {"size", {r.uniform(4, 15), h, r.uniform(4, 15)}},
                       {"rotation_y_deg", r.uniform(0, 90)}});
  }
  return {{"objects", objects}};
}

std::vector<HardScene> hard_scenes(std::uint64_t seed) {
  const std::string equinox = "2026-03-20T00:00:00Z";
  return {
      {"cube-on-plane", "built-in: a unit cube on a 50 x 50 floor at y = -0.5; grid 0.01 above the floor, 50 x 50 m",
       "cube-on-plane", kLondon, equinox, -0.49, 50.0},
      {"three-cubes", "built-in: three turned cubes on the same floor; grid 0.01 above it, 50 x 50 m",
       "three-cubes", kLondon, equinox, -0.49, 50.0},
      {"city", "12 x 12 blocks, footprints 8-20 m, heights 3-60 m uniform, streets >= 5 m; grid 1.5 m above the street, 300 x 300 m",
       city(seed), kLondon, equinox, 1.5, 300.0},
      {"city-mesh", "the city's 144 blocks as one closed model of 1728 triangles (a city file's buildings); grid 1.5 m above the street, 300 x 300 m",
       city_mesh(seed), kLondon, equinox, 1.5, 300.0},
      {"city-mesh-open", "the same model without the blocks' ground faces (1584 triangles; as many city files write buildings): shells open at their floor; grid 1.5 m above the street, 300 x 300 m",
       city_mesh(seed, false), kLondon, equinox, 1.5, 300.0},
      {"thin-poles", "200 cylinders r 0.03-0.1 m, 2-8 m tall, over the grid; grid 0.01 above the ground, 50 x 50 m",
       poles(seed), kLondon, equinox, 0.01, 50.0},
      {"teapots-1m", "bench/scenes/mesh-teapots-1m.json's objects (10 teapots, ~1M triangles, 30 x 30 floor); grid 0.01 above it, 30 x 30 m",
       scene_file_objects("mesh-teapots-1m"), kLondon, equinox, 0.01, 30.0},
      {"grazing-tromso", "5 turned boxes 3-12 m tall; Tromso, day = 2026-01-28 (the sun at most ~2 degrees up); grid 0.01 above the ground, 300 x 300 m",
       grazing(seed), kTromso, "2026-01-28T00:00:00Z", 0.01, 300.0},
  };
}

// How much of a scene x period is measured, where the whole would not fit
// the benchmark's time (the report says so in its `shrunk` column).
struct Plan {
  int coarsen = 1;         // footprints grid: (n / coarsen)^2 points over the same area ...
  int window = 0;          // ... or, if > 0, the window x window points in its middle, at its spacing
  int pure_rows = 20;         // pure ray cast: this many rows spread evenly over that grid ...
  int pure_column_step = 1;  // ... and every n-th column of those rows
};

// Every case runs on the whole 1000 x 1000 grid: the footprints path
// costs its shadows' outlines and the pairs in their unsure bands, a
// sample at a time, so a few minutes in all on two cores. The pure ray
// cast runs on a subset of its points (20 rows; in a year, 50 points of
// each: about 27 M pairs).
Plan plan_for(const std::string& scene, const std::string& period, bool quick) {
  (void)scene;
  Plan p;
  if (quick) {
    p.pure_rows = 10;
    return p;
  }
  if (period == "year") p.pure_column_step = 20;  // 20 rows x 50 points
  return p;
}

std::string plan_note(const Plan& p, int full, double side) {
  std::string note;
  if (p.window > 0)
    note += "window: the middle " + std::to_string(p.window) + " x " + std::to_string(p.window) + " points of the " +
            std::to_string(full) + " x " + std::to_string(full) + " grid (" + fmt("%g", side * p.window / full) +
            " m square, same spacing)";
  else if (p.coarsen > 1)
    note += "grid " + std::to_string(full / p.coarsen) + " x " + std::to_string(full / p.coarsen) + " (spacing x" +
            std::to_string(p.coarsen) + ", same area)";
  if (p.pure_column_step > 1)
    note += std::string(note.empty() ? "" : "; ") + "pure: 1 column in " + std::to_string(p.pure_column_step);
  return note.empty() ? "-" : note;
}

// --------------------------------------------------------------- measuring

// The request as the API takes it, through the real parser.
SunHoursRequest parse_body(const json& body) {
  const umbra::ParsedSunHours p = umbra::parse_sun_hours_request(body.dump(), find_bench_model);
  if (!p.ok()) throw std::runtime_error("the request was refused: " + p.error.field + ": " + p.error.message);
  return *p.request;
}

json request_body(const json& scene, double latitude, double longitude, double north_deg, const Period& period,
                  const json& grid_center, double side, double spacing) {
  return {{"scene", scene},
          {"site", {{"latitude", latitude}, {"longitude", longitude}, {"north_deg", north_deg}}},
          {"period", {{"start", period.start}, {"end", period.end}, {"step_minutes", period.step_minutes}}},
          {"grid", {{"center", grid_center}, {"size", {side, side}}, {"spacing", spacing}}}};
}

struct PureSubset {
  std::vector<std::size_t> points;   // grid indices
  std::vector<PointTally> tally;     // per entry of points
  std::uint64_t pairs = 0;           // points x samples up
  double ms = 0.0;
};

// The pure ray cast at `points` of `grid`: one sees_sun per point and
// sample with the sun up, each point's tally fed in time order (as
// ray_cast_sun_hours does: a sample with the sun down is dark), on every
// hardware thread, in chunks of points each walking the samples in order.
void pure_ray_cast(const umbra::RayScene& rays, const SunGrid& grid, const std::vector<SunSample>& samples,
                   PureSubset& subset) {
  const std::size_t n = subset.points.size();
  subset.tally.assign(n, PointTally{});
  std::size_t up = 0;
  for (const SunSample& s : samples) up += s.up() ? 1 : 0;
  subset.pairs = std::uint64_t(n) * up;
  const std::size_t chunk = std::max<std::size_t>(1, (std::size_t(1) << 16) / std::max<std::size_t>(1, up));
  const std::size_t chunks = (n + chunk - 1) / chunk;
  std::atomic<std::size_t> next{0};
  const auto work = [&] {
    std::vector<glm::dvec3> at;
    for (;;) {
      const std::size_t c = next.fetch_add(1);
      if (c >= chunks) return;
      const std::size_t first = c * chunk, last = std::min(n, first + chunk);
      at.clear();
      for (std::size_t i = first; i < last; ++i) at.push_back(grid.point(subset.points[i]));
      for (const SunSample& sample : samples) {
        const bool sun_up = sample.up();
        for (std::size_t i = first; i < last; ++i)
          subset.tally[i].record(sun_up && umbra::sees_sun(rays, at[i - first], sample.direction));
      }
    }
  };
  const auto start = Clock::now();
  const unsigned threads = std::max(1u, std::min<unsigned>(std::thread::hardware_concurrency(), unsigned(chunks)));
  std::vector<std::thread> pool;
  for (unsigned i = 1; i < threads; ++i) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  subset.ms = ms_since(start);
}

bool same(const PointTally& a, const PointTally& b) { return a.lit == b.lit && a.longest == b.longest; }

// Where a point differs: the first sample after which the footprints
// path's tally of it (over that prefix of the samples) is no longer the
// pure one's, by bisection over prefixes (each a whole footprints run, so
// only asked where that run is short).
long first_differing_sample(const umbra::RayScene& rays, const SunHoursRequest& q,
                            const std::vector<SunSample>& samples, std::size_t point) {
  const glm::dvec3 p = q.grid.point(point);
  const auto differs_within = [&](std::size_t count) {
    const std::vector<SunSample> prefix(samples.begin(), samples.begin() + long(count));
    SunHoursResult fp;
    umbra::footprint_sun_hours(rays, q.view.scene, q.grid, prefix, fp);
    PointTally pure;
    for (const SunSample& s : prefix) pure.record(s.up() && umbra::sees_sun(rays, p, s.direction));
    return !same(pure, fp.tally[point]);
  };
  if (!differs_within(samples.size())) return -1;
  std::size_t lo = 0, hi = samples.size();  // differs within hi, not within lo
  while (hi - lo > 1) {
    const std::size_t mid = (lo + hi) / 2;
    (differs_within(mid) ? hi : lo) = mid;
  }
  return long(hi - 1);
}

struct Difference {
  std::string where;
  std::size_t point = 0;
  glm::dvec3 at{0.0};
  PointTally footprints, pure;
  long sample = -1;  // -1: not located
  std::string utc;
};

json difference_json(const Difference& d) {
  return {{"case", d.where},
          {"point", d.point},
          {"xyz", {d.at.x, d.at.y, d.at.z}},
          {"footprints", {{"lit", d.footprints.lit}, {"longest", d.footprints.longest}}},
          {"pure", {{"lit", d.pure.lit}, {"longest", d.pure.longest}}},
          {"first_differing_sample", d.sample},
          {"sample_utc", d.utc}};
}

std::string utc_of(double unix_s) {
  const std::time_t t = std::time_t(std::floor(unix_s));
  char buffer[32];
  std::strftime(buffer, sizeof buffer, "%Y-%m-%dT%H:%M:%S", std::gmtime(&t));
  return std::string(buffer) + fmt("%.1fZ", unix_s - std::floor(unix_s)).substr(1);
}

struct HardRow {
  std::string scene, period, site;
  int columns = 0, rows = 0;
  double spacing = 0.0;
  std::size_t samples = 0, samples_up = 0;
  std::uint64_t pairs = 0, pairs_ray_cast = 0;
  double fp_ms = 0.0;
  double share_estimate_here = NAN, share_estimate_full = NAN;  // footprint_shares().queried over probe suns
  std::uint64_t pure_pairs = 0;
  double pure_ms = 0.0;
  std::size_t compared = 0, differing = 0;
  std::string shrunk;
  // The service's choice for this request (plan_sun_hours, the function
  // submit_sun_hours plans by) and its estimates, ms.
  bool service_footprints = false;
  double service_estimate_ms = NAN, service_pure_estimate_ms = NAN;
  json service_estimate_parts = json::object();  // the plan's parts, ms
  json shares = json::object();                  // footprint_shares on the whole grid
  double fp_rate() const { return double(pairs) / (fp_ms / 1000.0); }
  double pure_rate() const { return double(pure_pairs) / (pure_ms / 1000.0); }
  double speedup() const { return fp_rate() / pure_rate(); }
  double share() const { return pairs ? double(pairs_ray_cast) / double(pairs) : 0.0; }
};

struct RandomRow {
  int index = 0;
  std::string what;
  double latitude = 0.0;
  std::string day;
  int side = 0;
  std::size_t samples_up = 0;
  std::uint64_t pairs = 0, pairs_ray_cast = 0;
  double fp_ms = 0.0, pure_ms = 0.0;
  std::size_t compared = 0, differing = 0;
  double speedup() const { return fp_ms > 0.0 ? pure_ms / fp_ms : NAN; }
  double share() const { return pairs ? double(pairs_ray_cast) / double(pairs) : 0.0; }
};

// Compares footprints' tallies at `subset`'s points; records the first
// differences (the bisection only where a footprints run is cheap).
std::size_t compare(const SunHoursResult& fp, const PureSubset& subset, const std::string& where,
                    const umbra::RayScene& rays, const SunHoursRequest& q, const std::vector<SunSample>& samples,
                    double fp_ms, std::vector<Difference>& differences) {
  std::size_t differing = 0;
  for (std::size_t k = 0; k < subset.points.size(); ++k) {
    const std::size_t i = subset.points[k];
    if (same(fp.tally[i], subset.tally[k])) continue;
    if (++differing > 3) continue;  // the first three of each case are reported
    Difference d{where, i, q.grid.point(i), fp.tally[i], subset.tally[k], -1, ""};
    if (differing == 1 && fp_ms < 3000.0) {
      d.sample = first_differing_sample(rays, q, samples, i);
      if (d.sample >= 0) d.utc = utc_of(samples[std::size_t(d.sample)].utc_unix_s);
    }
    std::fprintf(stderr, "DIFFERS: %s point %zu (%.17g, %.17g, %.17g): footprints lit %u longest %u, pure lit %u longest %u%s\n",
                 where.c_str(), i, d.at.x, d.at.y, d.at.z, d.footprints.lit, d.footprints.longest, d.pure.lit,
                 d.pure.longest, d.sample >= 0 ? (", first at sample " + std::to_string(d.sample) + " " + d.utc).c_str() : "");
    differences.push_back(d);
  }
  return differing;
}

// --------------------------------------------------------------- random scenes

json random_scene(Random& r, double y0, double half) {
  json objects = json::array();
  objects.push_back({{"type", "plane"}, {"center", {0, r.uniform(y0 - 0.5, y0 - 0.001), 0}}, {"size", {4 * half, 4 * half}}});
  const int n = 2 + r.below(10);
  int teapots = 0;
  for (int k = 0; k < n; ++k) {
    const json at = {r.uniform(-half, half), y0 + r.uniform(-0.5, 2.5), r.uniform(-half, half)};
    switch (r.below(6)) {
      case 0:
      case 1:
        objects.push_back({{"type", "box"},
                           {"center", at},
                           {"size", {r.uniform(0.1, 3), r.uniform(0.1, 4), r.uniform(0.1, 3)}},
                           {"rotation_y_deg", r.uniform(0, 360)}});
        break;
      case 2: objects.push_back({{"type", "sphere"}, {"center", at}, {"radius", r.uniform(0.05, 1.5)}}); break;
      case 3:  // a thin pole
        objects.push_back({{"type", "cylinder"}, {"center", at}, {"radius", r.uniform(0.005, 0.06)}, {"height", r.uniform(0.5, 6)}});
        break;
      case 4:  // a plate just above the grid's plane
        objects.push_back({{"type", "box"},
                           {"center", {at[0], y0 + r.uniform(1e-5, 0.05), at[2]}},
                           {"size", {r.uniform(0.3, 3), r.uniform(0.001, 0.02), r.uniform(0.3, 3)}},
                           {"rotation_y_deg", r.uniform(0, 90)}});
        break;
      default:
        if (teapots < 2) {
          ++teapots;
          objects.push_back({{"type", "mesh"},
                             {"model", "teapot"},
                             {"position", {at[0], y0 + r.uniform(-0.3, 0.5), at[2]}},
                             {"rotation_deg", {0, r.uniform(0, 360), 0}},
                             {"scale", r.uniform(0.2, 0.8)}});
        } else {
          objects.push_back({{"type", "sphere"}, {"center", at}, {"radius", r.uniform(0.05, 0.5)}});
        }
    }
  }
  return {{"objects", objects}};
}

std::string day_of_2026(int day) {
  const std::time_t t = std::time_t(1767225600) + std::time_t(day) * 86400;  // 2026-01-01T00:00:00Z
  char buffer[32];
  std::strftime(buffer, sizeof buffer, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return buffer;
}

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false, inject = false;
  std::uint64_t seed = 1;
  int random_count = -1, coarsen_override = 0, column_step_override = 0;
  std::string out_dir = UMBRA_RESULTS_DIR, only_period;
  std::vector<std::string> only;
  std::string command_line = "umbra-sun-hours-bench";
  for (int i = 1; i < argc; ++i) command_line += std::string(" ") + argv[i];
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "--quick") {
      quick = true;
    } else if (arg == "--inject-difference") {
      inject = true;
    } else if (arg == "--seed" && has_value) {
      seed = std::strtoull(argv[++i], nullptr, 10);
    } else if (arg == "--random" && has_value) {
      random_count = std::max(0, std::atoi(argv[++i]));
    } else if (arg == "--out" && has_value) {
      out_dir = argv[++i];
    } else if (arg == "--only" && has_value) {
      only.push_back(argv[++i]);
    } else if (arg == "--coarsen" && has_value) {
      coarsen_override = std::atoi(argv[++i]);
    } else if (arg == "--pure-column-step" && has_value) {
      column_step_override = std::atoi(argv[++i]);
    } else if (arg == "--period" && has_value) {
      only_period = argv[++i];
    } else {
      std::fprintf(stderr,
                   "usage: umbra-sun-hours-bench [--quick] [--seed 1] [--random 30] [--out DIR] [--only NAME]... "
                   "[--period day|year] [--coarsen N] [--pure-column-step N] [--inject-difference]\n");
      return 2;
    }
  }
  if (random_count < 0) random_count = quick ? 6 : 30;
  const int full = quick ? 100 : 1000;  // the hard scenes' grid: full x full points
  const auto run_start = Clock::now();
  std::filesystem::create_directories(out_dir);

  const std::vector<Period> periods_template = {
      {"day", "", "", quick ? 10.0 : 1.0},
      {"year", "2026-01-01T00:00:00Z", "2027-01-01T00:00:00Z", quick ? 360.0 : 10.0},
  };
  std::vector<HardRow> hard;
  std::vector<Difference> differences;
  std::size_t refused = 0;
  json cases = json::array();

  for (const HardScene& hs : hard_scenes(seed)) {
    if (!only.empty() && std::find(only.begin(), only.end(), hs.name) == only.end()) continue;
    for (Period period : periods_template) {
      if (!only_period.empty() && only_period != period.label) continue;
      if (period.label == "day") {
        period.start = hs.day_start;
        period.end = umbra::format_utc(*umbra::parse_utc(hs.day_start, nullptr) + 86400.0);
      }
      Plan plan = plan_for(hs.name, period.label, quick);
      if (coarsen_override > 0) plan.coarsen = coarsen_override;
      if (column_step_override > 0) plan.pure_column_step = column_step_override;
      const int n = plan.window > 0 ? plan.window : full / plan.coarsen;
      const double spacing = plan.window > 0 ? hs.grid_side / full : hs.grid_side / n;
      const json body = request_body(hs.scene, hs.place.latitude, hs.place.longitude, 0.0, period,
                                     {0, hs.grid_y, 0}, n * spacing, spacing);
      const std::string where = hs.name + " / " + period.label;
      HardRow row;
      row.scene = hs.name;
      row.period = period.label + " (" + period.start.substr(0, 10) + (period.label == "year" ? " + 1 y" : "") +
                   ", " + fmt("%g", period.step_minutes) + " min)";
      row.site = hs.place.name;
      row.shrunk = plan_note(plan, full, hs.grid_side);
      try {
        const SunHoursRequest q = parse_body(body);
        const std::size_t count = *umbra::sample_count(q.period);
        const std::vector<SunSample> samples = umbra::sun_samples(q.site, q.period, count);
        const umbra::RayScene rays(q.view.scene);
        row.columns = q.grid.columns;
        row.rows = q.grid.rows;
        row.spacing = q.grid.spacing;
        row.samples = count;

        // The cost model's own estimate of the share (footprint_shares over
        // 64 of the probe suns), on this grid and on the whole 1000 x 1000
        // one: what a shrunk row would have cast there.
        {
          const std::vector<SunSample> probes = umbra::probe_samples(q.site, q.period, count);
          std::vector<glm::dvec3> up, directions;
          for (const SunSample& s : probes)
            if (s.up()) up.push_back(s.direction);
          const std::size_t picked = std::min<std::size_t>(64, up.size());
          for (std::size_t i = 0; i < picked; ++i) directions.push_back(up[i * up.size() / picked]);
          SunGrid whole = q.grid;
          whole.size_x = whole.size_z = hs.grid_side;
          whole.spacing = hs.grid_side / full;
          whole.columns = whole.rows = full;
          row.share_estimate_here = umbra::footprint_shares(q.view.scene, q.grid, directions).queried;
          const umbra::FootprintShares full_shares = umbra::footprint_shares(q.view.scene, whole, directions);
          row.share_estimate_full = full_shares.queried;
          row.shares = {{"queried", full_shares.queried},       {"candidates", full_shares.candidates},
                        {"depth", full_shares.depth},           {"tests", full_shares.tests},
                        {"hulls", full_shares.hulls},           {"core_rows", full_shares.core_rows},
                        {"mesh_shadow_work", full_shares.mesh_shadow_work}};
          // As submit_sun_hours plans it (the same function).
          const umbra::SunHoursCost cost = umbra::plan_sun_hours(q).estimate;
          row.service_footprints = cost.footprints;
          row.service_pure_estimate_ms = cost.ray_cast_ms;
          row.service_estimate_ms = 0.0;
          for (const umbra::CostPart& part : cost.cost.parts) {
            if (part.name.rfind("sun-hours", 0) == 0) row.service_estimate_ms += part.ms;
            row.service_estimate_parts[part.name] = part.ms;
          }
        }

        // The pure ray cast's points: about pure_rows rows spread evenly over
        // the grid, cast in two halves (alternate rows), one before the
        // footprints run and one after, so that a change in the shared
        // machine's load weighs on both paths alike.
        PureSubset halves[2], subset;
        const int row_step = std::max(1, q.grid.rows / plan.pure_rows);
        int nth = 0;
        for (int r = row_step / 2; r < q.grid.rows; r += row_step, ++nth)
          for (int c = 0; c < q.grid.columns; c += plan.pure_column_step)
            halves[nth % 2].points.push_back(std::size_t(r) * std::size_t(q.grid.columns) + std::size_t(c));
        std::fprintf(stderr, "%-28s pure ray cast over %zu + %zu points, footprints over %d x %d points ...\n",
                     where.c_str(), halves[0].points.size(), halves[1].points.size(), q.grid.columns, q.grid.rows);
        pure_ray_cast(rays, q.grid, samples, halves[0]);

        SunHoursResult fp;
        fp.step_minutes = q.period.step_minutes;
        const auto fp_start = Clock::now();
        umbra::footprint_sun_hours(rays, q.view.scene, q.grid, samples, fp);
        row.fp_ms = ms_since(fp_start);
        row.samples_up = fp.samples_up;
        row.pairs = fp.pairs;
        row.pairs_ray_cast = fp.pairs_ray_cast;

        pure_ray_cast(rays, q.grid, samples, halves[1]);
        for (const PureSubset& h : halves) {
          subset.points.insert(subset.points.end(), h.points.begin(), h.points.end());
          subset.tally.insert(subset.tally.end(), h.tally.begin(), h.tally.end());
          subset.pairs += h.pairs;
          subset.ms += h.ms;
        }
        if (inject && hard.empty() && !subset.tally.empty()) ++subset.tally[subset.tally.size() / 2].lit;
        row.pure_pairs = subset.pairs;
        row.pure_ms = subset.ms;
        row.compared = subset.points.size();
        row.differing = compare(fp, subset, where, rays, q, samples, row.fp_ms, differences);
        if (row.differing) {
          std::ofstream(out_dir + "/sun-hours-differs-" + hs.name + "-" + period.label + ".json") << body.dump(1) << "\n";
        }
        std::fprintf(stderr, "%-28s pure %.0f ms; speed-up %.2f; ray cast %.4f%%; differing %zu of %zu\n",
                     where.c_str(), row.pure_ms, row.speedup(), 100.0 * row.share(), row.differing, row.compared);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "%s: %s\n", where.c_str(), e.what());
        row.shrunk = std::string("FAILED: ") + e.what();
        ++refused;
      }
      hard.push_back(row);
      cases.push_back({{"scene", row.scene},
                       {"what", hs.what},
                       {"period", row.period},
                       {"site", row.site},
                       {"grid", {{"columns", row.columns}, {"rows", row.rows}, {"spacing", row.spacing}}},
                       {"samples", row.samples},
                       {"samples_up", row.samples_up},
                       {"pairs", row.pairs},
                       {"footprints_ms", row.fp_ms},
                       {"footprints_pairs_per_s", row.fp_rate()},
                       {"pairs_ray_cast", row.pairs_ray_cast},
                       {"share_ray_cast", row.share()},
                       {"share_estimate_this_grid", row.share_estimate_here},
                       {"share_estimate_full_grid", row.share_estimate_full},
                       {"pure_points", row.compared},
                       {"pure_pairs", row.pure_pairs},
                       {"pure_ms", row.pure_ms},
                       {"pure_pairs_per_s", row.pure_rate()},
                       {"speedup", row.speedup()},
                       {"compared_points", row.compared},
                       {"differing_points", row.differing},
                       {"shrunk", row.shrunk},
                       {"service_picks", row.service_footprints ? "footprints" : "ray_cast"},
                       {"service_estimate_ms_of_its_pick", row.service_estimate_ms},
                       {"service_estimate_ms_pure", row.service_pure_estimate_ms},
                       {"service_estimate_parts_ms", row.service_estimate_parts},
                       {"footprint_shares_whole_grid", row.shares}});
    }
  }

  // Random scenes: the whole grid by both paths.
  std::vector<RandomRow> randoms;
  const double random_ms_start = ms_since(run_start);
  const std::vector<double> latitudes = {0.0, 23.4, 40.7, 51.5, 59.9, 64.1, 66.6, 69.65, 74.0, 78.2,
                                         -12.0, -33.9, -41.3, -54.8, -66.0, -69.0, -77.8};
  const int side = quick ? 40 : 120;
  for (int s = 0; s < random_count; ++s) {
    Random r(seed * 1000003ull + std::uint64_t(s));
    RandomRow row;
    row.index = s;
    row.side = side;
    const double y0 = r.uniform(-0.2, 0.3);
    const double spacing = r.uniform(0.05, 0.2);
    const double half = 0.5 * side * spacing;
    const json scene = random_scene(r, y0, half);
    row.latitude = latitudes[std::size_t(s) % latitudes.size()];
    const int day = r.below(365);
    const Period period{"day", day_of_2026(day), day_of_2026(day + 1), 5.0};
    row.day = period.start.substr(0, 10);
    // The grid: side x side points, spacing to 1e-3 so the size is a whole number of cells.
    const double sp = std::round(spacing * 1000.0) / 1000.0;
    const json body = request_body(scene, row.latitude, r.uniform(-180, 180), r.uniform(-180, 180), period,
                                   {r.uniform(-1, 1), y0, r.uniform(-1, 1)}, side * sp, sp);
    int boxes = 0, spheres = 0, poles_n = 0, plates = 0, teapots = 0;
    for (const json& o : scene["objects"]) {
      const std::string t = o["type"];
      if (t == "box") (o["size"][1].get<double>() < 0.05 ? plates : boxes)++;
      if (t == "sphere") ++spheres;
      if (t == "cylinder") ++poles_n;
      if (t == "mesh") ++teapots;
    }
    row.what = std::to_string(boxes) + " boxes, " + std::to_string(spheres) + " spheres, " + std::to_string(poles_n) +
               " poles, " + std::to_string(plates) + " plates, " + std::to_string(teapots) + " teapots";
    const std::string where = "random " + std::to_string(s);
    try {
      const SunHoursRequest q = parse_body(body);
      const std::vector<SunSample> samples = umbra::sun_samples(q.site, q.period, *umbra::sample_count(q.period));
      const umbra::RayScene rays(q.view.scene);
      SunHoursResult fp, pure;
      auto start = Clock::now();
      umbra::footprint_sun_hours(rays, q.view.scene, q.grid, samples, fp);
      row.fp_ms = ms_since(start);
      start = Clock::now();
      umbra::ray_cast_sun_hours(rays, q.grid, samples, pure);
      row.pure_ms = ms_since(start);
      row.samples_up = fp.samples_up;
      row.pairs = fp.pairs;
      row.pairs_ray_cast = fp.pairs_ray_cast;
      PureSubset all;
      all.points.resize(q.grid.points());
      for (std::size_t i = 0; i < all.points.size(); ++i) all.points[i] = i;
      all.tally = pure.tally;
      row.compared = all.points.size();
      row.differing = compare(fp, all, where, rays, q, samples, row.fp_ms, differences);
      if (fp.pairs != pure.pairs) {
        std::fprintf(stderr, "%s: pairs differ (%llu, %llu)\n", where.c_str(), (unsigned long long)fp.pairs,
                     (unsigned long long)pure.pairs);
        row.differing = std::max<std::size_t>(row.differing, 1);
      }
      if (row.differing) {
        std::filesystem::create_directories(out_dir);
        std::ofstream(out_dir + "/sun-hours-differs-random-" + std::to_string(s) + ".json") << body.dump(1) << "\n";
      }
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s: %s\n", where.c_str(), e.what());
      ++refused;
      row.what += std::string(" FAILED: ") + e.what();
    }
    randoms.push_back(row);
  }
  const double random_ms = ms_since(run_start) - random_ms_start;
  const double total_s = ms_since(run_start) / 1000.0;

  // ------------------------------------------------------------------ report
  std::size_t differing = 0, compared = 0, random_differing = 0, random_compared = 0;
  for (const HardRow& h : hard) differing += h.differing, compared += h.compared;
  for (const RandomRow& r : randoms) random_differing += r.differing, random_compared += r.compared;
  std::vector<double> speedups, shares;
  for (const RandomRow& r : randoms)
    if (r.pairs > 0 && std::isfinite(r.speedup())) speedups.push_back(r.speedup()), shares.push_back(r.share());

  std::ostringstream table;
  table << "| scene | period | grid | samples up | pairs | footprints ms | footprints pairs/s | pure pairs/s (subset) "
           "| speed-up | share ray cast | est. share here / at " << full << "² | service picks | differing points / compared | shrunk |\n"
        << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const HardRow& h : hard)
    table << "| " << h.scene << " | " << h.period << " | " << h.columns << " x " << h.rows << " @ " << fmt("%g", h.spacing)
          << " | " << h.samples_up << " of " << h.samples << " | " << si(double(h.pairs)) << " | " << fmt("%.0f", h.fp_ms)
          << " | " << si(h.fp_rate()) << " | " << si(h.pure_rate()) << " (" << si(double(h.pure_pairs)) << " pairs, "
          << fmt("%.1f", h.pure_ms / 1000.0) << " s) | " << fmt(h.speedup() >= 100 ? "%.0f" : "%.1f", h.speedup()) << "x | "
          << fmt("%.3g", 100.0 * h.share()) << " % | " << fmt("%.3g", 100.0 * h.share_estimate_here) << " / "
          << fmt("%.3g", 100.0 * h.share_estimate_full) << " % | "
          << (h.service_footprints ? "footprints" : "ray cast")
          << (h.speedup() > 0.8 && h.speedup() < 1.25 ? " (paths within 25 %)"
              : h.service_footprints == (h.speedup() >= 1.0) ? "" : " (the slower)")
          << " | " << h.differing << " / " << h.compared << " | " << h.shrunk << " |\n";

  std::ostringstream random_table;
  random_table << "| # | objects | latitude | day (5 min) | samples up | pairs | footprints ms | pure ms | speed-up | share ray cast | differing / points |\n"
               << "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const RandomRow& r : randoms)
    random_table << "| " << r.index << " | " << r.what << " | " << fmt("%g", r.latitude) << " | " << r.day << " | "
                 << r.samples_up << " | " << si(double(r.pairs)) << " | " << fmt("%.1f", r.fp_ms) << " | "
                 << fmt("%.1f", r.pure_ms) << " | " << (r.pairs ? fmt("%.1f", r.speedup()) + "x" : "-") << " | "
                 << (r.pairs ? fmt("%.3g", 100.0 * r.share()) + " %" : "-") << " | " << r.differing << " / "
                 << r.compared << " |\n";
  const auto min_of = [](const std::vector<double>& v) { return v.empty() ? NAN : *std::min_element(v.begin(), v.end()); };
  const auto max_of = [](const std::vector<double>& v) { return v.empty() ? NAN : *std::max_element(v.begin(), v.end()); };
  std::ostringstream random_summary;
  random_summary << randoms.size() << " random scenes, " << side << " x " << side << " points each (" << random_compared
                 << " points compared): " << random_differing << " differing points. Speed-up (pure ms / footprints ms, "
                 << speedups.size() << " scenes with the sun up): min " << fmt("%.2f", min_of(speedups)) << "x, median "
                 << fmt("%.2f", median(speedups)) << "x, max " << fmt("%.2f", max_of(speedups)) << "x; share ray cast: min "
                 << fmt("%.3g", 100.0 * min_of(shares)) << " %, median " << fmt("%.3g", 100.0 * median(shares))
                 << " %, max " << fmt("%.3g", 100.0 * max_of(shares)) << " %.";

  std::printf("%s\n%s\n\nhard scenes: %zu differing of %zu compared points; random: %zu differing of %zu; %.1f s in all\n",
              table.str().c_str(), random_summary.str().c_str(), differing, compared, random_differing, random_compared,
              total_s);

  std::filesystem::create_directories(out_dir);
  const std::string md_path = out_dir + "/sun-hours.md", json_path = out_dir + "/sun-hours.json";
  {
    std::ofstream md(md_path);
    md << "# Sun hours: the footprints path against the pure ray cast\n\n"
       << "Written by `umbra-sun-hours-bench` (" << utc_now() << ").\n\n"
       << "- Machine: " << machine() << "\n"
       << "- Command: `" << command_line << "`" << (quick ? " (a smoke run: small grids, coarse steps)" : "") << "\n"
       << "- Run time: " << fmt("%.0f", total_s) << " s in all (random scenes " << fmt("%.0f", random_ms / 1000.0) << " s)\n"
       << "- Result: hard scenes " << differing << " differing of " << compared << " compared points; random scenes "
       << random_differing << " differing of " << random_compared << " points" << (refused ? "; " + std::to_string(refused) + " case(s) FAILED" : "")
       << ".\n"
       << (inject ? "- --inject-difference: one pure tally of the first case was corrupted on purpose (the smoke "
                    "test that a difference fails the run).\n" : "")
       << "\n## Method\n\n"
       << "Each case is a `POST /api/sun-hours` body built by the benchmark and read by the API's own parser "
          "(`parse_sun_hours_request`); the samples are `sun_samples` (every sample of the period, each at the middle of "
          "its step) and the scene's rays one `RayScene`, built before any clock starts and shared by both paths. "
          "Nothing else runs in the process; the machine is shared, so times are indicative (one run each).\n\n"
       << "- **footprints ms**: wall clock of `footprint_sun_hours` itself (the service's footprints path) over the whole "
          "grid, on all hardware threads. **footprints pairs/s** = pairs / that time, where **pairs** = grid points x "
          "samples with the sun up (what the pure ray cast would cast).\n"
       << "- **pure pairs/s (subset)**: the pure ray cast (`sees_sun` per point and sample with the sun up, each point's "
          "tally fed in time order as `ray_cast_sun_hours` does, chunks of points walking the samples in order, all "
          "hardware threads) over a subset of the same grid's points: about 20 rows spread evenly over the grid (every 50th row of "
          "1000: rows 25, 75, ..., 975) and every column of those rows unless the **shrunk** column says otherwise; its "
          "pairs and seconds are in brackets. The subset is cast in two halves (alternate rows), one just before the "
          "footprints run and one just after, so that a change in the shared machine's load weighs on both. A subset "
          "spread over the whole grid gives the pure ray cast's rate on it; the whole grid by the pure ray cast would "
          "take from minutes to hours for most cases.\n"
       << "- **speed-up** = footprints pairs/s / pure pairs/s (the same grid, samples and scene; both on all threads).\n"
       << "- **share ray cast** = the footprints path's pairs_ray_cast / pairs: the pairs inside some object's footprint "
          "and not proved dark (a ray surely through a box or sphere, or a point inside one), each settled by one "
          "`sees_sun`; the rest are proved lit or dark without a ray.\n"
       << "- **service picks**: the path `RenderService::submit_sun_hours` would run for this request: "
          "`plan_sun_hours`, the very function it plans by (512 probe samples; the footprints path simulated on a "
          "lattice of the grid at 32 of their suns; the cost model's estimates, ms, are in the JSON); \"(the slower)\" where the measured "
          "speed-up says the other path is faster by more than 25 %, \"(paths within 25 %)\" where the two are too "
          "close for one run on a shared machine to tell.\n"
       << "- **differing points / compared**: the points of the subset whose tally (lit samples AND longest run of "
          "consecutive lit samples, the latter as `PointTally::record` counts it) from the footprints path differs from "
          "the pure ray cast's. Must be 0.\n"
       << "- **shrunk**: where the whole case would not fit the benchmark's time on this machine, what was measured "
          "instead: a coarser grid over the same area for both paths (`grid n x n (spacing xk)`: the whole scene, but "
          "each footprint widened by its spare cells, so the share ray cast grows), a window of the grid at its own "
          "spacing (`window`: the middle points only), or fewer pure points (1 column in k of the 20 rows). **est. "
          "share** is the cost model's `footprint_shares` (queried) over 64 of the period's probe suns, on the grid measured and on "
          "the whole 1000 x 1000 one: what a shrunk case would have ray cast there. Nothing is dropped.\n"
       << "- Periods: **day** = one UTC day at 1-minute steps (the equinox 2026-03-20 at London; Tromso's own day "
          "2026-01-28, when the sun stays within about 2 degrees of the horizon); **year** = 2026 at 10-minute steps, at "
          "the scene's site. North is -Z (north_deg 0).\n\n"
       << "Scenes (seed " << seed << "):\n\n";
    for (const HardScene& hs : hard_scenes(seed))
      md << "- **" << hs.name << "** (" << hs.place.name << "): " << hs.what << ".\n";
    md << "\n## Hard scenes\n\n" << table.str() << "\n"
       << "## Random scenes\n\n"
       << "Seeded random scenes (boxes turned, spheres, thin poles r 5-60 mm, plates 0.01-50 mm above the grid's plane, "
          "up to two teapots, over a plane below the grid), each over one random day of 2026 at 5-minute steps at a "
          "latitude from the list 0 to 78.2 N and 12 to 77.8 S (north turned at random), on a "
       << side << " x " << side
       << " grid: the pure ray cast is `ray_cast_sun_hours` itself over the WHOLE grid, so every point is compared. "
          "Speed-up = pure ms / footprints ms (both the real functions, all threads; at these sizes a few milliseconds, so "
          "noisy).\n\n"
       << random_summary.str() << "\n\n" << random_table.str();
    if (!differences.empty()) {
      md << "\n## Differing points\n\n";
      for (const Difference& d : differences)
        md << "- " << d.where << ": point " << d.point << " at (" << fmt("%.17g", d.at.x) << ", " << fmt("%.17g", d.at.y)
           << ", " << fmt("%.17g", d.at.z) << "): footprints lit " << d.footprints.lit << " longest " << d.footprints.longest
           << ", pure lit " << d.pure.lit << " longest " << d.pure.longest
           << (d.sample >= 0 ? ", first differing sample " + std::to_string(d.sample) + " (" + d.utc + ")" : "") << "\n";
      md << "\nThe requests are in `sun-hours-differs-*.json` beside this file.\n";
    }
  }
  {
    json random_json = json::array();
    for (const RandomRow& r : randoms)
      random_json.push_back({{"index", r.index},
                             {"objects", r.what},
                             {"latitude", r.latitude},
                             {"day", r.day},
                             {"grid", r.side},
                             {"samples_up", r.samples_up},
                             {"pairs", r.pairs},
                             {"pairs_ray_cast", r.pairs_ray_cast},
                             {"share_ray_cast", r.share()},
                             {"footprints_ms", r.fp_ms},
                             {"pure_ms", r.pure_ms},
                             {"speedup", r.pairs ? json(r.speedup()) : json(nullptr)},
                             {"compared_points", r.compared},
                             {"differing_points", r.differing}});
    json diffs = json::array();
    for (const Difference& d : differences) diffs.push_back(difference_json(d));
    const auto number = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
    const json doc = {{"generator", "umbra-sun-hours-bench"},
                      {"date", utc_now()},
                      {"machine", machine()},
                      {"command", command_line},
                      {"quick", quick},
                      {"seed", seed},
                      {"run_seconds", total_s},
                      {"hard", cases},
                      {"random", {{"scenes", random_json},
                                  {"speedup_min", number(min_of(speedups))},
                                  {"speedup_median", number(median(speedups))},
                                  {"speedup_max", number(max_of(speedups))},
                                  {"compared_points", random_compared},
                                  {"differing_points", random_differing}}},
                      {"differing_points", differing + random_differing},
                      {"differences", diffs}};
    std::ofstream(json_path) << doc.dump(1) << "\n";
  }
  std::printf("wrote %s and %s\n", md_path.c_str(), json_path.c_str());
  return differing + random_differing > 0 || refused > 0 ? 1 : 0;
}
