// umbra-bench: speed against error, measured, for every hard-case scene in
// bench/scenes/ and a grid of shadow techniques.
//
// For each scene and technique it renders the "shadow" output once and
// measures it against the exact ray-cast reference (renderer/shadow_error),
// then renders the "color" output `--frames` times, the light moving 0.37 s
// of orbit per frame (so a frame reuses no shadow map unless orbiting does
// not move its light: such a frame is measured again after one that makes
// the map stale), and takes the median of the GL time per frame
// (shadow + main pass + read-back; PNG encoding is not part of rendering and
// is excluded). Everything in one table comes from one
// run on one machine. Writes Markdown, JSON and an SVG of error against time
// (the Pareto front) under --out.
//
// With --speed it runs the other mode instead: Umbra's frame time against
// the plain frame's (speed_bench.cpp).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench_report.hpp"
#include "reference/ray_cast.hpp"
#include "service/render_service.hpp"
#include "scene_files.hpp"
#include "reference/shadow_error.hpp"
#include "speed_bench.hpp"

namespace umbra {
namespace {

using nlohmann::json;
using bench::format;
using bench::frame_with_shadow_pass;
using bench::machine_description;
using bench::median;
using bench::parse_int_list;
using bench::percent;
using bench::utc_now;
using bench::write_file;

struct Options {
  std::string scenes_dir = UMBRA_SCENES_DIR;
  std::string out_dir = UMBRA_RESULTS_DIR;
  std::string name = "shadow-accuracy";
  int frames = 10;
  int width = 960, height = 540;
  std::vector<int> map_sizes = {512, 1024, 2048, 4096, 8192};
  std::vector<std::string> only_scenes;  // empty: all
  std::string from_json;                 // rewrite the reports of a saved run
};

// One shadow technique: the settings that vary across the grid.
struct Technique {
  std::string fit;     // "scene" | "fixed"
  std::string filter;  // "hard" | "pcf" | "pcss"
  int pcf_radius = 1;
  int map_size = 2048;

  std::string label() const {
    std::string f = filter == "pcf" ? "pcf r" + std::to_string(pcf_radius) : filter;
    return (fit == "fixed" ? "seeds-fixed " : "scene ") + f + " " + std::to_string(map_size);
  }
  std::string filter_label() const { return filter == "pcf" ? "pcf r" + std::to_string(pcf_radius) : filter; }
  // The seeds' exact configuration: fixed frustum, their bias, 1024, 3x3 PCF.
  bool is_seeds() const { return fit == "fixed" && map_size == 1024 && filter == "pcf" && pcf_radius == 1; }

  json overrides(bool perspective) const {
    json shadow = {{"map_size", map_size}, {"filter", filter}};
    if (filter == "pcf") shadow["pcf_radius"] = pcf_radius;
    if (fit == "fixed") {
      // The seeds: glm::ortho(-10, 10, -10, 10, 1, 7.5) (or a 90 degree
      // perspective with the same planes) and max(0.05 (1 - N.L), 0.005).
      shadow["fit"] = "fixed";
      shadow["near"] = 1.0;
      shadow["far"] = 7.5;
      if (!perspective) shadow["ortho_half_size"] = 10.0;
      shadow["bias"] = {{"constant", 0.005}, {"slope", 0.05}};
    }
    json o = {{"shadow", shadow}};
    if (fit == "fixed" && perspective) o["light"] = {{"fov_y_deg", 90.0}};
    return o;
  }
};

struct Row {
  std::string scene;
  Technique technique;
  std::string views;
  double median_ms = 0.0, median_shadow_ms = 0.0;
  ShadowError error;
  int remeasured = 0;  // frames measured again because the map had been kept (see frame_with_shadow_pass)
};

std::vector<Technique> techniques_for(const RenderRequest& base, const Options& options) {
  // An ideal light (size 0) has hard and PCF filters (PCSS would be PCF r1
  // again); an area light accepts PCSS only.
  std::vector<std::pair<std::string, int>> filters;
  if (base.light.size > 0.0)
    filters = {{"pcss", 1}};
  else
    filters = {{"hard", 0}, {"pcf", 1}, {"pcf", 2}};
  std::vector<Technique> out;
  for (const char* fit : {"fixed", "scene"})
    for (int map : options.map_sizes)
      for (const auto& [filter, radius] : filters) out.push_back({fit, filter, radius, map});
  return out;
}

Row measure(RenderService& service, const Options& options, const std::string& scene, const Technique& technique,
            const std::vector<ExactPixel>& exact, const PixelCoverageOf& finer, bool perspective) {
  json overrides = technique.overrides(perspective);
  overrides["width"] = options.width;
  overrides["height"] = options.height;
  overrides["output"] = "shadow";
  RenderRequest request = load_scene_request(options.scenes_dir, scene, overrides);
  Row row{scene, technique, "", 0.0, 0.0, {}};
  const RenderResult shadow = service.submit(request).get();
  row.error = measure_shadow_error(shadow.image, exact, finer);
  row.views = shadow.shadow_views;

  request.output = Output::Color;
  service.submit(request).get();  // warm-up: first use of this map size
  std::vector<double> total, shadow_pass;
  const double start_time = request.time;
  for (int i = 0; i < options.frames; ++i) {
    // The light moves between frames (as in the panel's Play), so every
    // frame draws its shadow map instead of reusing the last one.
    request.time = start_time + (i + 1) * 0.37;
    const RenderResult r = frame_with_shadow_pass(service, request, row.remeasured);
    total.push_back(r.timings.shadow_ms + r.timings.main_ms + r.timings.readback_ms);
    shadow_pass.push_back(r.timings.shadow_ms);
  }
  row.median_ms = median(total);
  row.median_shadow_ms = median(shadow_pass);
  return row;
}

// ---------------------------------------------------------------------------
// Summary over scenes and the Pareto front.

struct Summary {
  std::string label;
  Technique technique;
  double mean_ms = 0.0;      // mean over scenes of the per-scene median
  double mean_wrong = 0.0;   // mean over scenes of `wrong`
  double worst_wrong = 0.0;  // the worst scene's `wrong`
  std::string worst_scene;
  int scenes = 0;
  bool pareto = false;
};

std::vector<Summary> summarise(const std::vector<Row>& rows) {
  std::map<std::string, Summary> by_label;
  for (const Row& r : rows) {
    Summary& s = by_label[r.technique.label()];
    s.label = r.technique.label();
    s.technique = r.technique;
    s.mean_ms += r.median_ms;
    s.mean_wrong += r.error.wrong;
    if (r.error.wrong >= s.worst_wrong) s.worst_wrong = r.error.wrong, s.worst_scene = r.scene;
    ++s.scenes;
  }
  std::vector<Summary> out;
  for (auto& [label, s] : by_label) {
    s.mean_ms /= s.scenes;
    s.mean_wrong /= s.scenes;
    out.push_back(s);
  }
  // Only techniques measured on the same scenes compare: group by scene count.
  for (Summary& a : out) {
    a.pareto = true;
    for (const Summary& b : out)
      if (b.scenes == a.scenes && &a != &b && b.mean_ms <= a.mean_ms && b.mean_wrong <= a.mean_wrong &&
          (b.mean_ms < a.mean_ms || b.mean_wrong < a.mean_wrong))
        a.pareto = false;
  }
  std::sort(out.begin(), out.end(), [](const Summary& a, const Summary& b) { return a.mean_ms < b.mean_ms; });
  return out;
}

std::string svg_escape(const std::string& s) {
  std::string out;
  for (char c : s) out += c == '<' ? "&lt;" : c == '>' ? "&gt;" : c == '&' ? "&amp;" : std::string(1, c);
  return out;
}

// Error (mean wrong %) against time (mean median ms), both log scaled.
std::string pareto_svg(const std::vector<Summary>& all, const std::string& caption) {
  std::vector<Summary> points;
  int scenes = 0;
  for (const Summary& s : all) scenes = std::max(scenes, s.scenes);
  for (const Summary& s : all)
    if (s.scenes == scenes) points.push_back(s);
  const double W = 860, H = 520, left = 70, right = 20, top = 40, bottom = 60;
  const double floor_wrong = 1e-3;  // percent; zero error is drawn here
  double x0 = 1e30, x1 = 0, y0 = 1e30, y1 = 0;
  for (const Summary& s : points) {
    x0 = std::min(x0, s.mean_ms), x1 = std::max(x1, s.mean_ms);
    const double w = std::max(100.0 * s.mean_wrong, floor_wrong);
    y0 = std::min(y0, w), y1 = std::max(y1, w);
  }
  x0 = std::pow(10.0, std::floor(std::log10(x0))), x1 = std::pow(10.0, std::ceil(std::log10(x1)));
  y0 = std::pow(10.0, std::floor(std::log10(y0))), y1 = std::pow(10.0, std::ceil(std::log10(y1)));
  auto X = [&](double ms) { return left + (W - left - right) * std::log10(ms / x0) / std::log10(x1 / x0); };
  auto Y = [&](double pct) {
    return top + (H - top - bottom) * (1.0 - std::log10(std::max(pct, floor_wrong) / y0) / std::log10(y1 / y0));
  };
  std::ostringstream svg;
  svg << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << W << "\" height=\"" << H
      << "\" font-family=\"sans-serif\" font-size=\"11\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  const std::size_t split = caption.find(" (");
  svg << "<text x=\"" << left << "\" y=\"16\" font-size=\"13\">" << svg_escape(caption.substr(0, split)) << "</text>\n";
  if (split != std::string::npos)
    svg << "<text x=\"" << left << "\" y=\"32\" fill=\"#555\">" << svg_escape(caption.substr(split + 2, caption.size() - split - 3))
        << "</text>\n";
  for (double v = x0; v <= x1 * 1.0001; v *= 10.0) {
    svg << "<line x1=\"" << X(v) << "\" y1=\"" << top << "\" x2=\"" << X(v) << "\" y2=\"" << H - bottom
        << "\" stroke=\"#ddd\"/><text x=\"" << X(v) << "\" y=\"" << H - bottom + 15 << "\" text-anchor=\"middle\">"
        << v << "</text>\n";
  }
  for (double v = y0; v <= y1 * 1.0001; v *= 10.0) {
    svg << "<line x1=\"" << left << "\" y1=\"" << Y(v) << "\" x2=\"" << W - right << "\" y2=\"" << Y(v)
        << "\" stroke=\"#ddd\"/><text x=\"" << left - 5 << "\" y=\"" << Y(v) + 4 << "\" text-anchor=\"end\">" << v
        << "</text>\n";
  }
  svg << "<text x=\"" << (left + W - right) / 2 << "\" y=\"" << H - 20
      << "\" text-anchor=\"middle\">median render time per frame, ms (mean over scenes, log)</text>\n";
  svg << "<text transform=\"translate(18," << (top + H - bottom) / 2
      << ") rotate(-90)\" text-anchor=\"middle\">wrong pixels, % (mean over scenes, log)</text>\n";
  // The front, as a line through its points in order of time.
  svg << "<polyline fill=\"none\" stroke=\"#2a7\" stroke-width=\"2\" points=\"";
  for (const Summary& s : points)
    if (s.pareto) svg << X(s.mean_ms) << "," << Y(100.0 * s.mean_wrong) << " ";
  svg << "\"/>\n";
  int labelled = 0;
  for (const Summary& s : points) {
    const bool fixed = s.technique.fit == "fixed";
    const double x = X(s.mean_ms), y = Y(100.0 * s.mean_wrong);
    svg << "<circle cx=\"" << x << "\" cy=\"" << y << "\" r=\"" << (s.technique.is_seeds() ? 7 : 4) << "\" fill=\""
        << (fixed ? "#d44" : "#36c") << "\" fill-opacity=\"0.8\"><title>" << svg_escape(s.label) << "</title></circle>\n";
    // Labels for Umbra's front and the seeds' own configuration only;
    // alternately above and below the line so neighbours do not overlap.
    if (s.technique.is_seeds())
      svg << "<text x=\"" << x + 10 << "\" y=\"" << y + 18 << "\">the seeds (fixed, pcf r1, 1024)</text>\n";
    else if (s.pareto && !fixed)
      svg << "<text x=\"" << x + 7 << "\" y=\"" << (labelled++ % 2 ? y + 15 : y - 7) << "\">" << svg_escape(s.label)
          << "</text>\n";
  }
  svg << "<circle cx=\"" << W - 250 << "\" cy=\"" << top + 10 << "\" r=\"4\" fill=\"#36c\"/><text x=\"" << W - 240
      << "\" y=\"" << top + 14 << "\">fit scene (Umbra)</text>\n";
  svg << "<circle cx=\"" << W - 250 << "\" cy=\"" << top + 28 << "\" r=\"4\" fill=\"#d44\"/><text x=\"" << W - 240
      << "\" y=\"" << top + 32 << "\">fit fixed (the seeds' frustum and bias)</text>\n";
  svg << "<line x1=\"" << W - 256 << "\" y1=\"" << top + 46 << "\" x2=\"" << W - 244 << "\" y2=\"" << top + 46
      << "\" stroke=\"#2a7\" stroke-width=\"2\"/><text x=\"" << W - 240 << "\" y=\"" << top + 50
      << "\">Pareto front</text>\n";
  svg << "</svg>\n";
  return svg.str();
}

// ---------------------------------------------------------------------------

void write_reports(const std::vector<Row>& rows, const Options& options, const std::string& machine,
                   const std::string& when);
std::vector<Row> read_rows(const json& j);

void usage() {
  std::cout << "usage: umbra-bench [--frames N] [--size WxH] [--maps 512,1024,...] [--scene NAME]...\n"
               "                   [--scenes DIR] [--out DIR] [--name STEM] [--from-json SAVED.json]\n"
               "Renders every scene in --scenes (default: the source tree's bench/scenes) with a grid\n"
               "of shadow techniques and writes STEM.md, STEM.json and STEM.svg under --out\n"
               "(default: the source tree's bench/results). --from-json rewrites the reports of a\n"
               "saved run without measuring again.\n"
               "umbra-bench --speed [...] compares Umbra's frame time with the plain frame's instead\n"
               "(see umbra-bench --speed --help).\n";
}

int run(int argc, char** argv) {
  Options options;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw std::runtime_error(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--frames") options.frames = std::max(1, std::stoi(value()));
    else if (arg == "--size") {
      const std::string v = value();
      const auto x = v.find('x');
      if (x == std::string::npos) throw std::runtime_error("--size is WxH, e.g. 960x540");
      options.width = std::stoi(v.substr(0, x));
      options.height = std::stoi(v.substr(x + 1));
    } else if (arg == "--maps") options.map_sizes = parse_int_list(value());
    else if (arg == "--scene") options.only_scenes.push_back(value());
    else if (arg == "--scenes") options.scenes_dir = value();
    else if (arg == "--out") options.out_dir = value();
    else if (arg == "--name") options.name = value();
    else if (arg == "--from-json") options.from_json = value();
    else if (arg == "--help" || arg == "-h") return usage(), 0;
    else throw std::runtime_error("unknown option " + arg + " (see --help)");
  }
  if (!options.from_json.empty()) {
    std::ifstream in(options.from_json);
    const json saved = json::parse(in, nullptr, false);
    if (saved.is_discarded()) throw std::runtime_error(options.from_json + ": not valid JSON");
    options.width = saved.at("image")[0];
    options.height = saved.at("image")[1];
    options.frames = saved.at("frames");
    write_reports(read_rows(saved), options, saved.at("machine"), saved.at("date"));
    return 0;
  }
  std::vector<std::string> scenes = options.only_scenes.empty() ? scene_file_names(options.scenes_dir) : options.only_scenes;

  RenderService service;
  const std::string machine = machine_description(service);
  const std::string when = utc_now();
  std::vector<Row> rows;
  std::printf("%-20s %-24s %-24s %9s %9s %9s %8s %8s %8s %8s\n", "scene", "technique", "views", "ms", "shadow ms",
              "MAE", "wrong%", "f.shad%", "f.light%", "artif.%");
  for (const std::string& scene : scenes) {
    const RenderRequest base = load_scene_request(options.scenes_dir, scene,
                                                  {{"width", options.width}, {"height", options.height}, {"output", "shadow"}});
    const ExactView view(base);
    const std::vector<ExactPixel> exact = view.pixels();
    const PixelCoverageOf finer = view.coverage_of();
    const bool perspective = base.light.projection == LightProjection::Perspective;
    for (const Technique& t : techniques_for(base, options)) {
      Row row = measure(service, options, scene, t, exact, finer, perspective);
      std::printf("%-20s %-24s %-24s %9.2f %9.2f %9.5f %8s %8s %8s %8s\n", scene.c_str(), t.label().c_str(),
                  row.views.c_str(), row.median_ms, row.median_shadow_ms, row.error.mae, percent(row.error.wrong).c_str(),
                  percent(row.error.false_shadow).c_str(), percent(row.error.false_light).c_str(),
                  percent(row.error.artifacts).c_str());
      std::fflush(stdout);
      rows.push_back(std::move(row));
    }
  }

  write_reports(rows, options, machine, when);
  return 0;
}

// Rows back from a JSON report, to rewrite its Markdown and SVG.
std::vector<Row> read_rows(const json& j) {
  std::vector<Row> rows;
  for (const json& r : j.at("rows")) {
    Row row;
    row.scene = r.at("scene");
    const std::string filter = r.at("filter");
    row.technique.fit = r.at("fit");
    row.technique.filter = filter.rfind("pcf", 0) == 0 ? "pcf" : filter;
    row.technique.pcf_radius = filter.rfind("pcf r", 0) == 0 ? std::stoi(filter.substr(5)) : 0;
    row.technique.map_size = r.at("map_size");
    row.views = r.at("views");
    row.median_ms = r.at("median_ms");
    row.median_shadow_ms = r.at("median_shadow_ms");
    row.error.mae = r.at("mae");
    row.error.wrong = r.at("wrong");
    row.error.false_shadow = r.at("false_shadow");
    row.error.false_light = r.at("false_light");
    // Reports written before the artifact figure existed have none.
    row.error.artifacts = r.value("artifacts", 0.0);
    row.error.interior_pixels = r.value("interior_pixels", std::size_t(0));
    row.error.pixels = r.at("pixels");
    rows.push_back(row);
  }
  return rows;
}

void write_reports(const std::vector<Row>& rows, const Options& options, const std::string& machine,
                   const std::string& when) {
  std::filesystem::create_directories(options.out_dir);
  const std::vector<Summary> summary = summarise(rows);
  const std::string setup = std::to_string(options.width) + "x" + std::to_string(options.height) + ", median of " +
                            std::to_string(options.frames) + " frames";
  json j = {{"machine", machine}, {"date", when}, {"image", {options.width, options.height}}, {"frames", options.frames},
            {"rows", json::array()}, {"summary", json::array()}};
  for (const Row& r : rows) {
    j["rows"].push_back({{"scene", r.scene}, {"fit", r.technique.fit}, {"filter", r.technique.filter_label()},
                         {"map_size", r.technique.map_size}, {"views", r.views}, {"median_ms", r.median_ms},
                         {"median_shadow_ms", r.median_shadow_ms}, {"mae", r.error.mae}, {"wrong", r.error.wrong},
                         {"false_shadow", r.error.false_shadow}, {"false_light", r.error.false_light},
                         {"artifacts", r.error.artifacts}, {"interior_pixels", r.error.interior_pixels},
                         {"pixels", r.error.pixels}, {"seeds", r.technique.is_seeds()}});
  }
  for (const Summary& s : summary)
    j["summary"].push_back({{"technique", s.label}, {"scenes", s.scenes}, {"mean_ms", s.mean_ms},
                            {"mean_wrong", s.mean_wrong}, {"worst_wrong", s.worst_wrong},
                            {"worst_scene", s.worst_scene}, {"pareto", s.pareto}});
  const std::string stem = options.out_dir + "/" + options.name;
  write_file(stem + ".json", j.dump(1) + "\n");

  std::ostringstream md;
  md << "# Shadow accuracy against time\n\n"
     << "Written by `umbra-bench` (" << when << ").\n\n"
     << "- Machine: " << machine << "\n"
     << "- Frames: " << setup << ", the light moving 0.37 s of orbit per frame; time = shadow + main pass + read-back "
        "on the GL thread (PNG encoding excluded); a frame whose light orbiting does not move, and which therefore "
        "kept its shadow map, is measured again after an untimed frame that makes the map stale.\n"
     << "- Error: the `shadow` output against the exact ray-cast reference (`renderer/reference/shadow_error.hpp`): "
        "`wrong` = share of measured pixels with |v - v_exact| > 0.5, split into false shadow and false light; "
        "`artifacts` = share of interior pixels (exactly lit or dark, over 3 px from any shadow edge, silhouette or "
        "crease, an edge between pixel centres included: 4 x 4 samples per pixel around each candidate) off by "
        "more than 0.1.\n"
     << "- `seeds-fixed`: the seeds' frustum (ortho +-10, or a 90 degree cone; near 1, far 7.5) and bias "
        "max(0.05 (1 - N.L), 0.005); the seeds' own configuration is `seeds-fixed pcf r1 1024`. "
        "`scene`: Umbra's fit and automatic bias.\n\n"
     << "## Summary over scenes\n\n"
     << "| technique | scenes | mean ms | mean wrong % | worst wrong % (scene) | Pareto |\n|---|---|---|---|---|---|\n";
  for (const Summary& s : summary)
    md << "| " << s.label << " | " << s.scenes << " | " << format("%.2f", s.mean_ms) << " | " << percent(s.mean_wrong)
       << " | " << percent(s.worst_wrong) << " (" << s.worst_scene << ") | " << (s.pareto ? "yes" : "") << " |\n";
  md << "\n![error against time](" << options.name << ".svg)\n";
  std::string current;
  for (const Row& r : rows) {
    if (r.scene != current) {
      current = r.scene;
      md << "\n## " << current << "\n\n| technique | views | median ms | shadow ms | MAE | wrong % | false shadow % | "
                                  "false light % | artifacts % |\n|---|---|---|---|---|---|---|---|---|\n";
    }
    md << "| " << r.technique.label() << (r.technique.is_seeds() ? " (the seeds)" : "") << " | " << r.views << " | "
       << format("%.2f", r.median_ms) << " | " << format("%.2f", r.median_shadow_ms) << " | "
       << format("%.5f", r.error.mae) << " | " << percent(r.error.wrong) << " | " << percent(r.error.false_shadow)
       << " | " << percent(r.error.false_light) << " | " << percent(r.error.artifacts) << " |\n";
  }
  write_file(stem + ".md", md.str());
  write_file(stem + ".svg", pareto_svg(summary, "Umbra shadows: error against time, " + setup + " (" + machine + ")"));
  std::printf("\nwrote %s.md, %s.json, %s.svg\n", stem.c_str(), stem.c_str(), stem.c_str());
}

}  // namespace
}  // namespace umbra

int main(int argc, char** argv) {
  try {
    for (int i = 1; i < argc; ++i)
      if (std::string(argv[i]) == "--speed") return umbra::bench::run_speed(argc, argv);
    return umbra::run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "umbra-bench: %s\n", e.what());
    return 1;
  }
}
