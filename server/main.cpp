// umbra-server: the headless shadow-mapping render service.
//
//   umbra-server [--host 127.0.0.1] [--port 8080] [--web DIR] [--queue 16] [--deadline-ms 10000]
//                [--max-request-ms 4000] [--max-request-mib 2048] [--max-run-ms 8000] [--memory-mib 2048]
//                [--fresh-context-mib 64] [--max-connections 256] [--request-timeout-ms 10000] [--cors ORIGIN] [--models DIR]
//                [--model-store DIR] [--model-store-max-gib 8] [--max-model-mib 64] [--models-budget-mib 2048]
//                [--upload-quota-mib N] [--allowed-hosts LIST] [--tokens FILE | --no-auth] [--quiet]
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

#include <malloc.h>
#include <pthread.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include "http_api.hpp"
#include "assets/model_store.hpp"
#include "service/render_service.hpp"

namespace {

void usage(std::FILE* out) {
  std::fprintf(out,
               "usage: umbra-server [--host ADDRESS] [--port N] [--web DIR] [--queue N] [--deadline-ms N]\n"
               "                    [--max-request-ms N] [--max-request-mib N] [--max-run-ms N] [--memory-mib N]\n"
               "                    [--fresh-context-mib N] [--max-connections N] [--request-timeout-ms N] [--send-stall-ms N]\n"
               "                    [--cors ORIGIN] [--models DIR]\n"
               "                    [--model-store DIR] [--model-store-max-gib N] [--max-model-mib N]\n"
               "                    [--models-budget-mib N] [--upload-quota-mib N]\n"
               "                    [--allowed-hosts LIST] [--tokens FILE | --no-auth] [--quiet]\n"
               "  --host ADDRESS  address to listen on (default 127.0.0.1: this machine only). Any other address\n"
               "                  (0.0.0.0, a LAN address, a name but localhost) needs --tokens or --no-auth\n"
               "  --port N        TCP port, 0 for any free one (default 8080)\n"
               "  --web DIR       serve the web panel from DIR instead of the copy built in\n"
               "  --queue N       renders waiting or running at most, 1..4096; more get 503 (default 16)\n"
               "  --deadline-ms N a render that waited longer gets 503 unrendered, 1..3600000 (default 10000)\n"
               "  --max-request-ms N\n"
               "                  a request estimated to take longer (ms of this 2-core llvmpipe machine) gets 422\n"
               "                  unrendered, naming what to lower, 1..3600000 (default 4000)\n"
               "  --max-request-mib N\n"
               "                  a request estimated to need more memory at its peak (MiB) gets 422, 1..1048576\n"
               "                  (default 2048)\n"
               "  --max-run-ms N  the watchdog: a render running longer (a GL frame, checked between passes and between\n"
               "                  the ~20 ms chunks a deep or long mesh is drawn in; an exact or error ray cast, between rows)\n"
               "                  is stopped with 503 and nothing of it returned, 1..3600000 (default 8000)\n"
               "  --memory-mib N  memory budget of the renderer (MiB): caches are released to fit each request and\n"
               "                  after 1.5 s idle; a request needing more alone gets 422, 64..1048576 (default 2048)\n"
               "  --fresh-context-mib N\n"
               "                  when idle, make the GL context anew once this much GL memory (MiB) was released since\n"
               "                  the last one, giving back what llvmpipe keeps until then; 0: never, 0..1048576 (default 64)\n"
               "  --max-connections N\n"
               "                  connections open at once, 1..65536; past it a new one replaces the one longest\n"
               "                  without progress (idle, receiving its request, or sending an answer the client does\n"
               "                  not read), or gets 503 if every one is being handled (default 256)\n"
               "  --request-timeout-ms N\n"
               "                  a request not received whole (headers and body) this long after its first byte\n"
               "                  gets 408 and the connection closes, 1..3600000 (default 10000)\n"
               "  --send-stall-ms N\n"
               "                  a connection whose client reads no byte of its answer this long is closed,\n"
               "                  1..3600000 (default 5000). A client's pipelined requests wait while more than\n"
               "                  1 MiB of its answers are unread\n"
               "  --cors ORIGIN   let web pages from ORIGIN (or \"*\": any) call the API; default: none\n"
               "  --models DIR    load every .glb and .gltf in DIR at start, named by file name (\"teapot\" for teapot.glb);\n"
               "                  their external buffer files are read from inside DIR only. A file that fails is\n"
               "                  skipped with its reason on stderr. Never dropped from memory (pinned)\n"
               "  --model-store DIR\n"
               "                  a folder shared with other servers (several on one machine, or a network file system):\n"
               "                  every upload is written there, named by its id, and a model this server does not hold\n"
               "                  is loaded from there, so any server behind a load balancer can render any upload\n"
               "  --model-store-max-gib N\n"
               "                  the most the --model-store folder holds, GiB of disk blocks, and at most 100000 models:\n"
               "                  before a file is written, the least recently used ones its uploader may delete go (its\n"
               "                  own; another owner's beyond its share, the fraction --upload-quota-mib is of\n"
               "                  --models-budget-mib; any unused 24 h), else 507 (give every server sharing it the same\n"
               "                  value); a model deleted so is unknown until uploaded again, 1..1048576 (default 8)\n"
               "  --max-model-mib N\n"
               "                  largest model upload (POST /api/models body) and --models file, MiB; larger gets 413,\n"
               "                  1..4095 (default 64). Every other request body stays limited to 1 MiB\n"
               "  --models-budget-mib N\n"
               "                  memory for models' geometry, MiB: every model loaded (uploaded, or read from\n"
               "                  --model-store for a render) is counted before it is built; room is made by dropping\n"
               "                  least recently used uploads its owner may drop; a scene whose models can never fit\n"
               "                  together gets 422, 1..1048576 (default 2048)\n"
               "  --upload-quota-mib N\n"
               "                  each owner's share of --models-budget-mib, MiB (an owner: a --tokens token; without\n"
               "                  tokens, all clients are one): one owner's uploads never drop another's models within\n"
               "                  its share (only beyond it, or unused for an hour); a model larger gets 422,\n"
               "                  1..1048576 (default a quarter of --models-budget-mib)\n"
               "  --allowed-hosts LIST\n"
               "                  comma-separated names or addresses (no port) a request's Host may give, besides\n"
               "                  localhost, 127.0.0.1, [::1] and the --host address (unless 0.0.0.0 or ::); any port.\n"
               "                  \"*\": any Host. Another gets 421; none or two on HTTP/1.1 get 400. With --host 0.0.0.0\n"
               "                  list the names clients use (default: none, so only loopback names are answered)\n"
               "  --tokens FILE   one \"TOKEN SCOPE[,SCOPE]\" a line (scopes: render, upload, metrics; # comments;\n"
               "                  tokens of 16+ characters of A-Z a-z 0-9 - . _ ~ + / =). Every route but GET /api/health,\n"
               "                  OPTIONS and the panel's files then needs Authorization: Bearer TOKEN with its scope:\n"
               "                  401 without a known token, 403 without the scope. Default: no tokens\n"
               "  --no-auth       serve a non-loopback --host without tokens: anyone who can connect may render,\n"
               "                  upload and read /metrics\n"
               "  --quiet         no per-request log lines\n"
               "SIGINT or SIGTERM: stop accepting, close idle connections and requests still arriving, answer the requests\n"
               "already received, exit 0 (a second one exits at once). Every render already received is answered within\n"
               "--deadline-ms + --max-run-ms of the signal (18 s at the defaults), plus the chunk in progress.\n");
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
  std::string models_dir, tokens_file;
  bool no_auth = false;
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
    } else if (arg == "--max-request-ms") {
      limits.max_request_cost =
          std::chrono::milliseconds(integer_flag("--max-request-ms", value("--max-request-ms"), 1, 3600000));
    } else if (arg == "--max-request-mib") {
      limits.max_request_bytes =
          std::uint64_t(integer_flag("--max-request-mib", value("--max-request-mib"), 1, 1048576)) << 20;
    } else if (arg == "--max-run-ms") {
      limits.max_run_time = std::chrono::milliseconds(integer_flag("--max-run-ms", value("--max-run-ms"), 1, 3600000));
    } else if (arg == "--memory-mib") {
      limits.memory_budget_bytes = std::uint64_t(integer_flag("--memory-mib", value("--memory-mib"), 64, 1048576)) << 20;
    } else if (arg == "--fresh-context-mib") {
      limits.fresh_context_bytes =
          std::uint64_t(integer_flag("--fresh-context-mib", value("--fresh-context-mib"), 0, 1048576)) << 20;
    } else if (arg == "--cors") {
      options.cors_origin = value("--cors");
      if (!umbra::valid_cors_origin(options.cors_origin)) {
        std::fprintf(stderr, "umbra-server: --cors must be \"*\" or an origin like https://app.example:8443, got '%s'\n",
                     options.cors_origin.c_str());
        return 2;
      }
    } else if (arg == "--web") {
      options.web_dir = value("--web");
    } else if (arg == "--max-connections") {
      options.connections.max_connections =
          std::size_t(integer_flag("--max-connections", value("--max-connections"), 1, 65536));
    } else if (arg == "--send-stall-ms") {
      options.connections.send_stall_timeout =
          std::chrono::milliseconds(integer_flag("--send-stall-ms", value("--send-stall-ms"), 1, 3600000));
    } else if (arg == "--request-timeout-ms") {
      options.connections.request_timeout =
          std::chrono::milliseconds(integer_flag("--request-timeout-ms", value("--request-timeout-ms"), 1, 3600000));
    } else if (arg == "--models") {
      models_dir = value("--models");
    } else if (arg == "--model-store") {
      options.model_store_dir = value("--model-store");
    } else if (arg == "--model-store-max-gib") {
      options.model_store_max_bytes =
          std::uint64_t(integer_flag("--model-store-max-gib", value("--model-store-max-gib"), 1, 1048576)) << 30;
    } else if (arg == "--upload-quota-mib") {
      options.upload_share_bytes =
          std::uint64_t(integer_flag("--upload-quota-mib", value("--upload-quota-mib"), 1, 1048576)) << 20;
    } else if (arg == "--max-model-mib") {
      options.max_model_bytes = std::size_t(integer_flag("--max-model-mib", value("--max-model-mib"), 1, 4095)) << 20;
    } else if (arg == "--models-budget-mib") {
      options.models_budget_bytes =
          std::uint64_t(integer_flag("--models-budget-mib", value("--models-budget-mib"), 1, 1048576)) << 20;
    } else if (arg == "--allowed-hosts") {
      std::string why;
      if (!umbra::AllowedHosts::parse_list(value("--allowed-hosts"), options.allowed_hosts, why)) {
        std::fprintf(stderr, "umbra-server: --allowed-hosts: %s\n", why.c_str());
        return 2;
      }
    } else if (arg == "--tokens") {
      tokens_file = value("--tokens");
    } else if (arg == "--no-auth") {
      no_auth = true;
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
