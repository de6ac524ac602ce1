// umbra-certified-bench: shadow filter "exact" (certified hard shadows)
// against the default PCF frame and the full CPU ray cast, on the real server.
//
// Starts build/server/umbra-server (or --server PATH) on a free loopback
// port and, for each bench scene in bench/scenes/*.json at 960x540 with the
// scene's own settings, posts after one warm-up frame --frames frames of
// each of (interleaved, frame i at the scene's time + i x 0.37 s, so the
// light moves and every frame redraws its maps):
//   - the scene as it is (filter pcf by default), output "shadow":
//     ms = shadow + main + readback (Server-Timing);
//   - the same with "shadow": {"filter": "exact"}, output "shadow":
//     ms = shadow + main + readback + settle, and the uncertain share from
//     Umbra-Certified;
//   - output "exact" (the ray-cast reference): ms = raycast.
// Accuracy: filter exact's "shadow" PNG against the "exact" PNG at the
// scene's own time (pixels that differ at all, off by more than 127, MAE),
// and over an orbit sweep of 9 light angles (t = k x 18 / 9 s) the worst
// count of differing pixels. Then --random N seeded random hard scenes
// (needles, grazing suns, near-coincident surfaces, spheres and cylinders,
// point and directional lights) at a smaller size, each compared byte for
// byte. Writes DIR/certified.md, DIR/certified.json and the failing random
// scenes as DIR/certified-failures/random-<i>.json.
//
//   umbra-certified-bench [--frames 7] [--random 200] [--seed 1] [--size 960x540] [--random-size 320x180]
//                         [--scene NAME]... [--no-sweep] [--server PATH] [--out DIR]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <csignal>

#include <httplib.h>
#include <spng.h>
#include <sys/stat.h>
#include <nlohmann/json.hpp>

#include "machine.hpp"
#include "scene_files.hpp"
#include "server_process.hpp"

using umbra::bench::cpu_model_and_threads;
using umbra::bench::utc_now;

namespace {

using json = nlohmann::json;
constexpr double kTimeStep = 0.37;  // seconds between measured frames: the light moves, maps are redrawn

std::string fmt(const char* pattern, double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, pattern, value);
  return buffer;
}

// "shadow;dur=1.5, main;dur=2.0, ..." -> the duration named `name` (-1 if absent).
double timing(const std::string& header, const std::string& name) {
  std::size_t from = 0;
  const std::string key = name + ";dur=";
  while (true) {
    const std::size_t at = header.find(key, from);
    if (at == std::string::npos) return -1.0;
    // A whole stage name: at the start or after ", ".
    if (at == 0 || header[at - 1] == ' ' || header[at - 1] == ',') return std::atof(header.c_str() + at + key.size());
    from = at + 1;
  }
}

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

struct Grey {
  int width = 0, height = 0;
  std::vector<std::uint8_t> pixels;
  std::string error;
};

// A PNG's first channel as 8 bits (the shadow and exact outputs are 8-bit grey).
Grey decode_grey(const std::string& png) {
  Grey g;
  spng_ctx* ctx = spng_ctx_new(0);
  if (!ctx) return g.error = "spng_ctx_new failed", g;
  std::unique_ptr<spng_ctx, void (*)(spng_ctx*)> guard(ctx, spng_ctx_free);
  spng_ihdr ihdr{};
  if (int e = spng_set_png_buffer(ctx, png.data(), png.size()); e) return g.error = spng_strerror(e), g;
  if (int e = spng_get_ihdr(ctx, &ihdr); e) return g.error = spng_strerror(e), g;
  const bool grey8 = ihdr.color_type == SPNG_COLOR_TYPE_GRAYSCALE && ihdr.bit_depth == 8;
  const int format = grey8 ? SPNG_FMT_G8 : SPNG_FMT_RGBA8;
  std::size_t size = 0;
  if (int e = spng_decoded_image_size(ctx, format, &size); e) return g.error = spng_strerror(e), g;
  std::vector<std::uint8_t> out(size);
  if (int e = spng_decode_image(ctx, out.data(), size, format, 0); e) return g.error = spng_strerror(e), g;
  g.width = int(ihdr.width);
  g.height = int(ihdr.height);
  if (grey8) {
    g.pixels = std::move(out);
  } else {
    g.pixels.resize(std::size_t(g.width) * g.height);
    for (std::size_t i = 0; i < g.pixels.size(); ++i) g.pixels[i] = out[4 * i];
  }
  return g;
}

struct Compare {
  long differing = 0;  // pixels that differ at all
  long wrong = 0;      // off by more than 127
  double mae = 0.0;    // mean |a - b| / 255 over all pixels
  long pixels = 0;
  bool bytes_equal = false;  // the PNG files themselves
  std::string error;
};

Compare compare(const std::string& png_a, const std::string& png_b) {
  Compare c;
  c.bytes_equal = png_a == png_b;
  const Grey a = decode_grey(png_a), b = decode_grey(png_b);
  if (!a.error.empty() || !b.error.empty()) return c.error = "decode: " + a.error + b.error, c;
  if (a.width != b.width || a.height != b.height) return c.error = "sizes differ", c;
  double sum = 0.0;
  for (std::size_t i = 0; i < a.pixels.size(); ++i) {
    const int d = std::abs(int(a.pixels[i]) - int(b.pixels[i]));
    if (d > 0) ++c.differing;
    if (d > 127) ++c.wrong;
    sum += d;
  }
  c.pixels = long(a.pixels.size());
  c.mae = c.pixels ? sum / 255.0 / double(c.pixels) : 0.0;
  return c;
}

struct Answer {
  int status = 0;  // 0: no answer
  std::string body, timing, certified, sun, unused;
  double ms(std::initializer_list<const char*> stages) const {
    double sum = 0.0;
    for (const char* s : stages) sum += std::max(0.0, ::timing(timing, s));
    return sum;
  }
  // "..., path=maps" -> "maps"; "-" if absent.
  std::string path() const {
    const std::size_t at = certified.find("path=");
    if (at == std::string::npos) return "-";
    const std::size_t end = certified.find_first_of(", \r\n", at + 5);
    return certified.substr(at + 5, end == std::string::npos ? std::string::npos : end - at - 5);
  }
  // "uncertain=0.1234%, ..." -> 0.1234; -1 if absent.
  double uncertain_percent() const {
    const std::size_t at = certified.find("uncertain=");
    return at == std::string::npos ? -1.0 : std::atof(certified.c_str() + at + 10);
  }
  std::string error_text() const {
    if (status == 0) return "no answer";
    std::string text = std::to_string(status) + " " + body.substr(0, 300);
    std::replace(text.begin(), text.end(), '\n', ' ');
    std::replace(text.begin(), text.end(), '|', '/');
    return text;
  }
};

class Poster {
 public:
  explicit Poster(int port) : client_("127.0.0.1", port) {
    client_.set_keep_alive(true);
    client_.set_tcp_nodelay(true);
    client_.set_read_timeout(1800, 0);
    client_.set_write_timeout(60, 0);
  }
  Answer post(const json& body) {
    Answer a;
    auto res = client_.Post("/api/render", body.dump(), "application/json");
    if (!res) return a;
    a.status = res->status;
    a.body = std::move(res->body);
    a.timing = res->get_header_value("Server-Timing");
    a.certified = res->get_header_value("Umbra-Certified");
    a.sun = res->get_header_value("Umbra-Sun");
    a.unused = res->get_header_value("Umbra-Unused-Fields");
    return a;
  }
  httplib::Client& client() { return client_; }

 private:
  httplib::Client client_;
};

json with(json body, const std::string& output, bool exact_filter, double time) {
  body["output"] = output;
  body["time"] = time;
  if (exact_filter) body["shadow"]["filter"] = "exact";
  return body;
}

struct SceneRow {
  std::string scene;
  std::string skipped;  // why, if not measured
  double pcf_ms = NAN, exact_ms = NAN, raycast_ms = NAN, settle_ms = NAN, uncertain = NAN;
  // The exact filter's other stages, medians on their own: the maps
  // (shadow), the main pass (main), the read-back (with the CPU's sliver
  // marks, where it finds them).
  double exact_shadow_ms = NAN, exact_main_ms = NAN, exact_readback_ms = NAN;
  std::string path;  // Umbra-Certified's path of the rounds (several: joined with "/")
  Compare at_own_time;
  long sweep_worst = -1;
  double sweep_worst_time = 0.0;
  long sweep_wrong_worst = -1;
  int frames = 0;
};

SceneRow measure_scene(Poster& poster, const std::string& name, const json& base, int frames, bool sweep) {
  SceneRow row;
  row.scene = name;
  const double t0 = base.value("time", 0.0);
  // Warm-up (and the accuracy sample): the scene's own time.
  const Answer exact_filter0 = poster.post(with(base, "shadow", true, t0));
  if (exact_filter0.status != 200) {
    row.skipped = exact_filter0.error_text();
    return row;
  }
  const Answer pcf0 = poster.post(with(base, "shadow", false, t0));
  const Answer exact0 = poster.post(with(base, "exact", false, t0));
  if (pcf0.status != 200 || exact0.status != 200) {
    row.skipped = pcf0.status != 200 ? "pcf: " + pcf0.error_text() : "exact output: " + exact0.error_text();
    return row;
  }
  row.at_own_time = compare(exact_filter0.body, exact0.body);

  std::vector<double> pcf, exact, raycast, settle, uncertain, exact_shadow, exact_main, exact_readback;
  for (int i = 1; i <= frames; ++i) {
    const double t = t0 + i * kTimeStep;
    const Answer p = poster.post(with(base, "shadow", false, t));
    const Answer e = poster.post(with(base, "shadow", true, t));
    const Answer r = poster.post(with(base, "exact", false, t));
    if (p.status == 200) pcf.push_back(p.ms({"shadow", "main", "readback"}));
    if (e.status == 200) {
      exact.push_back(e.ms({"shadow", "main", "readback", "settle"}));
      settle.push_back(e.ms({"settle"}));
      exact_shadow.push_back(e.ms({"shadow"}));
      exact_main.push_back(e.ms({"main"}));
      exact_readback.push_back(e.ms({"readback"}));
      uncertain.push_back(e.uncertain_percent());
      if (row.path.find(e.path()) == std::string::npos) row.path += (row.path.empty() ? "" : "/") + e.path();
    }
    if (r.status == 200) raycast.push_back(r.ms({"raycast"}));
    if (p.status != 200 || e.status != 200 || r.status != 200)
      std::fprintf(stderr, "%s t=%.2f: pcf %d, exact filter %d, exact output %d\n", name.c_str(), t, p.status, e.status,
                   r.status);
  }
  row.frames = frames;
  row.pcf_ms = median(pcf);
  row.exact_ms = median(exact);
  row.raycast_ms = median(raycast);
  row.settle_ms = median(settle);
  row.exact_shadow_ms = median(exact_shadow);
  row.exact_main_ms = median(exact_main);
  row.exact_readback_ms = median(exact_readback);
  row.uncertain = median(uncertain);

  if (sweep) {
    for (int k = 0; k < umbra::kOrbitSweepTimes; ++k) {
      const double t = umbra::orbit_sweep_time(k, umbra::kOrbitSweepTimes);
      const Answer e = poster.post(with(base, "shadow", true, t));
      const Answer r = poster.post(with(base, "exact", false, t));
      if (e.status != 200 || r.status != 200) {
        std::fprintf(stderr, "%s sweep t=%.1f: exact filter %d, exact output %d\n", name.c_str(), t, e.status,
                     r.status);
        continue;
      }
      const Compare c = compare(e.body, r.body);
      if (c.differing > row.sweep_worst) row.sweep_worst = c.differing, row.sweep_worst_time = t;
      row.sweep_wrong_worst = std::max(row.sweep_wrong_worst, c.wrong);
    }
  }
  return row;
}

// ---------------------------------------------------------------- random scenes

struct RandomScene {
  int index = 0;
  std::string kind;
  json body;
};

class SceneMaker {
 public:
  SceneMaker(std::uint64_t seed, int width, int height) : rng_(seed), width_(width), height_(height) {}

  RandomScene make(int index) {
    static const char* kKinds[] = {"needles", "grazing-sun", "grazing-directional", "resting-box",
                                   "shared-face", "hovering-plate", "spheres-cylinders"};
    RandomScene s;
    s.index = index;
    s.kind = kKinds[index % 7];
    json objects = json::array();
    objects.push_back({{"type", "plane"}, {"center", {0, 0, 0}}, {"size", {uni(10, 30), uni(10, 30)}},
                       {"color", {0.72, 0.66, 0.58}}});
    bool near_surfaces = false;
    if (s.kind == "needles") {
      const int n = 1 + int(uni(0, 6));
      for (int i = 0; i < n; ++i) {
        const double thin = uni(0.002, 0.02), other = chance(0.5) ? uni(0.002, 0.02) : uni(0.1, 1.0);
        const double h = uni(1.0, 4.0);
        const bool thin_x = chance(0.5);
        objects.push_back(box({uni(-2, 2), h / 2, uni(-2, 2)}, {thin_x ? thin : other, h, thin_x ? other : thin},
                              uni(-180, 180)));
      }
      if (chance(0.5)) objects.push_back(sphere({uni(-2, 2), uni(0.3, 1.5), uni(-2, 2)}, uni(0.2, 0.8)));
    } else if (s.kind == "grazing-sun" || s.kind == "grazing-directional") {
      const int n = 2 + int(uni(0, 4));
      for (int i = 0; i < n; ++i) add_random_solid(objects, 3.0);
      if (chance(0.5)) objects.push_back(box({uni(-3, 3), 1.0, uni(-3, 3)}, {0.2, 2.0, uni(2, 8)}, uni(-90, 90)));
    } else if (s.kind == "resting-box") {
      const double eps = std::exp(uni(std::log(1e-4), std::log(1e-3)));
      const double sy = uni(0.05, 1.0);
      objects.push_back(box({uni(-1, 1), eps + sy / 2, uni(-1, 1)}, {uni(0.3, 1.5), sy, uni(0.3, 1.5)}, uni(-90, 90)));
      if (chance(0.5)) add_random_solid(objects, 2.5);
      near_surfaces = true;
    } else if (s.kind == "shared-face") {
      const double ax = uni(0.4, 1.2), ay = uni(0.4, 1.5), az = uni(0.4, 1.2), rot = uni(-90, 90);
      const double cx = uni(-1, 1), cz = uni(-1, 1);
      objects.push_back(box({cx, ay / 2, cz}, {ax, ay, az}, rot));
      if (chance(0.5)) {
        // Stacked: the second box's bottom face is the first one's top face.
        const double by = uni(0.2, 1.0);
        objects.push_back(box({cx, ay + by / 2, cz}, {uni(0.2, ax), by, uni(0.2, az)}, rot));
      } else {
        // Side by side along the box's own x axis: they share the face x = ax / 2.
        const double bx = uni(0.2, 1.0), r = rot * M_PI / 180.0;
        const double d = ax / 2 + bx / 2;
        // rotation_y_deg is counter-clockwise seen from +Y: local x (1,0,0) -> (cos r, 0, -sin r).
        const double hb = uni(0.2, ay);
        objects.push_back(box({cx + d * std::cos(r), hb / 2, cz - d * std::sin(r)}, {bx, hb, uni(0.2, az)}, rot));
      }
      near_surfaces = true;
    } else if (s.kind == "hovering-plate") {
      const double gap = std::exp(uni(std::log(1e-3), std::log(0.05)));
      const double thick = uni(0.005, 0.03);
      objects.push_back(box({uni(-1, 1), gap + thick / 2, uni(-1, 1)}, {uni(0.5, 2), thick, uni(0.5, 2)}, uni(-90, 90)));
      if (chance(0.5)) add_random_solid(objects, 2.5);
      near_surfaces = true;
    } else {  // spheres-cylinders
      const int n = 2 + int(uni(0, 6));
      for (int i = 0; i < n; ++i) {
        if (chance(0.5)) {
          const double r = uni(0.1, 0.9);
          objects.push_back(sphere({uni(-3, 3), chance(0.5) ? r : r + uni(0.01, 1.0), uni(-3, 3)}, r));
        } else {
          const double r = chance(0.3) ? uni(0.01, 0.05) : uni(0.1, 0.7), h = uni(0.3, 3.0);
          objects.push_back(cylinder({uni(-3, 3), chance(0.7) ? h / 2 : h / 2 + uni(0.01, 0.5), uni(-3, 3)}, r, h));
        }
      }
    }

    json light;
    if (s.kind == "grazing-sun") {
      // Near sunrise at longitude 0 around an equinox: the sun a few degrees up (or, now and then, just below).
      const int day = 15 + int(uni(0, 12));
      const int month = chance(0.5) ? 3 : 9;
      const int minute = 50 + int(uni(0, 30));  // 05:50..06:19 UTC
      char utc[40];
      std::snprintf(utc, sizeof utc, "2026-%02d-%02dT%02d:%02d:00Z", month, day, 5 + minute / 60, minute % 60);
      light = {{"sun", {{"latitude", uni(-45, 45)}, {"longitude", 0}, {"utc", utc}, {"north_deg", uni(-180, 180)}}}};
    } else {
      const bool point = s.kind != "grazing-directional" && chance(0.5);
      if (point) {
        light = {{"position", {uni(-3, 3), uni(0.8, 5), uni(-3, 3)}}, {"target", {0, 0, 0}},
                 {"projection", "perspective"}};
      } else {
        const double elevation = s.kind == "grazing-directional" ? uni(1, 5) : uni(8, 85);
        const double azimuth = uni(0, 360), e = elevation * M_PI / 180.0, a = azimuth * M_PI / 180.0;
        const double r = 20.0;
        light = {{"position", {r * std::cos(e) * std::cos(a), r * std::sin(e), r * std::cos(e) * std::sin(a)}},
                 {"target", {0, 0, 0}}};
      }
    }
    const double cam_a = uni(0, 2 * M_PI), cam_d = near_surfaces ? uni(1.5, 6) : uni(4, 10);
    json camera = {{"position", {cam_d * std::cos(cam_a), uni(0.3, 6), cam_d * std::sin(cam_a)}},
                   {"target", {uni(-0.5, 0.5), uni(0, 0.5), uni(-0.5, 0.5)}}};
    if (near_surfaces) camera["near"] = 0.01;
    s.body = {{"scene", {{"objects", objects}}}, {"camera", camera}, {"light", light}, {"time", 0},
              {"width", width_}, {"height", height_}};
    return s;
  }

 private:
  double uni(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng_); }
  bool chance(double p) { return uni(0, 1) < p; }
  json colour() { return {uni(0.2, 0.9), uni(0.2, 0.9), uni(0.2, 0.9)}; }
  json box(std::vector<double> c, std::vector<double> size, double rot) {
    return {{"type", "box"}, {"center", c}, {"size", size}, {"rotation_y_deg", rot}, {"color", colour()}};
  }
  json sphere(std::vector<double> c, double r) {
    return {{"type", "sphere"}, {"center", c}, {"radius", r}, {"color", colour()}};
  }
  json cylinder(std::vector<double> c, double r, double h) {
    return {{"type", "cylinder"}, {"center", c}, {"radius", r}, {"height", h}, {"color", colour()}};
  }
  void add_random_solid(json& objects, double spread) {
    const double pick = uni(0, 3);
    if (pick < 1) {
      const double sy = uni(0.2, 2);
      objects.push_back(box({uni(-spread, spread), sy / 2, uni(-spread, spread)}, {uni(0.2, 1.5), sy, uni(0.2, 1.5)},
                            uni(-90, 90)));
    } else if (pick < 2) {
      const double r = uni(0.2, 1);
      objects.push_back(sphere({uni(-spread, spread), r + (chance(0.5) ? 0 : uni(0, 1)), uni(-spread, spread)}, r));
    } else {
      const double h = uni(0.3, 3);
      objects.push_back(cylinder({uni(-spread, spread), h / 2, uni(-spread, spread)}, uni(0.05, 0.6), h));
    }
  }

  std::mt19937_64 rng_;
  int width_, height_;
};

struct RandomResult {
  RandomScene scene;
  std::string error;  // a request that failed
  Compare c;
  double uncertain = NAN;
  std::string sun;
  bool filter_unused = false;  // the server listed shadow.filter as unused (a sun below the horizon)
};

// ---------------------------------------------------------------- report

std::string cell(double v, const char* pattern) { return std::isnan(v) ? "-" : fmt(pattern, v); }

bool parse_size(const std::string& text, int& w, int& h) {
  return std::sscanf(text.c_str(), "%dx%d", &w, &h) == 2 && w > 0 && h > 0;
}

}  // namespace

int main(int argc, char** argv) {
  int frames = 7, random_count = 200, width = 960, height = 540, rwidth = 320, rheight = 180;
  std::uint64_t seed = 1;
  bool sweep = true;
  std::vector<std::string> only;
  std::string server_binary = UMBRA_SERVER_BINARY, out_dir = UMBRA_RESULTS_DIR;
  std::string command_line = "umbra-certified-bench";
  for (int i = 1; i < argc; ++i) command_line += std::string(" ") + argv[i];
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "--frames" && has_value) {
      frames = std::max(1, std::atoi(argv[++i]));
    } else if (arg == "--random" && has_value) {
      random_count = std::max(0, std::atoi(argv[++i]));
    } else if (arg == "--seed" && has_value) {
      seed = std::strtoull(argv[++i], nullptr, 10);
    } else if (arg == "--size" && has_value && parse_size(argv[i + 1], width, height)) {
      ++i;
    } else if (arg == "--random-size" && has_value && parse_size(argv[i + 1], rwidth, rheight)) {
      ++i;
    } else if (arg == "--scene" && has_value) {
      only.push_back(argv[++i]);
    } else if (arg == "--no-sweep") {
      sweep = false;
    } else if (arg == "--server" && has_value) {
      server_binary = argv[++i];
    } else if (arg == "--out" && has_value) {
      out_dir = argv[++i];
    } else {
      std::fprintf(stderr,
                   "usage: umbra-certified-bench [--frames 7] [--random 200] [--seed 1] [--size 960x540] "
                   "[--random-size 320x180] [--scene NAME]... [--no-sweep] [--server PATH] [--out DIR]\n");
      return 2;
    }
  }

  // Generous limits: the full ray cast of a 960x540 frame of a mesh scene may
  // exceed the default cost budget and watchdog on a small machine.
  const std::vector<std::string> server_args = {"--quiet", "--max-request-ms", "3600000", "--max-run-ms", "3600000",
                                                "--deadline-ms", "3600000", "--max-request-mib", "16384"};
  auto server = std::make_unique<umbra::testing::ServerProcess>(server_binary, server_args);
  auto poster = std::make_unique<Poster>(server->port());
  auto health_res = poster->client().Get("/api/health");
  if (!health_res || health_res->status != 200) {
    std::fprintf(stderr, "umbra-certified-bench: the server does not answer /api/health\n");
    return 1;
  }
  const json health = json::parse(health_res->body, nullptr, false);
  const std::string gl = health.is_object() ? health.value("gl_renderer", std::string("?")) + " (" +
                                                  health.value("gl_version", std::string("?")) + ")"
                                            : "?";
  const std::string machine = cpu_model_and_threads() + "; GL: " + gl;
  const std::string when = utc_now();
  // The working tree moves: say which build of the server was measured.
  std::string server_built = "unknown";
  if (struct stat st {}; stat(server_binary.c_str(), &st) == 0) {
    char buffer[32];
    std::strftime(buffer, sizeof buffer, "%Y-%m-%d %H:%M:%S UTC", std::gmtime(&st.st_mtime));
    server_built = buffer;
  }
  std::printf("machine: %s\ncommand: %s\n", machine.c_str(), command_line.c_str());

  // ---- bench scenes
  std::vector<SceneRow> rows;
  const auto started = std::chrono::steady_clock::now();
  std::printf("%-20s %9s %9s %10s %8s %8s %10s %9s %8s %10s %8s\n", "scene", "pcf ms", "exact ms", "raycast ms",
              "ex/pcf", "ex/ray", "uncert %", "diff px", "wrong px", "MAE", "sweep");
  for (const std::string& name : umbra::scene_file_names(UMBRA_SCENES_DIR)) {
    if (!only.empty() && std::find(only.begin(), only.end(), name) == only.end()) continue;
    std::ifstream in(std::string(UMBRA_SCENES_DIR) + "/" + name + ".json");
    std::stringstream text;
    text << in.rdbuf();
    json base = json::parse(text.str(), nullptr, false);
    if (base.is_discarded()) {
      std::fprintf(stderr, "%s: not valid JSON\n", name.c_str());
      continue;
    }
    base["width"] = width;
    base["height"] = height;
    SceneRow row;
    const double size = base.contains("light") ? base["light"].value("size", 0.0) : 0.0;
    if (size > 0.0) {
      row.scene = name;
      row.skipped = "area light (light.size " + fmt("%g", size) + "): filter exact is for size 0 (400)";
    } else {
      row = measure_scene(*poster, name, base, frames, sweep);
    }
    rows.push_back(row);
    if (!row.skipped.empty()) {
      std::printf("%-20s skipped: %s\n", name.c_str(), row.skipped.c_str());
    } else {
      std::printf("%-20s %9.2f %9.2f %10.2f %8.2f %8.3f %10.4f %9ld %8ld %10.2e %8ld\n", name.c_str(), row.pcf_ms,
                  row.exact_ms, row.raycast_ms, row.exact_ms / row.pcf_ms, row.exact_ms / row.raycast_ms,
                  row.uncertain, row.at_own_time.differing, row.at_own_time.wrong, row.at_own_time.mae,
                  row.sweep_worst);
    }
    std::fflush(stdout);
  }
  const double scenes_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();

  // ---- size switch: on a fresh server (whose caches no memory pressure
  // has released), the first random scenes (smaller), each right after a
  // frame at the bench size.
  const auto restart = [&] {
    server->send_signal(SIGTERM);
    server->wait();
    server = std::make_unique<umbra::testing::ServerProcess>(server_binary, server_args);
    poster = std::make_unique<Poster>(server->port());
  };
  const int switch_count = std::min(random_count, 5);
  std::vector<std::pair<RandomScene, Compare>> switched;
  if (switch_count > 0) {
    restart();
    SceneMaker switch_maker(seed, rwidth, rheight);
    for (int i = 0; i < switch_count; ++i) {
      RandomScene sc = switch_maker.make(i);
      if (width == rwidth && height == rheight) break;
      // A frame at the bench size first, so the size changes before each scene.
      poster->post(json{{"scene", "cube-on-plane"}, {"width", width}, {"height", height}, {"output", "shadow"},
                        {"shadow", {{"filter", "exact"}}}});
      const Answer e = poster->post(with(sc.body, "shadow", true, 0.0));
      const Answer x = poster->post(with(sc.body, "exact", false, 0.0));
      Compare c;
      if (e.status == 200 && x.status == 200) c = compare(e.body, x.body);
      else c.error = e.error_text() + " / " + x.error_text();
      std::printf("size switch %dx%d -> %dx%d, random %d: %ld differing px, uncertain %s\n", width, height, rwidth,
                  rheight, i, c.differing, e.certified.c_str());
      switched.emplace_back(sc, c);
    }
  }
  // The random scenes on a fresh server, so that what one server process
  // kept from frames of another size (see the size switch) plays no part.
  restart();

  // ---- random scenes
  std::filesystem::create_directories(out_dir);
  const std::string failures_dir = out_dir + "/certified-failures";
  std::vector<RandomResult> results;
  SceneMaker maker(seed, rwidth, rheight);
  int failing = 0, errors = 0, printed = 0, failing_unused = 0;
  long total_differing = 0, total_wrong = 0, total_pixels = 0;
  double max_mae = 0.0;
  std::map<std::string, std::vector<int>> kind_stats;  // kind -> {scenes, failing, differing px, wrong px}
  if (random_count > 0) std::filesystem::remove_all(failures_dir);
  const auto random_started = std::chrono::steady_clock::now();
  for (int i = 0; i < random_count; ++i) {
    RandomResult r;
    r.scene = maker.make(i);
    const Answer e = poster->post(with(r.scene.body, "shadow", true, 0.0));
    const Answer x = poster->post(with(r.scene.body, "exact", false, 0.0));
    auto& ks = kind_stats[r.scene.kind];
    ks.resize(5);
    ++ks[0];
    if (e.status != 200 || x.status != 200) {
      r.error = e.status != 200 ? "filter exact: " + e.error_text() : "exact output: " + x.error_text();
      ++errors;
      ++ks[4];
      std::fprintf(stderr, "random %d (%s): %s\n  %s\n", i, r.scene.kind.c_str(), r.error.c_str(),
                   r.scene.body.dump().c_str());
      results.push_back(r);
      continue;
    }
    r.c = compare(e.body, x.body);
    r.uncertain = e.uncertain_percent();
    r.sun = e.sun;
    r.filter_unused = e.unused.find("shadow.filter") != std::string::npos;
    total_differing += r.c.differing;
    total_wrong += r.c.wrong;
    total_pixels += r.c.pixels;
    max_mae = std::max(max_mae, r.c.mae);
    ks[2] += int(r.c.differing);
    ks[3] += int(r.c.wrong);
    if (r.c.differing > 0 || !r.c.error.empty()) {
      ++failing;
      ++ks[1];
      if (r.filter_unused) ++failing_unused;
      std::filesystem::create_directories(failures_dir);
      json saved = r.scene.body;
      saved["output"] = "shadow";
      saved["shadow"]["filter"] = "exact";
      std::ofstream(failures_dir + "/random-" + std::to_string(i) + ".json") << saved.dump(2) << "\n";
      if (printed < 5) {
        ++printed;
        std::fprintf(stderr, "FAIL random %d (%s): %ld differing px, %ld wrong, MAE %.3g %s\n  %s\n", i,
                     r.scene.kind.c_str(), r.c.differing, r.c.wrong, r.c.mae, r.c.error.c_str(), saved.dump().c_str());
      }
    }
    results.push_back(r);
    if ((i + 1) % 20 == 0) {
      std::printf("random: %d/%d scenes, %d with differing pixels, %d errors\n", i + 1, random_count, failing, errors);
      std::fflush(stdout);
    }
  }
  // The grazing suns' elevations, from Umbra-Sun.
  double sun_min = 1e9, sun_max = -1e9;
  int suns = 0, suns_down = 0;
  for (const RandomResult& r : results) {
    const std::size_t at = r.sun.find("elevation_deg=");
    if (at == std::string::npos) continue;
    const double e = std::atof(r.sun.c_str() + at + 14);
    ++suns;
    if (e <= 0) ++suns_down;
    sun_min = std::min(sun_min, e);
    sun_max = std::max(sun_max, e);
  }
  const double random_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - random_started).count();

  // ---- report
  std::ostringstream md;
  md << "# Filter \"exact\": certified hard shadows against PCF and the full ray cast\n\n"
     << "Written by `umbra-certified-bench` (" << when << ").\n\n"
     << "- Machine: " << machine << "\n"
     << "- Command: `" << command_line << "`\n"
     << "- Server: `" << server_binary << "` started by the benchmark on loopback (`--quiet`, cost budget, "
        "watchdog and deadline raised to 1 h so that no full ray cast is refused), one client, one request at a time; "
        "started afresh for the size switch and for the random scenes; binary built " << server_built << ".\n"
     << "- Scenes: `bench/scenes/*.json` at " << width << "x" << height << ", each with its own settings. Per "
        "scene one warm-up round at the scene's own time, then " << frames << " rounds, round i at the scene's time "
        "+ i x " << kTimeStep << " s (the light orbits, so every frame redraws its maps); each round posts the "
        "scene as it is (default filter, pcf) with output `shadow`, the same with `\"shadow\": {\"filter\": "
        "\"exact\"}` with output `shadow`, and output `exact`. Times are the medians, from `Server-Timing`: pcf ms "
        "= shadow + main + readback; exact ms = shadow + main + readback + settle (settle: the CPU ray cast of the "
        "pixels the maps left uncertain; its median on its own is the settle column, and so are the other stages': "
        "shadow holds the maps, main the main pass, readback the read-back and, where the CPU finds them, the sliver "
        "marks); raycast ms = the `exact` output's raycast stage (the full CPU ray cast). "
        "uncertain % = median share of pixels ray cast, and path how the server certified the frames (maps, proofs: "
        "no maps, the floor's proofs and the rest ray cast, ray-cast: every pixel), from `Umbra-Certified`.\n"
     << "- Accuracy: filter exact's `shadow` PNG against the `exact` PNG (decoded, 8-bit grey) at the scene's own "
        "time: diff px = pixels that differ at all, wrong px = off by more than 127, MAE = mean |a - b| / 255 over "
        "all pixels. Sweep = the most differing pixels over " << umbra::kOrbitSweepTimes << " light angles t = k x "
     << umbra::kOrbitTurnSeconds << " / " << umbra::kOrbitSweepTimes << " s, k = 0.." << umbra::kOrbitSweepTimes - 1
     << " (" << (sweep ? "measured" : "not measured: --no-sweep") << ").\n"
     << "- The machine is shared and noisy: the times are indicative.\n\n"
     << "| scene | pcf ms | exact-filter ms | of which settle ms | exact stages ms: shadow / main / readback | raycast ms | "
        "exact/pcf | exact/raycast | path | uncertain % | differing px | wrong px | MAE | sweep worst differing px |\n"
     << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const SceneRow& r : rows) {
    if (!r.skipped.empty()) {
      md << "| " << r.scene << " | skipped: " << r.skipped << " | | | | | | | | | | | | |\n";
      continue;
    }
    md << "| " << r.scene << " | " << cell(r.pcf_ms, "%.2f") << " | " << cell(r.exact_ms, "%.2f") << " | " << cell(r.settle_ms, "%.2f") << " | "
       << cell(r.exact_shadow_ms, "%.1f") << " / " << cell(r.exact_main_ms, "%.1f") << " / " << cell(r.exact_readback_ms, "%.1f") << " | "
       << cell(r.raycast_ms, "%.2f") << " | " << cell(r.exact_ms / r.pcf_ms, "%.2f") << " | "
       << cell(r.exact_ms / r.raycast_ms, "%.3f") << " | " << r.path << " | " << cell(r.uncertain, "%.4f") << " | "
       << r.at_own_time.differing << " | " << r.at_own_time.wrong << " | " << fmt("%.2e", r.at_own_time.mae) << " | "
       << (r.sweep_worst < 0 ? std::string("-")
                             : std::to_string(r.sweep_worst) + (r.sweep_worst > 0 ? " (t=" + fmt("%.0f", r.sweep_worst_time) + " s)" : ""))
       << " |\n";
  }
  md << "\nBench scenes took " << fmt("%.0f", scenes_s) << " s.\n\n";
  md << "## Random hard scenes\n\n"
     << random_count << " scenes, seed " << seed << ", " << rwidth << "x" << rheight << ", time 0 (generator in "
     << "`bench/certified_bench.cpp`, reproducible with the same seed): thin needles (boxes with one side "
        "0.002..0.02 wide, 1..4 tall), grazing suns (`light.sun` near sunrise at longitude 0 around an equinox), "
        "grazing directional lights (1..5 degrees above the horizon), boxes resting 1e-4..1e-3 above the floor, "
        "two boxes sharing a face (stacked or side by side), plates hovering 1e-3..0.05 above the floor, spheres "
        "and cylinders (resting or floating, thin poles included); point lights (`perspective`) and directional "
        "lights at random. Each: filter exact's `shadow` output against the `exact` output, pixel for pixel.\n\n"
     << "- scenes with any differing pixel: " << failing << " of " << (random_count - errors) << " answered"
     << (errors ? " (" + std::to_string(errors) + " requests failed)" : std::string())
     << (failing_unused ? "; " + std::to_string(failing_unused) +
                              " of them with the filter unused (sun below the horizon: `Umbra-Unused-Fields: "
                              "shadow.filter`, no maps, nothing certified)"
                        : std::string())
     << "\n"
     << "- differing pixels in all: " << total_differing << " of " << total_pixels << "\n"
     << "- wrong pixels (off by more than 127) in all: " << total_wrong << "\n"
     << "- largest MAE of a scene: " << fmt("%.3e", max_mae) << "\n"
     << "- sun scenes: " << suns << ", elevation " << (suns ? fmt("%.1f", sun_min) + ".." + fmt("%.1f", sun_max) : "-")
     << " degrees (" << suns_down << " with the sun down: ambient only: certified without a map, every surface dark and the outlines ray cast)\n"
     << "- took " << fmt("%.0f", random_s) << " s\n\n"
     << "| kind | scenes | with differing px | differing px | wrong px | failed requests |\n|---|---|---|---|---|---|\n";
  for (const auto& [kind, s] : kind_stats)
    md << "| " << kind << " | " << s[0] << " | " << s[1] << " | " << s[2] << " | " << s[3] << " | " << s[4] << " |\n";
  if (!switched.empty()) {
    md << "\n### Size switch\n\nThe first " << switched.size() << " random scenes (" << rwidth << "x" << rheight
       << "), each right after a filter-exact frame of `cube-on-plane` at " << width << "x" << height
       << ", on a server of their own, started afresh (the random scenes above ran on another fresh server, at one "
          "size throughout):\n\n| random scene | kind | differing px | wrong px | MAE |\n|---|---|---|---|---|\n";
    for (const auto& [sc, c] : switched)
      md << "| " << sc.index << " | " << sc.kind << " | " << c.differing << " | " << c.wrong << " | "
         << fmt("%.2e", c.mae) << (c.error.empty() ? "" : " (" + c.error + ")") << " |\n";
  }
  int listed = 0;
  for (const RandomResult& r : results) {
    if (r.error.empty() && r.c.differing == 0 && r.c.error.empty()) continue;
    if (listed == 0) md << "\nFailing scenes (all in `certified-failures/`; first 10 here):\n\n";
    if (++listed > 10) break;
    md << "- random " << r.scene.index << " (" << r.scene.kind << "): "
       << (r.error.empty() ? std::to_string(r.c.differing) + " differing px, " + std::to_string(r.c.wrong) +
                                 " wrong, " +
                                 (r.uncertain >= 0 ? "uncertain " + fmt("%.4f", r.uncertain) + " %"
                                                   : std::string("no Umbra-Certified header")) +
                                 (r.filter_unused ? ", filter unused (" + r.sun + ")" : std::string())
                           : r.error)
       << "\n  `" << r.scene.body.dump() << "`\n";
  }

  json j = {{"machine", machine}, {"date", when}, {"command", command_line}, {"frames", frames},
            {"time_step_s", kTimeStep}, {"size", {width, height}}, {"rows", json::array()}};
  for (const SceneRow& r : rows) {
    json row = {{"scene", r.scene}};
    if (!r.skipped.empty()) {
      row["skipped"] = r.skipped;
    } else {
      row.update({{"pcf_ms", r.pcf_ms}, {"exact_filter_ms", r.exact_ms}, {"settle_ms", r.settle_ms},
                  {"exact_shadow_ms", r.exact_shadow_ms}, {"exact_main_ms", r.exact_main_ms},
                  {"exact_readback_ms", r.exact_readback_ms},
                  {"raycast_ms", r.raycast_ms}, {"uncertain_percent", r.uncertain}, {"path", r.path},
                  {"differing_px", r.at_own_time.differing}, {"wrong_px", r.at_own_time.wrong},
                  {"mae", r.at_own_time.mae}, {"pixels", r.at_own_time.pixels},
                  {"png_bytes_equal", r.at_own_time.bytes_equal}, {"sweep_worst_differing_px", r.sweep_worst},
                  {"sweep_worst_time_s", r.sweep_worst_time}, {"sweep_worst_wrong_px", r.sweep_wrong_worst}});
    }
    j["rows"].push_back(row);
  }
  json random = {{"count", random_count}, {"seed", seed}, {"size", {rwidth, rheight}}, {"failing", failing},
                 {"failed_requests", errors}, {"differing_px", total_differing}, {"wrong_px", total_wrong},
                 {"pixels", total_pixels}, {"max_mae", max_mae}, {"failures", json::array()}};
  for (const RandomResult& r : results)
    if (!r.error.empty() || r.c.differing > 0)
      random["failures"].push_back({{"index", r.scene.index}, {"kind", r.scene.kind}, {"differing_px", r.c.differing},
                                    {"wrong_px", r.c.wrong}, {"mae", r.c.mae}, {"error", r.error},
                                    {"filter_unused", r.filter_unused}, {"sun", r.sun}, {"uncertain_percent", r.uncertain},
                                    {"body", r.scene.body}});
  random["size_switch"] = json::array();
  for (const auto& [sc, c] : switched)
    random["size_switch"].push_back({{"index", sc.index}, {"kind", sc.kind}, {"differing_px", c.differing},
                                     {"wrong_px", c.wrong}, {"mae", c.mae}});
  j["random"] = random;

  std::printf("\n%s", md.str().c_str());
  std::ofstream(out_dir + "/certified.md") << md.str();
  std::ofstream(out_dir + "/certified.json") << j.dump(2) << "\n";
  std::printf("wrote %s/certified.md\n", out_dir.c_str());
  server->send_signal(SIGTERM);
  server->wait();
  return 0;
}
