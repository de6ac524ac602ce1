// Umbra behind the real HAProxy, configured by deploy/haproxy.cfg as
// scripts/cluster.sh runs it: three servers sharing a --model-store folder,
// sixteen clients for a while, one server killed (SIGKILL) and started
// again, another drained (SIGTERM) and started again. Every client must get
// a whole PNG, or a 503 with Retry-After only when every server is full:
// no connection error, no 502 or 504, nothing cut short.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <glm/vec3.hpp>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include "gltf_builder.hpp"
#include "server_process.hpp"

namespace umbra {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
using umbra::testing::ServerProcess;

// A port no one listens on now (the kernel's pick, released at once).
int free_port() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address);
  socklen_t length = sizeof address;
  getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length);
  close(fd);
  return ntohs(address.sin_port);
}

// HAProxy in the foreground, its output in a file; stopped when destroyed.
struct Balancer {
  pid_t pid = -1;
  Balancer(const fs::path& config, int port, const fs::path& log) {
    pid = fork();
    if (pid == 0) {
      const int out = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      dup2(out, 1);
      dup2(out, 2);
      setenv("UMBRA_BIND", ("127.0.0.1:" + std::to_string(port)).c_str(), 1);
      setenv("UMBRA_DIR", UMBRA_DEPLOY_DIR, 1);
      execl(UMBRA_HAPROXY, UMBRA_HAPROXY, "-f", config.c_str(), "-db", static_cast<char*>(nullptr));
      _exit(127);
    }
  }
  ~Balancer() {
    if (pid > 0) {
      kill(pid, SIGTERM);
      waitpid(pid, nullptr, 0);
    }
  }
};

// A whole PNG: the signature first, the IEND chunk last.
bool whole_png(const std::string& bytes) {
  static const std::string signature = "\x89PNG\r\n\x1a\n";
  static const std::string iend("\0\0\0\0IEND\xae\x42\x60\x82", 12);
  return bytes.size() > signature.size() + iend.size() && bytes.compare(0, signature.size(), signature) == 0 &&
         bytes.compare(bytes.size() - iend.size(), iend.size(), iend) == 0;
}

std::string cube_glb() {
  test::GltfBuilder b;
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices;
  test::unit_cube(positions, indices, 0.5f);
  b.scene({b.node({{"mesh", b.mesh(b.vec3s(positions), b.indices_u32(indices))}})});
  return b.glb();
}

TEST(Cluster, SixteenClientsLoseNothingWhileServersAreKilledAndDrained) {
  ASSERT_STRNE(UMBRA_HAPROXY, "") << "haproxy not found: bash scripts/install-deps.sh --cluster";
  const fs::path root = fs::temp_directory_path() / ("umbra-cluster-" + std::to_string(getpid()));
  fs::remove_all(root);
  fs::create_directories(root / "models");
  const int balancer_port = free_port();
  std::vector<int> ports;
  for (int i = 0; i < 3; ++i) ports.push_back(free_port());
  // deploy/haproxy.cfg as it is, and one server line per server.
  {
    std::ifstream in(std::string(UMBRA_DEPLOY_DIR) + "/haproxy.cfg");
    std::ofstream out(root / "haproxy.cfg");
    out << in.rdbuf();
    for (int i = 0; i < 3; ++i) out << "    server render" << i << " 127.0.0.1:" << ports[i] << "\n";
  }
  const auto start_server = [&](int i) {
    return std::make_unique<ServerProcess>(
        UMBRA_SERVER_BINARY, std::vector<std::string>{"--port", std::to_string(ports[i]), "--model-store",
                                                      (root / "models").string(), "--quiet"});
  };
  std::vector<std::unique_ptr<ServerProcess>> servers;
  for (int i = 0; i < 3; ++i) servers.push_back(start_server(i));
  Balancer balancer(root / "haproxy.cfg", balancer_port, root / "haproxy.log");
  // Until HAProxy listens and has seen every server up (checks every 250 ms
  // while a server is down).
  httplib::Client probe("127.0.0.1", balancer_port);
  for (int tries = 0;; ++tries) {
    auto res = probe.Get("/api/health");
    if (res && res->status == 200) break;
    ASSERT_LT(tries, 100) << "HAProxy does not answer";
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  std::this_thread::sleep_for(std::chrono::seconds(1));

  // An upload through the balancer: it lands on one server; the others
  // must find it in the shared folder.
  auto uploaded = probe.Post("/api/models", cube_glb(), "model/gltf-binary");
  ASSERT_TRUE(uploaded);
  ASSERT_EQ(uploaded->status, 201) << uploaded->body;
  const std::string model = json::parse(uploaded->body)["id"];

  const std::vector<std::pair<const char*, std::string>> bodies = {
      {"/api/render", R"({"width": 160, "height": 90})"},
      {"/api/depth", R"({"shadow": {"map_size": 256}})"},
      {"/api/render", R"({"width": 160, "height": 90, "output": "shadow", "time": 2})"},
      {"/api/render", json{{"width", 160}, {"height", 90},
                           {"scene", {{"objects", {{{"type", "plane"}, {"size", {8, 8}}},
                                                   {{"type", "mesh"}, {"model", model}, {"position", {0, 0.5, 0}}}}}}}}
                          .dump()}};
#ifdef UMBRA_SANITIZED
  const auto run_for = std::chrono::seconds(15);  // servers 3-4x slower: fewer requests, same events
#else
  const auto run_for = std::chrono::seconds(30);
#endif
  const auto started = Clock::now();
  std::atomic<bool> running{true};
  std::mutex mutex;
  std::map<std::string, int> outcomes;  // "200", "503", or what went wrong
  std::vector<std::string> failures;
  std::vector<double> latencies_ms;
  std::vector<std::thread> clients;
  for (int c = 0; c < 16; ++c) {
    clients.emplace_back([&, c] {
      httplib::Client client("127.0.0.1", balancer_port);
      client.set_read_timeout(60, 0);
      for (int k = c; running; ++k) {
        const auto& [path, body] = bodies[std::size_t(k) % bodies.size()];
        const auto sent = Clock::now();
        auto res = client.Post(path, body, "application/json");
        const double ms = std::chrono::duration<double, std::milli>(Clock::now() - sent).count();
        std::string outcome;
        if (!res)
          outcome = "connection error: " + httplib::to_string(res.error());
        else if (res->status == 200)
          outcome = whole_png(res->body) ? "200" : "200 with a PNG cut short";
        else if (res->status == 503)
          outcome = res->has_header("Retry-After") ? "503" : "503 without Retry-After";
        else
          outcome = std::to_string(res->status) + ": " + res->body.substr(0, 200);
        std::lock_guard<std::mutex> lock(mutex);
        ++outcomes[outcome];
        if (outcome != "200" && outcome != "503") failures.push_back(std::string(path) + " " + body + " -> " + outcome);
        if (outcome == "200") latencies_ms.push_back(ms);
      }
    });
  }
  // The events, at fixed moments of the run.
  const auto at = [&](double fraction) {
    std::this_thread::sleep_until(started + std::chrono::duration_cast<Clock::duration>(run_for * fraction));
  };
  at(0.25);
  servers[0]->send_signal(SIGKILL);  // mid-render, most likely
  servers[0]->wait();
  at(0.4);
  servers[0] = start_server(0);  // back, with nothing in memory
  at(0.6);
  servers[1]->send_signal(SIGTERM);  // drains: finishes what it has, then exits 0
  EXPECT_EQ(servers[1]->wait(), 0) << servers[1]->log();
  at(0.75);
  servers[1] = start_server(1);
  at(1.0);
  running = false;
  for (auto& t : clients) t.join();

  std::string summary;
  int answered = 0;
  for (const auto& [outcome, n] : outcomes) summary += outcome + ": " + std::to_string(n) + "\n", answered += n;
  std::sort(latencies_ms.begin(), latencies_ms.end());
  const double seconds = std::chrono::duration<double>(run_for).count();
  if (!latencies_ms.empty())
    std::printf("cluster: %d requests in %.0f s (%.1f/s); 200s: p50 %.1f ms, p99 %.1f ms\n%s", answered, seconds,
                answered / seconds, latencies_ms[latencies_ms.size() / 2], latencies_ms[latencies_ms.size() * 99 / 100],
                summary.c_str());
  EXPECT_TRUE(failures.empty()) << failures.size() << " requests failed, e.g. " << failures.front() << "\n" << summary;
  EXPECT_GE(outcomes["200"], 100) << summary;
  // Server 0 started again with nothing in memory and no upload sent to
  // it: it can only hold the model by having loaded it from the folder to
  // render it for someone.
  httplib::Client restarted("127.0.0.1", ports[0]);
  auto held = restarted.Get("/api/models");
  ASSERT_TRUE(held);
  const json listed = json::parse(held->body);
  bool found = false;
  for (const json& m : listed["models"]) found |= m["id"] == model;
  EXPECT_TRUE(found) << "the restarted server never rendered the uploaded model:\n"
                     << held->body << "\n" << restarted.Get("/metrics")->body.substr(0, 3000);
  fs::remove_all(root);
}

}  // namespace
}  // namespace umbra
