// umbra-model-load-bench: load time and peak memory of umbra::load_gltf for
// one model written four ways (bench/results/model-load.md): plain glTF,
// KHR_mesh_quantization (gltfpack's default), EXT_meshopt_compression
// (gltfpack -cc) and KHR_draco_mesh_compression (draco_transcoder), each
// against the plain load in the same run.
//
// Two models: a trefoil torus knot tube, one mesh of a million triangles
// with normals (a dense smooth closed surface, as a scan or a sculpt is;
// not a flat grid), written by the benchmark as a plain .glb; and a real
// CAD model written by others, the two-cylinder engine in Debian's
// assimp-testmodels (121k triangles in 29 meshes), as shipped. Debian's own
// tools write the other variants from each, as users' tools would;
// gltfpack's plain output (-noq) is measured too, because gltfpack welds
// and reorders: the same triangles as its compressed outputs, without
// quantization or compression.
//
// Every load runs in a forked child process of its own (the parent never
// loads, so it stays small and has no threads): the child reads the file,
// times load_gltf alone and reports through a pipe; its peak resident set
// comes from wait4's rusage. A baseline child per variant reads the file
// and does not load: peak minus baseline is what the load itself held at
// its peak. Runs go round a model's variants in turn, so that a change in
// the shared machine's load weighs on every variant alike.
//
// Exit status 1 when a variant's tool or load fails (the report says which
// and the loader's message).
//
//   umbra-model-load-bench [--quick] [--runs 9] [--out FILE.md]
//
// --quick: a 10,000-triangle knot (and the engine) and 1 run: the smoke
// test. The JSON is written next to the markdown (FILE.json).
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <nlohmann/json.hpp>

#include "machine.hpp"
#include "assets/gltf_loader.hpp"
#include "core/model.hpp"
#include "core/model_rig.hpp"
#include "gltf_builder.hpp"

using umbra::bench::cpu_model_and_threads;
using umbra::bench::utc_now;

namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

std::string fmt(const char* pattern, double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, pattern, value);
  return buffer;
}

double mib(double bytes) { return bytes / double(1 << 20); }

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

double min_of(const std::vector<double>& v) { return v.empty() ? NAN : *std::min_element(v.begin(), v.end()); }

// ------------------------------------------------------------------ the model

// A (2, 3) torus knot (a trefoil) swept by a circular tube: `along` rings
// of `around` vertices, welded all round (the tube closes on itself), so
// 2 x along x around triangles and along x around vertices.
struct KnotSize {
  int along, around;
  std::size_t triangles() const { return 2 * std::size_t(along) * std::size_t(around); }
};

glm::vec3 knot_centre(double t) {
  constexpr double kRadius = 2.0, kWind = 1.0;  // metres; the strands pass about 1 m apart
  const double r = kRadius + kWind * std::cos(3.0 * t);
  return glm::vec3(glm::dvec3(r * std::cos(2.0 * t), kWind * std::sin(3.0 * t), r * std::sin(2.0 * t)));
}

// How the knot moves, for the posing section: not at all (the load
// variants), as one rigid node turning (a node channel), or skinned to two
// joints (a root and one that turns about Y, each vertex weighted between
// them by its height: as a character's limb or a hinged part is rigged).
enum class KnotMotion { None, Rigid, Skinned };

// The plain .glb: POSITION, NORMAL (the tube's own, exact) and 32-bit
// indices, one mesh, one node; with a motion, its animation ("turn", a
// half turn over 2 s, LINEAR).
std::string torus_knot_glb(KnotSize size, KnotMotion motion = KnotMotion::None) {
  constexpr double kTube = 0.35, kTwoPi = 6.283185307179586;
  std::vector<glm::vec3> positions, normals;
  positions.reserve(std::size_t(size.along) * std::size_t(size.around));
  normals.reserve(positions.capacity());
  for (int i = 0; i < size.along; ++i) {
    const double t = kTwoPi * i / size.along;
    // A frame that depends on t alone (as three.js's TorusKnotGeometry
    // builds it), so the last ring meets the first exactly.
    const glm::vec3 p = knot_centre(t), q = knot_centre(t + 1e-3);
    const glm::vec3 tangent = glm::normalize(q - p);
    const glm::vec3 b = glm::normalize(glm::cross(tangent, q + p));
    const glm::vec3 n = glm::cross(b, tangent);
    for (int j = 0; j < size.around; ++j) {
      const double v = kTwoPi * j / size.around;
      const glm::vec3 out = float(std::cos(v)) * n + float(std::sin(v)) * b;
      positions.push_back(p + float(kTube) * out);
      normals.push_back(out);
    }
  }
  std::vector<std::uint32_t> indices;
  indices.reserve(3 * size.triangles());
  const auto vertex = [&](int i, int j) {
    return std::uint32_t((i % size.along) * size.around + (j % size.around));
  };
  for (int i = 0; i < size.along; ++i)
    for (int j = 0; j < size.around; ++j) {
      // Counter-clockwise seen from outside the tube.
      const std::uint32_t a = vertex(i, j), b = vertex(i + 1, j), c = vertex(i + 1, j + 1), d = vertex(i, j + 1);
      indices.insert(indices.end(), {a, c, b, a, d, c});
    }
  umbra::test::GltfBuilder builder;
  const int mesh = builder.mesh(builder.vec3s(positions), builder.indices_u32(indices), builder.vec3s(normals));
  if (motion == KnotMotion::None) {
    builder.scene({builder.node({{"mesh", mesh}})});
    return builder.glb();
  }
  const int times = builder.accessor(builder.view(umbra::test::GltfBuilder::bytes_of(std::vector<float>{0, 1, 2})),
                                     umbra::test::GltfBuilder::kFloat, 3, "SCALAR");
  const float h = float(std::sqrt(0.5));
  const int turns = builder.accessor(
      builder.view(umbra::test::GltfBuilder::bytes_of(std::vector<float>{0, 0, 0, 1, 0, h, 0, h, 0, 1, 0, 0})),
      umbra::test::GltfBuilder::kFloat, 3, "VEC4");
  int turned = 0;
  if (motion == KnotMotion::Rigid) {
    turned = builder.node({{"mesh", mesh}});
    builder.scene({turned});
  } else {
    std::vector<std::uint16_t> joints;
    std::vector<float> weights;
    joints.reserve(positions.size() * 4);
    weights.reserve(positions.size() * 4);
    for (const glm::vec3& p : positions) {
      const float upper = std::clamp((p.y + 1.35f) / 2.7f, 0.0f, 1.0f);
      joints.insert(joints.end(), {0, 1, 0, 0});
      weights.insert(weights.end(), {1.0f - upper, upper, 0.0f, 0.0f});
    }
    const int joint_accessor = builder.accessor(builder.view(umbra::test::GltfBuilder::bytes_of(joints)),
                                                umbra::test::GltfBuilder::kShort, positions.size(), "VEC4");
    const int weight_accessor = builder.accessor(builder.view(umbra::test::GltfBuilder::bytes_of(weights)),
                                                 umbra::test::GltfBuilder::kFloat, positions.size(), "VEC4");
    builder.doc["meshes"][std::size_t(mesh)]["primitives"][0]["attributes"]["JOINTS_0"] = joint_accessor;
    builder.doc["meshes"][std::size_t(mesh)]["primitives"][0]["attributes"]["WEIGHTS_0"] = weight_accessor;
    turned = builder.node(json::object());
    const int root = builder.node({{"children", {turned}}});
    const int skinned = builder.node({{"mesh", mesh}, {"skin", 0}});
    builder.doc["skins"] = json::array({{{"joints", {root, turned}}}});  // inverse binds: identity
    builder.scene({root, skinned});
  }
  builder.doc["animations"] = json::array(
      {{{"name", "turn"},
        {"samplers", {{{"input", times}, {"output", turns}}}},
        {"channels", {{{"sampler", 0}, {"target", {{"node", turned}, {"path", "rotation"}}}}}}}});
  return builder.glb();
}

const fs::path kEngine = "/usr/share/assimp/models/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb";

void write_bytes(const fs::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out << bytes;
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

std::string read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::string bytes(std::size_t(fs::file_size(path)), '\0');
  in.read(bytes.data(), std::streamsize(bytes.size()));
  return in ? bytes : std::string();
}

// Writes the knot's plain .glb from a child process, so that the parent,
// whose memory every load's process starts with, never holds it: glibc
// keeps freed blocks of that size resident for reuse, and a load could
// then fill them without its peak RSS growing.
void write_knot_in_child(const fs::path& path, KnotSize size) {
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    try {
      write_bytes(path, torus_knot_glb(size));
      ::_exit(0);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s\n", e.what());
      ::_exit(1);
    }
  }
  int status = 0;
  if (::waitpid(pid, &status, 0) != pid || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw std::runtime_error("cannot write " + path.string());
}

// ------------------------------------------------------------- the variants

struct Variant {
  std::string name;
  std::string written_by;  // the command line, as the report shows it
  fs::path file;
  double write_s = 0.0;
  std::uintmax_t file_bytes = 0;
  // From the load children, one entry per run.
  std::vector<double> load_ms, peak_kib;
  double baseline_kib = NAN;
  std::size_t triangles = 0, model_bytes = 0;
  int status = 0;
  std::string error;

  double peak() const { return median(peak_kib); }
  double increase() const { return peak() - baseline_kib; }
};

bool have_command(const char* name) { return std::system((std::string("command -v ") + name + " >/dev/null").c_str()) == 0; }

// Runs one tool's command line in `dir` (its output to dir/tool.log); the
// variant keeps its wall time. False, with the tool's output on stderr, if
// it fails.
bool write_with_tool(Variant& v, const std::string& command, const fs::path& dir) {
  v.written_by = command;
  const fs::path log = dir / "tool.log";
  const auto start = Clock::now();
  const int rc = std::system(("cd '" + dir.string() + "' && " + command + " >tool.log 2>&1").c_str());
  v.write_s = seconds_since(start);
  if (rc == 0 && fs::exists(v.file)) return true;
  std::fprintf(stderr, "failed (status %d): %s\n%s\n", rc, command.c_str(), read_bytes(log).c_str());
  v.status = -1;
  v.error = "the tool failed: " + command;
  return false;
}

// ------------------------------------------------------- one load per child

struct ChildReport {
  bool ran = false;  // the child exited 0 after writing its report
  double max_rss_kib = NAN;
  double load_ms = NAN;
  int status = 0;
  std::size_t triangles = 0, model_bytes = 0;
  std::string error;
};

// In the child: reads `file`, then (if `load`) times load_gltf on it. The
// report is one text line and then the loader's error message.
std::string child_work(const fs::path& file, bool load) {
  const std::string bytes = read_bytes(file);
  if (bytes.empty()) return "nan -1 0 0\ncannot read " + file.string();
  if (!load) return "nan 0 0 0\n";
  const auto start = Clock::now();
  const umbra::LoadResult r = umbra::load_gltf(bytes, umbra::LoadOptions{});
  const double ms = seconds_since(start) * 1e3;
  std::ostringstream report;
  report << fmt("%.6f", ms) << ' ' << r.status << ' ' << (r.ok() ? r.model->triangle_count() : 0) << ' '
         << (r.ok() ? r.model->bytes() : 0) << '\n'
         << r.error;
  return report.str();
}

void write_all(int fd, const std::string& text) {
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n <= 0) return;
    done += std::size_t(n);
  }
}

std::string read_all(int fd) {
  std::string text;
  char buffer[4096];
  ssize_t n;
  while ((n = ::read(fd, buffer, sizeof buffer)) > 0) text.append(buffer, std::size_t(n));
  return text;
}

// A fresh process for one measurement: its peak RSS is this load's alone
// (and its heap starts cold, as after a server's freed memory went back to
// the system: the page faults of the load's memory are in its time).
ChildReport measure_in_child(const fs::path& file, bool load) {
  int pipe_fds[2];
  if (::pipe(pipe_fds) != 0) throw std::runtime_error("pipe failed");
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    ::close(pipe_fds[0]);
    write_all(pipe_fds[1], child_work(file, load));
    ::_exit(0);
  }
  ::close(pipe_fds[1]);
  const std::string text = read_all(pipe_fds[0]);
  ::close(pipe_fds[0]);
  int wait_status = 0;
  struct rusage usage {};
  ChildReport report;
  if (::wait4(pid, &wait_status, 0, &usage) != pid) return report;
  report.ran = WIFEXITED(wait_status) && WEXITSTATUS(wait_status) == 0;
  report.max_rss_kib = double(usage.ru_maxrss);  // Linux: KiB
  std::istringstream in(text);
  std::string ms;
  in >> ms >> report.status >> report.triangles >> report.model_bytes;
  report.load_ms = std::strtod(ms.c_str(), nullptr);
  in.ignore(1);
  std::getline(in, report.error, '\0');
  if (!report.ran) report.status = -1, report.error = "the load's process died (signal or crash)";
  return report;
}

void record_load(Variant& v, const ChildReport& r) {
  v.status = r.status;
  v.error = r.error;
  if (r.status != 0) return;
  v.load_ms.push_back(r.load_ms);
  v.peak_kib.push_back(r.max_rss_kib);
  v.triangles = r.triangles;
  v.model_bytes = r.model_bytes;
}

// One model: its plain .glb and the tools' variants of it, plain first.
struct Model {
  std::string name;  // "knot-1m", "engine"
  std::string what;  // one line for the report
  std::vector<Variant> variants;
};

// Writes each tool's variant of dir/plain.glb, the plain variant. False if
// a tool failed (its variant says so).
bool write_variants(Model& model, const fs::path& dir, const std::string& plain_written_by) {
  model.variants.assign(1, Variant{});
  model.variants[0].name = "plain";
  model.variants[0].written_by = plain_written_by;
  model.variants[0].file = dir / "plain.glb";
  // gltfpack's default is KHR_mesh_quantization (14-bit positions, 8-bit
  // normals); -cc adds EXT_meshopt_compression; draco_transcoder's default
  // quantizes positions to 11 bits, normals to 8. Both take -i and -o.
  const struct {
    const char* name;
    const char* program;
    const char* output;
    const char* flags;
  } tools[] = {{"gltfpack plain (-noq)", "gltfpack", "gltfpack-noq.glb", " -noq"},
               {"quantized", "gltfpack", "quantized.glb", ""},
               {"meshopt", "gltfpack", "meshopt.glb", " -cc"},
               {"draco", "draco_transcoder", "draco.glb", ""}};
  bool ok = true;
  for (const auto& tool : tools) {
    Variant& v = model.variants.emplace_back();
    v.name = tool.name;
    v.file = dir / tool.output;
    std::fprintf(stderr, "%s: writing %s ...\n", model.name.c_str(), v.name.c_str());
    ok &= write_with_tool(v, std::string(tool.program) + " -i plain.glb -o " + tool.output + tool.flags, dir);
  }
  for (Variant& v : model.variants)
    if (v.status == 0) v.file_bytes = fs::file_size(v.file);
  return ok;
}

void measure(Model& model, int runs) {
  for (Variant& v : model.variants)
    if (v.status == 0) v.baseline_kib = measure_in_child(v.file, false).max_rss_kib;
  for (int run = 0; run < runs; ++run) {
    std::fprintf(stderr, "%s: run %d of %d ...\n", model.name.c_str(), run + 1, runs);
    for (Variant& v : model.variants)
      if (v.status == 0) record_load(v, measure_in_child(v.file, true));
  }
}

// --------------------------------------------------------------- the report

std::string first_line(const char* command) {
  std::string line;
  if (FILE* pipe = ::popen(command, "r")) {
    char buffer[512];
    if (std::fgets(buffer, sizeof buffer, pipe)) line = buffer;
    ::pclose(pipe);
  }
  while (!line.empty() && std::isspace(static_cast<unsigned char>(line.back()))) line.pop_back();
  return line.empty() ? "unknown" : line;
}

// What the numbers were measured on: the source tree's commit ("-dirty"
// when it has uncommitted changes, as the loader's may be) and the tools'
// Debian versions.
struct Provenance {
  std::string date = utc_now(),
              machine = cpu_model_and_threads() + "; each load is single-threaded";
  std::string commit = first_line("git -C '" UMBRA_SOURCE_DIR "' describe --always --dirty 2>/dev/null");
  std::string tools = first_line("dpkg-query -W -f='${Package} ${Version}  ' gltfpack draco 2>/dev/null");
};

std::string ratio(double value, double plain) {
  return std::isfinite(value) && std::isfinite(plain) && plain > 0 ? fmt("%.2f", value / plain) : "-";
}

std::string markdown_table(const Model& model) {
  const Variant& plain = model.variants.front();
  std::ostringstream t;
  t << "| " << model.name << " | file MiB | triangles loaded | load ms (median) | load ms (min) | time / plain "
       "| peak RSS MiB (median) | baseline MiB | load's own MiB | memory / plain |\n"
    << "|---|---|---|---|---|---|---|---|---|---|\n";
  for (const Variant& v : model.variants) {
    t << "| " << v.name << " | " << fmt("%.2f", mib(double(v.file_bytes))) << " | ";
    if (v.status != 0) {
      t << "FAILED (" << v.status << "): " << v.error << " | - | - | - | - | - | - | - |\n";
      continue;
    }
    t << v.triangles << " | " << fmt("%.1f", median(v.load_ms)) << " | " << fmt("%.1f", min_of(v.load_ms)) << " | "
      << ratio(median(v.load_ms), median(plain.load_ms)) << " | " << fmt("%.1f", v.peak() / 1024) << " | "
      << fmt("%.1f", v.baseline_kib / 1024) << " | " << fmt("%.1f", v.increase() / 1024) << " | "
      << ratio(v.increase(), plain.increase()) << " |\n";
  }
  return t.str();
}

// Below a model's table: the variants that load other triangles than the
// plain one, and where each variant came from.
std::string model_notes(const Model& model) {
  const Variant& plain = model.variants.front();
  std::ostringstream md;
  md << "- **plain**: " << plain.written_by << "\n";
  for (const Variant& v : model.variants) {
    if (&v == &plain) continue;
    md << "- **" << v.name << "**: `" << v.written_by << "` (" << fmt("%.1f", v.write_s) << " s)";
    if (v.status == 0 && plain.status == 0 && v.triangles != plain.triangles)
      md << "; loads " << v.triangles << " triangles, plain " << plain.triangles;
    md << "\n";
  }
  return md.str();
}

void write_markdown(const fs::path& path, const std::vector<Model>& models, int runs, const Provenance& p,
                    const std::string& command, double run_s) {
  std::ofstream md(path);
  md << "# Model load: plain, quantized, meshopt and Draco glTF\n\n"
     << "Written by `umbra-model-load-bench` (" << p.date << ").\n\n"
     << "- Machine: " << p.machine << "; shared, so times are indicative\n"
     << "- Source: commit " << p.commit << "; tools: " << p.tools << "\n"
     << "- Command: `" << command << "`\n"
     << "- Run time: " << fmt("%.0f", run_s) << " s in all\n\n"
     << "## Method\n\n"
     << "Each load is `umbra::load_gltf(bytes, LoadOptions{})` on the whole file's bytes, in a forked process of its "
        "own: the process reads the file, then times the call alone (`steady_clock`), and exits. "
     << runs << (runs == 1 ? " run" : " runs")
     << " per variant, going round a model's variants in turn so that a change in the shared machine's load weighs "
        "on each alike; **median** and **min** of the runs. A fresh process per load means a cold heap: the page "
        "faults of the load's memory are in its time, as in a server whose freed memory went back to the system.\n\n"
     << "- **peak RSS**: the load process's `ru_maxrss` (from `wait4`), median over the runs. **baseline**: the same "
        "for a process that reads the same file and does not load it (the benchmark's own code and the file's bytes). "
        "**load's own** = peak - baseline: what `load_gltf` held at its peak, the finished model included.\n"
     << "- **time / plain**, **memory / plain**: the median load time and the load's own memory over the plain "
        "variant's, in this run.\n"
     << "- **plain** is the model as float positions and normals; the other variants are written from it by "
        "Debian's tools (below each table), as a user's tools would write them.\n";
  for (const Model& m : models)
    md << "\n## " << m.name << "\n\n" << m.what << ".\n\n" << markdown_table(m) << "\n" << model_notes(m);
}

json variant_json(const Variant& v, const Variant& plain) {
  const auto number = [](double x) { return std::isfinite(x) ? json(x) : json(nullptr); };
  return {{"name", v.name},
          {"written_by", v.written_by},
          {"write_seconds", v.write_s},
          {"file_bytes", v.file_bytes},
          {"status", v.status},
          {"error", v.error},
          {"triangles", v.triangles},
          {"model_bytes", v.model_bytes},
          {"load_ms", v.load_ms},
          {"load_ms_median", number(median(v.load_ms))},
          {"load_ms_min", number(min_of(v.load_ms))},
          {"time_over_plain", number(median(v.load_ms) / median(plain.load_ms))},
          {"peak_rss_kib", v.peak_kib},
          {"peak_rss_kib_median", number(v.peak())},
          {"baseline_rss_kib", number(v.baseline_kib)},
          {"load_own_kib", number(v.increase())},
          {"memory_over_plain", number(v.increase() / plain.increase())}};
}

json model_json(const Model& m) {
  json variants = json::array();
  for (const Variant& v : m.variants) variants.push_back(variant_json(v, m.variants.front()));
  return {{"name", m.name}, {"what", m.what}, {"variants", variants}};
}

fs::path json_path_for(const fs::path& md_path) { return fs::path(md_path).replace_extension(".json"); }

}  // namespace

// ------------------------------------------------------------------ posing

// What a request naming an animation costs before it is drawn: the pose
// (core/model_rig.hpp's pose_model, what PoseCache runs once per distinct
// pose), measured in this process on the knot animated two ways.
struct PoseRow {
  std::string name;
  std::size_t triangles = 0;
  double load_ms = NAN;             // load_gltf, the rig included
  std::vector<double> pose_ms;      // one pose per instant
  double model_mib = NAN, rig_mib = NAN, pose_mib = NAN;
};

std::vector<PoseRow> measure_posing(KnotSize size, int runs) {
  std::vector<PoseRow> rows;
  for (const auto& [name, motion] : {std::pair{"rigid (a node channel)", KnotMotion::Rigid},
                                     std::pair{"skinned (two joints)", KnotMotion::Skinned}}) {
    std::fprintf(stderr, "posing: %s ...\n", name);
    PoseRow row;
    row.name = name;
    const std::string glb = torus_knot_glb(size, motion);
    auto start = Clock::now();
    const umbra::LoadResult r = umbra::load_gltf(glb, umbra::LoadOptions{});
    row.load_ms = 1000.0 * seconds_since(start);
    if (!r.ok() || !r.model->rig) {
      std::fprintf(stderr, "posing: %s did not load: %s\n", name, r.error.c_str());
      rows.push_back(row);
      continue;
    }
    row.triangles = r.model->triangle_count();
    row.rig_mib = double(r.model->rig->bytes()) / (1 << 20);
    row.model_mib = double(r.model->bytes()) / (1 << 20);
    for (int k = 0; k < std::max(runs, 3); ++k) {
      const double t = 2.0 * (k + 0.5) / std::max(runs, 3);
      start = Clock::now();
      const umbra::TriangleModel posed = umbra::pose_model(*r.model->rig, 0, t);
      row.pose_ms.push_back(1000.0 * seconds_since(start));
      row.pose_mib = double(posed.bytes()) / (1 << 20);
    }
    rows.push_back(row);
  }
  return rows;
}

std::string posing_markdown(const std::vector<PoseRow>& rows, KnotSize size) {
  std::ostringstream md;
  md << "\n## Posing\n\nThe knot above (" << size.triangles()
     << " triangles), animated: its one node turning a half turn over 2 s (a rotation channel), and skinned to two "
        "joints (a root and a joint turning about Y the same way, each vertex weighted between them by its height). "
        "**load ms**: `load_gltf` with the rig (one run, in this process); **pose ms**: `pose_model` at instants "
        "spread over the animation, each a pose a request's `animation` asks for the first time (`PoseCache` then "
        "shares it): morph and skin, transform, normals, and `finish_model` (bounds, closedness, the cost model's "
        "bins); **model MiB** counts the rig, **pose MiB** is one posed model.\n\n"
     << "| motion | triangles | load ms | pose ms (median) | pose ms (min) | poses | model MiB | rig MiB | pose MiB |\n"
     << "|---|---|---|---|---|---|---|---|---|\n";
  for (const PoseRow& r : rows)
    md << "| " << r.name << " | " << r.triangles << " | " << fmt("%.1f", r.load_ms) << " | "
       << fmt("%.1f", median(r.pose_ms)) << " | " << fmt("%.1f", min_of(r.pose_ms)) << " | " << r.pose_ms.size()
       << " | " << fmt("%.1f", r.model_mib) << " | " << fmt("%.1f", r.rig_mib) << " | " << fmt("%.1f", r.pose_mib)
       << " |\n";
  return md.str();
}

json posing_json(const std::vector<PoseRow>& rows) {
  json list = json::array();
  const auto number = [](double x) { return std::isfinite(x) ? json(x) : json(nullptr); };
  for (const PoseRow& r : rows)
    list.push_back({{"motion", r.name},
                    {"triangles", r.triangles},
                    {"load_ms", number(r.load_ms)},
                    {"pose_ms", r.pose_ms},
                    {"pose_ms_median", number(median(r.pose_ms))},
                    {"model_mib", number(r.model_mib)},
                    {"rig_mib", number(r.rig_mib)},
                    {"pose_mib", number(r.pose_mib)}});
  return list;
}

int main(int argc, char** argv) {
  bool quick = false;
  int runs = 9;
  fs::path out = fs::path(UMBRA_RESULTS_DIR) / "model-load.md";
  std::string command = "umbra-model-load-bench";
  for (int i = 1; i < argc; ++i) command += std::string(" ") + argv[i];
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "--quick") {
      quick = true;
    } else if (arg == "--runs" && has_value) {
      runs = std::max(1, std::atoi(argv[++i]));
    } else if (arg == "--out" && has_value) {
      out = argv[++i];
    } else {
      std::fprintf(stderr, "usage: umbra-model-load-bench [--quick] [--runs 9] [--out FILE.md]\n");
      return 2;
    }
  }
  if (!have_command("gltfpack") || !have_command("draco_transcoder") || !fs::exists(kEngine)) {
    std::fprintf(stderr,
                 "umbra-model-load-bench needs Debian's gltfpack, draco (draco_transcoder) and assimp-testmodels "
                 "(%s): bash scripts/install-deps.sh installs them\n",
                 kEngine.c_str());
    return 2;
  }
  if (quick) runs = 1;
  const auto run_start = Clock::now();
  const fs::path dir = fs::temp_directory_path() / ("umbra-model-load-" + std::to_string(::getpid()));
  bool failed = false;

  const KnotSize size = quick ? KnotSize{200, 25} : KnotSize{4000, 125};
  std::vector<Model> models(2);
  models[0].name = quick ? "knot-10k" : "knot-1m";
  models[0].what = "A (2, 3) torus knot tube (a trefoil about 6 m across and 2.7 m tall, tube radius 0.35 m): one mesh "
                   "of " + std::to_string(size.triangles()) + " triangles and " +
                   std::to_string(std::size_t(size.along) * std::size_t(size.around)) + " vertices (" +
                   std::to_string(size.along) + " rings of " + std::to_string(size.around) +
                   "), with normals, welded and closed";
  fs::create_directories(dir / "knot");
  write_knot_in_child(dir / "knot" / "plain.glb", size);
  failed |= !write_variants(models[0], dir / "knot",
                            "written by the benchmark (tests/gltf_builder.hpp): float POSITION and NORMAL, 32-bit "
                            "indices");
  models[1].name = "engine";
  models[1].what = "Debian's assimp-testmodels `2CylinderEngine.glb` (a CAD model exported by COLLADA2GLTF: 29 meshes, "
                   "82 nodes), as shipped";
  fs::create_directories(dir / "engine");
  fs::copy_file(kEngine, dir / "engine" / "plain.glb");
  failed |= !write_variants(models[1], dir / "engine", "`" + kEngine.string() + "`, as shipped");

  for (Model& m : models) measure(m, runs);
  fs::remove_all(dir);
  // After the loads: their processes start from this one's memory.
  const std::vector<PoseRow> posing = measure_posing(size, runs);
  for (const PoseRow& r : posing) failed |= r.pose_ms.empty();
  for (const Model& m : models)
    for (const Variant& v : m.variants) failed |= v.status != 0;

  const Provenance provenance;
  for (const Model& m : models) std::printf("%s\n", markdown_table(m).c_str());
  fs::create_directories(fs::absolute(out).parent_path());
  const double run_s = seconds_since(run_start);
  write_markdown(out, models, runs, provenance, command, run_s);
  std::ofstream(out, std::ios::app) << posing_markdown(posing, size);
  std::printf("%s\n", posing_markdown(posing, size).c_str());
  json list = json::array();
  for (const Model& m : models) list.push_back(model_json(m));
  const json doc = {{"generator", "umbra-model-load-bench"},
                    {"date", provenance.date},
                    {"machine", provenance.machine},
                    {"commit", provenance.commit},
                    {"tools", provenance.tools},
                    {"command", command},
                    {"quick", quick},
                    {"runs", runs},
                    {"run_seconds", run_s},
                    {"models", list},
                    {"posing", posing_json(posing)}};
  std::ofstream(json_path_for(out)) << doc.dump(1) << "\n";
  std::printf("wrote %s and %s\n", out.c_str(), json_path_for(out).c_str());
  return failed ? 1 : 0;
}
