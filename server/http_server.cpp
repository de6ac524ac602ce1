#include "http_server.hpp"

#include <algorithm>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <thread>
#include <unordered_map>
#include <vector>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <linux/sockios.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

namespace umbra {

namespace {

using Clock = std::chrono::steady_clock;

constexpr std::size_t kReadChunk = 64 << 10;        // bytes read per readiness event
constexpr std::size_t kAcceptsPerWake = 128;        // so that a flood of connects cannot starve the rest
constexpr auto kLinger = std::chrono::seconds(1);   // reading after a closing response
constexpr auto kAcceptPause = std::chrono::milliseconds(100);  // out of descriptors: rest accepting
// How often a connection whose pipelined requests wait for its answers to
// be read looks at its send queue again: no readiness event says that it
// shrank below max_unsent_bytes (EPOLLOUT fires whenever there is room).
constexpr auto kDrainPoll = std::chrono::milliseconds(50);

// Draining: every byte of the answers is with the kernel, but the client
// has not read them all; the connection waits for it to read (below
// max_unsent_bytes to go on with a pipelined request, all of it to close).
enum class Phase { Idle, Receiving, Handling, Sending, Draining, Lingering };

struct Connection {
  int fd = -1;
  std::uint64_t id = 0;
  Phase phase = Phase::Idle;
  Clock::time_point deadline;  // of the phase; none while handling
  Clock::time_point idle_since;  // idle: accepted, or its last answer sent
  Clock::time_point started;   // the request's first byte, for the log
  RequestReader reader;
  std::string in;              // read, not yet parsed
  std::string out;             // to send
  std::size_t sent = 0;
  bool close_after_send = false;
  Clock::time_point answer_due;   // sending: the whole answer out by then (write_timeout)
  Clock::time_point progressed;   // sending, draining: when the client last took a byte of its answers
  std::size_t unsent_in_kernel = 0;  // draining: as last seen
  bool close_when_drained = false;   // draining: close once all is read, rather than read on
  bool body_deadline_set = false;  // the deadline allows for this request's body
  bool admitted = false;           // this request's head passed HttpHandlers::admit
  std::string principal;           // of this request, from admit
  std::size_t counted_body = 0;    // bytes of its body counted in Impl::buffered_body_bytes
  std::uint32_t events = 0;    // registered with epoll; 0: not registered

  explicit Connection(const HttpLimits& limits) : reader(limits) {}
};

// A request on its way to or from a worker. The connection it came on is
// out of epoll meanwhile and its descriptor stays open, so request.socket
// is safe to look at (peer_closed) until the answer is back.
struct Work {
  int fd = -1;
  std::uint64_t id = 0;
  HttpRequest request;
  HttpResponse response;
};

void close_quietly(int fd) {
  if (fd >= 0) ::close(fd);
}

// Bytes sent on `fd` that the peer has not acknowledged yet: answers it
// has not read (on loopback, once its receive buffer is full).
std::size_t unsent_in_kernel(int fd) {
  int bytes = 0;
  if (ioctl(fd, SIOCOUTQ, &bytes) != 0 || bytes < 0) return 0;
  return std::size_t(bytes);
}

}  // namespace

struct HttpServer::Impl {
  HttpServerOptions options;
  HttpHandlers handlers;
  int listen_fd = -1, epoll_fd = -1, wake_fd = -1;
  int bound_port = 0;
  std::atomic<bool> running{false}, stop_requested{false};

  // Owned by the I/O thread.
  std::unordered_map<int, std::unique_ptr<Connection>> connections;
  std::uint64_t next_id = 1;
  bool stopping = false;
  Clock::time_point accepting_again{};  // set while accepting rests (out of descriptors)
  std::size_t buffered_body_bytes = 0;  // request bodies held, all connections (max_buffered_body_bytes)

  // Shared with the workers.
  // A worker takes requests handed to it, then any still waiting, and
  // sleeps on its own condition. Idle workers form a stack: the one idle
  // most recently (its stack and malloc arena warm) takes the next request,
  // so a light load keeps to one or two threads instead of touching every
  // worker's memory in turn.
  struct Worker {
    std::condition_variable wake;
    bool handed = false;  // `work` holds a request for it
    Work work;
    std::thread thread;
  };
  std::mutex mutex;
  std::vector<std::unique_ptr<Worker>> workers;
  std::vector<Worker*> idle_workers;
  std::deque<Work> waiting, done;
  bool workers_quit = false;
  std::size_t handling_on_workers = 0;  // I/O thread only

  mutable std::mutex stats_mutex;
  HttpServerStats stats;

  Impl(HttpServerOptions o, HttpHandlers h) : options(std::move(o)), handlers(std::move(h)) {
    epoll_fd = epoll_create1(EPOLL_CLOEXEC);
    wake_fd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  }
  ~Impl() {
    for (auto& [fd, c] : connections) close_quietly(fd);
    close_quietly(listen_fd);
    close_quietly(wake_fd);
    close_quietly(epoll_fd);
  }

  void wake() {
    const std::uint64_t one = 1;
    [[maybe_unused]] ssize_t n = ::write(wake_fd, &one, sizeof one);
  }

  template <class F>
  void count(F f) {
    std::lock_guard<std::mutex> lock(stats_mutex);
    f(stats);
  }

  // ---- epoll registration

  void watch(Connection& c, std::uint32_t events) {
    if (events == c.events) return;
    epoll_event ev{};
    ev.events = events;
    ev.data.fd = c.fd;
    if (c.events == 0)
      epoll_ctl(epoll_fd, EPOLL_CTL_ADD, c.fd, &ev);
    else if (events == 0)
      epoll_ctl(epoll_fd, EPOLL_CTL_DEL, c.fd, nullptr);
    else
      epoll_ctl(epoll_fd, EPOLL_CTL_MOD, c.fd, &ev);
    c.events = events;
  }

  // ---- connections

  // `reset`: with RST, dropping what the kernel still holds to send. For a
  // client that does not read: a plain close would leave its unread
  // answers in kernel memory until the kernel gives up on the peer.
  void close_connection(int fd, bool reset = false) {
    auto it = connections.find(fd);
    if (it == connections.end()) return;
    watch(*it->second, 0);
    release_body(*it->second);
    if (reset) {
      const linger abort{1, 0};
      setsockopt(fd, SOL_SOCKET, SO_LINGER, &abort, sizeof abort);
    }
    ::close(fd);
    connections.erase(it);
    count([](HttpServerStats& s) { --s.connections_open; });
  }

  void release_body(Connection& c) {
    buffered_body_bytes -= c.counted_body;
    c.counted_body = 0;
  }

  // Counts what the request being read holds of its body; false if that
  // takes all connections' bodies past max_buffered_body_bytes.
  bool count_body(Connection& c) {
    const std::size_t size = c.reader.request().body.size();
    buffered_body_bytes += size - c.counted_body;
    c.counted_body = size;
    return buffered_body_bytes <= options.max_buffered_body_bytes;
  }

  void become_idle(Connection& c) {
    c.phase = Phase::Idle;
    c.idle_since = Clock::now();
    c.deadline = c.idle_since + options.idle_timeout;
    c.reader.reset();
    c.admitted = false;
    c.principal.clear();
  }

  // Once per request, when its head is whole: false if it was answered
  // (refused) instead.
  bool admit(Connection& c) {
    if (c.admitted) return true;
    c.admitted = true;
    if (!handlers.admit) return true;
    Admission admission = handlers.admit(c.reader.request());
    c.principal = std::move(admission.principal);
    if (!admission.refusal) return true;
    // The body is not read: the connection closes unless there is none.
    const bool whole = c.reader.state() == RequestReader::State::Complete;
    HttpRequest head = whole ? c.reader.take_request() : partial_request(c);
    respond(c, head, std::move(*admission.refusal), !whole);
    return false;
  }

  // The connection to close to make room at the cap: one already closing
  // (lingering), else the one that has gone longest without progress: idle
  // since it was accepted or last answered, receiving its request since its
  // first byte (a legitimate request arrives in milliseconds), or sending an
  // answer the client last took a byte of then (a client that does not
  // read). The slowest is the likeliest attacker, and the nearest its own
  // timeout anyway; a connection just accepted is the newest of all, so a
  // flood of reconnecting non-readers cannot push a health probe out before
  // its request is read. -1: every one is being handled.
  int connection_to_evict() const {
    int oldest = -1;
    Clock::time_point oldest_since = Clock::time_point::max();
    for (const auto& [fd, c] : connections) {
      if (c->phase == Phase::Lingering) return fd;
      const Clock::time_point since = c->phase == Phase::Idle                                      ? c->idle_since
                                      : c->phase == Phase::Receiving                                 ? c->started
                                      : c->phase == Phase::Sending || c->phase == Phase::Draining ? c->progressed
                                                                                                    : Clock::time_point::max();
      if (since < oldest_since) {
        oldest = fd;
        oldest_since = since;
      }
    }
    return oldest;
  }

  // Best effort, never blocking: the few hundred bytes of an error fit in
  // any socket buffer.
  void refuse_at_once(int fd, int status, const std::string& message) {
    const HttpResponse response = handlers.error(status, message);
    const std::string bytes = response_head(response, response.body.size(), true, 0) + response.body;
    [[maybe_unused]] ssize_t n = ::send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
    ::shutdown(fd, SHUT_WR);
    ::close(fd);
  }

  void accept_connections() {
    for (std::size_t i = 0; i < kAcceptsPerWake; ++i) {
      const int fd = accept4(listen_fd, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
      if (fd < 0) {
        // Out of descriptors: the listener stays readable, and a level-
        // triggered loop would spin on it. Rest it for a moment; the
        // backlog holds the connections meanwhile.
        if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM) pause_accepting();
        return;
      }
      if (connections.size() >= options.max_connections) {
        const int evict = connection_to_evict();
        if (evict < 0) {
          refuse_at_once(fd, 503, "too many connections (" + std::to_string(options.max_connections) + "); retry later");
          count([](HttpServerStats& s) { ++s.connections_refused; });
          continue;
        }
        const Phase phase = connections.at(evict)->phase;
        close_connection(evict, phase == Phase::Sending || phase == Phase::Draining);
        count([](HttpServerStats& s) { ++s.connections_evicted; });
      }
      // A response goes out as head, then body: with Nagle's algorithm the
      // body would wait for the client's delayed ACK (~40 ms).
      int yes = 1;
      setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &yes, sizeof yes);
      auto c = std::make_unique<Connection>(options.limits);
      c->fd = fd;
      c->id = next_id++;
      become_idle(*c);
      watch(*c, EPOLLIN);
      connections.emplace(fd, std::move(c));
      count([](HttpServerStats& s) {
        ++s.connections_open;
        ++s.connections_accepted;
      });
    }
  }

  void on_event(int fd, std::uint32_t events) {
    auto it = connections.find(fd);
    if (it == connections.end()) return;
    Connection& c = *it->second;
    if (events & (EPOLLERR | EPOLLHUP)) {
      if (!(events & EPOLLIN) || c.phase == Phase::Sending) return close_connection(fd);
    }
    if ((events & EPOLLOUT) && !flush(c)) return;
    if (events & EPOLLIN) read_from(c);
    resume(fd);
  }

  void read_from(Connection& c) {
    char buffer[kReadChunk];
    const ssize_t n = ::recv(c.fd, buffer, sizeof buffer, 0);
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) return;
    if (n <= 0) return close_connection(c.fd);  // gone: nothing more will be read or answered
    if (c.phase == Phase::Lingering) return;     // dropped
    c.in.append(buffer, std::size_t(n));
    parse(c);
  }

  // Reads requests out of c.in while the connection may take one.
  void parse(Connection& c) {
    const int fd = c.fd;
    while (c.phase == Phase::Idle || c.phase == Phase::Receiving) {
      c.reader.feed(c.in);
      switch (c.reader.state()) {
        case RequestReader::State::Idle:
          return;  // only blank lines so far: still idle, same deadline
        case RequestReader::State::Head:
        case RequestReader::State::Body:
          if (c.phase == Phase::Idle) {
            c.phase = Phase::Receiving;
            c.started = Clock::now();
            c.deadline = c.started + options.request_timeout;
            c.body_deadline_set = false;
          }
          if (c.reader.state() == RequestReader::State::Body && !admit(c)) return;
          if (c.reader.state() == RequestReader::State::Body && !c.body_deadline_set) {
            c.body_deadline_set = true;
            c.deadline += std::chrono::milliseconds(std::uint64_t(c.reader.body_limit()) * 1000 /
                                                    std::max<std::size_t>(1, options.min_body_rate));
          }
          if (!count_body(c)) return refuse_body(c);
          if (c.reader.wants_continue()) {
            c.reader.continue_sent();
            c.out += "HTTP/1.1 100 Continue\r\n\r\n";
            if (!flush(c)) return;
          }
          return;
        case RequestReader::State::Failed: {
          if (c.phase == Phase::Idle) c.started = Clock::now();
          return respond(c, partial_request(c), handlers.error(c.reader.error_status(), c.reader.error_message()),
                         true);
        }
        case RequestReader::State::Complete: {
          if (c.phase == Phase::Idle) c.started = Clock::now();
          if (!admit(c)) {
            if (!connections.count(fd)) return;
            break;  // refused and answered; the next pipelined request may follow
          }
          if (!count_body(c)) return refuse_body(c);
          HttpRequest request = c.reader.take_request();
          request.socket = c.fd;
          request.principal = c.principal;
          dispatch(c, std::move(request));
          if (!connections.count(fd)) return;
          break;  // answered inline and sent: the next pipelined request may follow
        }
      }
    }
  }

  // What the log and respond() need of a request refused before it was
  // read whole: its method and path, where they were read.
  static HttpRequest partial_request(const Connection& c) {
    HttpRequest partial;
    partial.method = c.reader.request().method;
    partial.path = c.reader.request().path;
    return partial;
  }

  void refuse_body(Connection& c) {
    count([](HttpServerStats& s) { ++s.bodies_refused; });
    const HttpRequest partial = partial_request(c);
    release_body(c);
    HttpResponse busy = handlers.error(
        503, "the server holds " + std::to_string(options.max_buffered_body_bytes >> 20) +
                 " MiB of request bodies already; retry later");
    busy.set_header("Retry-After", "1");
    respond(c, partial, std::move(busy), true);
  }

  void dispatch(Connection& c, HttpRequest request) {
    c.phase = Phase::Handling;
    if (!handlers.blocks(request)) {
      HttpResponse response;
      run_handler(request, response);
      return respond(c, request, std::move(response), false);
    }
    Worker* woken = nullptr;
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (idle_workers.empty() && waiting.size() >= options.max_waiting_requests) {
        HttpResponse busy = handlers.error(503, "the server is busy (" + std::to_string(options.worker_threads) +
                                                    " requests running and " +
                                                    std::to_string(options.max_waiting_requests) +
                                                    " waiting); retry later");
        busy.set_header("Retry-After", "1");
        return respond(c, request, std::move(busy), false);
      }
      watch(c, 0);  // no reading meanwhile; the descriptor stays open
      Work work{c.fd, c.id, std::move(request), {}};
      if (idle_workers.empty()) {
        waiting.push_back(std::move(work));
      } else {
        woken = idle_workers.back();
        idle_workers.pop_back();
        woken->work = std::move(work);
        woken->handed = true;
      }
    }
    ++handling_on_workers;
    if (woken) woken->wake.notify_one();
  }

  void run_handler(const HttpRequest& request, HttpResponse& response) {
    try {
      handlers.handle(request, response);
    } catch (const std::exception& e) {
      response = handlers.error(500, std::string("internal error: ") + e.what());
    } catch (...) {
      response = handlers.error(500, "internal error");
    }
  }

  void worker_loop(Worker& self) {
    for (;;) {
      Work work;
      {
        std::unique_lock<std::mutex> lock(mutex);
        if (!self.handed && waiting.empty()) {
          if (workers_quit) return;
          idle_workers.push_back(&self);
          self.wake.wait(lock, [&] { return self.handed || workers_quit; });
          if (!self.handed) return;
        }
        if (self.handed) {
          work = std::move(self.work);
          self.handed = false;
        } else {
          work = std::move(waiting.front());
          waiting.pop_front();
        }
      }
      run_handler(work.request, work.response);
      {
        std::lock_guard<std::mutex> lock(mutex);
        done.push_back(std::move(work));
      }
      wake();
    }
  }

  void collect_done() {
    std::deque<Work> finished;
    {
      std::lock_guard<std::mutex> lock(mutex);
      finished.swap(done);
    }
    for (Work& work : finished) {
      --handling_on_workers;
      auto it = connections.find(work.fd);
      if (it == connections.end() || it->second->id != work.id) continue;
      respond(*it->second, work.request, std::move(work.response), false);
      resume(work.fd);
    }
  }

  void respond(Connection& c, const HttpRequest& request, HttpResponse response, bool close) {
    close = close || response.close || !request.keep_alive || stopping;
    release_body(c);  // answered: the body is no longer held
    if (handlers.log)
      handlers.log(request, response, std::chrono::duration<double, std::milli>(Clock::now() - c.started).count());
    const int keep_alive_s = int(std::chrono::duration_cast<std::chrono::seconds>(options.idle_timeout).count());
    c.out += response_head(response, response.body.size(), close, std::max(1, keep_alive_s));
    if (request.method != "HEAD") c.out += response.body;
    c.phase = Phase::Sending;
    c.progressed = Clock::now();
    c.answer_due = c.progressed + options.write_timeout;
    c.deadline = sending_deadline(c);
    c.close_after_send = close;
    watch(c, EPOLLOUT);
    flush(c);
  }

  // The whole answer within write_timeout, and a byte of it taken at least
  // every send_stall_timeout.
  Clock::time_point sending_deadline(const Connection& c) const {
    return std::min(c.answer_due, c.progressed + options.send_stall_timeout);
  }

  // Sends what it can; false if the connection was closed. When a
  // response is out, the connection closes or waits for the next request
  // (which may already be buffered: pipelined requests are answered in
  // order, one at a time).
  bool flush(Connection& c) {
    while (c.sent < c.out.size()) {
      const ssize_t n = ::send(c.fd, c.out.data() + c.sent, c.out.size() - c.sent, MSG_NOSIGNAL);
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
        watch(c, c.phase == Phase::Receiving ? EPOLLIN | EPOLLOUT : EPOLLOUT);
        return true;
      }
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        close_connection(c.fd);
        return false;
      }
      c.sent += std::size_t(n);
      c.progressed = Clock::now();
      if (c.phase == Phase::Sending) c.deadline = sending_deadline(c);
    }
    c.out.clear();
    c.sent = 0;
    if (c.phase == Phase::Receiving) {
      watch(c, EPOLLIN);
      return true;
    }
    if (c.phase != Phase::Sending) return true;
    if (c.close_after_send) {
      // Half-close, then read and drop for a moment: closing with unread
      // bytes would send RST, and the client could lose the answer.
      ::shutdown(c.fd, SHUT_WR);
      c.phase = Phase::Lingering;
      c.deadline = Clock::now() + kLinger;
      c.in.clear();
      watch(c, EPOLLIN);
      return true;
    }
    if (!c.in.empty() && unsent_in_kernel(c.fd) > options.max_unsent_bytes) {
      start_draining(c, false);
      return true;
    }
    become_idle(c);
    watch(c, EPOLLIN);
    return true;
  }

  // Waits for the client to read what the kernel holds of its answers:
  // down to max_unsent_bytes before a pipelined request is read (one that
  // never reads holds that much, not an answer per request it sent), or
  // all of it before a connection that is done closes (else its unread
  // answers would stay in kernel memory long after). Nothing is read
  // meanwhile; no byte read for send_stall_timeout resets the connection.
  // Draining has no event to wait for: look again after kDrainPoll, or
  // at the stall limit if that comes first.
  Clock::time_point draining_deadline(const Connection& c, Clock::time_point now) const {
    return std::min(now + kDrainPoll, c.progressed + options.send_stall_timeout);
  }

  void start_draining(Connection& c, bool then_close) {
    c.phase = Phase::Draining;
    c.close_when_drained = then_close;
    c.unsent_in_kernel = unsent_in_kernel(c.fd);
    c.deadline = draining_deadline(c, Clock::now());
    watch(c, 0);
  }

  // A connection done with, idle or lingering: closed, once the client has
  // read its answers.
  void close_when_read(Connection& c, Clock::time_point now) {
    if (stopping || unsent_in_kernel(c.fd) == 0) return close_connection(c.fd);
    c.progressed = now;
    start_draining(c, true);
  }

  void recheck_draining(Connection& c, Clock::time_point now) {
    const std::size_t unsent = unsent_in_kernel(c.fd);
    if (unsent < c.unsent_in_kernel) c.progressed = now;
    c.unsent_in_kernel = unsent;
    if (c.close_when_drained && unsent == 0) return close_connection(c.fd);
    if (!c.close_when_drained && unsent <= options.max_unsent_bytes) {
      become_idle(c);
      watch(c, EPOLLIN);
      return resume(c.fd);
    }
    if (now - c.progressed >= options.send_stall_timeout) return close_stalled(c.fd);
    c.deadline = draining_deadline(c, now);
  }

  void close_stalled(int fd) {
    count([](HttpServerStats& s) { ++s.connections_stalled; });
    close_connection(fd, true);
  }

  // After an answer went out: a request already buffered (pipelined) is
  // read now, as no readiness event will announce it.
  void resume(int fd) {
    auto it = connections.find(fd);
    if (it != connections.end() && it->second->phase == Phase::Idle && !it->second->in.empty()) parse(*it->second);
  }

  // ---- time

  void pause_accepting() {
    epoll_ctl(epoll_fd, EPOLL_CTL_DEL, listen_fd, nullptr);
    accepting_again = Clock::now() + kAcceptPause;
  }

  void resume_accepting(Clock::time_point now) {
    if (accepting_again == Clock::time_point{} || now < accepting_again || listen_fd < 0) return;
    accepting_again = Clock::time_point{};
    epoll_event ev{};
    ev.events = EPOLLIN;
    ev.data.fd = listen_fd;
    epoll_ctl(epoll_fd, EPOLL_CTL_ADD, listen_fd, &ev);
  }

  int next_timeout_ms() const {
    Clock::time_point next = accepting_again == Clock::time_point{} ? Clock::time_point::max() : accepting_again;
    for (const auto& [fd, c] : connections)
      if (c->phase != Phase::Handling) next = std::min(next, c->deadline);
    if (next == Clock::time_point::max()) return -1;
    const auto ms = std::chrono::ceil<std::chrono::milliseconds>(next - Clock::now()).count();
    return int(std::clamp<long long>(ms, 0, 60000));
  }

  void expire(Clock::time_point now) {
    std::vector<int> late;
    for (const auto& [fd, c] : connections)
      if (c->phase != Phase::Handling && c->deadline <= now) late.push_back(fd);
    for (int fd : late) {
      auto it = connections.find(fd);
      if (it == connections.end()) continue;
      Connection& c = *it->second;
      if (c.phase == Phase::Draining) {
        recheck_draining(c, now);
      } else if (c.phase == Phase::Sending && now - c.progressed >= options.send_stall_timeout) {
        close_stalled(fd);  // the client took no byte of its answer for send_stall_timeout
      } else if (c.phase == Phase::Receiving) {
        count([](HttpServerStats& s) { ++s.requests_timed_out; });
        const HttpRequest partial = partial_request(c);
        const auto limit = std::chrono::duration<double>(options.request_timeout).count();
        char text[96];
        std::snprintf(text, sizeof text, "the request was not received whole within %g s", limit);
        respond(c, partial, handlers.error(408, text), true);
      } else if (c.phase == Phase::Sending) {
        close_connection(fd, true);  // too slow to read its whole answer within write_timeout
      } else {
        close_when_read(c, now);  // idle, or done lingering
      }
    }
  }

  // First pass of a stop: no new connections, none waiting for a request.
  void begin_stop() {
    stopping = true;
    if (listen_fd >= 0) {
      epoll_ctl(epoll_fd, EPOLL_CTL_DEL, listen_fd, nullptr);
      ::close(listen_fd);
      listen_fd = -1;
    }
    std::vector<int> closable;
    // A draining connection's answers are in the kernel, which still
    // delivers them after the close; what it pipelined after is not answered.
    for (const auto& [fd, c] : connections)
      if (c->phase == Phase::Idle || c->phase == Phase::Receiving || c->phase == Phase::Draining)
        closable.push_back(fd);
    for (int fd : closable) close_connection(fd);
  }

  void serve() {
    {
      std::lock_guard<std::mutex> lock(mutex);
      workers_quit = false;
      for (std::size_t i = 0; i < std::max<std::size_t>(1, options.worker_threads); ++i)
        workers.push_back(std::make_unique<Worker>());
    }
    for (auto& worker : workers) worker->thread = std::thread([this, w = worker.get()] { worker_loop(*w); });
    epoll_event ev{};
    ev.events = EPOLLIN;
    ev.data.fd = listen_fd;
    epoll_ctl(epoll_fd, EPOLL_CTL_ADD, listen_fd, &ev);
    ev.data.fd = wake_fd;
    epoll_ctl(epoll_fd, EPOLL_CTL_ADD, wake_fd, &ev);
    running = true;
    epoll_event events[64];
    for (;;) {
      if (stop_requested && !stopping) begin_stop();
      if (stopping && connections.empty() && handling_on_workers == 0) break;
      const int n = epoll_wait(epoll_fd, events, 64, next_timeout_ms());
      for (int i = 0; i < n; ++i) {
        const int fd = events[i].data.fd;
        if (fd == listen_fd) {
          accept_connections();
        } else if (fd == wake_fd) {
          std::uint64_t value;
          [[maybe_unused]] ssize_t r = ::read(wake_fd, &value, sizeof value);
          collect_done();
        } else {
          on_event(fd, events[i].events);
        }
      }
      expire(Clock::now());
      resume_accepting(Clock::now());
    }
    {
      std::lock_guard<std::mutex> lock(mutex);
      workers_quit = true;
    }
    for (auto& worker : workers) worker->wake.notify_one();
    for (auto& worker : workers) worker->thread.join();
    workers.clear();
    idle_workers.clear();
    running = false;
  }

  bool bind() {
    addrinfo hints{}, *found = nullptr;
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
    const std::string port = std::to_string(options.port);
    if (getaddrinfo(options.host.c_str(), port.c_str(), &hints, &found) != 0 || !found) {
      errno = EADDRNOTAVAIL;
      return false;
    }
    int error = 0;
    for (addrinfo* a = found; a; a = a->ai_next) {
      const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol);
      if (fd < 0) {
        error = errno;
        continue;
      }
      // SO_REUSEADDR allows a quick restart; not SO_REUSEPORT, which would
      // let a second server take half of this one's connections.
      int yes = 1;
      setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
      if (::bind(fd, a->ai_addr, a->ai_addrlen) == 0 && ::listen(fd, options.listen_backlog) == 0) {
        listen_fd = fd;
        break;
      }
      error = errno;
      ::close(fd);
    }
    freeaddrinfo(found);
    if (listen_fd < 0) {
      errno = error;
      return false;
    }
    sockaddr_storage address{};
    socklen_t length = sizeof address;
    getsockname(listen_fd, reinterpret_cast<sockaddr*>(&address), &length);
    bound_port = address.ss_family == AF_INET6 ? ntohs(reinterpret_cast<sockaddr_in6*>(&address)->sin6_port)
                                               : ntohs(reinterpret_cast<sockaddr_in*>(&address)->sin_port);
    return true;
  }
};

HttpServer::HttpServer(HttpServerOptions options, HttpHandlers handlers)
    : impl_(std::make_unique<Impl>(std::move(options), std::move(handlers))) {}

HttpServer::~HttpServer() = default;

bool HttpServer::bind() { return impl_->bind(); }

int HttpServer::port() const { return impl_->bound_port; }

void HttpServer::serve() {
  if (impl_->listen_fd < 0) return;
  impl_->serve();
}

bool HttpServer::serving() const { return impl_->running; }

void HttpServer::stop() {
  impl_->stop_requested = true;
  impl_->wake();
}

HttpServerStats HttpServer::stats() const {
  std::lock_guard<std::mutex> lock(impl_->stats_mutex);
  return impl_->stats;
}

}  // namespace umbra
