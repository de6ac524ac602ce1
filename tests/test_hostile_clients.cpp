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

#include "http_api.hpp"
#include "render_service.hpp"

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
  explicit Server(HttpServerOptions connections = {}) : api(*RendererEnvironment::renderer, options(connections)) {
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

// Issue 29's finding 4: 256 connections (the cap) with a 1 KB receive
// buffer, each pipelining 60 GET /api/openapi.json (100 KB each) and
// reading nothing, held every slot in the sending phase, which was never
// evicted: health probes got 503 "too many connections" until the write
// timeout (10 s). The same with a cap of 64, to spare the machine.
TEST(HostileClients, ClientsThatDoNotReadTheirAnswersDoNotLockOutHealth) {
  HttpServerOptions options;  // else the defaults: 10 s to send an answer
  options.max_connections = 64;
  Server server(options);
  const std::string flood = repeated("GET /api/openapi.json HTTP/1.1\r\nHost: localhost\r\n\r\n", 60);
  std::vector<int> readers_of_nothing;
  for (std::size_t i = 0; i < options.max_connections; ++i) {
    const int fd = connect_small_window(server.port());
    ASSERT_GE(fd, 0);
    ASSERT_TRUE(send_all(fd, flood));
    readers_of_nothing.push_back(fd);
  }
  // Every one answered (its first bytes arrived, unread), then a moment
  // for the server to fill what the kernel takes of its answers.
  for (int fd : readers_of_nothing) ASSERT_TRUE(readable(fd, milliseconds(20000)));
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
