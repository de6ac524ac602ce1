// umbra-server: the headless shadow-mapping render service.
//
// Its flags are the table flags() below: each one's name, range, member and
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
#include "assets/model_store.hpp"
#include "service/render_service.hpp"

namespace {

// What the flags set.
struct Settings {
  umbra::ServerOptions options;
  umbra::ServiceLimits limits;
  std::string models_dir, tokens_file;
  bool no_auth = false;
};

// One command-line flag. A whole-number flag has a range and a member (in
// the flag's unit: MiB, ms), its default being what a default Settings
// holds; any other flag stores its text (empty for a switch) itself, or
// refuses it saying why. In `help`, "{range}" becomes "min..max" and
// "{default}" the default; '\n' starts another line.
struct Flag {
  const char* name;
  const char* value;  // the argument's name in the usage, nullptr for a switch
  const char* help;
  long min = 0, max = 0;
  long (*number_default)(const Settings&) = nullptr;
  void (*store_number)(Settings&, long) = nullptr;
  bool (*store_text)(Settings&, const std::string& text, std::string& why) = nullptr;
  std::string (*text_default)(const Settings&) = nullptr;  // "{default}" of a text flag
  bool or_next = false;  // the usage line offers it or the next one, not both
};

using Ms = std::chrono::milliseconds;

Flag number_flag(const char* name, const char* help, long min, long max, long (*number_default)(const Settings&),
                 void (*store)(Settings&, long)) {
  return Flag{name, "N", help, min, max, number_default, store};
}
Flag text_flag(const char* name, const char* value, const char* help,
               bool (*store)(Settings&, const std::string&, std::string&)) {
  Flag f{name, value, help};
  f.store_text = store;
  return f;
}

const std::vector<Flag>& flags() {
  static const std::vector<Flag> table = [] {
    std::vector<Flag> f = {
        text_flag("--host", "ADDRESS",
                  "address to listen on (default {default}: this machine only). Any other address\n"
                  "(0.0.0.0, a LAN address, a name but localhost) needs --tokens or --no-auth",
                  [](Settings& s, const std::string& t, std::string&) {
                    s.options.host = t;
                    return true;
                  }),
        number_flag("--port", "TCP port, 0 for any free one (default {default})", 0, 65535,
                    [](const Settings& s) { return long(s.options.port); },
                    [](Settings& s, long v) { s.options.port = int(v); }),
        text_flag("--web", "DIR", "serve the web panel from DIR instead of the copy built in",
                  [](Settings& s, const std::string& t, std::string&) {
                    s.options.web_dir = t;
                    return true;
                  }),
        number_flag("--queue", "renders waiting or running at most, {range}; more get 503 (default {default})", 1, 4096,
                    [](const Settings& s) { return long(s.limits.queue_capacity); },
                    [](Settings& s, long v) { s.limits.queue_capacity = std::size_t(v); }),
        number_flag("--deadline-ms", "a render that waited longer gets 503 unrendered, {range} (default {default})", 1,
                    3600000, [](const Settings& s) { return long(s.limits.deadline.count()); },
                    [](Settings& s, long v) { s.limits.deadline = Ms(v); }),
        number_flag("--max-request-ms",
                    "a request estimated to take longer (ms of this 2-core llvmpipe machine) gets 422\n"
                    "unrendered, naming what to lower, {range} (default {default})",
                    1, 3600000, [](const Settings& s) { return long(s.limits.max_request_cost.count()); },
                    [](Settings& s, long v) { s.limits.max_request_cost = Ms(v); }),
        number_flag("--max-request-mib",
                    "a request estimated to need more memory at its peak (MiB) gets 422, {range}\n"
                    "(default {default})",
                    1, 1048576, [](const Settings& s) { return long(s.limits.max_request_bytes >> 20); },
                    [](Settings& s, long v) { s.limits.max_request_bytes = std::uint64_t(v) << 20; }),
        number_flag("--max-run-ms",
                    "the watchdog: a render running longer (a GL frame, checked between passes and between\n"
                    "the ~20 ms chunks a deep or long mesh is drawn in; an exact or error ray cast, between rows)\n"
                    "is stopped with 503 and nothing of it returned, {range} (default {default})",
                    1, 3600000, [](const Settings& s) { return long(s.limits.max_run_time.count()); },
                    [](Settings& s, long v) { s.limits.max_run_time = Ms(v); }),
        number_flag("--memory-mib",
                    "memory budget of the renderer (MiB): caches are released to fit each request and\n"
                    "after 1.5 s idle; a request needing more alone gets 422, {range} (default {default})",
                    64, 1048576, [](const Settings& s) { return long(s.limits.memory_budget_bytes >> 20); },
                    [](Settings& s, long v) { s.limits.memory_budget_bytes = std::uint64_t(v) << 20; }),
        number_flag("--fresh-context-mib",
                    "when idle, make the GL context anew once this much GL memory (MiB) was released since\n"
                    "the last one, giving back what llvmpipe keeps until then; 0: never, {range} (default {default})",
                    0, 1048576, [](const Settings& s) { return long(s.limits.fresh_context_bytes >> 20); },
                    [](Settings& s, long v) { s.limits.fresh_context_bytes = std::uint64_t(v) << 20; }),
        number_flag("--max-connections",
                    "connections open at once, {range}; past it a new one replaces the one longest\n"
                    "without progress (idle, receiving its request, or sending an answer the client does\n"
                    "not read), or gets 503 if every one is being handled (default {default})",
                    1, 65536, [](const Settings& s) { return long(s.options.connections.max_connections); },
                    [](Settings& s, long v) { s.options.connections.max_connections = std::size_t(v); }),
        number_flag("--request-timeout-ms",
                    "a request not received whole (headers and body) this long after its first byte\n"
                    "gets 408 and the connection closes, {range} (default {default})",
                    1, 3600000, [](const Settings& s) { return long(s.options.connections.request_timeout.count()); },
                    [](Settings& s, long v) { s.options.connections.request_timeout = Ms(v); }),
        number_flag("--send-stall-ms",
                    "a connection whose client reads no byte of its answer this long is closed,\n"
                    "{range} (default {default}). A client's pipelined requests wait while more than\n"
                    "1 MiB of its answers are unread",
                    1, 3600000, [](const Settings& s) { return long(s.options.connections.send_stall_timeout.count()); },
                    [](Settings& s, long v) { s.options.connections.send_stall_timeout = Ms(v); }),
        text_flag("--cors", "ORIGIN", "let web pages from ORIGIN (or \"*\": any) call the API; default: none",
                  [](Settings& s, const std::string& t, std::string& why) {
                    s.options.cors_origin = t;
                    if (umbra::valid_cors_origin(t)) return true;
                    why = "--cors must be \"*\" or an origin like https://app.example:8443, got '" + t + "'";
                    return false;
                  }),
        text_flag("--models", "DIR",
                  "load every .glb and .gltf in DIR at start, named by file name (\"teapot\" for teapot.glb);\n"
                  "their external buffer files are read from inside DIR only. A file that fails is\n"
                  "skipped with its reason on stderr. Never dropped from memory (pinned)",
                  [](Settings& s, const std::string& t, std::string&) {
                    s.models_dir = t;
                    return true;
                  }),
        text_flag("--model-store", "DIR",
                  "a folder shared with other servers (several on one machine, or a network file system):\n"
                  "every upload is written there, named by its id, and a model this server does not hold\n"
                  "is loaded from there, so any server behind a load balancer can render any upload",
                  [](Settings& s, const std::string& t, std::string&) {
                    s.options.model_store_dir = t;
                    return true;
                  }),
        number_flag("--model-store-max-gib",
                    "the most the --model-store folder holds, GiB of disk blocks, and at most 100000 models:\n"
                    "before a file is written, the least recently used ones its uploader may delete go (its\n"
                    "own; another owner's beyond its share, the fraction --upload-quota-mib is of\n"
                    "--models-budget-mib; any unused 24 h), else 507 (give every server sharing it the same\n"
                    "value); a model deleted so is unknown until uploaded again, {range} (default {default})",
                    1, 1048576, [](const Settings& s) { return long(s.options.model_store_max_bytes >> 30); },
                    [](Settings& s, long v) { s.options.model_store_max_bytes = std::uint64_t(v) << 30; }),
        number_flag("--max-model-mib",
                    "largest model upload (POST /api/models body) and --models file, MiB; larger gets 413,\n"
                    "{range} (default {default}). Every other request body stays limited to 1 MiB",
                    1, 4095, [](const Settings& s) { return long(s.options.max_model_bytes >> 20); },
                    [](Settings& s, long v) { s.options.max_model_bytes = std::size_t(v) << 20; }),
        number_flag("--models-budget-mib",
                    "memory for models' geometry, MiB: every model loaded (uploaded, or read from\n"
                    "--model-store for a render) is counted before it is built; room is made by dropping\n"
                    "least recently used uploads its owner may drop; a scene whose models can never fit\n"
                    "together gets 422, {range} (default {default})",
                    1, 1048576, [](const Settings& s) { return long(s.options.models_budget_bytes >> 20); },
                    [](Settings& s, long v) { s.options.models_budget_bytes = std::uint64_t(v) << 20; }),
        // Its default (0 in ServerOptions) is a fraction of another flag's value.
        number_flag("--upload-quota-mib",
                    "each owner's share of --models-budget-mib, MiB (an owner: a --tokens token; without\n"
                    "tokens, all clients are one): one owner's uploads never drop another's models within\n"
                    "its share (only beyond it, or unused for an hour); a model larger gets 422,\n"
                    "{range} (default a quarter of --models-budget-mib)",
                    1, 1048576, nullptr,
                    [](Settings& s, long v) { s.options.upload_share_bytes = std::uint64_t(v) << 20; }),
        text_flag("--allowed-hosts", "LIST",
                  "comma-separated names or addresses (no port) a request's Host may give, besides\n"
                  "localhost, 127.0.0.1, [::1] and the --host address (unless 0.0.0.0 or ::); any port.\n"
                  "\"*\": any Host. Another gets 421; none or two on HTTP/1.1 get 400. With --host 0.0.0.0\n"
                  "list the names clients use (default: none, so only loopback names are answered)",
                  [](Settings& s, const std::string& t, std::string& why) {
                    if (umbra::AllowedHosts::parse_list(t, s.options.allowed_hosts, why)) return true;
                    why = "--allowed-hosts: " + why;
                    return false;
                  }),
        text_flag("--tokens", "FILE",
                  "one \"TOKEN SCOPE[,SCOPE]\" a line (scopes: render, upload, metrics; # comments;\n"
                  "tokens of 16+ characters of A-Z a-z 0-9 - . _ ~ + / =). Every route but GET /api/health,\n"
                  "OPTIONS and the panel's files then needs Authorization: Bearer TOKEN with its scope:\n"
                  "401 without a known token, 403 without the scope. Default: no tokens",
                  [](Settings& s, const std::string& t, std::string&) {
                    s.tokens_file = t;
                    return true;
                  }),
        text_flag("--no-auth", nullptr,
                  "serve a non-loopback --host without tokens: anyone who can connect may render,\n"
                  "upload and read /metrics",
                  [](Settings& s, const std::string&, std::string&) {
                    s.no_auth = true;
                    return true;
                  }),
        text_flag("--quiet", nullptr, "no per-request log lines",
                  [](Settings& s, const std::string&, std::string&) {
                    s.options.log_requests = false;
                    return true;
                  }),
    };
    for (Flag& flag : f) {
      if (std::string(flag.name) == "--host") flag.text_default = [](const Settings& s) { return s.options.host; };
      if (std::string(flag.name) == "--tokens") flag.or_next = true;
    }
    return f;
  }();
  return table;
}

// `text` with every `from` replaced by `to`.
std::string replaced(std::string text, const std::string& from, const std::string& to) {
  for (auto at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size()))
    text.replace(at, from.size(), to);
  return text;
}

std::string usage_text() {
  const Settings defaults;
  // The synopsis: every flag, wrapped.
  std::string text = "usage: umbra-server", line = text;
  const auto& all = flags();
  for (std::size_t i = 0; i < all.size(); ++i) {
    std::string item = std::string("[") + all[i].name + (all[i].value ? std::string(" ") + all[i].value : "");
    while (all[i].or_next && i + 1 < all.size()) {
      ++i;
      item += std::string(" | ") + all[i].name + (all[i].value ? std::string(" ") + all[i].value : "");
    }
    item += "]";
    if (line.size() + 1 + item.size() > 110) {
      text += "\n" + std::string(19, ' ');
      line = std::string(19, ' ');
    }
    text += " " + item;
    line += " " + item;
  }
  text += "\n";
  // Each flag's help: beside its name if that is short, else below it.
  constexpr std::size_t kColumn = 18;
  for (const Flag& flag : all) {
    std::string help = flag.help;
    help = replaced(help, "{range}", std::to_string(flag.min) + ".." + std::to_string(flag.max));
    if (flag.number_default) help = replaced(help, "{default}", std::to_string(flag.number_default(defaults)));
    if (flag.text_default) help = replaced(help, "{default}", flag.text_default(defaults));
    const std::string name = std::string(flag.name) + (flag.value ? std::string(" ") + flag.value : "");
    text += "  " + name;
    if (name.size() + 2 < kColumn)
      text += std::string(kColumn - 2 - name.size(), ' ');
    else
      text += "\n" + std::string(kColumn, ' ');
    text += replaced(help, "\n", "\n" + std::string(kColumn, ' ')) + "\n";
  }
  const long drain_s = long((defaults.limits.deadline + defaults.limits.max_run_time).count() / 1000);
  text += "SIGINT or SIGTERM: stop accepting, close idle connections and requests still arriving, answer the requests\n"
          "already received, exit 0 (a second one exits at once). Every render already received is answered within\n"
          "--deadline-ms + --max-run-ms of the signal (" +
          std::to_string(drain_s) + " s at the defaults), plus the chunk in progress.\n";
  return text;
}

void usage(std::FILE* out) { std::fputs(usage_text().c_str(), out); }

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
  Settings settings;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      usage(stdout);
      return 0;
    }
    const auto& all = flags();
    const auto flag = std::find_if(all.begin(), all.end(), [&](const Flag& f) { return arg == f.name; });
    if (flag == all.end()) {
      std::fprintf(stderr, "umbra-server: unknown option '%s'\n", arg.c_str());
      usage(stderr);
      return 2;
    }
    std::string text;
    if (flag->value != nullptr) {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "umbra-server: %s needs a value\n", flag->name);
        return 2;
      }
      text = argv[++i];
    }
    if (flag->store_number) {
      flag->store_number(settings, integer_flag(flag->name, text, flag->min, flag->max));
    } else {
      std::string why;
      if (!flag->store_text(settings, text, why)) {
        std::fprintf(stderr, "umbra-server: %s\n", why.c_str());
        return 2;
      }
    }
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
