// umbra-png-bench: PNG size against encode time, to choose PngSettings.
//
// Renders the default scene's frame, shadow mask (960x540) and depth map
// (2048^2), then encodes each with stb_image_write's own deflate (Debian's
// libstb, level 8: what Umbra used before) and with zlib at several levels
// and row filters. Prints a Markdown table (median of --reps encodes) and
// writes it to bench/results/png.md.
//
//   umbra-png-bench [--reps 11] [--out bench/results/png.md]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include <stb_image_write.h>  // libstb: stb's own deflate, the baseline

#include "png.hpp"
#include "render_service.hpp"
#include "request_parser.hpp"

namespace {

using Clock = std::chrono::steady_clock;

umbra::RenderRequest request(const std::string& body) { return *umbra::parse_render_request(body).request; }

void append(void* context, void* data, int size) {
  static_cast<std::string*>(context)->append(static_cast<const char*>(data), std::size_t(size));
}

std::string libstb_png(const umbra::Image& image) {
  std::string out;
  stbi_write_png_to_func(append, &out, image.width, image.height, image.channels, image.pixels.data(),
                         image.width * image.channels);
  return out;
}

struct Measure {
  double median_ms;
  std::size_t bytes;
};

Measure measure(const std::function<std::string()>& encode, int reps) {
  std::vector<double> ms;
  std::size_t bytes = 0;
  for (int i = 0; i < reps; ++i) {
    const auto start = Clock::now();
    bytes = encode().size();
    ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - start).count());
  }
  std::nth_element(ms.begin(), ms.begin() + ms.size() / 2, ms.end());
  return {ms[ms.size() / 2], bytes};
}

}  // namespace

int main(int argc, char** argv) {
  int reps = 11;
  std::string out = std::string(UMBRA_RESULTS_DIR) + "/png.md";
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--reps" && i + 1 < argc) {
      reps = std::max(1, std::atoi(argv[++i]));
    } else if (arg == "--out" && i + 1 < argc) {
      out = argv[++i];
    } else {
      std::fprintf(stderr, "usage: umbra-png-bench [--reps N] [--out FILE]\n");
      return 2;
    }
  }
  umbra::RenderService renderer;
  struct Input {
    const char* name;
    umbra::Image image;
  };
  const std::vector<Input> inputs = {
      {"frame 960x540 RGB", renderer.submit(request(R"({})")).get().image},
      {"shadow 960x540 grey", renderer.submit(request(R"({"output": "shadow"})")).get().image},
      {"depth 2048^2 grey", renderer.submit(request(R"({"output": "depth"})")).get().image},
  };
  const int filters[] = {-1, 0, 1, 2, 4};
  const char* filter_names[] = {"adaptive", "none", "sub", "up", "average", "Paeth"};

  std::string table = "| image | deflate | level | filter | median ms | KiB | ms vs libstb | size vs libstb |\n"
                      "|---|---|---|---|---|---|---|---|\n";
  std::printf("%-20s %-7s %5s %-8s %10s %9s %8s %8s\n", "image", "deflate", "level", "filter", "median ms", "KiB",
              "ms x", "size x");
  for (const Input& input : inputs) {
    const Measure base = measure([&] { return libstb_png(input.image); }, reps);
    const auto row = [&](const char* deflate, int level, const char* filter, const Measure& m) {
      char line[256];
      std::snprintf(line, sizeof line, "| %s | %s | %d | %s | %.2f | %.0f | %.2f | %.2f |\n", input.name, deflate, level,
                    filter, m.median_ms, m.bytes / 1024.0, m.median_ms / base.median_ms,
                    double(m.bytes) / double(base.bytes));
      table += line;
      std::printf("%-20s %-7s %5d %-8s %10.2f %9.0f %8.2f %8.2f\n", input.name, deflate, level, filter, m.median_ms,
                  m.bytes / 1024.0, m.median_ms / base.median_ms, double(m.bytes) / double(base.bytes));
    };
    row("stb", 8, "adaptive", base);
    for (int level : {1, 2, 3, 6, 9}) {
      for (int filter : filters) {
        if (level != 1 && filter > 0) continue;  // every filter at level 1; adaptive and none at every level
        umbra::set_png_settings({level, filter});
        row("zlib", level, filter_names[filter + 1], measure([&] { return umbra::encode_png(input.image); }, reps));
      }
    }
  }
  umbra::set_png_settings({});
  const umbra::RendererInfo& info = renderer.info();
  std::ofstream file(out);
  file << "# PNG encoding: size against time\n\n"
       << "`build/bench/umbra-png-bench --reps " << reps << "`: median of " << reps
       << " encodes of each image, on one thread, on " << info.gl_renderer
       << " (rendering), 2-core AMD EPYC (the encodes). `ms x` and `size x` are relative to libstb's own deflate at "
          "its default level 8 (what Umbra used before).\n\n"
       << table;
  std::printf("wrote %s\n", out.c_str());
  return 0;
}
