// umbra-server's flag table (server/server_flags.hpp): the usage text shows
// each default as its member holds it, the parser stores each flag in its
// member and refuses what the help line's range leaves out, naming the flag.
#include <gtest/gtest.h>

#include <regex>
#include <string>
#include <vector>

#include "server_flags.hpp"

namespace umbra {
namespace {

// The "(default N)" --help prints for `flag`, or "" if none.
std::string printed_default(const std::string& flag) {
  const std::string usage = usage_text();
  const auto at = usage.find("\n  " + flag + " ");
  if (at == std::string::npos) return "";
  const auto next = usage.find("\n  --", at + 1);
  const std::string help = usage.substr(at, next == std::string::npos ? std::string::npos : next - at);
  std::smatch m;
  return std::regex_search(help, m, std::regex(R"(\(default ([0-9.]+))")) ? m[1].str() : "";
}

TEST(ServerFlags, TheUsageShowsEachDefaultAsItsMemberHoldsIt) {
  const ServerSettings defaults;
  EXPECT_EQ(printed_default("--queue"), std::to_string(defaults.limits.queue_capacity));
  EXPECT_EQ(printed_default("--deadline-ms"), std::to_string(defaults.limits.deadline.count()));
  EXPECT_EQ(printed_default("--max-run-ms"), std::to_string(defaults.limits.max_run_time.count()));
  EXPECT_EQ(printed_default("--memory-mib"), std::to_string(defaults.limits.memory_budget_bytes >> 20));
  EXPECT_EQ(printed_default("--port"), std::to_string(defaults.options.port));
  EXPECT_EQ(printed_default("--max-connections"), std::to_string(defaults.options.connections.max_connections));
  EXPECT_EQ(printed_default("--max-model-mib"), std::to_string(defaults.options.max_model_bytes >> 20));
  EXPECT_NE(usage_text().find("[--tokens FILE | --no-auth]"), std::string::npos);
}

TEST(ServerFlags, EachFlagSetsItsMember) {
  ServerSettings s;
  const FlagsParsed parsed = parse_flags({"--queue", "3", "--deadline-ms", "250", "--memory-mib", "512", "--port", "0",
                                          "--host", "0.0.0.0", "--models", "/m", "--no-auth", "--quiet"},
                                         s);
  ASSERT_EQ(parsed.outcome, FlagsParsed::Outcome::Run) << parsed.error;
  EXPECT_EQ(s.limits.queue_capacity, 3u);
  EXPECT_EQ(s.limits.deadline.count(), 250);
  EXPECT_EQ(s.limits.memory_budget_bytes, std::uint64_t(512) << 20);
  EXPECT_EQ(s.options.port, 0);
  EXPECT_EQ(s.options.host, "0.0.0.0");
  EXPECT_EQ(s.models_dir, "/m");
  EXPECT_TRUE(s.no_auth);
  EXPECT_FALSE(s.options.log_requests);
}

TEST(ServerFlags, RefusalsNameTheFlagAndWhy) {
  const auto refused = [](std::vector<std::string> args) {
    ServerSettings s;
    const FlagsParsed parsed = parse_flags(args, s);
    EXPECT_EQ(parsed.outcome, FlagsParsed::Outcome::Refused);
    return parsed;
  };
  EXPECT_EQ(refused({"--queue", "0"}).error, "--queue must be 1..4096, got '0'");
  EXPECT_EQ(refused({"--queue", "4097"}).error, "--queue must be 1..4096, got '4097'");
  EXPECT_EQ(refused({"--port", "80x"}).error, "--port must be 0..65535, got '80x'");
  EXPECT_EQ(refused({"--deadline-ms"}).error, "--deadline-ms needs a value");
  const FlagsParsed unknown = refused({"--queue", "4", "--frobnicate"});
  EXPECT_EQ(unknown.error, "unknown option '--frobnicate'");
  EXPECT_TRUE(unknown.show_usage);
  EXPECT_NE(refused({"--cors", "not an origin"}).error.find("--cors must be"), std::string::npos);
}

TEST(ServerFlags, HelpEndsTheReadingAndTheFirstRefusalWins) {
  ServerSettings s;
  EXPECT_EQ(parse_flags({"--queue", "5", "--help", "--queue", "0"}, s).outcome, FlagsParsed::Outcome::Help);
  EXPECT_EQ(s.limits.queue_capacity, 5u);
  ServerSettings t;
  const FlagsParsed parsed = parse_flags({"--queue", "0", "--help"}, t);
  EXPECT_EQ(parsed.outcome, FlagsParsed::Outcome::Refused);
  EXPECT_EQ(parsed.error, "--queue must be 1..4096, got '0'");
}

}  // namespace
}  // namespace umbra
