// Umbra's HTTP/1.1 connection layer: one I/O thread (epoll) owns every
// connection; handlers that may block (renders) run on a small pool of
// workers. Knows nothing of routes or GL.
//
// Why not cpp-httplib's server (Debian 12 ships 0.11): it gives each
// connection a thread for its whole life and times out each recv() on its
// own, so a dozen clients trickling a byte a second, or a few hundred idle
// sockets, hold every thread; it reads chunked bodies without a limit and
// drops pipelined requests. Here a connection costs a buffer, not a thread,
// and every phase of it has a total deadline:
//
//   idle      no byte of a request yet              idle_timeout, then closed
//   receiving request line, headers, body           request_timeout from its first byte (plus the
//                                                   largest body's time at min_body_rate), then 408
//   handling  the handler runs                      the handler's own bounds (render queue, cost budget)
//   sending   the response goes out                 write_timeout in all, and send_stall_timeout without
//                                                   a byte taken by the client, then closed; a
//                                                   pipelined request waits while more than
//                                                   max_unsent_bytes of answers are unread
//   lingering after a closing response              1 s of reading (and dropping) what the client still
//                                                   sends, so that it reads the response before the close
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "http_message.hpp"

namespace umbra {

struct HttpServerOptions {
  std::string host = "127.0.0.1";
  int port = 8080;  ///< 0: any free port
  HttpLimits limits;
  /// Connections open at once, 1... Past it a new one takes the place of
  /// the longest-idle connection, else of the one that has gone longest
  /// without progress: receiving its request (since its first byte) or
  /// sending an answer (since the client last took a byte of it). Only
  /// when every connection's request is being handled (at most
  /// worker_threads + max_waiting_requests of them, plus none on the I/O
  /// thread) is a new one answered 503 and closed. Default 256.
  std::size_t max_connections = 256;
  /// Pending connections the kernel holds before accept. Default 1024.
  int listen_backlog = 1024;
  std::chrono::milliseconds idle_timeout{2000};      ///< before a request's first byte. Default 2 s
  /// First byte to last of one request, plus the time its largest allowed
  /// body takes at min_body_rate (so a route that takes big bodies allows
  /// for them). Default 10 s.
  std::chrono::milliseconds request_timeout{10000};
  /// Slowest body upload allowed for, bytes/s. Default 1 MiB/s: a 1 MiB
  /// render body adds 1 s, a 64 MiB model 64 s.
  std::size_t min_body_rate = 1 << 20;
  /// Request bodies held at once, all connections together (while read and
  /// until answered). Past it a request is answered 503 and its connection
  /// closed. Default 256 MiB.
  std::size_t max_buffered_body_bytes = 256u << 20;
  std::chrono::milliseconds write_timeout{10000};    ///< to send one response. Default 10 s
  /// An answer the client takes no byte of for this long closes the
  /// connection (a client that does not read). Default 5 s.
  std::chrono::milliseconds send_stall_timeout{5000};
  /// Answers sent but not yet read by the client (the kernel's send queue)
  /// above which a pipelined request waits before it is read and handled,
  /// so that a client pipelining requests without reading their answers
  /// holds at most this much plus one answer. Default 1 MiB.
  std::size_t max_unsent_bytes = 1u << 20;
  /// Threads for handlers that may block, 1... Default 4.
  std::size_t worker_threads = 4;
  /// Requests that may wait for a free worker; past it 503. Default 16.
  std::size_t max_waiting_requests = 16;
};

/// What HttpHandlers::admit says of a request's head.
struct Admission {
  /// Set: answer this at once, before the body is read (the connection
  /// then closes unless the request had no body).
  std::optional<HttpResponse> refusal;
  std::string principal;  ///< becomes HttpRequest::principal
};

struct HttpHandlers {
  /// Once a request's head is read, before its body: may refuse it (a
  /// foreign Host, no token) so that no body is read for nothing, and
  /// names who sent it. May be empty: every request admitted. Runs on the
  /// I/O thread, which must never wait.
  std::function<Admission(const HttpRequest& head)> admit;
  /// True if handle() may block for `request`: it then runs on a worker;
  /// otherwise on the I/O thread, which must never wait.
  std::function<bool(const HttpRequest&)> blocks;
  std::function<void(const HttpRequest&, HttpResponse&)> handle;
  /// The response to an error the server found itself (malformed or late
  /// request, no room), so that it reads like the handler's own errors.
  std::function<HttpResponse(int status, const std::string& message)> error;
  /// Once per response, as it starts to go out; may be empty. `request`
  /// is empty but for its method and path where none was read whole.
  std::function<void(const HttpRequest& request, const HttpResponse& response, double ms)> log;
};

/// Counters since start, for /api/health.
struct HttpServerStats {
  std::uint64_t connections_open = 0;
  std::uint64_t connections_accepted = 0;
  std::uint64_t connections_evicted = 0;  ///< closed to make room for a new one
  std::uint64_t connections_stalled = 0;  ///< closed: the client read no byte of its answer for send_stall_timeout
  std::uint64_t connections_refused = 0;  ///< answered 503 at the connection cap
  std::uint64_t requests_timed_out = 0;   ///< answered 408
  std::uint64_t bodies_refused = 0;       ///< answered 503: max_buffered_body_bytes held already
};

class HttpServer {
 public:
  HttpServer(HttpServerOptions options, HttpHandlers handlers);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  /// Binds and listens; false (with errno set) if the address is unusable.
  bool bind();
  int port() const;
  /// Serves until stop(): then closes the listener and every connection
  /// that is idle or still sending its request, answers the requests
  /// already read, and returns.
  void serve();
  /// True once serve() is accepting connections (and until it returns).
  bool serving() const;
  /// Thread-safe; also before serve(), which then returns at once.
  void stop();

  HttpServerStats stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace umbra
