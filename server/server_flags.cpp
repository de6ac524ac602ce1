#include "server_flags.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdint>
#include <cstdlib>

#include "access.hpp"

namespace umbra {

namespace {

// One command-line flag. A whole-number flag has a range and a member (in
// the flag's unit: MiB, ms), its default being what a default ServerSettings
// holds; any other flag stores its text (empty for a switch) itself, or
// refuses it saying why. In `help`, "{range}" becomes "min..max" and
// "{default}" the default; '\n' starts another line.
struct Flag {
  const char* name;
  const char* value;  // the argument's name in the usage, nullptr for a switch
  const char* help;
  long min = 0, max = 0;
  long (*number_default)(const ServerSettings&) = nullptr;
  void (*store_number)(ServerSettings&, long) = nullptr;
  bool (*store_text)(ServerSettings&, const std::string& text, std::string& why) = nullptr;
  std::string (*text_default)(const ServerSettings&) = nullptr;  // "{default}" of a text flag
  bool or_next = false;  // the usage line offers it or the next one, not both
};

using Ms = std::chrono::milliseconds;

Flag number_flag(const char* name, const char* help, long min, long max, long (*number_default)(const ServerSettings&),
                 void (*store)(ServerSettings&, long)) {
  return Flag{name, "N", help, min, max, number_default, store};
}
Flag text_flag(const char* name, const char* value, const char* help,
               bool (*store)(ServerSettings&, const std::string&, std::string&)) {
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
                  [](ServerSettings& s, const std::string& t, std::string&) {
                    s.options.host = t;
                    return true;
                  }),
        number_flag("--port", "TCP port, 0 for any free one (default {default})", 0, 65535,
                    [](const ServerSettings& s) { return long(s.options.port); },
                    [](ServerSettings& s, long v) { s.options.port = int(v); }),
        text_flag("--web", "DIR", "serve the web panel from DIR instead of the copy built in",
                  [](ServerSettings& s, const std::string& t, std::string&) {
                    s.options.web_dir = t;
                    return true;
                  }),
        number_flag("--queue", "renders waiting or running at most, {range}; more get 503 (default {default})", 1, 4096,
                    [](const ServerSettings& s) { return long(s.limits.queue_capacity); },
                    [](ServerSettings& s, long v) { s.limits.queue_capacity = std::size_t(v); }),
        number_flag("--deadline-ms", "a render that waited longer gets 503 unrendered, {range} (default {default})", 1,
                    3600000, [](const ServerSettings& s) { return long(s.limits.deadline.count()); },
                    [](ServerSettings& s, long v) { s.limits.deadline = Ms(v); }),
        number_flag("--max-request-ms",
                    "a request estimated to take longer (ms of this 2-core llvmpipe machine) gets 422\n"
                    "unrendered, naming what to lower, {range} (default {default})",
                    1, 3600000, [](const ServerSettings& s) { return long(s.limits.max_request_cost.count()); },
                    [](ServerSettings& s, long v) { s.limits.max_request_cost = Ms(v); }),
        number_flag("--max-request-mib",
                    "a request estimated to need more memory at its peak (MiB) gets 422, {range}\n"
                    "(default {default})",
                    1, 1048576, [](const ServerSettings& s) { return long(s.limits.max_request_bytes >> 20); },
                    [](ServerSettings& s, long v) { s.limits.max_request_bytes = std::uint64_t(v) << 20; }),
        number_flag("--max-run-ms",
                    "the watchdog: a render running longer (a GL frame, checked between passes and between\n"
                    "the ~20 ms chunks a deep or long mesh is drawn in; an exact or error ray cast, between rows)\n"
                    "is stopped with 503 and nothing of it returned, {range} (default {default})",
                    1, 3600000, [](const ServerSettings& s) { return long(s.limits.max_run_time.count()); },
                    [](ServerSettings& s, long v) { s.limits.max_run_time = Ms(v); }),
        number_flag("--max-job-ms",
                    "a sun-hours analysis estimated over --max-request-ms runs as a job (202; GET\n"
                    "/api/sun-hours/jobs/ID) if estimated within this (ms); more gets 422. Jobs run one at\n"
                    "a time, each stopped at twice this, {range} (default {default})",
                    1, 86400000, [](const ServerSettings& s) { return long(s.limits.max_job_cost.count()); },
                    [](ServerSettings& s, long v) { s.limits.max_job_cost = Ms(v); }),
        number_flag("--job-keep-s",
                    "how long a finished sun-hours job's result is kept for its GET (s); at most 16 jobs\n"
                    "are held, {range} (default {default})",
                    1, 604800, [](const ServerSettings& s) { return long(s.options.jobs.keep.count()); },
                    [](ServerSettings& s, long v) { s.options.jobs.keep = std::chrono::seconds(v); }),
        number_flag("--memory-mib",
                    "memory budget of the renderer (MiB): caches are released to fit each request and\n"
                    "after 1.5 s idle; a request needing more alone gets 422, {range} (default {default})",
                    64, 1048576, [](const ServerSettings& s) { return long(s.limits.memory_budget_bytes >> 20); },
                    [](ServerSettings& s, long v) { s.limits.memory_budget_bytes = std::uint64_t(v) << 20; }),
        number_flag("--fresh-context-mib",
                    "when idle, make the GL context anew once this much GL memory (MiB) was released since\n"
                    "the last one, giving back what llvmpipe keeps until then; 0: never, {range} (default {default})",
                    0, 1048576, [](const ServerSettings& s) { return long(s.limits.fresh_context_bytes >> 20); },
                    [](ServerSettings& s, long v) { s.limits.fresh_context_bytes = std::uint64_t(v) << 20; }),
        number_flag("--max-connections",
                    "connections open at once, {range}; past it a new one replaces the one longest\n"
                    "without progress (idle, receiving its request, or sending an answer the client does\n"
                    "not read), or gets 503 if every one is being handled (default {default})",
                    1, 65536, [](const ServerSettings& s) { return long(s.options.connections.max_connections); },
                    [](ServerSettings& s, long v) { s.options.connections.max_connections = std::size_t(v); }),
        number_flag("--request-timeout-ms",
                    "a request not received whole (headers and body) this long after its first byte\n"
                    "gets 408 and the connection closes, {range} (default {default})",
                    1, 3600000, [](const ServerSettings& s) { return long(s.options.connections.request_timeout.count()); },
                    [](ServerSettings& s, long v) { s.options.connections.request_timeout = Ms(v); }),
        number_flag("--send-stall-ms",
                    "a connection whose client reads no byte of its answer this long is closed,\n"
                    "{range} (default {default}). A client's pipelined requests wait while more than\n"
                    "1 MiB of its answers are unread",
                    1, 3600000, [](const ServerSettings& s) { return long(s.options.connections.send_stall_timeout.count()); },
                    [](ServerSettings& s, long v) { s.options.connections.send_stall_timeout = Ms(v); }),
        text_flag("--cors", "ORIGIN", "let web pages from ORIGIN (or \"*\": any) call the API; default: none",
                  [](ServerSettings& s, const std::string& t, std::string& why) {
                    s.options.cors_origin = t;
                    if (valid_cors_origin(t)) return true;
                    why = "--cors must be \"*\" or an origin like https://app.example:8443, got '" + t + "'";
                    return false;
                  }),
        text_flag("--models", "DIR",
                  "load every .glb and .gltf in DIR at start, named by file name (\"teapot\" for teapot.glb);\n"
                  "their external buffer files are read from inside DIR only. A file that fails is\n"
                  "skipped with its reason on stderr. Never dropped from memory (pinned)",
                  [](ServerSettings& s, const std::string& t, std::string&) {
                    s.models_dir = t;
                    return true;
                  }),
        text_flag("--name", "NAME",
                  "this server's name behind a load balancer (letters, digits, '-' and '_'): sun-hours job\n"
                  "ids begin with NAME., so that the balancer can send a job's requests back here\n"
                  "(scripts/cluster.sh gives render1, render2, ...)",
                  [](ServerSettings& s, const std::string& t, std::string& why) {
                    const bool ok = !t.empty() && t.size() <= 32 &&
                                    std::all_of(t.begin(), t.end(), [](unsigned char c) {
                                      return std::isalnum(c) || c == '-' || c == '_';
                                    });
                    if (!ok) {
                      why = "--name takes 1 to 32 letters, digits, '-' or '_'";
                      return false;
                    }
                    s.options.name = t;
                    return true;
                  }),
        text_flag("--model-importer", "PATH",
                  "the umbra-model-import program that converts OBJ, STL, PLY, DAE, FBX, 3DS and IFC\n"
                  "uploads to glTF (default: the one beside this umbra-server)",
                  [](ServerSettings& s, const std::string& t, std::string& why) {
                    if (t.empty()) {
                      why = "must name a program";
                      return false;
                    }
                    s.options.model_importer = t;
                    return true;
                  }),
        text_flag("--model-store", "DIR",
                  "a folder shared with other servers (several on one machine, or a network file system):\n"
                  "every upload is written there, named by its id, and a model this server does not hold\n"
                  "is loaded from there, so any server behind a load balancer can render any upload",
                  [](ServerSettings& s, const std::string& t, std::string&) {
                    s.options.model_store_dir = t;
                    return true;
                  }),
        number_flag("--model-store-max-gib",
                    "the most the --model-store folder holds, GiB of disk blocks, and at most 100000 models:\n"
                    "before a file is written, the least recently used ones its uploader may delete go (its\n"
                    "own; another owner's beyond its share, the fraction --upload-quota-mib is of\n"
                    "--models-budget-mib; any unused 24 h), else 507 (give every server sharing it the same\n"
                    "value); a model deleted so is unknown until uploaded again, {range} (default {default})",
                    1, 1048576, [](const ServerSettings& s) { return long(s.options.model_store_max_bytes >> 30); },
                    [](ServerSettings& s, long v) { s.options.model_store_max_bytes = std::uint64_t(v) << 30; }),
        number_flag("--max-model-mib",
                    "largest model upload (POST /api/models body) and --models file, MiB; larger gets 413,\n"
                    "{range} (default {default}). Every other request body stays limited to 1 MiB",
                    1, 4095, [](const ServerSettings& s) { return long(s.options.max_model_bytes >> 20); },
                    [](ServerSettings& s, long v) { s.options.max_model_bytes = std::size_t(v) << 20; }),
        number_flag("--models-budget-mib",
                    "memory for models' geometry, MiB: every model loaded (uploaded, or read from\n"
                    "--model-store for a render) is counted before it is built; room is made by dropping\n"
                    "least recently used uploads its owner may drop; a scene whose models can never fit\n"
                    "together gets 422, {range} (default {default})",
                    1, 1048576, [](const ServerSettings& s) { return long(s.options.models_budget_bytes >> 20); },
                    [](ServerSettings& s, long v) { s.options.models_budget_bytes = std::uint64_t(v) << 20; }),
        // Its default (0 in ServerOptions) is a fraction of another flag's value.
        number_flag("--upload-quota-mib",
                    "each owner's share of --models-budget-mib, MiB (an owner: a --tokens token; without\n"
                    "tokens, all clients are one): one owner's uploads never drop another's models within\n"
                    "its share (only beyond it, or unused for an hour); a model larger gets 422,\n"
                    "{range} (default a quarter of --models-budget-mib)",
                    1, 1048576, nullptr,
                    [](ServerSettings& s, long v) { s.options.upload_share_bytes = std::uint64_t(v) << 20; }),
        text_flag("--allowed-hosts", "LIST",
                  "comma-separated names or addresses (no port) a request's Host may give, besides\n"
                  "localhost, 127.0.0.1, [::1] and the --host address (unless 0.0.0.0 or ::); any port.\n"
                  "\"*\": any Host. Another gets 421; none or two on HTTP/1.1 get 400. With --host 0.0.0.0\n"
                  "list the names clients use (default: none, so only loopback names are answered)",
                  [](ServerSettings& s, const std::string& t, std::string& why) {
                    if (AllowedHosts::parse_list(t, s.options.allowed_hosts, why)) return true;
                    why = "--allowed-hosts: " + why;
                    return false;
                  }),
        text_flag("--tokens", "FILE",
                  "one \"TOKEN SCOPE[,SCOPE]\" a line (scopes: render, upload, metrics; # comments;\n"
                  "tokens of 16+ characters of A-Z a-z 0-9 - . _ ~ + / =). Every route but GET /api/health,\n"
                  "OPTIONS and the panel's files then needs Authorization: Bearer TOKEN with its scope:\n"
                  "401 without a known token, 403 without the scope. Default: no tokens",
                  [](ServerSettings& s, const std::string& t, std::string&) {
                    s.tokens_file = t;
                    return true;
                  }),
        text_flag("--no-auth", nullptr,
                  "serve a non-loopback --host without tokens: anyone who can connect may render,\n"
                  "upload and read /metrics",
                  [](ServerSettings& s, const std::string&, std::string&) {
                    s.no_auth = true;
                    return true;
                  }),
        text_flag("--quiet", nullptr, "no per-request log lines",
                  [](ServerSettings& s, const std::string&, std::string&) {
                    s.options.log_requests = false;
                    return true;
                  }),
    };
    for (Flag& flag : f) {
      if (std::string(flag.name) == "--host") flag.text_default = [](const ServerSettings& s) { return s.options.host; };
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

// A whole number in [lo, hi]; else false with `why` naming the flag.
bool integer_flag(const char* flag, const std::string& text, long lo, long hi, long& value, std::string& why) {
  char* end = nullptr;
  const long v = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || v < lo || v > hi) {
    why = std::string(flag) + " must be " + std::to_string(lo) + ".." + std::to_string(hi) + ", got '" + text + "'";
    return false;
  }
  value = v;
  return true;
}

}  // namespace

std::string usage_text() {
  const ServerSettings defaults;
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

FlagsParsed parse_flags(const std::vector<std::string>& args, ServerSettings& settings) {
  FlagsParsed parsed;
  const auto refuse = [&](std::string why, bool show_usage = false) {
    parsed.outcome = FlagsParsed::Outcome::Refused;
    parsed.error = std::move(why);
    parsed.show_usage = show_usage;
    return parsed;
  };
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg == "--help" || arg == "-h") {
      parsed.outcome = FlagsParsed::Outcome::Help;
      return parsed;
    }
    const auto& all = flags();
    const auto flag = std::find_if(all.begin(), all.end(), [&](const Flag& f) { return arg == f.name; });
    if (flag == all.end()) return refuse("unknown option '" + arg + "'", true);
    std::string text;
    if (flag->value != nullptr) {
      if (i + 1 >= args.size()) return refuse(std::string(flag->name) + " needs a value");
      text = args[++i];
    }
    std::string why;
    if (flag->store_number) {
      long value = 0;
      if (!integer_flag(flag->name, text, flag->min, flag->max, value, why)) return refuse(why);
      flag->store_number(settings, value);
    } else if (!flag->store_text(settings, text, why)) {
      return refuse(why);
    }
  }
  return parsed;
}

}  // namespace umbra
