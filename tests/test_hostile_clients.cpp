// Issue 11's attacks on the real server over loopback sockets: bodies past
// the limit in any framing, clients that trickle or idle, more connections
// than allowed, pipelining, 100-continue, and a stop in the middle of it all.
// Each was a reproduced failure of the cpp-httplib 0.11 server Umbra used
// before (see server/http_server.hpp).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <cerrno>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "access.hpp"
#include "http_api.hpp"
#include "service/render_service.hpp"

namespace umbra {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

class RendererEnvironment : public testing::Environment {
 public:
  void SetUp() override { renderer = std::make_unique<RenderService>(); }
  void TearDown() override { renderer.reset(); }
  static inline std::unique_ptr<RenderService> renderer;
};

// A server of its own per test, on the shared renderer.
struct Server {
  explicit Server(HttpServerOptions connections = {}) : Server(options(connections)) {}
  explicit Server(ServerOptions options) : api(*RendererEnvironment::renderer, options) {
    EXPECT_TRUE(api.bind());
    thread = std::thread([this] { api.serve(); });
    while (!api.serving()) std::this_thread::sleep_for(milliseconds(1));
  }
  ~Server() {
    api.stop();
    thread.join();
  }
  static ServerOptions options(HttpServerOptions connections) {
    ServerOptions o;
    o.port = 0;
    o.log_requests = false;
    o.connections = connections;
    return o;
  }
  int port() { return api.port(); }
  HttpApi api;
  std::thread thread;
};

int connect_to(int port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(std::uint16_t(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    close(fd);
    return -1;
  }
  return fd;
}

bool send_all(int fd, const std::string& bytes) {
  for (std::size_t sent = 0; sent < bytes.size();) {
    const ssize_t n = send(fd, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) return false;
    sent += std::size_t(n);
  }
  return true;
}

// True if `fd` has bytes (or an end) to read within `timeout`.
bool readable(int fd, milliseconds timeout) {
  pollfd p{fd, POLLIN, 0};
  return poll(&p, 1, int(timeout.count())) > 0;
}

// True if the server has closed `fd` (an end of stream or a reset comes
// within `timeout`, after any answer it sent).
bool closed_by_server(int fd, milliseconds timeout) {
  const auto until = Clock::now() + timeout;
  char buffer[4096];
  while (Clock::now() < until) {
    if (!readable(fd, std::chrono::duration_cast<milliseconds>(until - Clock::now()))) return false;
    const ssize_t n = recv(fd, buffer, sizeof buffer, 0);
    if (n <= 0) return true;
  }
  return false;
}

struct Answer {
  int status = 0;  // 0: none came
  std::string head, body;
};

// Reads responses one at a time off one connection (pipelined answers come
// back to back), each framed by its Content-Length.
class AnswerReader {
 public:
  explicit AnswerReader(int fd) : fd_(fd) {}
  Answer next(milliseconds timeout = milliseconds(10000)) {
    const auto until = Clock::now() + timeout;
    Answer a;
    std::size_t head_end;
    while ((head_end = buffer_.find("\r\n\r\n")) == std::string::npos)
      if (!fill(until)) return a;
    a.head = buffer_.substr(0, head_end + 4);
    buffer_.erase(0, head_end + 4);
    a.status = std::atoi(a.head.c_str() + 9);
    std::size_t length = 0;
    const std::size_t at = a.head.find("Content-Length: ");
    if (at != std::string::npos) length = std::stoull(a.head.substr(at + 16));
    while (buffer_.size() < length)
      if (!fill(until)) return Answer{};
    a.body = buffer_.substr(0, length);
    buffer_.erase(0, length);
    return a;
  }

 private:
  bool fill(Clock::time_point until) {
    const auto left = std::chrono::duration_cast<milliseconds>(until - Clock::now());
    if (left.count() <= 0 || !readable(fd_, left)) return false;
    char chunk[65536];
    const ssize_t n = recv(fd_, chunk, sizeof chunk, 0);
    if (n <= 0) return false;
    buffer_.append(chunk, std::size_t(n));
    return true;
  }
  int fd_;
  std::string buffer_;
};

Answer exchange(int port, const std::string& request, milliseconds timeout = milliseconds(10000)) {
  const int fd = connect_to(port);
  if (fd < 0) return {};
  send_all(fd, request);
  Answer a = AnswerReader(fd).next(timeout);
  close(fd);
  return a;
}

const std::string kHealth = "GET /api/health HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n";

// A client sending its request a byte at a time, every `gap`, until told
// to stop; each byte arrives well within any per-recv timeout.
class Trickler {
 public:
  Trickler(int port, milliseconds gap) : fd_(connect_to(port)) {
    thread_ = std::thread([this, gap] {
      const std::string request = "POST /api/render HTTP/1.1\r\nHost: localhost\r\nX-Slow: " + std::string(100000, 'a');
      for (std::size_t i = 0; i < request.size() && !stop_; ++i) {
        if (!send_all(fd_, request.substr(i, 1))) break;
        std::this_thread::sleep_for(gap);
      }
    });
  }
  ~Trickler() {
    stop_ = true;
    thread_.join();
    close(fd_);
  }
  int fd() const { return fd_; }

 private:
  int fd_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

TEST(HostileClients, AChunkedBodyIs413AtTheChunkThatPassesTheLimitAndTheConnectionCloses) {
  Server server;
  const int fd = connect_to(server.port());
  ASSERT_GE(fd, 0);
  ASSERT_TRUE(send_all(fd, "POST /api/render HTTP/1.1\r\nHost: localhost\r\nTransfer-Encoding: chunked\r\n\r\n"));
  // 64 KiB chunks, like curl's, up to 4 MiB; the server must refuse at 1 MiB.
  const std::string chunk = "10000\r\n" + std::string(65536, ' ') + "\r\n";
  std::size_t sent = 0;
  bool refused_early = false;
  for (int i = 0; i < 64; ++i) {
    if (readable(fd, milliseconds(0))) {
      refused_early = true;
      break;
    }
    if (!send_all(fd, chunk)) break;
    sent += 65536;
  }
  AnswerReader reader(fd);
  const Answer a = reader.next();
  EXPECT_EQ(a.status, 413) << a.head << a.body;
  EXPECT_NE(a.body.find("larger than 1 MiB"), std::string::npos) << a.body;
  EXPECT_NE(a.head.find("Connection: close"), std::string::npos) << a.head;
  EXPECT_TRUE(closed_by_server(fd, milliseconds(5000)));
  close(fd);
  EXPECT_TRUE(refused_early || sent <= (4u << 20)) << sent;
  // One chunk announced past the limit is refused before its data.
  const Answer big = exchange(server.port(), "POST /api/render HTTP/1.1\r\nHost: localhost\r\nTransfer-Encoding: chunked\r\n\r\n"
                                             "200000\r\n", milliseconds(5000));
  EXPECT_EQ(big.status, 413);
  EXPECT_EQ(exchange(server.port(), kHealth).status, 200);
}

TEST(HostileClients, ARequestTrickledPastItsTotalDeadlineGets408) {
  HttpServerOptions options;
  options.request_timeout = milliseconds(600);
  Server server(options);
  const auto start = Clock::now();
  Trickler slow(server.port(), milliseconds(50));  // a byte every 50 ms: never idle for a per-recv timeout
  const Answer a = AnswerReader(slow.fd()).next(milliseconds(10000));
  const double took = seconds_since(start);
  EXPECT_EQ(a.status, 408) << a.head << a.body;
  EXPECT_NE(a.body.find("within 0.6 s"), std::string::npos) << a.body;
  EXPECT_GE(took, 0.5);
  EXPECT_LT(took, 5.0) << "408 is due 0.6 s after the first byte";
  EXPECT_TRUE(closed_by_server(slow.fd(), milliseconds(3000)));
  EXPECT_EQ(json::parse(exchange(server.port(), kHealth).body)["requests_timed_out"], 1);
}

// A JSON body of exactly `size` bytes: a small frame, padded with spaces.
std::string padded_body(std::size_t size) {
  std::string body = R"({"width": 16, "height": 16})";
  body.resize(size, ' ');
  return body;
}

TEST(HostileClients, TheDeadlineAllowsForTheLargestBodyAtTheSlowestRate) {
  HttpServerOptions options;
  options.request_timeout = milliseconds(400);
  options.min_body_rate = 1000;  // bytes/s: a 1 MiB limit allows ~1000 s more, far beyond this test
  Server server(options);
  const std::string body = padded_body(1200);
  const int fd = connect_to(server.port());
  ASSERT_TRUE(send_all(fd, "POST /api/render HTTP/1.1\r\nHost: localhost\r\nContent-Length: 1200\r\n\r\n"));
  // 1200 bytes over ~1.2 s: past request_timeout alone, well within the
  // time the body is allowed.
  for (std::size_t at = 0; at < body.size(); at += 100) {
    std::this_thread::sleep_for(milliseconds(100));
    ASSERT_TRUE(send_all(fd, body.substr(at, 100)));
  }
  const Answer a = AnswerReader(fd).next();
  EXPECT_EQ(a.status, 200) << a.head << a.body;
  close(fd);
}

TEST(HostileClients, BodiesHeldAtOnceAreBounded) {
  HttpServerOptions options;
  options.max_buffered_body_bytes = 100000;
  Server server(options);
  const std::string body = padded_body(60000);
  const std::string head = "POST /api/render HTTP/1.1\r\nHost: localhost\r\nContent-Length: 60000\r\n\r\n";
  const int first = connect_to(server.port()), second = connect_to(server.port());
  ASSERT_TRUE(send_all(first, head + body.substr(0, 50000)));
  std::this_thread::sleep_for(milliseconds(100));
  ASSERT_TRUE(send_all(second, head + body.substr(0, 55000)));
  const Answer refused = AnswerReader(second).next();
  EXPECT_EQ(refused.status, 503) << refused.body;
  EXPECT_NE(refused.head.find("Retry-After: 1"), std::string::npos);
  EXPECT_TRUE(closed_by_server(second, milliseconds(3000)));
  close(second);
  // The first goes on, and what the second held is free again.
  ASSERT_TRUE(send_all(first, body.substr(50000)));
  EXPECT_EQ(AnswerReader(first).next().status, 200);
  close(first);
  const json health = json::parse(exchange(server.port(), kHealth).body);
  EXPECT_EQ(health["bodies_refused"], 1);
  const Answer again = exchange(server.port(), head + body);
  EXPECT_EQ(again.status, 200);
}

TEST(HostileClients, IdleAndTricklingClientsDoNotSilenceHealth) {
  Server server;
  std::vector<int> idle;
  for (int i = 0; i < 150; ++i) idle.push_back(connect_to(server.port()));
  std::vector<std::unique_ptr<Trickler>> slow;
  for (int i = 0; i < 12; ++i) slow.push_back(std::make_unique<Trickler>(server.port(), milliseconds(100)));
  std::this_thread::sleep_for(milliseconds(300));
  double slowest = 0;
  for (int probe = 0; probe < 20; ++probe) {
    const auto start = Clock::now();
    const Answer a = exchange(server.port(), kHealth, milliseconds(5000));
    slowest = std::max(slowest, seconds_since(start));
    ASSERT_EQ(a.status, 200) << "probe " << probe;
  }
  // The design answers in about a millisecond; 2 s only allows for a
  // loaded machine, where the old server did not answer at all.
  EXPECT_LT(slowest, 2.0);
  for (int fd : idle) close(fd);
}

TEST(HostileClients, PastTheConnectionCapTheLongestIdleMakesRoom) {
  HttpServerOptions options;
  options.max_connections = 8;
  Server server(options);
  std::vector<int> idle;
  for (int i = 0; i < 8; ++i) {
    idle.push_back(connect_to(server.port()));
    std::this_thread::sleep_for(milliseconds(5));  // an order of age
  }
  std::this_thread::sleep_for(milliseconds(50));
  EXPECT_EQ(exchange(server.port(), kHealth).status, 200);
  EXPECT_TRUE(closed_by_server(idle[0], milliseconds(2000))) << "the oldest idle connection made room";
  EXPECT_FALSE(closed_by_server(idle[7], milliseconds(100))) << "the newest stays";
  for (int fd : idle) close(fd);

  // Every slot busy sending a request: the one receiving longest goes.
  std::vector<std::unique_ptr<Trickler>> slow;
  for (int i = 0; i < 8; ++i) {
    slow.push_back(std::make_unique<Trickler>(server.port(), milliseconds(20)));
    std::this_thread::sleep_for(milliseconds(30));
  }
  EXPECT_EQ(exchange(server.port(), kHealth).status, 200);
  EXPECT_TRUE(closed_by_server(slow[0]->fd(), milliseconds(2000)));
  const json health = json::parse(exchange(server.port(), kHealth).body);
  EXPECT_GE(health["connections_evicted"].get<int>(), 2);
}

// A client with a receive buffer of about `receive_buffer` bytes (set
// before connecting, so that the window it offers stays that small).
int connect_small_window(int port, int receive_buffer = 1024) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof receive_buffer);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(std::uint16_t(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    close(fd);
    return -1;
  }
  return fd;
}

std::string repeated(const std::string& request, int times) {
  std::string all;
  for (int i = 0; i < times; ++i) all += request;
  return all;
}

// 60 pipelined GET /api/openapi.json (100 KB each).
const std::string kOpenApiFlood = repeated("GET /api/openapi.json HTTP/1.1\r\nHost: localhost\r\n\r\n", 60);

// `count` more clients with a small receive window that each send
// kOpenApiFlood and never read, appended to `fds`; true once every one
// has been answered (its first bytes arrived, unread).
bool open_non_readers(int port, std::size_t count, std::vector<int>& fds) {
  for (std::size_t i = 0; i < count; ++i) {
    const int fd = connect_small_window(port);
    if (fd < 0) return false;
    fds.push_back(fd);
    if (!send_all(fd, kOpenApiFlood)) return false;
  }
  for (std::size_t i = fds.size() - count; i < fds.size(); ++i)
    if (!readable(fds[i], milliseconds(20000))) return false;
  return true;
}

// Issue 29's finding 4: 256 connections (the cap) with a 1 KB receive
// buffer, each pipelining 60 GET /api/openapi.json (100 KB each) and
// reading nothing, held every slot in the sending phase, which was never
// evicted: health probes got 503 "too many connections" until the write
// timeout (10 s). The same with a cap of 64, to spare the machine.
TEST(HostileClients, ClientsThatDoNotReadTheirAnswersDoNotLockOutHealth) {
  HttpServerOptions options;  // else the defaults: 10 s to send an answer
  options.max_connections = 64;
  Server server(options);
  std::vector<int> readers_of_nothing;
  ASSERT_TRUE(open_non_readers(server.port(), options.max_connections, readers_of_nothing));
  // A moment for the server to fill what the kernel takes of its answers.
  std::this_thread::sleep_for(milliseconds(500));
  for (int probe = 0; probe < 20; ++probe) {
    const Answer a = exchange(server.port(), kHealth, milliseconds(5000));
    ASSERT_EQ(a.status, 200) << "probe " << probe << ": " << a.body;
  }
  const json health = json::parse(exchange(server.port(), kHealth).body);
  EXPECT_GE(health["connections_evicted"].get<int>(), 1) << "a probe took a stalled sender's place";
  EXPECT_EQ(health["connections_refused"], 0);
  for (int fd : readers_of_nothing) close(fd);
}

// The review of issue 29: non-readers that reconnect as soon as they are
// closed made room at the cap by evicting the one idle connection there,
// a health probe accepted a moment before, before its request was read
// (2 of 37 probes got a reset). The connection longest without progress
// goes instead: not the newest.
TEST(HostileClients, AReconnectingNonReaderDoesNotEvictAProbeJustAccepted) {
  HttpServerOptions options;
  options.max_connections = 8;
  Server server(options);
  std::vector<int> readers_of_nothing;
  ASSERT_TRUE(open_non_readers(server.port(), options.max_connections, readers_of_nothing));
  std::this_thread::sleep_for(milliseconds(200));
  const int probe = connect_to(server.port());  // takes a stalled sender's place
  ASSERT_GE(probe, 0);
  std::this_thread::sleep_for(milliseconds(200));
  ASSERT_TRUE(open_non_readers(server.port(), 1, readers_of_nothing));  // at the cap again
  std::this_thread::sleep_for(milliseconds(200));
  ASSERT_TRUE(send_all(probe, kHealth));
  const Answer a = AnswerReader(probe).next(milliseconds(5000));
  EXPECT_EQ(a.status, 200) << "the probe was evicted before its request was read";
  close(probe);
  for (int fd : readers_of_nothing) close(fd);
}

TEST(HostileClients, AClientThatReadsNoneOfItsAnswerIsClosedAfterTheStallTimeout) {
  HttpServerOptions options;
  options.write_timeout = milliseconds(600000);  // so that only the stall can close it
  options.send_stall_timeout = milliseconds(500);
  Server server(options);
  const int fd = connect_small_window(server.port());
  ASSERT_TRUE(send_all(fd, repeated("GET /api/openapi.json HTTP/1.1\r\nHost: localhost\r\n\r\n", 10)));
  const auto start = Clock::now();
  int stalled = 0;
  while (stalled == 0 && seconds_since(start) < 30) {
    std::this_thread::sleep_for(milliseconds(100));
    stalled = json::parse(exchange(server.port(), kHealth).body)["connections_stalled"].get<int>();
  }
  EXPECT_EQ(stalled, 1);
  // Closed with a reset: its unread answers are dropped, not left in the
  // kernel for a client that will never read them.
  char byte;
  ssize_t n;
  while ((n = recv(fd, &byte, 1, 0)) > 0) {
  }
  EXPECT_EQ(n, -1);
  EXPECT_EQ(errno, ECONNRESET);
  close(fd);
}

// Past max_unsent_bytes of unread answers, a client's pipelined requests
// wait: one that pipelines thousands and reads none holds about that much,
// not (as before) as much as the kernel's send buffer grows to (~4 MB).
TEST(HostileClients, PipelinedRequestsWaitWhileTheirAnswersAreUnread) {
  HttpServerOptions options;
  options.max_unsent_bytes = 64 << 10;
  Server server(options);
  const std::string scenes = "GET /api/scenes HTTP/1.1\r\nHost: localhost\r\n\r\n";
  const std::size_t answer_bytes = exchange(server.port(), scenes).body.size();
  ASSERT_GT(answer_bytes, 1000u);
  const int fd = connect_small_window(server.port());
  ASSERT_TRUE(send_all(fd, repeated(scenes, 2000)));
  std::this_thread::sleep_for(milliseconds(1500));
  const auto metrics = exchange(server.port(), "GET /metrics HTTP/1.1\r\nHost: localhost\r\n\r\n").body;
  const std::string counter = "umbra_http_requests_total{route=\"/api/scenes\",status=\"200\"} ";
  const std::size_t at = metrics.find(counter);
  ASSERT_NE(at, std::string::npos) << metrics;
  const std::size_t answered = std::stoull(metrics.substr(at + counter.size())) - 1;  // less the size probe
  // The bound, one answer past it, and what the client's own small buffer took.
  EXPECT_LE(answered * answer_bytes, options.max_unsent_bytes + 2 * answer_bytes + (16u << 10)) << answered;
  EXPECT_GT(answered, 2u) << "pipelining itself goes on";
  close(fd);
}

// Issue 29's finding 8: with Host: evil.example (DNS rebinding: a page of
// evil.example whose name now points at 127.0.0.1) every route answered,
// and a missing or repeated Host on HTTP/1.1 got 200.
TEST(HostileClients, AForeignHostIs421AndAMissingOrRepeatedOneIs400) {
  Server server;
  const auto get = [&](const std::string& host_lines, const std::string& version = "HTTP/1.1") {
    return exchange(server.port(), "GET /api/scenes " + version + "\r\n" + host_lines + "Connection: close\r\n\r\n");
  };
  const Answer foreign = get("Host: evil.example\r\n");
  EXPECT_EQ(foreign.status, 421) << foreign.head << foreign.body;
  EXPECT_NE(foreign.head.find("Misdirected Request"), std::string::npos);
  EXPECT_NE(json::parse(foreign.body)["error"].get<std::string>().find("'evil.example'"), std::string::npos)
      << foreign.body;
  EXPECT_EQ(get("Host: evil.example:" + std::to_string(server.port()) + "\r\n").status, 421);
  const Answer missing = get("");
  EXPECT_EQ(missing.status, 400) << missing.body;
  EXPECT_NE(missing.body.find("no Host header field"), std::string::npos) << missing.body;
  EXPECT_EQ(get("Host: localhost\r\nHost: localhost\r\n").status, 400);
  EXPECT_EQ(get("Host: local host\r\n").status, 400);
  // A POST is refused before its body: nothing is read for a foreign Host.
  const Answer upload = exchange(server.port(), "POST /api/models HTTP/1.1\r\nHost: evil.example\r\n"
                                                "Content-Type: model/gltf-binary\r\nContent-Length: 50000000\r\n\r\n");
  EXPECT_EQ(upload.status, 421);
  // Loopback names and the bound address, at any port; HTTP/1.0 need not name one.
  for (const std::string& host :
       std::vector<std::string>{"localhost", "127.0.0.1:" + std::to_string(server.port()), "[::1]:1", "LOCALHOST"})
    EXPECT_EQ(get("Host: " + host + "\r\n").status, 200) << host;
  EXPECT_EQ(get("", "HTTP/1.0").status, 200);
  // Health too: it is no exception to the Host check.
  EXPECT_EQ(exchange(server.port(), "GET /api/health HTTP/1.1\r\nHost: evil.example\r\n\r\n").status, 421);
}

TEST(HostileClients, AllowedHostsAddNamesOrAny) {
  ServerOptions options = Server::options({});
  options.allowed_hosts = {"render.example"};
  Server listed(options);
  EXPECT_EQ(exchange(listed.port(), "GET /api/scenes HTTP/1.1\r\nHost: render.example:8080\r\n\r\n").status, 200);
  EXPECT_EQ(exchange(listed.port(), "GET /api/scenes HTTP/1.1\r\nHost: localhost\r\n\r\n").status, 200);
  EXPECT_EQ(exchange(listed.port(), "GET /api/scenes HTTP/1.1\r\nHost: evil.example\r\n\r\n").status, 421);
  options.allowed_hosts = {"*"};
  Server any(options);
  EXPECT_EQ(exchange(any.port(), "GET /api/scenes HTTP/1.1\r\nHost: evil.example\r\n\r\n").status, 200);
  EXPECT_EQ(exchange(any.port(), "GET /api/scenes HTTP/1.1\r\n\r\n").status, 400) << "still one Host on HTTP/1.1";
}

constexpr const char* kTokens =
    "renderer-token-000000001 render\n"
    "uploader-token-000000002 render,upload\n"
    "monitor-token-0000000003 metrics\n";

ServerOptions with_tokens(const std::string& cors = "") {
  ServerOptions options = Server::options({});
  std::string error;
  options.tokens = std::make_shared<const TokenTable>(*TokenTable::parse(kTokens, error));
  options.cors_origin = cors;
  return options;
}

Answer ask(int port, const std::string& method, const std::string& path, const std::string& token,
           const std::string& body = "", const std::string& type = "application/json") {
  std::string request = method + " " + path + " HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n";
  if (!token.empty()) request += "Authorization: Bearer " + token + "\r\n";
  if (!body.empty()) request += "Content-Type: " + type + "\r\nContent-Length: " + std::to_string(body.size()) + "\r\n";
  return umbra::exchange(port, request + "\r\n" + body);  // not std::exchange, found by argument

}

// Issue 29's finding 8: without tokens, anyone who could connect could
// upload, list models and read /metrics.
TEST(HostileClients, WithTokensEachRouteNeedsATokenWithItsScope) {
  Server server(with_tokens());
  const int port = server.port();
  const std::string render = "renderer-token-000000001", upload = "uploader-token-000000002",
                    monitor = "monitor-token-0000000003";
  const std::string frame = R"({"width": 16, "height": 16})";
  struct Case {
    std::string method, path, body;
    int status = 200;  // with the scope
  };
  const std::vector<Case> render_routes = {{"GET", "/api/scenes", ""},
                                           {"GET", "/api/openapi.json", ""},
                                           {"POST", "/api/render", frame},
                                           {"POST", "/api/depth", frame},
                                           {"GET", "/api/models", ""},
                                           {"GET", "/api/models/teapot", "", 404}};  // this server holds none
  for (const Case& c : render_routes) {
    const Answer none = ask(port, c.method, c.path, "", c.body);
    EXPECT_EQ(none.status, 401) << c.path << ": " << none.body;
    EXPECT_NE(none.head.find("WWW-Authenticate: Bearer realm=\"umbra\"\r\n"), std::string::npos) << none.head;
    const Answer unknown = ask(port, c.method, c.path, "renderer-token-000000009", c.body);
    EXPECT_EQ(unknown.status, 401) << c.path;
    EXPECT_NE(unknown.head.find("error=\"invalid_token\""), std::string::npos) << unknown.head;
    const Answer wrong = ask(port, c.method, c.path, monitor, c.body);
    EXPECT_EQ(wrong.status, 403) << c.path << ": " << wrong.body;
    EXPECT_NE(wrong.head.find("error=\"insufficient_scope\", scope=\"render\""), std::string::npos) << wrong.head;
    EXPECT_EQ(ask(port, c.method, c.path, render, c.body).status, c.status) << c.path;
    EXPECT_EQ(ask(port, c.method, c.path, upload, c.body).status, c.status) << c.path;
  }
  // An upload needs the upload scope (then the body is judged: not a glTF).
  const Answer refused = ask(port, "POST", "/api/models", render, "not a model", "model/gltf-binary");
  EXPECT_EQ(refused.status, 403) << refused.body;
  EXPECT_NE(refused.body.find("POST /api/models needs the upload scope; this token has render"), std::string::npos)
      << refused.body;
  EXPECT_EQ(ask(port, "POST", "/api/models", upload, "not a model", "model/gltf-binary").status, 400);
  EXPECT_EQ(ask(port, "GET", "/metrics", render, "").status, 403);
  EXPECT_EQ(ask(port, "GET", "/metrics", monitor, "").status, 200);
  EXPECT_EQ(ask(port, "GET", "/metrics", "", "").status, 401);
  // No token for health and the panel's own files; elsewhere any known one.
  EXPECT_EQ(ask(port, "GET", "/api/health", "", "").status, 200);
  EXPECT_EQ(ask(port, "GET", "/", "", "").status, 200);
  EXPECT_EQ(ask(port, "GET", "/app.js", "", "").status, 200);
  EXPECT_EQ(ask(port, "GET", "/api/nowhere", "", "").status, 401);
  EXPECT_EQ(ask(port, "GET", "/api/nowhere", monitor, "").status, 404);
  EXPECT_EQ(ask(port, "DELETE", "/api/render", monitor, "").status, 405);
}

TEST(HostileClients, AnUploadWithoutATokenIsRefusedBeforeItsBody) {
  Server server(with_tokens());
  const int fd = connect_to(server.port());
  ASSERT_TRUE(send_all(fd, "POST /api/models HTTP/1.1\r\nHost: localhost\r\nContent-Type: model/gltf-binary\r\n"
                           "Content-Length: 60000000\r\n\r\n"));
  const Answer a = AnswerReader(fd).next(milliseconds(5000));
  EXPECT_EQ(a.status, 401) << a.head << a.body;
  EXPECT_NE(a.head.find("Connection: close"), std::string::npos) << a.head;
  close(fd);
  // Expect: 100-continue is refused, never continued.
  const Answer asked = exchange(server.port(), "POST /api/models HTTP/1.1\r\nHost: localhost\r\n"
                                               "Authorization: Bearer renderer-token-000000001\r\n"
                                               "Expect: 100-continue\r\nContent-Length: 60000000\r\n\r\n");
  EXPECT_EQ(asked.status, 403);
}

TEST(HostileClients, APreflightNeedsNoTokenAndAllowsTheAuthorizationHeader) {
  Server server(with_tokens("https://app.example"));
  const Answer a = exchange(server.port(), "OPTIONS /api/render HTTP/1.1\r\nHost: localhost\r\n"
                                           "Origin: https://app.example\r\nAccess-Control-Request-Method: POST\r\n"
                                           "Access-Control-Request-Headers: authorization, content-type\r\n\r\n");
  EXPECT_EQ(a.status, 204) << a.head;
  EXPECT_NE(a.head.find("Access-Control-Allow-Headers: Content-Type, Authorization"), std::string::npos) << a.head;
  const Answer refused = ask(server.port(), "GET", "/api/scenes", "");
  EXPECT_NE(refused.head.find("Access-Control-Allow-Origin: https://app.example"), std::string::npos) << refused.head;
  EXPECT_NE(refused.head.find("WWW-Authenticate"), std::string::npos);
}

TEST(HostileClients, TheUploaderIsTheTokensPrincipalOnlyWithTokens) {
  HttpRequest request;
  request.principal = token_principal("uploader-token-000000002");
  Server with(with_tokens());
  EXPECT_EQ(with.api.uploader_of(request), request.principal);
  EXPECT_EQ(request.principal.size(), 6u + 12u);
  Server without;
  EXPECT_EQ(without.api.uploader_of(request), "");
}

TEST(HostileClients, PipelinedRequestsAreAnsweredInOrder) {
  Server server;
  const int fd = connect_to(server.port());
  const std::string body = R"({"width": 16, "height": 16})";
  ASSERT_TRUE(send_all(fd, "GET /api/health HTTP/1.1\r\nHost: localhost\r\n\r\n"
                           "POST /api/render HTTP/1.1\r\nHost: localhost\r\nContent-Length: " +
                               std::to_string(body.size()) + "\r\n\r\n" + body +
                               "GET /api/scenes HTTP/1.1\r\nHost: localhost\r\n\r\n"
                               "GET /nowhere HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n"));
  AnswerReader reader(fd);
  const Answer health = reader.next(), frame = reader.next(), scenes = reader.next(), missing = reader.next();
  EXPECT_EQ(health.status, 200);
  EXPECT_TRUE(json::parse(health.body, nullptr, false).contains("uptime_s"));
  EXPECT_EQ(frame.status, 200);
  EXPECT_NE(frame.head.find("image/png"), std::string::npos);
  EXPECT_EQ(scenes.status, 200);
  EXPECT_TRUE(json::parse(scenes.body, nullptr, false).contains("scenes"));
  EXPECT_EQ(missing.status, 404);
  EXPECT_TRUE(closed_by_server(fd, milliseconds(3000)));
  close(fd);
}

TEST(HostileClients, ExpectContinueIsAnsweredAndABodyPastTheLimitIsNeverAskedFor) {
  Server server;
  const std::string body = R"({"width": 16, "height": 16})";
  const int fd = connect_to(server.port());
  ASSERT_TRUE(send_all(fd, "POST /api/render HTTP/1.1\r\nHost: localhost\r\nExpect: 100-continue\r\nContent-Length: " +
                               std::to_string(body.size()) + "\r\n\r\n"));
  AnswerReader reader(fd);
  EXPECT_EQ(reader.next().status, 100);
  ASSERT_TRUE(send_all(fd, body));
  EXPECT_EQ(reader.next().status, 200);
  close(fd);
  const Answer big = exchange(server.port(), "POST /api/render HTTP/1.1\r\nHost: localhost\r\nExpect: 100-continue\r\n"
                                             "Content-Length: 2000000\r\n\r\n");
  EXPECT_EQ(big.status, 413);
}

TEST(HostileClients, AStopClosesIdleAndTricklingClientsAtOnceAndAnswersTheRequestInFlight) {
  auto server = std::make_unique<Server>();
  const int port = server->port();
  std::vector<std::unique_ptr<Trickler>> slow;
  for (int i = 0; i < 3; ++i) slow.push_back(std::make_unique<Trickler>(port, milliseconds(200)));
  std::vector<int> idle;
  for (int i = 0; i < 3; ++i) idle.push_back(connect_to(port));
  const std::string body = R"({"width": 256, "height": 256, "output": "exact"})";
  const int busy = connect_to(port);
  ASSERT_TRUE(send_all(busy, "POST /api/render HTTP/1.1\r\nHost: localhost\r\nContent-Length: " + std::to_string(body.size()) +
                                 "\r\n\r\n" + body));
  while (RendererEnvironment::renderer->queue_depth() == 0) std::this_thread::sleep_for(milliseconds(1));
  const auto start = Clock::now();
  server->api.stop();
  server->thread.join();
  const double took = seconds_since(start);
  EXPECT_LT(took, 2.0) << "the README promises 2 s";
  const Answer answered = AnswerReader(busy).next(milliseconds(1000));
  EXPECT_EQ(answered.status, 200);
  EXPECT_NE(answered.head.find("Connection: close"), std::string::npos);
  for (int fd : idle) EXPECT_TRUE(closed_by_server(fd, milliseconds(100)));
  for (auto& s : slow) EXPECT_TRUE(closed_by_server(s->fd(), milliseconds(100)));
  server->thread = std::thread([] {});  // joined by ~Server
  for (int fd : idle) close(fd);
  close(busy);
}

TEST(HostileClients, AClientVanishingMidBodyLeavesNothingBehind) {
  Server server;
  for (int i = 0; i < 20; ++i) {
    const int fd = connect_to(server.port());
    send_all(fd, "POST /api/render HTTP/1.1\r\nHost: localhost\r\nContent-Length: 1000\r\n\r\n{\"width\":");
    close(fd);
  }
  std::this_thread::sleep_for(milliseconds(200));
  const json health = json::parse(exchange(server.port(), kHealth).body);
  EXPECT_LE(health["connections_open"].get<int>(), 1) << "only the probe's own";
}

}  // namespace
}  // namespace umbra

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  testing::AddGlobalTestEnvironment(new umbra::RendererEnvironment);
  return RUN_ALL_TESTS();
}
