// HTTP/1.1 messages (RFC 9112) as Umbra reads and writes them. Pure: no
// sockets, no threads, so every framing rule is unit tested and fuzzed.
//
// RequestReader takes bytes as they arrive and yields one request at a
// time, or the error status that ends the connection. It enforces the
// limits while reading, so a body past its limit is refused at the byte
// that passes it, whatever its framing (Content-Length or chunked).
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace umbra {

struct HttpRequest;

struct HttpLimits {
  std::size_t max_body_bytes = 1 << 20;     ///< decoded body; 413 above. Default 1 MiB
  /// If set, the body limit of one request, judged from its head (e.g. a
  /// larger one for an upload route); max_body_bytes otherwise.
  std::function<std::size_t(const HttpRequest& head)> body_limit_for;
  std::size_t max_target_bytes = 4096;      ///< request-target; 414 above. Default 4 KiB
  std::size_t max_header_count = 100;       ///< header fields (trailers included); 431 above
  std::size_t max_header_bytes = 32 << 10;  ///< bytes of names and values; 431 above. Default 32 KiB
};

using HttpHeaders = std::vector<std::pair<std::string, std::string>>;

struct HttpRequest {
  std::string method;  ///< "GET", "POST", ... as sent (methods are case-sensitive)
  std::string target;  ///< as sent: "/api/render?x=1"
  std::string path;    ///< target's path, percent-decoded: "/api/render"
  int minor_version = 1;  ///< HTTP/1.x
  HttpHeaders headers;    ///< in order; names as sent
  std::string body;       ///< decoded (chunks joined)
  bool keep_alive = true; ///< false: the client asked to close (or spoke HTTP/1.0)
  int socket = -1;        ///< the connection's descriptor, for peer_closed(); owned by the server
  /// Who sent it, for accounting: with --tokens, "token:" + the first 12
  /// hex digits of its token's SHA-256 (never the token); else "".
  std::string principal;

  /// First value of `name` (case-insensitive), or "".
  std::string header(std::string_view name) const;
  std::size_t header_count(std::string_view name) const;
  bool has_header(std::string_view name) const { return header_count(name) > 0; }
};

struct HttpResponse {
  int status = 200;
  HttpHeaders headers;  ///< Content-Length, Connection and Keep-Alive are the server's
  std::string body;
  bool close = false;   ///< close the connection once this is sent

  void set_header(std::string name, std::string value);
  std::string header(std::string_view name) const;
  void set_content(std::string content, std::string content_type);
};

/// "Not Found" for 404, ... ("" for a code it does not know).
const char* reason_phrase(int status);

/// The status line and headers of `response`, ready to send, ending in the
/// blank line. `body_length` is Content-Length (for HEAD, the length a GET
/// would have had). `keep_alive_s` > 0 adds "Keep-Alive: timeout=N";
/// a closing response says "Connection: close".
std::string response_head(const HttpResponse& response, std::size_t body_length, bool close, int keep_alive_s);

/// Case-insensitive ASCII equality, for header names and tokens.
bool equal_ci(std::string_view a, std::string_view b);

/// Percent-decodes a path; false on a malformed escape. A decoded NUL is
/// kept (it names no file and no route: 404).
bool decode_path(std::string_view encoded, std::string& decoded);

/// The request-target's query ("?a=1&b=two") as name, value pairs in
/// order, percent-decoded ('+' is a space); a name without '=' has an
/// empty value. False on a malformed escape.
bool query_params(std::string_view target, std::vector<std::pair<std::string, std::string>>& params);

class RequestReader {
 public:
  explicit RequestReader(HttpLimits limits = {}) : limits_(limits) {}

  enum class State {
    Idle,      ///< no byte of a request yet
    Head,      ///< reading the request line and headers
    Body,      ///< reading a body
    Complete,  ///< request() is whole
    Failed,    ///< error_status()/error_message() say why; the connection must close
  };

  /// Consumes bytes from the front of `input` (what it leaves there
  /// belongs to the next request, e.g. a pipelined one) until a request is
  /// complete, the reader fails, or `input` runs out.
  void feed(std::string& input);

  State state() const { return state_; }
  /// Set once the head is read: the client asked for "100 Continue" and
  /// the body is still to come (answer it once, then call continue_sent()).
  bool wants_continue() const { return wants_continue_; }
  void continue_sent() { wants_continue_ = false; }

  /// The body limit of the request being read (once its head is read).
  std::size_t body_limit() const { return body_limit_; }

  const HttpRequest& request() const { return request_; }
  HttpRequest take_request();  ///< then reset() for the next one
  void reset();

  int error_status() const { return error_status_; }
  const std::string& error_message() const { return error_message_; }

 private:
  enum class BodyStep { Fixed, ChunkSize, ChunkData, ChunkDataEnd, Trailer };

  bool take_line(std::string& input, std::string& line, std::size_t max_bytes, int status_if_long,
                 const char* what_if_long);
  void parse_request_line(const std::string& line);
  void parse_header_line(const std::string& line, bool trailer);
  void end_of_head();
  bool read_body(std::string& input);
  void fail(int status, std::string message);
  void complete() { state_ = State::Complete; }

  HttpLimits limits_;
  State state_ = State::Idle;
  HttpRequest request_;
  std::string line_;              ///< the line being read, across feeds
  std::size_t header_bytes_ = 0;  ///< names and values so far
  std::size_t field_count_ = 0;   ///< header and trailer fields so far
  BodyStep body_step_ = BodyStep::Fixed;
  std::size_t remaining_ = 0;     ///< of a Content-Length body, or of the current chunk
  std::size_t body_limit_ = 0;    ///< of this request (HttpLimits::body_limit_for)
  bool wants_continue_ = false;
  int error_status_ = 0;
  std::string error_message_;
};

}  // namespace umbra
