// umbra-server: the headless shadow-mapping render service.
//
// Its flags are server_flags.cpp's table: each one's name, range, member and
// help line, its default being the member's own (ServerOptions,
// ServiceLimits); `umbra-server --help` prints them.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <malloc.h>
#include <pthread.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include "http_api.hpp"
#include "server_flags.hpp"
#include "assets/model_store.hpp"
#include "service/render_service.hpp"

namespace {

using Settings = umbra::ServerSettings;
using umbra::usage_text;

void usage(std::FILE* out) { std::fputs(usage_text().c_str(), out); }

}  // namespace

int main(int argc, char** argv) {
  Settings settings;
  const umbra::FlagsParsed parsed = umbra::parse_flags(std::vector<std::string>(argv + 1, argv + argc), settings);
  if (parsed.outcome == umbra::FlagsParsed::Outcome::Help) {
    usage(stdout);
    return 0;
  }
  if (parsed.outcome == umbra::FlagsParsed::Outcome::Refused) {
    std::fprintf(stderr, "umbra-server: %s\n", parsed.error.c_str());
    if (parsed.show_usage) usage(stderr);
    return 2;
  }
  umbra::ServerOptions& options = settings.options;
  const umbra::ServiceLimits& limits = settings.limits;
  const std::string& models_dir = settings.models_dir;
  const std::string& tokens_file = settings.tokens_file;
  const bool no_auth = settings.no_auth;

  if (!tokens_file.empty() && no_auth) {
    std::fprintf(stderr, "umbra-server: --tokens and --no-auth contradict each other; give one\n");
    return 2;
  }
  if (!tokens_file.empty()) {
    std::ifstream in(tokens_file, std::ios::binary);
    if (!in) {
      std::fprintf(stderr, "umbra-server: --tokens: cannot read '%s'\n", tokens_file.c_str());
      return 2;
    }
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::string why;
    auto tokens = umbra::TokenTable::parse(text, why);
    if (!tokens) {
      std::fprintf(stderr, "umbra-server: --tokens %s: %s\n", tokens_file.c_str(), why.c_str());
      return 2;
    }
    options.tokens = std::make_shared<const umbra::TokenTable>(std::move(*tokens));
    std::fprintf(stderr, "umbra-server: --tokens: %zu token(s); every route but GET /api/health and the panel's files needs one\n",
                 options.tokens->size());
  }
  // Anyone on the network could render, upload and read /metrics.
  if (!umbra::is_loopback_address(options.host) && !options.tokens && !no_auth) {
    std::fprintf(stderr,
                 "umbra-server: --host %s is not a loopback address: give --tokens FILE so that only clients with a "
                 "token are served, or --no-auth to serve anyone who can connect\n",
                 options.host.c_str());
    return 2;
  }
  if (!umbra::is_loopback_address(options.host) && umbra::AllowedHosts(options.host, options.allowed_hosts).loopback_only())
    std::fprintf(stderr,
                 "umbra-server: --host %s with no --allowed-hosts: only requests naming localhost, 127.0.0.1 or [::1] "
                 "as their Host are answered (421 otherwise); list the names clients use\n",
                 options.host.c_str());

  if (!options.model_store_dir.empty()) {
    struct stat info {};
    if (stat(options.model_store_dir.c_str(), &info) != 0 || !S_ISDIR(info.st_mode) ||
        access(options.model_store_dir.c_str(), W_OK) != 0) {
      std::fprintf(stderr, "umbra-server: --model-store: '%s' is not a folder this server can write to\n",
                   options.model_store_dir.c_str());
      return 2;
    }
  }
  if (!options.web_dir.empty()) {
    struct stat info {};
    if (stat(options.web_dir.c_str(), &info) != 0 || !S_ISDIR(info.st_mode)) {
      std::fprintf(stderr, "umbra-server: --web: '%s' is not a folder\n", options.web_dir.c_str());
      return 2;
    }
  }

  umbra::ModelStore models(umbra::model_store_limits(options));
  if (!models_dir.empty()) {
    umbra::FolderLoad loaded;
    std::string error;
    if (!umbra::load_model_folder(models_dir, models, options.max_model_bytes, loaded, error)) {
      std::fprintf(stderr, "umbra-server: --models: %s\n", error.c_str());
      return 2;
    }
    for (const auto& held : loaded.loaded)
      std::fprintf(stderr, "umbra-server: model '%s' (%s): %zu triangles\n", held->name.c_str(), held->id.c_str(),
                   held->model->triangle_count());
    // A broken file costs that model, not the server.
    for (const std::string& why : loaded.refused)
      std::fprintf(stderr, "umbra-server: --models: skipped %s\n", why.c_str());
  }
  std::vector<std::string> builtins_not_held;
  umbra::hold_builtin_models(models, builtins_not_held);
  for (const std::string& why : builtins_not_held) std::fprintf(stderr, "umbra-server: %s\n", why.c_str());

  // SIGINT and SIGTERM are blocked here, before any thread starts (threads
  // inherit the mask), and taken by one thread with sigwait: it may then do
  // what a signal handler may not, such as stopping the server.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

  // glibc gives each thread that allocates its own malloc arena (up to 8 per
  // core); memory freed in one is reused only there. The workers, the I/O
  // thread, the GL thread and llvmpipe's threads would each hold freed
  // pages of frames and PNGs. Two arenas keep resident memory close to
  // what is in use; the few large allocations per request do not contend.
  mallopt(M_ARENA_MAX, 2);
  // glibc maps blocks above a threshold afresh and gives back free memory at
  // the heap's top past another; left alone it moves both with what was
  // freed last, so a frame's few-megabyte buffers (the image, a certified
  // frame's codes and marks) were often mapped anew, and their first
  // touches page-faulted (about 1 ms of a 960x540 certified frame on
  // llvmpipe). Fixed: the heap keeps what a frame frees while requests
  // come, and the idle trim below gives it back once they stop. Blocks of
  // 4 MiB and more (large images, maps) are still mapped afresh: with the
  // speed benchmark's 32 and 64 MiB, such blocks fragmented the heap and
  // resident memory grew by a fifth over 5,000 mixed requests
  // (Memory.FiveThousandMixedRequestsHoldResidentMemorySteady).
  mallopt(M_MMAP_THRESHOLD, 4 << 20);
  mallopt(M_TRIM_THRESHOLD, 16 << 20);
  try {
    umbra::RenderService renderer(limits);
    const umbra::RendererInfo& info = renderer.info();
    std::fprintf(stderr, "umbra-server: OpenGL %s on %s (%s)\n", info.gl_version.c_str(), info.gl_renderer.c_str(),
                 info.egl_source.c_str());
    umbra::HttpApi api(renderer, models, options);
    if (!api.bind()) {
      std::fprintf(stderr, "umbra-server: cannot listen on %s:%d: %s\n", options.host.c_str(), options.port,
                   std::strerror(errno));
      return 1;
    }
    // First signal: stop accepting and close idle connections and requests
    // still arriving; requests already received are answered, then the
    // render queue drains and main returns 0. A second signal while
    // draining exits at once.
    std::atomic<bool> served{false};
    std::thread signal_waiter([&] {
      int signal = 0;
      sigwait(&stop_signals, &signal);
      if (served.load()) return;  // woken by main below, not by a signal
      std::fprintf(stderr, "umbra-server: %s: finishing %zu request(s) in flight, then stopping\n",
                   signal == SIGINT ? "SIGINT" : "SIGTERM", renderer.queue_depth());
      // A stop() before serve() has started holds: serve() then returns at
      // once. Meanwhile, watch for a second signal.
      api.stop();
      const timespec poll{0, 10 * 1000 * 1000};
      for (;;) {
        const int again = sigtimedwait(&stop_signals, nullptr, &poll);
        if (served.load()) return;
        if (again > 0) {
          std::fprintf(stderr, "umbra-server: second signal: exiting without finishing\n");
          std::_Exit(128 + again);
        }
      }
    });
    // Frames leave large freed blocks (images, PNGs, llvmpipe's scratch) in
    // the malloc arenas of whichever threads used them. Once the renderer
    // has been idle for a second, hand the free pages back to the system,
    // so that resident memory follows the work, not the history.
    std::thread idle_trimmer([&] {
      std::uint64_t seen = renderer.frames_rendered(), trimmed = seen;
      auto quiet_since = std::chrono::steady_clock::now();
      while (!served.load()) {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        const std::uint64_t frames = renderer.frames_rendered();
        const auto now = std::chrono::steady_clock::now();
        if (frames != seen || renderer.queue_depth() > 0) {
          seen = frames;
          quiet_since = now;
        } else if (trimmed != frames && now - quiet_since > std::chrono::seconds(1)) {
          malloc_trim(0);
          trimmed = frames;
        }
      }
    });
    std::fprintf(stderr, "umbra-server: listening on http://%s:%d/\n", options.host.c_str(), api.port());
    api.serve();
    served.store(true);
    idle_trimmer.join();
    pthread_kill(signal_waiter.native_handle(), SIGTERM);  // wake it; blocked signals are only queued
    signal_waiter.join();
    std::fprintf(stderr, "umbra-server: stopped\n");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "umbra-server: %s\n", e.what());
    return 1;
  }
  return 0;
}
