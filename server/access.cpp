#include "access.hpp"

#include <algorithm>
#include <cctype>

#include <nettle/sha2.h>

#include "http_message.hpp"

namespace umbra {

namespace {

constexpr const char* kLoopbackHostNames[] = {"localhost", "127.0.0.1", "[::1]"};

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = char(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

// RFC 3986 reg-name as host names use it, and IPv4 addresses.
bool is_name_char(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '.' || c == '_' || c == '~';
}

bool is_ipv6_char(char c) { return std::isxdigit(static_cast<unsigned char>(c)) || c == ':' || c == '.'; }

// RFC 6750 §2.1 b64token: what a bearer token may hold.
bool is_token_char(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '.' || c == '_' || c == '~' || c == '+' ||
         c == '/' || c == '=';
}

std::array<std::uint8_t, 32> sha256(std::string_view bytes) {
  sha256_ctx context;
  sha256_init(&context);
  sha256_update(&context, bytes.size(), reinterpret_cast<const std::uint8_t*>(bytes.data()));
  std::array<std::uint8_t, 32> digest{};
  sha256_digest(&context, digest.size(), digest.data());
  return digest;
}

// Equal digests, in time independent of where they differ.
bool same_digest(const std::array<std::uint8_t, 32>& a, const std::array<std::uint8_t, 32>& b) {
  std::uint8_t difference = 0;
  for (std::size_t i = 0; i < a.size(); ++i) difference |= std::uint8_t(a[i] ^ b[i]);
  return difference == 0;
}

// The authority of an absolute-form target ("http://host:port/path"),
// without any userinfo.
std::string_view target_authority(std::string_view target) {
  const std::size_t scheme = target.find("://");
  if (scheme == std::string_view::npos) return {};
  std::string_view rest = target.substr(scheme + 3);
  rest = rest.substr(0, rest.find_first_of("/?#"));
  const std::size_t at = rest.rfind('@');
  return at == std::string_view::npos ? rest : rest.substr(at + 1);
}

std::string quoted(std::string_view s) { return "'" + std::string(s.substr(0, 100)) + "'"; }

}  // namespace

std::optional<std::string> host_of(std::string_view value) {
  value = trim(value);
  std::string_view host = value, port;
  if (!value.empty() && value.front() == '[') {
    const std::size_t close = value.find(']');
    if (close == std::string_view::npos || close == 1) return std::nullopt;
    for (char c : value.substr(1, close - 1))
      if (!is_ipv6_char(c)) return std::nullopt;
    host = value.substr(0, close + 1);
    const std::string_view after = value.substr(close + 1);
    if (!after.empty() && after.front() != ':') return std::nullopt;
    port = after.empty() ? after : after.substr(1);
  } else {
    const std::size_t colon = value.find(':');
    if (colon != std::string_view::npos) {
      host = value.substr(0, colon);
      port = value.substr(colon + 1);
    }
    if (host.empty()) return std::nullopt;
    for (char c : host)
      if (!is_name_char(c)) return std::nullopt;
    if (host.size() > 1 && host.back() == '.') host.remove_suffix(1);  // "localhost." is localhost
  }
  for (char c : port)
    if (!std::isdigit(static_cast<unsigned char>(c))) return std::nullopt;
  if (port.size() > 5 || (!port.empty() && std::stoul(std::string(port)) > 65535)) return std::nullopt;
  return lower(host);
}

bool is_loopback_address(const std::string& host) {
  const std::string h = lower(host);
  if (h == "localhost" || h == "::1" || h == "[::1]") return true;
  // 127.0.0.0/8, as four decimal parts.
  if (h.rfind("127.", 0) != 0) return false;
  int parts = 0;
  std::size_t at = 0;
  while (at <= h.size()) {
    const std::size_t dot = std::min(h.find('.', at), h.size());
    const std::string part = h.substr(at, dot - at);
    if (part.empty() || part.size() > 3 || part.find_first_not_of("0123456789") != std::string::npos ||
        std::stoi(part) > 255)
      return false;
    ++parts;
    at = dot + 1;
  }
  return parts == 4;
}

AllowedHosts::AllowedHosts(const std::string& bound_address, const std::vector<std::string>& listed) {
  for (const char* name : kLoopbackHostNames) names_.emplace_back(name);
  const auto add = [this](const std::string& name) {
    if (name == "*") {
      any_ = true;
      return;
    }
    if (std::find(names_.begin(), names_.end(), name) == names_.end()) names_.push_back(name);
  };
  // The bound address, as a Host field gives it; a wildcard is no name.
  const std::string bound = bound_address.find(':') != std::string::npos && bound_address.front() != '['
                                ? "[" + bound_address + "]"
                                : bound_address;
  if (bound != "0.0.0.0" && bound != "[::]" && !bound.empty())
    if (const auto host = host_of(bound)) add(*host);
  for (const std::string& name : listed) add(name);
}

bool AllowedHosts::parse_list(const std::string& text, std::vector<std::string>& names, std::string& error) {
  names.clear();
  std::string_view rest = text;
  while (true) {
    const std::size_t comma = rest.find(',');
    const std::string_view entry = trim(rest.substr(0, comma));
    if (entry == "*") {
      names.emplace_back("*");
    } else {
      const auto host = host_of(entry);
      if (entry.empty() || !host) {
        error = "not a host name or address: " + quoted(entry);
        return false;
      }
      if (*host != lower(entry) && *host + "." != lower(entry)) {
        error = "give names without a port (any port is allowed): " + quoted(entry);
        return false;
      }
      names.push_back(*host);
    }
    if (comma == std::string_view::npos) return true;
    rest = rest.substr(comma + 1);
  }
}

bool AllowedHosts::allowed(const std::string& host) const {
  return any_ || std::find(names_.begin(), names_.end(), host) != names_.end();
}

AccessRefusal AllowedHosts::check(const HttpRequest& request) const {
  const std::size_t fields = request.header_count("Host");
  const bool http11 = request.minor_version >= 1;
  if (fields > 1) return {400, "more than one Host header field (RFC 9112 §3.2)"};
  if (fields == 0 && http11) return {400, "no Host header field; HTTP/1.1 requires one (RFC 9112 §3.2)"};
  const std::string field = request.header("Host");
  std::string_view named = field;
  const bool absolute = !request.target.empty() && request.target.front() != '/' && request.target != "*";
  if (absolute) named = target_authority(request.target);  // RFC 9112 §3.2.2: the target's authority wins
  if (fields == 0 && !absolute) return {};                   // HTTP/1.0 without a Host: nothing to check
  const auto host = host_of(named);
  if (!host) return {400, "the Host " + quoted(named) + " is not a host name or address"};
  if (allowed(*host)) return {};
  return {421, "this server does not answer for the host " + quoted(*host) +
                   "; it answers for its loopback names, its own address and those of --allowed-hosts"};
}

std::string scope_names(unsigned scopes) {
  std::string names;
  const auto add = [&](unsigned bit, const char* name) {
    if (scopes & bit) names += (names.empty() ? "" : ", ") + std::string(name);
  };
  add(kScopeRender, "render");
  add(kScopeUpload, "upload");
  add(kScopeMetrics, "metrics");
  return names.empty() ? "none" : names;
}

std::optional<std::string_view> bearer_token(std::string_view authorization) {
  authorization = trim(authorization);
  const std::size_t space = authorization.find(' ');
  if (space == std::string_view::npos || !equal_ci(authorization.substr(0, space), "Bearer")) return std::nullopt;
  const std::string_view token = trim(authorization.substr(space + 1));
  if (token.empty()) return std::nullopt;
  for (char c : token)
    if (!is_token_char(c)) return std::nullopt;
  return token;
}

std::string token_principal(std::string_view token) {
  static const char kHex[] = "0123456789abcdef";
  const auto digest = sha256(token);
  std::string principal = "token:";
  for (std::size_t i = 0; i < 6; ++i) {
    principal += kHex[digest[i] >> 4];
    principal += kHex[digest[i] & 15];
  }
  return principal;
}

std::optional<TokenTable> TokenTable::parse(const std::string& text, std::string& error) {
  TokenTable table;
  std::size_t line_number = 0;
  std::string_view rest = text;
  while (!rest.empty()) {
    ++line_number;
    const std::size_t end = rest.find('\n');
    const std::string_view line = trim(rest.substr(0, end));
    rest = end == std::string_view::npos ? std::string_view() : rest.substr(end + 1);
    if (line.empty() || line.front() == '#') continue;
    const std::string where = "line " + std::to_string(line_number) + ": ";
    const std::size_t gap = line.find_first_of(" \t");
    if (gap == std::string_view::npos) {
      error = where + "want TOKEN SCOPE[,SCOPE] (scopes: render, upload, metrics)";
      return std::nullopt;
    }
    const std::string_view token = line.substr(0, gap);
    if (!std::all_of(token.begin(), token.end(), is_token_char)) {
      error = where + "a token may hold only letters, digits and - . _ ~ + / =";
      return std::nullopt;
    }
    if (token.size() < kMinTokenChars) {
      error = where + "the token is shorter than " + std::to_string(kMinTokenChars) + " characters";
      return std::nullopt;
    }
    unsigned scopes = 0;
    std::string_view list = trim(line.substr(gap));
    while (true) {
      const std::size_t comma = list.find(',');
      const std::string_view scope = trim(list.substr(0, comma));
      if (scope == "render")
        scopes |= kScopeRender;
      else if (scope == "upload")
        scopes |= kScopeUpload;
      else if (scope == "metrics")
        scopes |= kScopeMetrics;
      else {
        error = where + "unknown scope " + quoted(scope) + " (scopes: render, upload, metrics)";
        return std::nullopt;
      }
      if (comma == std::string_view::npos) break;
      list = list.substr(comma + 1);
    }
    const auto digest = sha256(token);
    for (const Entry& e : table.entries_)
      if (same_digest(e.digest, digest)) {
        error = where + "the same token as an earlier line";
        return std::nullopt;
      }
    table.entries_.push_back({digest, scopes});
  }
  if (table.entries_.empty()) {
    error = "no token in the file (one \"TOKEN SCOPE[,SCOPE]\" a line)";
    return std::nullopt;
  }
  return table;
}

TokenTable::Found TokenTable::find(std::string_view token) const {
  const auto digest = sha256(token);
  Found found;
  for (const Entry& e : entries_) {
    const bool match = same_digest(e.digest, digest);
    found.known |= match;
    found.scopes |= match ? e.scopes : 0u;
  }
  if (found.known) found.principal = token_principal(token);
  return found;
}

AccessRefusal authorize(const TokenTable& tokens, const HttpRequest& request, unsigned needed,
                        const std::string& what, std::string& principal) {
  principal.clear();
  if (request.header_count("Authorization") > 1) return {400, "more than one Authorization header field"};
  const std::string header = request.header("Authorization");
  const auto token = bearer_token(header);
  if (!token)
    return {401, header.empty() ? what + " needs a token: send Authorization: Bearer TOKEN"
                                : what + " needs a token: the Authorization header is not Bearer TOKEN"};
  const TokenTable::Found found = tokens.find(*token);
  if (!found.known) return {401, "the bearer token is not one this server knows"};
  principal = found.principal;
  if ((found.scopes & needed) != needed)
    return {403, what + " needs the " + scope_names(needed) + " scope; this token has " + scope_names(found.scopes)};
  return {};
}

}  // namespace umbra
