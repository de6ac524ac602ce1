// scripts/cluster.sh as users run it: three umbra-servers behind the real
// HAProxy (deploy/haproxy.cfg), sharing a --model-store folder, sixteen
// clients for a while; one server killed (SIGKILL) and another drained
// (SIGTERM), each signal sent to that server alone. The script must start
// each again while the others keep serving, and every client must get a
// whole PNG, or a 503 with Retry-After only when every server is full: no
// connection error, no 502 or 504, nothing cut short. Then SIGTERM to the
// script alone stops everything.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <random>
#include <sstream>
#include <string>
#include <set>
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

namespace umbra {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

// True if a server could bind 127.0.0.1:port now (with SO_REUSEADDR, as
// umbra-server and HAProxy do).
bool bindable(int port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  const int yes = 1;
  setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  address.sin_port = htons(std::uint16_t(port));
  const bool bound = bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0;
  close(fd);
  return bound;
}

// The lowest port the kernel gives outgoing connections as their source
// (net.ipv4.ip_local_port_range).
int ephemeral_ports_start() {
  std::ifstream range("/proc/sys/net/ipv4/ip_local_port_range");
  int low = 32768;
  range >> low;
  return low;
}

// True if something accepts connections on 127.0.0.1:port.
bool listening(int port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  address.sin_port = htons(std::uint16_t(port));
  const bool connected = connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0;
  close(fd);
  return connected;
}

// A port with `after` free ports right above it (the script's servers go
// on port + 1 .. port + after), or 0. Below the kernel's ephemeral range: a
// port there is never handed to an outgoing connection, so one found free
// stays free until the script binds it. (A port the kernel picked for us
// could be taken as a source port by any client in between: render1 then
// failed to listen, under the sanitizers.)
int free_port_with(int after) {
  const int below = ephemeral_ports_start();
  std::mt19937 random(std::random_device{}());
  std::uniform_int_distribution<int> pick(std::max(1024, below - 10000), below - after - 1);
  for (int tries = 0; tries < 200; ++tries) {
    const int p = pick(random);
    bool free = true;
    for (int i = 0; i <= after && free; ++i) free = bindable(p + i) && !listening(p + i);
    if (free) return p;
  }
  return 0;
}

// The umbra-server process started with `--port port`, found in /proc as
// an operator finds it (pgrep -f), whatever the script records; -1 if none.
pid_t server_on_port(int port) {
  const std::string wanted = "--port" + std::string(1, '\0') + std::to_string(port) + std::string(1, '\0');
  for (const auto& entry : fs::directory_iterator("/proc")) {
    const std::string name = entry.path().filename();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream in(entry.path() / "cmdline", std::ios::binary);
    const std::string cmdline((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (cmdline.find("umbra-server") != std::string::npos && cmdline.find(wanted) != std::string::npos)
      return pid_t(std::stol(name));
  }
  return -1;
}

// `bash scripts/cluster.sh N PORT --quiet` in its own process group, its
// output in a file; stopped (SIGTERM to the script, then SIGKILL to the
// whole group if it has not ended in a minute) when destroyed.
struct ClusterScript {
  pid_t pid = -1;
  fs::path dir, log;
  int exit_code = -1;
  ClusterScript(int servers, int port, const fs::path& state, const std::vector<std::string>& server_flags = {"--quiet"})
      : dir(state), log(state / "cluster.log") {
    pid = fork();
    if (pid == 0) {
      setpgid(0, 0);
      const int out = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      dup2(out, 1);
      dup2(out, 2);
      setenv("UMBRA_CLUSTER_DIR", dir.c_str(), 1);
      setenv("UMBRA_SERVER", UMBRA_SERVER_BINARY, 1);
      const std::string script = std::string(UMBRA_SOURCE_DIR) + "/scripts/cluster.sh";
      std::vector<std::string> args = {"bash", script, std::to_string(servers), std::to_string(port)};
      args.insert(args.end(), server_flags.begin(), server_flags.end());
      std::vector<char*> argv;
      for (std::string& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      execv("/bin/bash", argv.data());
      _exit(127);
    }
  }
  // The script's exit code once it has ended within `limit` (by itself,
  // unsignalled), else -1.
  int wait_for_exit(std::chrono::seconds limit) { return finish(limit, false); }
  // The same after SIGTERM.
  int stop(std::chrono::seconds limit) { return finish(limit, true); }
  int finish(std::chrono::seconds limit, bool terminate) {
    if (pid <= 0) return exit_code;
    if (terminate) kill(pid, SIGTERM);
    const auto until = Clock::now() + limit;
    int status = 0;
    while (Clock::now() < until) {
      if (waitpid(pid, &status, WNOHANG) == pid) {
        exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        pid = -1;
        return exit_code;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return -1;
  }
  ~ClusterScript() {
    if (pid > 0 && stop(std::chrono::seconds(60)) < 0) {
      kill(-pid, SIGKILL);
      waitpid(pid, nullptr, 0);
    }
  }
  // The PID the script wrote for `name` (render1.., haproxy), or -1.
  pid_t pid_of(const std::string& name) const {
    std::ifstream in(dir / (name + ".pid"));
    pid_t p = -1;
    return in >> p ? p : -1;
  }
  std::string output() const {
    std::ifstream in(log);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
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

TEST(Cluster, TheScriptRestartsKilledAndDrainedServersAndSixteenClientsLoseNothing) {
  ASSERT_STRNE(UMBRA_HAPROXY, "") << "haproxy not found: bash scripts/install-deps.sh --cluster";
  const fs::path root = fs::temp_directory_path() / ("umbra-cluster-" + std::to_string(getpid()));
  fs::remove_all(root);
  fs::create_directories(root);
  // The balancer on `port`, the servers on port+1..port+3.
  const int port = free_port_with(3);
  ASSERT_NE(port, 0);
  const auto server_port = [&](int i) { return port + i; };  // render1 = port + 1
  auto cluster = std::make_unique<ClusterScript>(3, port, root);
  // Until HAProxy answers and every server answers on its own port.
  httplib::Client probe("127.0.0.1", port);
  for (int tries = 0;; ++tries) {
    auto res = probe.Get("/api/health");
    if (res && res->status == 200 && listening(server_port(1)) && listening(server_port(2)) &&
        listening(server_port(3)))
      break;
    ASSERT_LT(tries, 600) << "the cluster does not answer:\n" << cluster->output();
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  std::this_thread::sleep_for(std::chrono::seconds(1));  // HAProxy's checks see every server up

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
  const auto run_for = std::chrono::seconds(20);  // servers 3-4x slower: fewer requests, same events
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
      httplib::Client client("127.0.0.1", port);
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
  // The events, at fixed moments of the run: signals to one server each,
  // as an operator, the OOM killer or a crash would send them.
  const auto at = [&](double fraction) {
    std::this_thread::sleep_until(started + std::chrono::duration_cast<Clock::duration>(run_for * fraction));
  };
  const pid_t killed = server_on_port(server_port(1)), drained = server_on_port(server_port(2));
  ASSERT_GT(killed, 0);
  ASSERT_GT(drained, 0);
  EXPECT_EQ(cluster->pid_of("render1"), killed);  // the PIDs the script records are the servers'
  EXPECT_EQ(cluster->pid_of("render2"), drained);
  at(0.25);
  kill(killed, SIGKILL);  // mid-render, most likely
  at(0.5);
  kill(drained, SIGTERM);  // drains: finishes what it has, then exits 0
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

  // Both servers were started again by the script, under new PIDs, and
  // answer on their own ports; the drained one had exited 0.
  const std::string log = cluster->output();
  EXPECT_NE(log.find("render1 exited (status 137)"), std::string::npos) << log;
  EXPECT_NE(log.find("render2 exited (status 0)"), std::string::npos) << log;
  for (int i : {1, 2}) {
    const pid_t now = server_on_port(server_port(i));
    EXPECT_GT(now, 0);
    EXPECT_EQ(cluster->pid_of("render" + std::to_string(i)), now);
    EXPECT_NE(now, i == 1 ? killed : drained);
    httplib::Client direct("127.0.0.1", server_port(i));
    auto health = direct.Get("/api/health");
    ASSERT_TRUE(health) << "render" << i << " was not started again:\n" << log;
    EXPECT_EQ(health->status, 200);
  }
  // Server 1 started again with nothing in memory and no upload sent to
  // it: it can only hold the model by having loaded it from the folder to
  // render it for someone.
  httplib::Client restarted("127.0.0.1", server_port(1));
  auto held = restarted.Get("/api/models");
  ASSERT_TRUE(held);
  const json listed = json::parse(held->body);
  bool found = false;
  for (const json& m : listed["models"]) found |= m["id"] == model;
  EXPECT_TRUE(found) << "the restarted server never rendered the uploaded model:\n"
                     << held->body << "\n" << restarted.Get("/metrics")->body.substr(0, 3000);

  // SIGTERM to the script stops all: it exits 0, and nothing listens.
  EXPECT_EQ(cluster->stop(std::chrono::seconds(60)), 0) << cluster->output();
  for (int i = 0; i <= 3; ++i) EXPECT_FALSE(listening(port + i)) << "port " << port + i << " still open";
  cluster.reset();
  fs::remove_all(root);
}

// A server that cannot start (here an unknown flag) is not started again
// and again for ever: the script stops everything and exits 1, saying why.
TEST(Cluster, TheScriptStopsWhenAServerCannotStart) {
  const fs::path root = fs::temp_directory_path() / ("umbra-cluster-bad-" + std::to_string(getpid()));
  fs::remove_all(root);
  fs::create_directories(root);
  const int port = free_port_with(2);
  ASSERT_NE(port, 0);
  ClusterScript cluster(2, port, root, {"--no-such-flag"});
  EXPECT_EQ(cluster.wait_for_exit(std::chrono::seconds(120)), 1) << cluster.output();
  const std::string log = cluster.output();
  EXPECT_NE(log.find("after its first start: stopping"), std::string::npos) << log;
  for (int i = 0; i <= 2; ++i) EXPECT_FALSE(listening(port + i)) << "port " << port + i << " still open";
  fs::remove_all(root);
}

// Behind HAProxy, a sun-hours job's GET and DELETE reach the server that
// runs it (its id begins with that server's --name, and the script's
// haproxy.cfg sends such paths there), whichever server took the POST.
TEST(Cluster, ASunHoursJobIsFetchedFromTheServerThatRunsIt) {
  ASSERT_STRNE(UMBRA_HAPROXY, "") << "haproxy not found: bash scripts/install-deps.sh --cluster";
  const fs::path root = fs::temp_directory_path() / ("umbra-cluster-jobs-" + std::to_string(getpid()));
  fs::remove_all(root);
  fs::create_directories(root);
  const int port = free_port_with(3);
  ASSERT_NE(port, 0);
  // Every analysis over 1 ms of estimate is a job.
  ClusterScript cluster(3, port, root, {"--quiet", "--max-request-ms", "1"});
  httplib::Client client("127.0.0.1", port);
  client.set_read_timeout(60, 0);
  for (int tries = 0;; ++tries) {
    auto res = client.Get("/api/health");
    if (res && res->status == 200 && listening(port + 1) && listening(port + 2) && listening(port + 3)) break;
    ASSERT_LT(tries, 600) << "the cluster does not answer:\n" << cluster.output();
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  std::this_thread::sleep_for(std::chrono::seconds(1));  // HAProxy's checks see every server up
  const json body = {{"scene", "three-cubes"},
                     {"site", {{"latitude", 51.5}, {"longitude", -0.12}}},
                     {"period", {{"start", "2026-03-21T00:00:00Z"}, {"end", "2026-03-22T00:00:00Z"}, {"step_minutes", 10}}},
                     {"grid", {{"center", {0, 0.01, 0}}, {"size", {10, 10}}, {"spacing", 0.1}}}};
  // Concurrent POSTs: leastconn spreads them over the servers.
  std::vector<std::string> ids(6);
  std::vector<std::thread> posts;
  for (std::size_t i = 0; i < ids.size(); ++i)
    posts.emplace_back([&, i] {
      httplib::Client c("127.0.0.1", port);
      c.set_read_timeout(60, 0);
      auto res = c.Post("/api/sun-hours", body.dump(), "application/json");
      if (res && res->status == 202) ids[i] = json::parse(res->body)["job"];
    });
  for (auto& t : posts) t.join();
  std::set<std::string> servers;
  for (const std::string& id : ids) {
    ASSERT_FALSE(id.empty()) << cluster.output();
    ASSERT_EQ(id.rfind("render", 0), 0u) << id;
    servers.insert(id.substr(0, id.find('.')));
  }
  std::string first_answer;
  for (const std::string& id : ids) {
    // Every GET goes back to the job's server: never a 404 on the way.
    for (int tries = 0;; ++tries) {
      auto res = client.Get("/api/sun-hours/jobs/" + id);
      ASSERT_TRUE(res);
      if (res->status == 200) {
        const json answer = json::parse(res->body);
        EXPECT_EQ(answer["hours"].size(), 10000u);
        if (first_answer.empty()) first_answer = answer["hours"].dump();
        EXPECT_EQ(answer["hours"].dump(), first_answer) << id;  // the same analysis on every server
        break;
      }
      ASSERT_EQ(res->status, 202) << id << ": " << res->body;
      ASSERT_LT(tries, 600) << id;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
  // Another server does not hold it: asked directly, it says so.
  const std::string id = ids[0];
  const int owner = std::stoi(id.substr(6, id.find('.') - 6));
  httplib::Client other("127.0.0.1", port + (owner % 3) + 1);
  auto elsewhere = other.Get("/api/sun-hours/jobs/" + id);
  ASSERT_TRUE(elsewhere);
  EXPECT_EQ(elsewhere->status, 404);
  // DELETE through the balancer reaches it too.
  auto removed = client.Delete("/api/sun-hours/jobs/" + id);
  ASSERT_TRUE(removed);
  EXPECT_EQ(removed->status, 200) << removed->body;
  EXPECT_EQ(client.Get("/api/sun-hours/jobs/" + id)->status, 404);
  EXPECT_GE(servers.size(), 2u) << "six concurrent POSTs all went to one server";
  EXPECT_EQ(cluster.stop(std::chrono::seconds(60)), 0) << cluster.output();
  fs::remove_all(root);
}

}  // namespace
}  // namespace umbra
