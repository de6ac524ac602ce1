// umbra-bench --speed: what Umbra's accuracy costs in frame time.
//
// For every scene and image size, Umbra at its defaults (the scene file's
// request, only the size changed) and the plain frame (the seeds' algorithm,
// bench/plain_frame.hpp) on the same scene, size and map size, in one run:
//
// - speed: --frames frames each, interleaved (plain i, Umbra i, plain i+1,
//   ...) so that machine noise hits both alike, after one warm-up frame of
//   each. Frame i is at the scene's time + (i + 1) * kTimeStep, so the light
//   moves and every frame draws its shadow map. Time per frame = shadow +
//   main pass + read-back from each renderer's own FrameTimings;
// - accuracy: the shadow output of both at the scene's own time against the
//   exact ray-cast reference (renderer/reference/shadow_error.hpp).
//
// Prints a table as it goes and writes STEM.md and STEM.json under --out.
#include "speed_bench.hpp"

#include <malloc.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <iterator>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench_report.hpp"
#include "plain_frame.hpp"
#include "reference/ray_cast.hpp"
#include "service/render_service.hpp"
#include "scene_files.hpp"
#include "reference/shadow_error.hpp"

namespace umbra::bench {

namespace {

using nlohmann::json;

// Seconds of animation between measured frames: the default orbit (20
// degrees per second) turns the light 7.4 degrees per frame.
constexpr double kTimeStep = 0.37;
// glibc's malloc: blocks of at least kMmapThreshold bytes are mapped afresh
// and unmapped when freed, and free memory at the heap's top past
// kTrimThreshold is given back. Left alone, glibc raises both as large
// blocks are freed, so llvmpipe's per-draw scratch (tens of megabytes for
// a 100k-triangle mesh) is page-faulted in anew each frame or not,
// depending on what ran before: the plain teapot's frame took 133 ms
// before an orbit sweep had run and 35 ms after it. Fixed at the values
// glibc's own rule ends at, both renderers' frames cost the same whatever
// the run's history.
constexpr int kMmapThreshold = 32 << 20;
constexpr int kTrimThreshold = 2 * kMmapThreshold;
// The scene whose stage times the summary quotes.
constexpr const char* kDefaultScene = "seeds";

struct ImageSize {
  int width = 0, height = 0;
  std::string label() const { return std::to_string(width) + "x" + std::to_string(height); }
};

struct SpeedOptions {
  std::string scenes_dir = UMBRA_SCENES_DIR;
  std::string out_dir = UMBRA_RESULTS_DIR;
  std::string name = "speed";
  int frames = 15;
  // Light angles of the orbit sweep (orbit_sweep_time); 0: no sweep.
  int sweep = kOrbitSweepTimes;
  std::vector<ImageSize> sizes = {{640, 360}, {960, 540}};
  std::vector<std::string> only_scenes;  // empty: all
  std::string command_line;
};

// The error measures every report shows, for plain and Umbra alike. One
// line per measure: the stdout summary, the Markdown accuracy tables and the
// JSON all take their columns from here.
struct ErrorColumn {
  const char* key;     // JSON field
  const char* header;  // Markdown column (after "plain " / "Umbra ")
  double (*value)(const ShadowError&);
  std::string (*text)(double);
};
std::string mae_text(double v) { return format("%.5f", v); }
const ErrorColumn kErrorColumns[] = {
    {"mae", "MAE", [](const ShadowError& e) { return e.mae; }, mae_text},
    {"wrong", "wrong %", [](const ShadowError& e) { return e.wrong; }, percent},
    {"false_shadow", "false shadow %", [](const ShadowError& e) { return e.false_shadow; }, percent},
    {"false_light", "false light %", [](const ShadowError& e) { return e.false_light; }, percent},
    {"artifacts", "artifacts %", [](const ShadowError& e) { return e.artifacts; }, percent},
};

// One renderer on one scene at one size: medians over the measured frames
// (each stage's median on its own, so the three need not add up to the
// total's) and the error of its shadow output.
struct Measured {
  double total_ms = 0.0, shadow_ms = 0.0, main_ms = 0.0, readback_ms = 0.0;
  ShadowError error;

  // "shadow+main+readback", e.g. "1.5+3.6+0.2".
  std::string breakdown() const {
    return format("%.1f", shadow_ms) + "+" + format("%.1f", main_ms) + "+" + format("%.1f", readback_ms);
  }
  // "wrong % / MAE", e.g. "0.125 / 0.00310".
  std::string wrong_and_mae() const { return percent(error.wrong) + " / " + mae_text(error.mae); }

  json to_json() const {
    json j = {{"median_ms", total_ms}, {"shadow_ms", shadow_ms}, {"main_ms", main_ms}, {"readback_ms", readback_ms},
              {"pixels", error.pixels}};
    for (const ErrorColumn& c : kErrorColumns) j[c.key] = c.value(error);
    return j;
  }
};

// Frame timings gathered over the measured frames.
struct FrameSeries {
  std::vector<double> total, shadow, main, readback;

  void add(const FrameTimings& t) {
    total.push_back(t.shadow_ms + t.main_ms + t.readback_ms);
    shadow.push_back(t.shadow_ms);
    main.push_back(t.main_ms);
    readback.push_back(t.readback_ms);
  }
  void fill(Measured& m) const {
    m.total_ms = median(total);
    m.shadow_ms = median(shadow);
    m.main_ms = median(main);
    m.readback_ms = median(readback);
  }
};

struct SpeedRow {
  ImageSize size;
  std::string scene;
  Measured plain, umbra;
  std::string views;         // Umbra's shadow layout (RenderResult::shadow_views)
  int umbra_remeasured = 0;  // frames measured again because Umbra had reused its map
  // The orbit sweep: the worst artifact share of each over the swept
  // times, and the time it was seen at.
  double plain_sweep_artifacts = 0.0, umbra_sweep_artifacts = 0.0;
  double plain_sweep_worst_time = 0.0, umbra_sweep_worst_time = 0.0;

  double ratio() const { return plain.total_ms > 0.0 ? umbra.total_ms / plain.total_ms : 0.0; }
};

SpeedRow measure_scene(RenderService& service, PlainFrameRenderer& plain, const SpeedOptions& options,
                       const std::string& scene, ImageSize size) {
  SpeedRow row;
  row.size = size;
  row.scene = scene;
  const RenderRequest base =
      load_scene_request(options.scenes_dir, scene, {{"width", size.width}, {"height", size.height}});

  // Accuracy, at the scene's own time.
  const ExactView view(base);
  const std::vector<ExactPixel> exact = view.pixels();
  RenderRequest shadow_request = base;
  shadow_request.output = Output::Shadow;
  const RenderResult umbra_shadow = service.submit(shadow_request).get();
  const PixelCoverageOf finer = view.coverage_of();
  row.umbra.error = measure_shadow_error(umbra_shadow.image, exact, finer);
  row.views = umbra_shadow.shadow_views;
  row.plain.error = measure_shadow_error(plain.render(base, true).image, exact, finer);

  // Artifacts over the light's orbit: a seam or speckle that shows at some
  // moments of the panel's Play and not at the scene's own time.
  for (int k = 0; k < options.sweep; ++k) {
    RenderRequest moment = shadow_request;
    moment.time = orbit_sweep_time(k, options.sweep);
    const ExactView view_then(moment);
    const std::vector<ExactPixel> exact_then = view_then.pixels();
    const PixelCoverageOf finer_then = view_then.coverage_of();
    const double umbra_artifacts =
        measure_shadow_error(service.submit(moment).get().image, exact_then, finer_then).artifacts;
    const double plain_artifacts = measure_shadow_error(plain.render(moment, true).image, exact_then, finer_then).artifacts;
    if (umbra_artifacts > row.umbra_sweep_artifacts)
      row.umbra_sweep_artifacts = umbra_artifacts, row.umbra_sweep_worst_time = moment.time;
    if (plain_artifacts > row.plain_sweep_artifacts)
      row.plain_sweep_artifacts = plain_artifacts, row.plain_sweep_worst_time = moment.time;
  }

  // Speed: one warm-up frame each, then interleaved frames with the light moving.
  plain.render(base, false);
  service.submit(base).get();
  FrameSeries plain_frames, umbra_frames;
  RenderRequest request = base;
  for (int i = 0; i < options.frames; ++i) {
    request.time = base.time + (i + 1) * kTimeStep;
    plain_frames.add(plain.render(request, false).timings);
    umbra_frames.add(frame_with_shadow_pass(service, request, row.umbra_remeasured).timings);
  }
  plain_frames.fill(row.plain);
  umbra_frames.fill(row.umbra);
  return row;
}

// ---------------------------------------------------------------------------
// Reports.

struct SizeSummary {
  ImageSize size;
  double max_ratio = 0.0, median_ratio = 0.0;
  std::string max_ratio_scene;
  const SpeedRow* default_scene = nullptr;  // kDefaultScene's row, if it was measured
};

SizeSummary summarise(const std::vector<SpeedRow>& rows, ImageSize size) {
  SizeSummary s;
  s.size = size;
  std::vector<double> ratios;
  for (const SpeedRow& r : rows) {
    if (r.size.width != size.width || r.size.height != size.height) continue;
    ratios.push_back(r.ratio());
    if (r.ratio() >= s.max_ratio) s.max_ratio = r.ratio(), s.max_ratio_scene = r.scene;
    if (r.scene == kDefaultScene) s.default_scene = &r;
  }
  s.median_ratio = median(ratios);
  return s;
}

std::string summary_line(const SizeSummary& s) {
  std::string line = "max ratio " + format("%.2f", s.max_ratio) + " (" + s.max_ratio_scene + "), median ratio " +
                     format("%.2f", s.median_ratio);
  if (s.default_scene != nullptr) {
    const Measured& u = s.default_scene->umbra;
    const Measured& p = s.default_scene->plain;
    line += std::string("; ") + kDefaultScene + ": Umbra shadow " + format("%.2f", u.shadow_ms) + " + main " +
            format("%.2f", u.main_ms) + " + read-back " + format("%.2f", u.readback_ms) + " ms (plain " +
            format("%.2f", p.shadow_ms) + " + " + format("%.2f", p.main_ms) + " + " + format("%.2f", p.readback_ms) +
            ")";
  }
  return line;
}

constexpr const char* kRowPattern = "%-20s %9s %9s %6s %-15s %-15s %-19s %-19s %-10s %s\n";

void print_header(ImageSize size) {
  std::printf("\n%s\n", size.label().c_str());
  std::printf(kRowPattern, "scene", "plain ms", "Umbra ms", "ratio", "plain s+m+r", "Umbra s+m+r", "plain wrong%/MAE",
              "Umbra wrong%/MAE", "Umbra sweep", "Umbra views");
}

void print_row(const SpeedRow& r) {
  std::printf(kRowPattern, r.scene.c_str(), format("%.2f", r.plain.total_ms).c_str(),
              format("%.2f", r.umbra.total_ms).c_str(), format("%.2f", r.ratio()).c_str(),
              r.plain.breakdown().c_str(), r.umbra.breakdown().c_str(), r.plain.wrong_and_mae().c_str(),
              r.umbra.wrong_and_mae().c_str(), percent(r.umbra_sweep_artifacts).c_str(), r.views.c_str());
  std::fflush(stdout);
}

void write_reports(const std::vector<SpeedRow>& rows, const SpeedOptions& options, const std::string& machine,
                   const std::string& when) {
  std::filesystem::create_directories(options.out_dir);
  const std::string stem = options.out_dir + "/" + options.name;

  json j = {{"machine", machine}, {"date", when}, {"command", options.command_line}, {"frames", options.frames},
            {"time_step_s", kTimeStep}, {"sizes", json::array()}, {"rows", json::array()}, {"summary", json::array()}};
  for (const ImageSize& size : options.sizes) j["sizes"].push_back({size.width, size.height});
  j["sweep_times"] = options.sweep;
  for (const SpeedRow& r : rows)
    j["rows"].push_back({{"size", {r.size.width, r.size.height}}, {"scene", r.scene}, {"ratio", r.ratio()},
                         {"views", r.views}, {"umbra_remeasured_frames", r.umbra_remeasured},
                         {"sweep", {{"plain_max_artifacts", r.plain_sweep_artifacts},
                                    {"plain_worst_time_s", r.plain_sweep_worst_time},
                                    {"umbra_max_artifacts", r.umbra_sweep_artifacts},
                                    {"umbra_worst_time_s", r.umbra_sweep_worst_time}}},
                         {"plain", r.plain.to_json()}, {"umbra", r.umbra.to_json()}});

  std::ostringstream md;
  md << "# Umbra against the plain frame: speed and accuracy\n\n"
     << "Written by `umbra-bench --speed` (" << when << ").\n\n"
     << "- Machine: " << machine << "\n"
     << "- Command: `" << options.command_line << "`\n"
     << "- Plain: the seeds' algorithm written plainly (`bench/plain_frame.cpp`): one map_size^2 depth map, one "
        "light box holding the scene's bounds (a 90 degree cone for a point light), front faces of closed meshes "
        "culled in the map and back faces in the main pass, bias max(0.05 (1 - N.L), 0.005), 3x3 PCF; it ignores light.size. Umbra: the scene file's request "
        "at its defaults, only the image size changed. Both at the request's map size.\n"
     << "- Time: median of " << options.frames << " frames each, after one warm-up frame each, plain and Umbra "
     << "frames interleaved; frame i at the scene's time + (i + 1) x " << kTimeStep << " s, so the light moves and "
     << "every frame draws its shadow map; malloc's mmap and trim thresholds fixed at " << (kMmapThreshold >> 20)
     << " and " << (kTrimThreshold >> 20) << " MiB, so that no frame's cost depends on what the run allocated before. ms = shadow + main pass + read-back from each renderer's own timings "
        "(wall clock with glFinish); s+m+r = the median of each stage on its own. ratio = Umbra ms / plain ms.\n"
     << "- Error: the shadow output at the scene's own time against the exact ray-cast reference "
        "(`renderer/reference/shadow_error.hpp`); wrong = share of measured pixels with |v - v_exact| > 0.5; artifacts = "
        "share of interior pixels (exactly lit or dark, over 3 px from any shadow edge, silhouette or crease, "
        "an edge between pixel centres included: 4 x 4 samples per pixel around each candidate) off by more than "
        "0.1.\n"
     << "- Orbit sweep: the artifacts of the shadow output at " << options.sweep << " light angles spread evenly "
     << "over one turn of the default orbit (t = k x " << kOrbitTurnSeconds << " / " << options.sweep
     << " s), each against its own exact reference; the worst time of each (- where every angle had none).\n";
  std::string remeasured;
  for (const SpeedRow& r : rows)
    if (r.umbra_remeasured > 0)
      remeasured += (remeasured.empty() ? "" : ", ") + r.scene + " " + r.size.label() + " (" +
                    std::to_string(r.umbra_remeasured) + ")";
  if (!remeasured.empty())
    md << "- Frames where orbiting did not move the light, so Umbra kept its map; each was measured again after "
          "an untimed frame that made the map stale: "
       << remeasured << ".\n";

  for (const ImageSize& size : options.sizes) {
    const SizeSummary s = summarise(rows, size);
    json summary = {{"size", {size.width, size.height}}, {"max_ratio", s.max_ratio},
                    {"max_ratio_scene", s.max_ratio_scene}, {"median_ratio", s.median_ratio}};
    if (s.default_scene != nullptr)
      summary[kDefaultScene] = {{"plain", s.default_scene->plain.to_json()},
                                {"umbra", s.default_scene->umbra.to_json()}};
    j["summary"].push_back(summary);

    md << "\n## " << size.label() << "\n\n"
       << "| scene | plain ms | Umbra ms | ratio | plain s+m+r ms | Umbra s+m+r ms | plain wrong % / MAE | "
          "Umbra wrong % / MAE | Umbra views |\n|---|---|---|---|---|---|---|---|---|\n";
    for (const SpeedRow& r : rows) {
      if (r.size.width != size.width || r.size.height != size.height) continue;
      md << "| " << r.scene << " | " << format("%.2f", r.plain.total_ms) << " | " << format("%.2f", r.umbra.total_ms)
         << " | " << format("%.2f", r.ratio()) << " | " << r.plain.breakdown() << " | " << r.umbra.breakdown()
         << " | " << r.plain.wrong_and_mae() << " | " << r.umbra.wrong_and_mae() << " | " << r.views << " |\n";
    }
    md << "\nSummary: " << summary_line(s) << ".\n";

    md << "\n### Accuracy, " << size.label() << "\n\n| scene |";
    for (const char* who : {"plain", "Umbra"})
      for (const ErrorColumn& c : kErrorColumns) md << " " << who << " " << c.header << " |";
    md << "\n|---|";
    for (std::size_t i = 0; i < 2 * std::size(kErrorColumns); ++i) md << "---|";
    md << "\n";
    for (const SpeedRow& r : rows) {
      if (r.size.width != size.width || r.size.height != size.height) continue;
      md << "| " << r.scene << " |";
      for (const ShadowError* e : {&r.plain.error, &r.umbra.error})
        for (const ErrorColumn& c : kErrorColumns) md << " " << c.text(c.value(*e)) << " |";
      md << "\n";
    }

    if (options.sweep > 0) {
      md << "\n### Orbit sweep, " << size.label() << "\n\n| scene | plain worst artifacts % (at s) | "
            "Umbra worst artifacts % (at s) |\n|---|---|---|\n";
      for (const SpeedRow& r : rows) {
        if (r.size.width != size.width || r.size.height != size.height) continue;
        const auto worst = [](double share, double time) {
          return percent(share) + " (" + (share > 0.0 ? format("%.2f", time) : std::string("-")) + ")";
        };
        md << "| " << r.scene << " | " << worst(r.plain_sweep_artifacts, r.plain_sweep_worst_time) << " | "
           << worst(r.umbra_sweep_artifacts, r.umbra_sweep_worst_time) << " |\n";
      }
    }
  }

  write_file(stem + ".json", j.dump(1) + "\n");
  write_file(stem + ".md", md.str());
  std::printf("\nwrote %s.md, %s.json\n", stem.c_str(), stem.c_str());
}

// ---------------------------------------------------------------------------

std::vector<ImageSize> parse_sizes(const std::string& text) {
  std::vector<ImageSize> sizes;
  std::stringstream in(text);
  for (std::string item; std::getline(in, item, ',');) {
    const auto x = item.find('x');
    if (x == std::string::npos) throw std::runtime_error("--sizes is WxH[,WxH...], e.g. 640x360,960x540");
    sizes.push_back({std::stoi(item.substr(0, x)), std::stoi(item.substr(x + 1))});
  }
  if (sizes.empty()) throw std::runtime_error("--sizes names no size");
  return sizes;
}

void usage() {
  std::cout << "usage: umbra-bench --speed [--frames N] [--sizes WxH,WxH...] [--sweep T] [--scene NAME]...\n"
               "                   [--scenes DIR] [--out DIR] [--name STEM]\n"
               "Umbra at its defaults against the plain frame (the seeds' algorithm) on every scene in\n"
               "--scenes (default: the source tree's bench/scenes) at each size (default 640x360,960x540):\n"
               "median frame time over N frames (default 15) with the light moving, and the error of\n"
               "the shadow output against the exact reference, and its artifacts at T times (default 9)\n"
               "over one turn of the light's orbit. Writes STEM.md and STEM.json (default\n"
               "STEM: speed) under --out (default: the source tree's bench/results).\n";
}

}  // namespace

int run_speed(int argc, char** argv) {
  SpeedOptions options;
  options.command_line = "umbra-bench";
  for (int i = 1; i < argc; ++i) options.command_line += std::string(" ") + argv[i];
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw std::runtime_error(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--speed") continue;
    if (arg == "--frames") options.frames = std::max(1, std::stoi(value()));
    else if (arg == "--sizes") options.sizes = parse_sizes(value());
    else if (arg == "--sweep") options.sweep = std::max(0, std::stoi(value()));
    else if (arg == "--scene") options.only_scenes.push_back(value());
    else if (arg == "--scenes") options.scenes_dir = value();
    else if (arg == "--out") options.out_dir = value();
    else if (arg == "--name") options.name = value();
    else if (arg == "--help" || arg == "-h") return usage(), 0;
    else throw std::runtime_error("unknown option for --speed: " + arg + " (see --speed --help)");
  }
  const std::vector<std::string> scenes =
      options.only_scenes.empty() ? scene_file_names(options.scenes_dir) : options.only_scenes;

  mallopt(M_MMAP_THRESHOLD, kMmapThreshold);
  mallopt(M_TRIM_THRESHOLD, kTrimThreshold);
  RenderService service;
  // On this (the main) thread, with its own context beside the service's.
  PlainFrameRenderer plain;
  const std::string machine = machine_description(service);
  const std::string when = utc_now();
  std::vector<SpeedRow> rows;
  for (const ImageSize& size : options.sizes) {
    print_header(size);
    for (const std::string& scene : scenes) {
      rows.push_back(measure_scene(service, plain, options, scene, size));
      print_row(rows.back());
    }
    std::printf("summary: %s\n", summary_line(summarise(rows, size)).c_str());
  }
  write_reports(rows, options, machine, when);
  return 0;
}

}  // namespace umbra::bench
