#include "http_message.hpp"

#include <algorithm>
#include <cctype>
#include <cstdint>

namespace umbra {

namespace {

char lower(char c) { return char(std::tolower(static_cast<unsigned char>(c))); }

// RFC 9110 §5.6.2: the characters of a token (method, header name).
bool is_tchar(char c) {
  if (std::isalnum(static_cast<unsigned char>(c))) return true;
  switch (c) {
    case '!': case '#': case '$': case '%': case '&': case '\'': case '*': case '+':
    case '-': case '.': case '^': case '_': case '`': case '|': case '~':
      return true;
    default:
      return false;
  }
}

bool is_token(std::string_view s) {
  if (s.empty()) return false;
  for (char c : s)
    if (!is_tchar(c)) return false;
  return true;
}

std::string_view trim_ows(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

// "1 MiB", "64 KiB" or "1000 bytes": a limit as the client reads it.
std::string size_text(std::size_t bytes) {
  if (bytes >= (1u << 20) && bytes % (1u << 20) == 0) return std::to_string(bytes >> 20) + " MiB";
  if (bytes >= (1u << 10) && bytes % (1u << 10) == 0) return std::to_string(bytes >> 10) + " KiB";
  return std::to_string(bytes) + " bytes";
}

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// A response header's name or value never carries a line break, whatever
// text a handler put there (a client's own text, quoted back).
std::string header_safe(const std::string& s) {
  std::string out = s;
  for (char& c : out)
    if (c == '\r' || c == '\n' || c == '\0') c = ' ';
  return out;
}

// The longest chunk-size line (size, extensions) and request line accepted.
constexpr std::size_t kMaxChunkLineBytes = 4096;
constexpr std::size_t kRequestLineSlack = 1024;  // method, spaces, version beyond the target

}  // namespace

bool equal_ci(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (lower(a[i]) != lower(b[i])) return false;
  return true;
}

std::string HttpRequest::header(std::string_view name) const {
  for (const auto& [n, v] : headers)
    if (equal_ci(n, name)) return v;
  return "";
}

std::size_t HttpRequest::header_count(std::string_view name) const {
  std::size_t count = 0;
  for (const auto& [n, v] : headers) count += equal_ci(n, name);
  return count;
}

void HttpResponse::set_header(std::string name, std::string value) {
  for (auto& [n, v] : headers)
    if (equal_ci(n, name)) {
      v = std::move(value);
      return;
    }
  headers.emplace_back(std::move(name), std::move(value));
}

std::string HttpResponse::header(std::string_view name) const {
  for (const auto& [n, v] : headers)
    if (equal_ci(n, name)) return v;
  return "";
}

void HttpResponse::set_content(std::string content, std::string content_type) {
  body = std::move(content);
  set_header("Content-Type", std::move(content_type));
}

const char* reason_phrase(int status) {
  switch (status) {
    case 100: return "Continue";
    case 200: return "OK";
    case 201: return "Created";
    case 202: return "Accepted";
    case 204: return "No Content";
    case 206: return "Partial Content";
    case 304: return "Not Modified";
    case 400: return "Bad Request";
    case 401: return "Unauthorized";
    case 403: return "Forbidden";
    case 404: return "Not Found";
    case 405: return "Method Not Allowed";
    case 406: return "Not Acceptable";
    case 408: return "Request Timeout";
    case 413: return "Content Too Large";
    case 414: return "URI Too Long";
    case 415: return "Unsupported Media Type";
    case 416: return "Range Not Satisfiable";
    case 417: return "Expectation Failed";
    case 421: return "Misdirected Request";
    case 422: return "Unprocessable Content";
    case 431: return "Request Header Fields Too Large";
    case 499: return "Client Closed Request";
    case 500: return "Internal Server Error";
    case 501: return "Not Implemented";
    case 503: return "Service Unavailable";
    case 505: return "HTTP Version Not Supported";
    case 507: return "Insufficient Storage";
    default: return "";
  }
}

std::string response_head(const HttpResponse& response, std::size_t body_length, bool close, int keep_alive_s) {
  std::string head = "HTTP/1.1 " + std::to_string(response.status) + " " + reason_phrase(response.status) + "\r\n";
  for (const auto& [name, value] : response.headers) {
    // Framing is the server's alone.
    if (equal_ci(name, "Content-Length") || equal_ci(name, "Transfer-Encoding") || equal_ci(name, "Connection") ||
        equal_ci(name, "Keep-Alive"))
      continue;
    head += header_safe(name) + ": " + header_safe(value) + "\r\n";
  }
  // RFC 9110 §8.6: no Content-Length on 1xx and 204.
  if (response.status >= 200 && response.status != 204) head += "Content-Length: " + std::to_string(body_length) + "\r\n";
  if (close)
    head += "Connection: close\r\n";
  else if (keep_alive_s > 0)
    head += "Keep-Alive: timeout=" + std::to_string(keep_alive_s) + "\r\n";
  head += "\r\n";
  return head;
}

bool decode_path(std::string_view encoded, std::string& decoded) {
  decoded.clear();
  decoded.reserve(encoded.size());
  for (std::size_t i = 0; i < encoded.size(); ++i) {
    char c = encoded[i];
    if (c == '%') {
      if (i + 2 >= encoded.size()) return false;
      const int hi = hex_value(encoded[i + 1]), lo = hex_value(encoded[i + 2]);
      if (hi < 0 || lo < 0) return false;
      c = char(hi * 16 + lo);
      i += 2;
    }
    decoded += c;
  }
  return true;
}

bool query_params(std::string_view target, std::vector<std::pair<std::string, std::string>>& params) {
  params.clear();
  const std::size_t question = target.find('?');
  if (question == std::string_view::npos) return true;
  std::string_view query = target.substr(question + 1);
  query = query.substr(0, query.find('#'));
  while (!query.empty()) {
    const std::size_t amp = std::min(query.find('&'), query.size());
    const std::string_view item = query.substr(0, amp);
    query.remove_prefix(std::min(query.size(), amp + 1));
    if (item.empty()) continue;
    const std::size_t equals = std::min(item.find('='), item.size());
    std::string name(item.substr(0, equals)), value(item.substr(std::min(item.size(), equals + 1)));
    for (std::string* part : {&name, &value}) {
      std::replace(part->begin(), part->end(), '+', ' ');
      std::string decoded;
      if (!decode_path(*part, decoded)) return false;
      *part = std::move(decoded);
    }
    params.emplace_back(std::move(name), std::move(value));
  }
  return true;
}

HttpRequest RequestReader::take_request() {
  HttpRequest taken = std::move(request_);
  request_ = HttpRequest{};
  return taken;
}

void RequestReader::reset() {
  state_ = State::Idle;
  request_ = HttpRequest{};
  line_.clear();
  header_bytes_ = 0;
  field_count_ = 0;
  body_step_ = BodyStep::Fixed;
  remaining_ = 0;
  wants_continue_ = false;
  error_status_ = 0;
  error_message_.clear();
}

void RequestReader::fail(int status, std::string message) {
  state_ = State::Failed;
  error_status_ = status;
  error_message_ = std::move(message);
}

// Moves one line (without its CRLF or LF) from `input` into `line`, across
// feeds; false if the line is not whole yet, or if it failed: longer than
// `max_bytes`, or holding a bare CR (RFC 9112 §2.2).
bool RequestReader::take_line(std::string& input, std::string& line, std::size_t max_bytes, int status_if_long,
                              const char* what_if_long) {
  const std::size_t end = input.find('\n');
  const std::size_t available = end == std::string::npos ? input.size() : end;
  if (line_.size() + available > max_bytes + 1) {  // + 1: the CR of CRLF
    fail(status_if_long, std::string(what_if_long) + " longer than " + size_text(max_bytes));
    return false;
  }
  line_.append(input, 0, available);
  input.erase(0, end == std::string::npos ? available : end + 1);
  if (end == std::string::npos) return false;
  if (!line_.empty() && line_.back() == '\r') line_.pop_back();
  if (line_.find('\r') != std::string::npos) {
    fail(400, "malformed request: a bare CR in the head");
    return false;
  }
  line = std::move(line_);
  line_.clear();
  return true;
}

void RequestReader::feed(std::string& input) {
  std::string line;
  while (!input.empty() && (state_ == State::Idle || state_ == State::Head || state_ == State::Body)) {
    if (state_ == State::Idle) {
      // RFC 9112 §2.2: empty lines before a request line are ignored.
      if (input.front() == '\r' || input.front() == '\n') {
        input.erase(0, 1);
        continue;
      }
      state_ = State::Head;
    }
    if (state_ == State::Head) {
      const bool first = request_.method.empty();
      const std::size_t max = first ? limits_.max_target_bytes + kRequestLineSlack : limits_.max_header_bytes;
      if (!take_line(input, line, max, first ? 414 : 431, first ? "request line" : "a header line")) return;
      if (first)
        parse_request_line(line);
      else if (line.empty())
        end_of_head();
      else
        parse_header_line(line, false);
      continue;
    }
    if (!read_body(input)) return;
  }
}

void RequestReader::parse_request_line(const std::string& line) {
  const std::size_t sp1 = line.find(' ');
  const std::size_t sp2 = sp1 == std::string::npos ? sp1 : line.find(' ', sp1 + 1);
  if (sp2 == std::string::npos || line.find(' ', sp2 + 1) != std::string::npos)
    return fail(400, "malformed request line (want METHOD TARGET HTTP/1.1)");
  const std::string method = line.substr(0, sp1);
  const std::string target = line.substr(sp1 + 1, sp2 - sp1 - 1);
  const std::string version = line.substr(sp2 + 1);
  if (!is_token(method)) return fail(400, "malformed request line: the method is not a token");
  if (target.empty()) return fail(400, "malformed request line: no target");
  if (target.size() > limits_.max_target_bytes)
    return fail(414, "request URI longer than " + std::to_string(limits_.max_target_bytes) + " bytes");
  for (char c : target)
    if (static_cast<unsigned char>(c) <= 0x20 || c == 0x7f)
      return fail(400, "malformed request line: a control character in the target");
  if (version.size() == 8 && version.compare(0, 5, "HTTP/") == 0 && std::isdigit(static_cast<unsigned char>(version[5])) &&
      version[6] == '.' && std::isdigit(static_cast<unsigned char>(version[7]))) {
    if (version[5] != '1') return fail(505, "HTTP version " + version.substr(5) + " not supported; use HTTP/1.1");
    request_.minor_version = version[7] - '0';
  } else {
    return fail(400, "malformed request line: no HTTP version");
  }
  // origin-form "/path?query", absolute-form "http://host/path" (RFC 9112
  // §3.2.2: a server must accept it), asterisk-form "*" (OPTIONS).
  std::string_view path = target;
  if (target != "*" && target.front() != '/') {
    const std::size_t scheme = target.find("://");
    if (scheme == std::string::npos) return fail(400, "malformed request line: the target is not a path");
    const std::size_t slash = target.find('/', scheme + 3);
    path = slash == std::string::npos ? std::string_view("/") : std::string_view(target).substr(slash);
  }
  path = path.substr(0, path.find_first_of("?#"));
  if (!decode_path(path, request_.path)) return fail(400, "malformed request: a bad %-escape in the path");
  request_.method = method;
  request_.target = target;
}

void RequestReader::parse_header_line(const std::string& line, bool trailer) {
  if (line.front() == ' ' || line.front() == '\t')
    return fail(400, "malformed request: a folded header line (RFC 9112 §5.2)");
  const std::size_t colon = line.find(':');
  if (colon == std::string::npos) return fail(400, "malformed request: a header line without ':'");
  const std::string_view name = std::string_view(line).substr(0, colon);
  if (!is_token(name)) return fail(400, "malformed request: a header name that is not a token");
  const std::string_view value = trim_ows(std::string_view(line).substr(colon + 1));
  for (char c : value) {
    const auto u = static_cast<unsigned char>(c);
    if ((u < 0x20 && c != '\t') || u == 0x7f) return fail(400, "malformed request: a control character in a header");
  }
  header_bytes_ += name.size() + value.size();
  if (++field_count_ > limits_.max_header_count || header_bytes_ > limits_.max_header_bytes)
    return fail(431, "request headers too large (at most " + std::to_string(limits_.max_header_count) + " fields and " +
                         std::to_string(limits_.max_header_bytes) + " bytes)");
  // Trailer fields are read (for the limits) and dropped: none of them may
  // change how the request is understood.
  if (!trailer) request_.headers.emplace_back(std::string(name), std::string(value));
}

void RequestReader::end_of_head() {
  HttpRequest& r = request_;
  // Connection: a comma-separated list of options.
  r.keep_alive = r.minor_version >= 1;
  for (const auto& [name, value] : r.headers) {
    if (!equal_ci(name, "Connection")) continue;
    std::string_view rest = value;
    while (!rest.empty()) {
      const std::size_t comma = rest.find(',');
      const std::string_view option = trim_ows(rest.substr(0, comma));
      if (equal_ci(option, "close")) r.keep_alive = false;
      rest = comma == std::string_view::npos ? std::string_view() : rest.substr(comma + 1);
    }
  }
  // RFC 9112 §6.3: a Content-Length is a non-empty string of digits and
  // several must agree; Transfer-Encoding (whose one coding must be
  // chunked, the only one read here) excludes it. Anything else leaves the
  // body's length unknown: 400, and the connection closes, so that no byte
  // of such a body is ever read as the next request.
  const std::size_t lengths = r.header_count("Content-Length");
  const std::size_t codings = r.header_count("Transfer-Encoding");
  if (lengths > 0 && codings > 0)
    return fail(400, "malformed request framing: Content-Length and Transfer-Encoding together");
  if (codings > 0) {
    if (codings > 1 || !equal_ci(r.header("Transfer-Encoding"), "chunked"))
      return fail(400, "malformed request framing: Transfer-Encoding other than chunked");
    if (r.minor_version == 0) return fail(400, "malformed request framing: Transfer-Encoding in HTTP/1.0");
  }
  std::uint64_t length = 0;
  bool too_long = false;
  for (const auto& [name, value] : r.headers) {
    if (!equal_ci(name, "Content-Length")) continue;
    if (value.empty() || value.find_first_not_of("0123456789") != std::string::npos)
      return fail(400, "malformed request framing: Content-Length is not a decimal number of bytes");
    if (value != r.header("Content-Length"))
      return fail(400, "malformed request framing: several different Content-Length values");
    const std::size_t digits = value.size() - std::min(value.size(), value.find_first_not_of('0'));
    too_long = digits > 18;  // more than 10^18 bytes: far past any limit, and past 64 bits
    if (!too_long) length = std::stoull(value);
  }
  body_limit_ = limits_.body_limit_for ? limits_.body_limit_for(r) : limits_.max_body_bytes;
  if (too_long || length > body_limit_) return fail(413, "request body larger than " + size_text(body_limit_));
  const bool body_follows = codings > 0 || length > 0;
  const std::string expect = r.header("Expect");
  if (r.has_header("Expect")) {
    if (!equal_ci(expect, "100-continue")) return fail(417, "unsupported Expect; only 100-continue is understood");
    wants_continue_ = body_follows && r.minor_version >= 1;
  }
  state_ = State::Body;
  if (codings > 0) {
    body_step_ = BodyStep::ChunkSize;
  } else {
    body_step_ = BodyStep::Fixed;
    remaining_ = std::size_t(length);
    if (remaining_ == 0) complete();
  }
}

// Reads what it can of the body; false when it needs more input than
// there is (true: progress, or the state changed).
bool RequestReader::read_body(std::string& input) {
  std::string& body = request_.body;
  std::string line;
  const auto refuse = [this](int status, std::string message) {
    fail(status, std::move(message));
    return true;
  };
  const auto too_large = [&] { return refuse(413, "request body larger than " + size_text(body_limit_)); };
  switch (body_step_) {
    case BodyStep::Fixed:
    case BodyStep::ChunkData: {
      const std::size_t n = std::min(remaining_, input.size());
      body.append(input, 0, n);
      input.erase(0, n);
      remaining_ -= n;
      if (remaining_ > 0) return false;
      if (body_step_ == BodyStep::Fixed)
        complete();
      else
        body_step_ = BodyStep::ChunkDataEnd;
      return true;
    }
    case BodyStep::ChunkDataEnd: {
      // Exactly CRLF (or LF) after a chunk's data.
      const bool crlf = input.front() == '\r';
      if (crlf && input.size() < 2) return false;  // the LF is still to come
      if (input[crlf ? 1 : 0] != '\n') return refuse(400, "malformed chunked body: chunk data longer than its size");
      input.erase(0, crlf ? 2 : 1);
      body_step_ = BodyStep::ChunkSize;
      return true;
    }
    case BodyStep::ChunkSize: {
      if (!take_line(input, line, kMaxChunkLineBytes, 400, "a chunk-size line")) return state_ == State::Failed;
      std::size_t i = 0;
      std::uint64_t size = 0;
      for (; i < line.size() && hex_value(line[i]) >= 0; ++i) {
        if (i >= 15) return too_large();  // 16 hex digits: past any body, and near 64 bits
        size = size * 16 + std::uint64_t(hex_value(line[i]));
      }
      if (i == 0) return refuse(400, "malformed chunked body: no chunk size");
      const std::string_view rest = trim_ows(std::string_view(line).substr(i));
      if (!rest.empty() && rest.front() != ';') return refuse(400, "malformed chunked body: junk after a chunk size");
      if (size > body_limit_ - body.size()) return too_large();
      if (size == 0) {
        body_step_ = BodyStep::Trailer;
      } else {
        body_step_ = BodyStep::ChunkData;
        remaining_ = std::size_t(size);
      }
      return true;
    }
    case BodyStep::Trailer:
      if (!take_line(input, line, limits_.max_header_bytes, 431, "a trailer line")) return state_ == State::Failed;
      if (line.empty())
        complete();
      else
        parse_header_line(line, true);
      return true;
  }
  return false;
}

}  // namespace umbra
