// umbra-server's command-line flags: one table (server_flags.cpp) of each
// flag's name, argument, range, the member it sets and its help line, each
// default being its member's own (ServerOptions, ServiceLimits). The usage
// text and the parser are made from it; main.cpp only acts on the result.
#pragma once

#include <string>
#include <vector>

#include "http_api.hpp"
#include "service/render_service.hpp"

namespace umbra {

// What the flags set.
struct ServerSettings {
  ServerOptions options;
  ServiceLimits limits;
  std::string models_dir, tokens_file;
  bool no_auth = false;
};

/// What the command line asked for.
struct FlagsParsed {
  enum class Outcome {
    Run,      ///< every flag read into the settings
    Help,     ///< --help or -h: print usage_text() and exit 0
    Refused,  ///< `error` says why (exit 2); with show_usage, print the usage too
  } outcome = Outcome::Run;
  std::string error;  ///< e.g. "--queue must be 1..4096, got '0'"
  bool show_usage = false;
};

/// Reads `args` (argv without the program's name) into `settings`, in order:
/// the first flag refused ends the reading, as does --help.
FlagsParsed parse_flags(const std::vector<std::string>& args, ServerSettings& settings);

/// The synopsis, every flag's help with its range and default, and what
/// SIGINT and SIGTERM do: `umbra-server --help`.
std::string usage_text();

}  // namespace umbra
