// Who may ask what of Umbra (docs/operations.md#who-may-do-what): the Host
// a request names (against DNS rebinding) and the bearer token it carries.
// Pure: no sockets, no routes; HttpApi decides which scope each route
// needs and calls these at the end of a request's head, before its body.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace umbra {

struct HttpRequest;

/// A refusal: status 0 means none.
struct AccessRefusal {
  int status = 0;
  std::string message;
  explicit operator bool() const { return status != 0; }
};

/// The host of a Host field value (RFC 9110 §7.2, uri-host [":" port]),
/// lower-cased, without the port or a trailing dot; an IPv6 literal keeps
/// its brackets ("[::1]"). nullopt if it is not one.
std::optional<std::string> host_of(std::string_view value);

/// True for the --host values that reach this machine only: "localhost",
/// 127.0.0.0/8 and ::1 (written as such; a name other than localhost is
/// not resolved, so it counts as non-loopback).
bool is_loopback_address(const std::string& host);

/// The names a request's Host may give (any port): the loopback names
/// (localhost, 127.0.0.1, [::1]), the bound address unless it is a
/// wildcard (0.0.0.0, ::), and those of --allowed-hosts ("*": any).
class AllowedHosts {
 public:
  AllowedHosts() : AllowedHosts("127.0.0.1", {}) {}
  AllowedHosts(const std::string& bound_address, const std::vector<std::string>& listed);

  /// A comma-separated --allowed-hosts value: names or addresses without a
  /// port ("render.example, 10.0.0.5, [fd00::5]"), or "*". False with
  /// `error` if an entry is not a host.
  static bool parse_list(const std::string& text, std::vector<std::string>& names, std::string& error);

  /// RFC 9112 §3.2: 400 for an HTTP/1.1 request without a Host, with more
  /// than one, or with one that is not a host; 421 for a host not allowed
  /// (that of the target, when the target is in absolute form).
  AccessRefusal check(const HttpRequest& request) const;

  bool any() const { return any_; }
  /// True if only the loopback names are allowed (with a wildcard bound
  /// address and no --allowed-hosts: then no other machine's name works).
  bool loopback_only() const { return !any_ && names_.size() == kLoopbackNames; }

 private:
  static constexpr std::size_t kLoopbackNames = 3;
  bool allowed(const std::string& host) const;
  std::vector<std::string> names_;
  bool any_ = false;
};

/// What a token allows (--tokens FILE), as bits.
enum Scope : unsigned { kScopeRender = 1, kScopeUpload = 2, kScopeMetrics = 4 };

/// "render", "upload", "metrics"; "render, upload" for several.
std::string scope_names(unsigned scopes);

/// The token of an `Authorization: Bearer TOKEN` value (RFC 6750 §2.1;
/// the scheme is case-insensitive), or nullopt.
std::optional<std::string_view> bearer_token(std::string_view authorization);

/// "token:" + the first 12 hex digits of the token's SHA-256: who made a
/// request, for accounting and logs, never the token itself.
std::string token_principal(std::string_view token);

/// The tokens of --tokens FILE, held as SHA-256 digests only.
class TokenTable {
 public:
  /// The least characters a token must have: guessing one is hopeless.
  static constexpr std::size_t kMinTokenChars = 16;

  /// The file's text: one "TOKEN SCOPE[,SCOPE]" a line, "#" comments and
  /// blank lines allowed. nullopt with `error` naming the line (never the
  /// token) if a line is malformed, a scope unknown, a token short or
  /// repeated, or there is none.
  static std::optional<TokenTable> parse(const std::string& text, std::string& error);

  struct Found {
    bool known = false;
    unsigned scopes = 0;
    std::string principal;  ///< token_principal(token), if known
  };
  /// Compares the token's digest with every entry, each in constant time
  /// and without stopping at a match: the time taken says nothing of how
  /// much of a token was right.
  Found find(std::string_view token) const;

  std::size_t size() const { return entries_.size(); }

 private:
  struct Entry {
    std::array<std::uint8_t, 32> digest;
    unsigned scopes;
  };
  std::vector<Entry> entries_;
};

/// A request's token judged against `needed` scopes (0: any known token
/// will do): 401 without a bearer token or with an unknown one, 403 with
/// one lacking a needed scope. `principal` is set when it is known.
AccessRefusal authorize(const TokenTable& tokens, const HttpRequest& request, unsigned needed,
                        const std::string& what, std::string& principal);

}  // namespace umbra
