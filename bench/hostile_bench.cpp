// umbra-hostile-bench: does /api/health still answer, and how fast, while
// clients attack the server the ways issue 11 found (slow headers, idle
// sockets, more connections than allowed, huge chunked bodies, real load)?
//
// Starts build/server/umbra-server on a free loopback port with its
// defaults. For each attack: starts it, lets it settle for a second, then
// probes GET /api/health on a fresh connection every 50 ms for --seconds
// (a probe that takes over 5 s counts as failed), while sampling the
// server's resident memory. Then measures a graceful stop (SIGTERM) with
// three trickling and three idle clients (killed if not exited within
// 30 s). Writes bench/results/hostile.md.
//
//   umbra-hostile-bench [--seconds 5] [--out FILE] [--server PATH]
//
// --server runs another umbra-server binary (an older build, to compare).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include "server_process.hpp"

namespace {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

int connect_to(int port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(std::uint16_t(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  timeval five{5, 0};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &five, sizeof five);
  setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &five, sizeof five);
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

// True if the server closed `fd` (end of stream or error), without waiting.
bool closed(int fd) {
  pollfd p{fd, POLLIN, 0};
  if (poll(&p, 1, 0) <= 0) return false;
  char buffer[4096];
  return recv(fd, buffer, sizeof buffer, MSG_DONTWAIT) <= 0;
}

// One health probe on a fresh connection: its time in ms, or -1.
double probe(int port) {
  const auto start = Clock::now();
  const int fd = connect_to(port);
  if (fd < 0) return -1;
  std::string answer;
  if (send_all(fd, "GET /api/health HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n")) {
    char buffer[4096];
    for (ssize_t n; (n = recv(fd, buffer, sizeof buffer, 0)) > 0;) answer.append(buffer, std::size_t(n));
  }
  close(fd);
  const double ms = ms_since(start);
  return answer.rfind("HTTP/1.1 200", 0) == 0 && ms < 5000 ? ms : -1;
}

// Threads that attack until stopped.
class Attack {
 public:
  virtual ~Attack() { stop(); }
  void stop() {
    quit_ = true;
    for (std::thread& t : threads_) t.join();
    threads_.clear();
  }

 protected:
  std::atomic<bool> quit_{false};
  std::vector<std::thread> threads_;
};

// `count` connections that send a header byte every `gap`, reopened when closed.
class SlowHeaders : public Attack {
 public:
  SlowHeaders(int port, int count, milliseconds gap) {
    for (int i = 0; i < count; ++i)
      threads_.emplace_back([this, port, gap] {
        while (!quit_) {
          const int fd = connect_to(port);
          const std::string head = "GET /api/health HTTP/1.1\r\nHost: localhost\r\nX-Slow: " + std::string(1 << 20, 'a');
          for (std::size_t k = 0; k < head.size() && !quit_ && fd >= 0; ++k) {
            if (!send_all(fd, head.substr(k, 1)) || closed(fd)) break;
            for (auto t = Clock::now(); !quit_ && Clock::now() - t < gap;) std::this_thread::sleep_for(milliseconds(10));
          }
          if (fd >= 0) close(fd);
        }
      });
  }
};

// `count` connections that send nothing, reopened as soon as closed.
class IdleSockets : public Attack {
 public:
  IdleSockets(int port, int count) {
    threads_.emplace_back([this, port, count] {
      std::vector<int> fds(std::size_t(count), -1);
      while (!quit_) {
        for (int& fd : fds)
          if (fd < 0 || closed(fd)) {
            if (fd >= 0) close(fd);
            fd = connect_to(port);
          }
        std::this_thread::sleep_for(milliseconds(50));
      }
      for (int fd : fds)
        if (fd >= 0) close(fd);
    });
  }
};

// `count` clients each posting a 512 MiB chunked body as fast as they can,
// starting again when refused.
class HugeChunkedBodies : public Attack {
 public:
  HugeChunkedBodies(int port, int count) {
    for (int i = 0; i < count; ++i)
      threads_.emplace_back([this, port] {
        const std::string chunk = "10000\r\n" + std::string(65536, ' ') + "\r\n";
        while (!quit_) {
          const int fd = connect_to(port);
          if (fd < 0) continue;
          send_all(fd, "POST /api/render HTTP/1.1\r\nHost: localhost\r\nTransfer-Encoding: chunked\r\n\r\n");
          for (int k = 0; k < 8192 && !quit_; ++k)
            if (!send_all(fd, chunk) || closed(fd)) break;
          close(fd);
        }
      });
  }
};

// `count` clients rendering the default frame back to back.
class Renders : public Attack {
 public:
  Renders(int port, int count) {
    for (int i = 0; i < count; ++i)
      threads_.emplace_back([this, port] {
        while (!quit_) {
          const int fd = connect_to(port);
          if (fd < 0) continue;
          send_all(fd, "POST /api/render HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\nContent-Length: 2\r\n\r\n{}");
          char buffer[65536];
          while (recv(fd, buffer, sizeof buffer, 0) > 0) {
          }
          close(fd);
        }
      });
  }
};

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, std::size_t(p * double(v.size() - 1) + 0.5))];
}

struct Row {
  std::string attack;
  int probes = 0, failed = 0;
  double p50 = 0, p99 = 0, max = 0;
  long rss_before_mib = 0, rss_peak_mib = 0, rss_after_mib = 0;
};

Row measure(const std::string& name, umbra::testing::ServerProcess& server, double seconds,
            const std::function<std::unique_ptr<Attack>()>& start_attack) {
  Row row;
  row.attack = name;
  row.rss_before_mib = server.resident_kib() / 1024;
  std::unique_ptr<Attack> attack = start_attack();
  std::this_thread::sleep_for(milliseconds(1000));
  std::vector<double> ms;
  long peak = 0;
  const auto until = Clock::now() + std::chrono::duration<double>(seconds);
  while (Clock::now() < until) {
    const double t = probe(server.port());
    ++row.probes;
    if (t < 0)
      ++row.failed;
    else
      ms.push_back(t);
    peak = std::max(peak, server.resident_kib());
    std::this_thread::sleep_for(milliseconds(50));
  }
  attack.reset();
  std::this_thread::sleep_for(milliseconds(2500));  // idle trim happens after 1 s idle
  row.rss_peak_mib = peak / 1024;
  row.rss_after_mib = server.resident_kib() / 1024;
  row.p50 = percentile(ms, 0.5);
  row.p99 = percentile(ms, 0.99);
  row.max = ms.empty() ? 0 : *std::max_element(ms.begin(), ms.end());
  std::fprintf(stderr, "%-44s probes %3d failed %3d  p50 %7.2f  p99 %7.2f  max %7.2f ms  rss %ld/%ld/%ld MiB\n",
               name.c_str(), row.probes, row.failed, row.p50, row.p99, row.max, row.rss_before_mib, row.rss_peak_mib,
               row.rss_after_mib);
  return row;
}


}  // namespace

int main(int argc, char** argv) {
  double seconds = 5;
  std::string out = std::string(UMBRA_RESULTS_DIR) + "/hostile.md";
  std::string binary = UMBRA_SERVER_BINARY;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--seconds" && i + 1 < argc)
      seconds = std::atof(argv[++i]);
    else if (arg == "--out" && i + 1 < argc)
      out = argv[++i];
    else if (arg == "--server" && i + 1 < argc)
      binary = argv[++i];
    else {
      std::fprintf(stderr, "usage: umbra-hostile-bench [--seconds 5] [--out FILE] [--server PATH]\n");
      return 2;
    }
  }
  std::vector<Row> rows;
  double stop_ms = 0;
  int stop_status = -1;
  {
    umbra::testing::ServerProcess server(binary, {"--quiet"});
    const int port = server.port();
    rows.push_back(measure("none", server, seconds, [] { return std::make_unique<Attack>(); }));
    rows.push_back(measure("12 clients sending headers at 1 byte/s", server, seconds,
                           [port] { return std::make_unique<SlowHeaders>(port, 12, milliseconds(1000)); }));
    rows.push_back(measure("150 idle connections, reopened when closed", server, seconds,
                           [port] { return std::make_unique<IdleSockets>(port, 150); }));
    rows.push_back(measure("600 idle connections (cap 256), reopened", server, seconds,
                           [port] { return std::make_unique<IdleSockets>(port, 600); }));
    rows.push_back(measure("4 clients posting 512 MiB chunked bodies", server, seconds,
                           [port] { return std::make_unique<HugeChunkedBodies>(port, 4); }));
    rows.push_back(measure("2 clients rendering 960x540 back to back", server, seconds,
                           [port] { return std::make_unique<Renders>(port, 2); }));
  }
  {
    umbra::testing::ServerProcess server(binary, {"--quiet"});
    SlowHeaders trickling(server.port(), 3, milliseconds(1000));
    IdleSockets idle(server.port(), 3);
    std::this_thread::sleep_for(milliseconds(1500));
    const auto start = Clock::now();
    server.send_signal(SIGTERM);
    // A server that does not stop within 30 s is killed and reported so.
    std::atomic<bool> exited{false};
    std::thread killer([&] {
      while (!exited && ms_since(start) < 30000) std::this_thread::sleep_for(milliseconds(10));
      if (!exited) server.send_signal(SIGKILL);
    });
    stop_status = server.wait();
    stop_ms = ms_since(start);
    exited = true;
    killer.join();
    std::fprintf(stderr, "SIGTERM with 3 trickling + 3 idle clients: exit %d after %.0f ms\n", stop_status, stop_ms);
  }

  std::ostringstream md;
  md << "# Health under hostile clients\n\n"
     << "`umbra-hostile-bench --seconds " << seconds << "` on " << umbra::testing::machine_summary()
     << ", `" << binary.substr(binary.rfind('/') + 1) << "` at its defaults.\n"
     << "Each attack runs while `GET /api/health` is probed on a fresh connection every 50 ms "
     << "(failed: no 200 within 5 s). RSS: the server's resident memory before the attack, its peak during it, "
     << "and 2.5 s after it stopped.\n\n"
     << "| attack | probes | failed | p50 ms | p99 ms | max ms | RSS before / peak / after MiB |\n"
     << "|---|---:|---:|---:|---:|---:|---|\n";
  char line[512];
  for (const Row& r : rows) {
    std::snprintf(line, sizeof line, "| %s | %d | %d | %.2f | %.2f | %.2f | %ld / %ld / %ld |\n", r.attack.c_str(),
                  r.probes, r.failed, r.p50, r.p99, r.max, r.rss_before_mib, r.rss_peak_mib, r.rss_after_mib);
    md << line;
  }
  if (stop_status == 128 + SIGKILL)
    std::snprintf(line, sizeof line,
                  "\nGraceful stop: SIGTERM with 3 clients trickling headers and 3 idle connections: had not exited "
                  "after 30 s; killed.\n");
  else
    std::snprintf(line, sizeof line,
                  "\nGraceful stop: SIGTERM with 3 clients trickling headers and 3 idle connections: exit status %d "
                  "after %.0f ms.\n",
                  stop_status, stop_ms);
  md << line;
  std::ofstream(out) << md.str();
  std::fprintf(stderr, "wrote %s\n", out.c_str());
  return 0;
}
