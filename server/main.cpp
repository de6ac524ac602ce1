// umbra-server: the headless shadow-mapping render service.
//
//   umbra-server [--host 127.0.0.1] [--port 8080] [--web DIR] [--queue 16] [--deadline-ms 10000] [--quiet]
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>

#include "http_api.hpp"
#include "render_service.hpp"

namespace {

umbra::HttpApi* g_api = nullptr;

void usage(std::FILE* out) {
  std::fprintf(out,
               "usage: umbra-server [--host ADDRESS] [--port N] [--web DIR] [--queue N] [--deadline-ms N] [--quiet]\n"
               "  --host ADDRESS  address to listen on (default 127.0.0.1: this machine only)\n"
               "  --port N        TCP port, 0 for any free one (default 8080)\n"
               "  --web DIR       serve the web panel from DIR instead of the copy built in\n"
               "  --queue N       renders waiting or running at most, 1..4096; more get 503 (default 16)\n"
               "  --deadline-ms N a render that waited longer gets 503 unrendered, 1..3600000 (default 10000)\n"
               "  --quiet         no per-request log lines\n");
}

}  // namespace

// A whole number in [lo, hi], or exit 2 naming the flag.
static long integer_flag(const char* flag, const std::string& text, long lo, long hi) {
  char* end = nullptr;
  const long v = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || v < lo || v > hi) {
    std::fprintf(stderr, "umbra-server: %s must be %ld..%ld, got '%s'\n", flag, lo, hi, text.c_str());
    std::exit(2);
  }
  return v;
}

int main(int argc, char** argv) {
  umbra::ServerOptions options;
  umbra::ServiceLimits limits;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const auto value = [&](const char* name) -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "umbra-server: %s needs a value\n", name);
        std::exit(2);
      }
      return argv[++i];
    };
    if (arg == "--host") {
      options.host = value("--host");
    } else if (arg == "--port") {
      options.port = int(integer_flag("--port", value("--port"), 0, 65535));
    } else if (arg == "--queue") {
      limits.queue_capacity = std::size_t(integer_flag("--queue", value("--queue"), 1, 4096));
    } else if (arg == "--deadline-ms") {
      limits.deadline = std::chrono::milliseconds(integer_flag("--deadline-ms", value("--deadline-ms"), 1, 3600000));
    } else if (arg == "--web") {
      options.web_dir = value("--web");
    } else if (arg == "--quiet") {
      options.log_requests = false;
    } else if (arg == "--help" || arg == "-h") {
      usage(stdout);
      return 0;
    } else {
      std::fprintf(stderr, "umbra-server: unknown option '%s'\n", arg.c_str());
      usage(stderr);
      return 2;
    }
  }

  try {
    umbra::RenderService renderer(limits);
    const umbra::RendererInfo& info = renderer.info();
    std::fprintf(stderr, "umbra-server: OpenGL %s on %s (%s)\n", info.gl_version.c_str(), info.gl_renderer.c_str(),
                 info.egl_source.c_str());
    umbra::HttpApi api(renderer, options);
    if (!api.bind()) {
      std::fprintf(stderr, "umbra-server: cannot listen on %s:%d: %s\n", options.host.c_str(), options.port,
                   std::strerror(errno));
      return 1;
    }
    g_api = &api;
    std::signal(SIGINT, [](int) { if (g_api) g_api->stop(); });
    std::signal(SIGTERM, [](int) { if (g_api) g_api->stop(); });
    std::fprintf(stderr, "umbra-server: listening on http://%s:%d/\n", options.host.c_str(), api.port());
    api.serve();
    g_api = nullptr;
    std::fprintf(stderr, "umbra-server: stopped\n");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "umbra-server: %s\n", e.what());
    return 1;
  }
  return 0;
}
