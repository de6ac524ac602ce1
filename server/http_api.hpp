// The HTTP face of Umbra (../shared/API.md): routes, errors, static files.
// Turns JSON into a typed request, hands it to the RenderService, turns the
// pixels into PNG. Knows nothing of GL.
#pragma once

#include <chrono>
#include <memory>
#include <string>

#include "render_service.hpp"

namespace httplib {
class Server;
}

namespace umbra {

struct ServerOptions {
  std::string host = "127.0.0.1";  ///< loopback unless told otherwise
  int port = 8080;                 ///< 0: any free port (see HttpApi::port)
  std::string web_dir;             ///< empty: the web panel embedded at build time
  bool log_requests = true;        ///< one line per request on stderr
  /// Empty: no CORS headers, so browsers allow only same-origin pages to
  /// read responses. Else the one origin (e.g. "https://app.example", or
  /// "*") whose pages may call the API; see valid_cors_origin().
  std::string cors_origin;
};

/// "*", or scheme://host[:port] with scheme http or https and nothing after.
bool valid_cors_origin(const std::string& origin);

class HttpApi {
 public:
  // Explicit limits on what a request may be; above them it is refused
  // before any work. (cpp-httplib itself answers 414 above 8 KiB of
  // request line and 400 for one header line longer than 8 KiB.)
  static constexpr std::size_t kMaxBodyBytes = 1 << 20;     ///< 413 above this
  static constexpr std::size_t kMaxUriBytes = 4096;         ///< 414 above this
  static constexpr std::size_t kMaxHeaderCount = 100;       ///< 431 above this many header fields
  static constexpr std::size_t kMaxHeaderBytes = 32 << 10;  ///< 431 above this many bytes of names and values

  HttpApi(RenderService& renderer, ServerOptions options);
  ~HttpApi();

  /// Binds the socket; false (with errno set) if the address is unusable.
  bool bind();
  /// The bound port (after bind()).
  int port() const { return port_; }
  /// Serves until stop(); call after bind().
  void serve();
  /// True once serve() is accepting connections (and until it returns).
  bool serving() const;
  /// Stops serve(). A stop() before serve() has started is lost, so a
  /// caller that runs serve() on another thread waits for serving() first.
  void stop();

 private:
  void install_routes();
  /// The panel's file `name` (a path relative to the web folder): false if
  /// there is none, or if it lies outside the folder.
  bool read_static_file(const std::string& name, std::string& bytes) const;

  RenderService& renderer_;
  ServerOptions options_;
  std::unique_ptr<httplib::Server> http_;
  int port_ = 0;
  std::chrono::steady_clock::time_point started_;
};

}  // namespace umbra
