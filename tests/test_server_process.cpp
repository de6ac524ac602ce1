// The real umbra-server binary as a process: signals, exit codes, memory.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <thread>
#include <vector>

#include <iterator>
#include <regex>
#include <sstream>

#include <arpa/inet.h>
#include <fcntl.h>
#include <sys/wait.h>
#include <sys/resource.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <httplib.h>
#include <nlohmann/json.hpp>

#include "gltf_builder.hpp"
#include "server_process.hpp"

namespace umbra::testing {
namespace {

using json = nlohmann::json;

ServerProcess start(std::vector<std::string> args = {}) {
  args.push_back("--quiet");
  return ServerProcess(UMBRA_SERVER_BINARY, args);
}

httplib::Client client(const ServerProcess& server) {
  httplib::Client c("127.0.0.1", server.port());
  c.set_read_timeout(120, 0);
  return c;
}

std::size_t queue_depth(const ServerProcess& server) {
  auto res = client(server).Get("/api/health");
  return res && res->status == 200 ? json::parse(res->body)["queue_depth"].get<std::size_t>() : 0;
}

// A render that takes about a second on a 2-core llvmpipe machine: a wide
// kernel over a frame filled with the cube (far from any caster the
// filter is skipped).
const char* kSlowBody = R"({"width": 3072, "height": 3072, "output": "shadow", "shadow": {"pcf_radius": 8}, "camera": {"position": [0.5, 1.2, 1.5], "target": [0, 0, 0]}})";

class GracefulStop : public ::testing::TestWithParam<int> {};

TEST_P(GracefulStop, AnswersTheRequestInFlightThenExitsZero) {
  ServerProcess server = start();
  int status = 0;
  std::size_t bytes = 0;
  std::thread slow([&] {
    auto res = client(server).Post("/api/render", kSlowBody, "application/json");
    status = res ? res->status : -1;
    bytes = res ? res->body.size() : 0;
  });
  while (queue_depth(server) == 0) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  server.send_signal(GetParam());
  slow.join();
  EXPECT_EQ(status, 200) << "the request in flight is answered";
  EXPECT_GT(bytes, 1000u);
  EXPECT_EQ(server.wait(), 0) << server.log();
  EXPECT_NE(server.log().find("stopped"), std::string::npos) << server.log();
  // And it no longer accepts connections.
  httplib::Client after("127.0.0.1", server.port());
  after.set_connection_timeout(1, 0);
  EXPECT_FALSE(after.Get("/api/health"));
}

INSTANTIATE_TEST_SUITE_P(Signals, GracefulStop, ::testing::Values(SIGTERM, SIGINT),
                         [](const auto& info) { return info.param == SIGTERM ? "SIGTERM" : "SIGINT"; });

TEST(GracefulStop, AnIdleServerStopsAtOnceAndAnIdleKeepAliveClientDoesNotHoldItLong) {
  ServerProcess server = start();
  httplib::Client keep_alive = client(server);
  keep_alive.set_keep_alive(true);
  ASSERT_TRUE(keep_alive.Get("/api/health"));
  const auto start_time = std::chrono::steady_clock::now();
  server.send_signal(SIGTERM);
  EXPECT_EQ(server.wait(), 0) << server.log();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  EXPECT_LT(seconds, 2.0) << "an idle keep-alive connection is closed at once";
}

// Issue 11 found a stop waiting 57 s for three clients sending a byte now
// and then. Connections still sending their request, and idle ones, are
// closed at once; the README promises 2 s.
TEST(GracefulStop, TricklingAndIdleClientsDoNotHoldItUp) {
  ServerProcess server = start();
  const auto connect_to_server = [&] {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(std::uint16_t(server.port()));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
    return fd;
  };
  std::atomic<bool> done{false};
  std::vector<std::thread> tricklers;
  std::vector<int> sockets;
  for (int i = 0; i < 6; ++i) sockets.push_back(connect_to_server());
  for (int i = 0; i < 3; ++i)  // the other three stay idle
    tricklers.emplace_back([&, fd = sockets[i]] {
      const std::string head = "POST /api/render HTTP/1.1\r\nHost: localhost\r\nX-Slow: " + std::string(1000, 'a');
      for (std::size_t k = 0; k < head.size() && !done; ++k) {
        if (send(fd, head.data() + k, 1, MSG_NOSIGNAL) != 1) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
      }
    });
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const auto start_time = std::chrono::steady_clock::now();
  server.send_signal(SIGTERM);
  EXPECT_EQ(server.wait(), 0) << server.log();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  EXPECT_LT(seconds, 2.0) << server.log();
  done = true;
  for (std::thread& t : tricklers) t.join();
  for (int fd : sockets) close(fd);
}

// --- The watchdog (issue 29) ------------------------------------------------

// Issue 29's 288 KB model of 4,000 stacked 40 x 40 quads, uploaded: its id.
std::string upload_stacked_quads(const ServerProcess& server) {
  auto res = client(server).Post("/api/models", test::stacked_quads_glb(4000), "model/gltf-binary");
  EXPECT_TRUE(res && (res->status == 201 || res->status == 200)) << (res ? res->body : "no answer");
  return res ? json::parse(res->body).value("id", "") : "";
}

// A frame of it that the estimate refuses by default and that, let run,
// holds the GL thread for minutes: 1024^2 with PCF radius 8 (on the
// reference machine ~5 s of shadow pass, then ~3 minutes of main pass);
// without shadows, ~25 s of main pass.
std::string deep_frame(const std::string& id, bool shadows) {
  json body = {{"width", 1024}, {"height", 1024}, {"shadow", {{"pcf_radius", 8}}},
               {"scene", {{"objects", {{{"type", "mesh"}, {"model", id}}}}}}};
  if (!shadows) body["shadow"]["enabled"] = false;
  return body.dump();
}

// Whether the server has exited within `limit` (it is not reaped: wait()
// gives its status).
bool exits_within(const ServerProcess& server, std::chrono::seconds limit) {
  const auto until = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < until) {
    siginfo_t info{};
    if (waitid(P_PID, id_t(server.pid()), &info, WEXITED | WNOHANG | WNOWAIT) == 0 && info.si_pid == server.pid())
      return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return false;
}

// Waits (at most a minute) until the server holds a render.
void wait_for_a_render_in_flight(const ServerProcess& server) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (queue_depth(server) == 0 && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
}

struct Answer {
  int status = -1;
  std::string body;
  double seconds = 0.0;
};

Answer post_render(const ServerProcess& server, const std::string& body, int timeout_s) {
  httplib::Client c("127.0.0.1", server.port());
  c.set_read_timeout(timeout_s, 0);
  const auto start = std::chrono::steady_clock::now();
  auto res = c.Post("/api/render", body, "application/json");
  Answer a;
  a.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (res) a.status = res->status, a.body = res->body;
  return a;
}

void expect_cut_short(const Answer& a, const char* what) {
  EXPECT_EQ(a.status, 503) << what << ": " << a.body;
  EXPECT_LT(a.seconds, 45.0) << what << ": the 2 s limit, a chunk, and a busy machine's slack";
  if (a.status != 503) return;
  const json error = json::parse(a.body);
  EXPECT_EQ(error["field"], "scene.objects") << what;
  EXPECT_NE(error["error"].get<std::string>().find("ran past the limit of 2000 ms"), std::string::npos) << a.body;
}

// With the cost check relaxed, only the watchdog stands between such a
// frame and the GL thread: it is cut short at --max-run-ms and answered
// 503, small requests sent meanwhile are served after it, and frames after
// a cut (in the shadow pass, then in the main pass) are byte for byte what
// they were before: the half-drawn map is not reused, the GL state is
// restored.
TEST(Watchdog, AFrameTheEstimateLetThroughIsCutShortAndLaterFramesAreAsBefore) {
  ServerProcess server = start({"--max-request-ms", "3600000", "--max-run-ms", "2000", "--deadline-ms", "120000"});
  // Two small frames, each drawing its own shadow map (the light moves).
  const std::string small_a = R"({"width": 96, "height": 64, "time": 1})";
  const std::string small_b = R"({"width": 96, "height": 64, "time": 2})";
  const Answer a = post_render(server, small_a, 60), b = post_render(server, small_b, 60);
  ASSERT_EQ(a.status, 200);
  ASSERT_EQ(b.status, 200);
  const std::string id = upload_stacked_quads(server);
  ASSERT_FALSE(id.empty());

  Answer heavy;
  std::thread shadowed([&] { heavy = post_render(server, deep_frame(id, true), 90); });
  wait_for_a_render_in_flight(server);
  // The map holds b's light: b again would reuse it, were it taken as whole.
  const Answer meanwhile = post_render(server, small_b, 90);
  shadowed.join();
  expect_cut_short(heavy, "cut in the shadow pass");
  EXPECT_EQ(meanwhile.status, 200) << meanwhile.body;
  EXPECT_TRUE(meanwhile.body == b.body) << "the frame after the cut in the shadow pass differs from before";

  std::thread unshadowed([&] { heavy = post_render(server, deep_frame(id, false), 90); });
  wait_for_a_render_in_flight(server);
  // a's light: a shadow pass and a main pass, in what the cut left.
  const Answer after = post_render(server, small_a, 90);
  unshadowed.join();
  expect_cut_short(heavy, "cut in the main pass");
  EXPECT_EQ(after.status, 200) << after.body;
  EXPECT_TRUE(after.body == a.body) << "the frame after the cut in the main pass differs from before";

  auto health = client(server).Get("/api/health");
  ASSERT_TRUE(health);
  EXPECT_EQ(json::parse(health->body)["overran"], 2);
  server.send_signal(SIGTERM);
  EXPECT_EQ(server.wait(), 0) << server.log();
}

// Issue 29: SIGTERM during such a frame took 20 s; let run it would take
// minutes. The drain waits for the frame in progress, which the watchdog
// bounds: the server exits within --deadline-ms + --max-run-ms (and a
// chunk), as main.cpp's usage states, answering the frame 503.
TEST(Watchdog, SigtermDuringADeepFrameExitsWithinTheStatedBound) {
  ServerProcess server = start({"--max-request-ms", "3600000", "--max-run-ms", "2000", "--deadline-ms", "3000"});
  const std::string id = upload_stacked_quads(server);
  ASSERT_FALSE(id.empty());
  Answer heavy;
  std::thread frame([&] { heavy = post_render(server, deep_frame(id, true), 90); });
  wait_for_a_render_in_flight(server);
  const auto signalled = std::chrono::steady_clock::now();
  server.send_signal(SIGTERM);
  // Stated bound: 3 s + 2 s; allowed here: 30 s more for a busy machine.
  const bool exited = exits_within(server, std::chrono::seconds(35));
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - signalled).count();
  if (!exited) server.send_signal(SIGKILL);
  frame.join();
  EXPECT_TRUE(exited) << "still draining " << seconds << " s after SIGTERM";
  EXPECT_EQ(server.wait(), exited ? 0 : 128 + SIGKILL) << server.log();
  expect_cut_short(heavy, "in flight at SIGTERM");
}

// Issue 29, second round: 400,000 slivers (a 19.2 MB upload) across an
// 8192^2 map are 6.5e9 tile tests, 24 s of shadow pass on the reference
// machine, yet were one draw call: the watchdog could not cut it (the
// red team's frame answered 503 after 30.9 s, SIGTERM took 31.5 s). The
// draw's estimate (triangles and the tiles their boxes cover) splits it
// into chunks now, so the frame ends within the limit and a chunk.
TEST(Watchdog, AFrameOfLongSliversIsCutShortWithinTheLimit) {
  ServerProcess server = start({"--max-request-ms", "3600000", "--max-run-ms", "2000", "--deadline-ms", "120000"});
  auto res = client(server).Post("/api/models", test::slivers_glb(400000), "model/gltf-binary");
  ASSERT_TRUE(res && (res->status == 201 || res->status == 200)) << (res ? res->body : "no answer");
  const std::string id = json::parse(res->body)["id"];
  const json body = {{"width", 512},
                     {"height", 512},
                     {"scene", {{"objects", {{{"type", "mesh"}, {"model", id}}}}}},
                     {"camera", {{"position", {0, 0, 60}}, {"target", {0, 0, 0}}, {"fov_y_deg", 100}}},
                     {"light", {{"position", {0, 0, 60}}, {"target", {0, 0, 0}}}},
                     {"shadow", {{"map_size", 8192}}}};
  const Answer a = post_render(server, body.dump(), 120);
  EXPECT_EQ(a.status, 503) << a.body;
  // One draw call took 24 s on the reference machine: the bound leaves 10 s
  // of slack for a busy machine and still fails it.
  EXPECT_LT(a.seconds, 12.0) << "the 2 s limit, a chunk of about 20 ms, and a busy machine's slack";
  if (a.status == 503) {
    const json error = json::parse(a.body);
    EXPECT_EQ(error["field"], "shadow.map_size");
    EXPECT_NE(error["error"].get<std::string>().find("ran past the limit of 2000 ms"), std::string::npos) << a.body;
  }
  server.send_signal(SIGTERM);
  EXPECT_EQ(server.wait(), 0) << server.log();
}

// CPU seconds (user + system) process `pid` has used.
double cpu_seconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::istringstream fields(text.substr(text.rfind(')') + 2));
  std::string field;
  double ticks = 0;
  for (int i = 3; i <= 15 && fields >> field; ++i)
    if (i == 14 || i == 15) ticks += std::atof(field.c_str());
  return ticks / double(sysconf(_SC_CLK_TCK));
}

// Out of file descriptors, accept() fails while the listening socket stays
// readable: a level-triggered loop would spin on it at full CPU. The server
// rests accepting instead, and serves again once descriptors are free.
TEST(Connections, RunningOutOfDescriptorsNeitherSpinsNorStopsTheServer) {
  rlimit normal{};
  getrlimit(RLIMIT_NOFILE, &normal);
  rlimit low = normal;
  low.rlim_cur = 64;  // the server's own files, GL's and a few dozen sockets
  setrlimit(RLIMIT_NOFILE, &low);
  ServerProcess server = start();
  setrlimit(RLIMIT_NOFILE, &normal);
  std::vector<int> sockets;
  for (int i = 0; i < 150; ++i) {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(std::uint16_t(server.port()));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    fcntl(fd, F_SETFL, O_NONBLOCK);  // past the backlog a connect would wait
    connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address);
    sockets.push_back(fd);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const double cpu_before = cpu_seconds(server.pid());
  std::this_thread::sleep_for(std::chrono::seconds(2));
  const double cpu_used = cpu_seconds(server.pid()) - cpu_before;
  // Resting, it uses none; spinning, a core's worth (0.7 s even on this
  // machine loaded by three other jobs).
  EXPECT_LT(cpu_used, 0.25) << "the accept loop spins";
  for (int fd : sockets) close(fd);
  // The idle ones close after 2 s; then there are descriptors again.
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));
  auto res = client(server).Get("/api/health");
  ASSERT_TRUE(res) << httplib::to_string(res.error()) << "\n" << server.log();
  EXPECT_EQ(res->status, 200);
  server.send_signal(SIGTERM);
  EXPECT_EQ(server.wait(), 0) << server.log();
}

// GET /metrics after a mix of answers: Prometheus' own checker takes the
// page, and the counters say what happened.
TEST(Metrics, APageOfARealServerPassesPromtool) {
  ASSERT_STRNE(UMBRA_PROMTOOL, "") << "promtool not found: bash scripts/install-deps.sh --metrics";
  ServerProcess server = start();
  auto c = client(server);
  ASSERT_EQ(c.Post("/api/render", R"({"width": 64, "height": 48})", "application/json")->status, 200);
  ASSERT_EQ(c.Post("/api/depth", R"({"shadow": {"map_size": 256}})", "application/json")->status, 200);
  ASSERT_EQ(c.Post("/api/render", R"({"width": 64, "height": 48, "output": "exact"})", "application/json")->status, 200);
  ASSERT_EQ(c.Post("/api/render", R"({"width": 1})", "application/json")->status, 400);
  ASSERT_EQ(c.Get("/")->status, 200);
  ASSERT_EQ(c.Get("/no/such/file")->status, 404);
  auto res = c.Get("/metrics");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200);
  EXPECT_EQ(res->get_header_value("Content-Type"), "text/plain; version=0.0.4; charset=utf-8");
  const std::string& page = res->body;
  for (const char* line : {R"(umbra_frames_total{output="color",status="200"} 1)",
                           R"(umbra_frames_total{output="depth",status="200"} 1)",
                           R"(umbra_frames_total{output="exact",status="200"} 1)",
                           R"(umbra_frames_total{output="invalid",status="400"} 1)",
                           R"(umbra_http_requests_total{route="/api/render",status="200"} 2)",
                           R"(umbra_http_requests_total{route="static",status="200"} 1)",
                           R"(umbra_http_requests_total{route="static",status="404"} 1)",
                           R"(umbra_render_stage_seconds_count{stage="raycast"} 1)", "umbra_models 2"})
    EXPECT_NE(page.find(std::string("\n") + line + "\n"), std::string::npos) << line << "\n" << page;

  const std::string file = ::testing::TempDir() + "umbra-metrics-" + std::to_string(getpid()) + ".txt";
  std::ofstream(file) << page;
  const std::string command = std::string(UMBRA_PROMTOOL) + " check metrics < " + file + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string said;
  char buffer[512];
  while (fgets(buffer, sizeof buffer, pipe)) said += buffer;
  const int status = pclose(pipe);
  std::remove(file.c_str());
  // promtool exits non-zero on a malformed page, and lists lint problems
  // (names, units, help texts) on its output: neither may happen.
  EXPECT_EQ(status, 0) << said;
  EXPECT_EQ(said, "") << said;
  server.send_signal(SIGTERM);
  EXPECT_EQ(server.wait(), 0) << server.log();
}

// --models DIR: a model with its buffer beside it is loaded and named; one
// whose buffer lies outside the folder is skipped, said why, and the
// server starts all the same.
TEST(Models, AFolderIsLoadedAtStartAndAFileReachingOutsideIsSkippedWithItsReason) {
  namespace fs = std::filesystem;
  const fs::path root = fs::temp_directory_path() / ("umbra-process-models-" + std::to_string(getpid()));
  fs::remove_all(root);
  fs::create_directories(root / "models");
  const std::string triangle_bin(reinterpret_cast<const char*>(std::array<float, 9>{0, 0, 0, 1, 0, 0, 0, 1, 0}.data()), 36);
  const auto gltf = [](const std::string& uri) {
    return json{{"asset", {{"version", "2.0"}}},
                {"buffers", {{{"uri", uri}, {"byteLength", 36}}}},
                {"bufferViews", {{{"buffer", 0}, {"byteLength", 36}}}},
                {"accessors", {{{"bufferView", 0}, {"componentType", 5126}, {"count", 3}, {"type", "VEC3"}}}},
                {"meshes", {{{"primitives", {{{"attributes", {{"POSITION", 0}}}}}}}}},
                {"nodes", {{{"mesh", 0}}}}}
        .dump();
  };
  std::ofstream(root / "models" / "leaf.bin", std::ios::binary) << triangle_bin;
  std::ofstream(root / "models" / "leaf.gltf") << gltf("leaf.bin");
  std::ofstream(root / "outside.bin", std::ios::binary) << triangle_bin;
  std::ofstream(root / "models" / "escape.gltf") << gltf("../outside.bin");
  {
    ServerProcess server = start({"--models", (root / "models").string()});
    auto res = client(server).Get("/api/models/leaf");
    ASSERT_TRUE(res) << server.log();
    EXPECT_EQ(res->status, 200) << res->body;
    EXPECT_EQ(json::parse(res->body)["triangles"], 1);
    // The leaf and the two built-in models (teapot, torus-knot).
    const json listed = json::parse(client(server).Get("/api/models")->body);
    EXPECT_EQ(listed["count"], 3);
    EXPECT_EQ(listed["models"][0]["name"], "leaf");
    EXPECT_EQ(client(server).Get("/api/models/escape")->status, 404);
    EXPECT_NE(server.log().find("skipped escape.gltf: a buffer refers to '"), std::string::npos) << server.log();
    EXPECT_NE(server.log().find("outside the models folder"), std::string::npos) << server.log();
    EXPECT_NE(server.log().find("model 'leaf'"), std::string::npos) << server.log();
  }
  fs::remove_all(root);
}

// The n-th request of a fixed mix: every output, sizes, map sizes, scenes
// (built-in and custom, of changing size), light modes, filters and times,
// with a bad request now and then. Request n and n + 60 are alike, so the
// server's state after 500 and after 5000 requests is comparable.
std::string mixed_body(int n) {
  const char* outputs[] = {"color", "depth", "shadow", "color", "exact", "color", "error", "shadow"};
  const int sizes[][2] = {{64, 48}, {160, 90}, {97, 131}, {320, 180}, {48, 48}};
  const int maps[] = {256, 512, 1024, 128};
  const char* filters[] = {R"("filter": "pcf", "pcf_radius": 2)", R"("filter": "hard")", R"("filter": "pcf")"};
  const int k = n % 60;
  json body = {{"width", sizes[k % 5][0]}, {"height", sizes[k % 5][1]}, {"output", outputs[k % 8]}, {"time", 0.1 * k}};
  const bool cheap = body["output"] == "exact" || body["output"] == "error";
  if (cheap) body["width"] = 40, body["height"] = 30;
  json shadow = json::parse(std::string("{") + filters[k % 3] + "}");
  shadow["map_size"] = maps[k % 4];
  const bool point_light = k % 4 == 1;
  if (k % 7 == 0 && !point_light) shadow["cascades"] = 1 + k % 3;
  body["shadow"] = shadow;
  if (point_light) body["light"] = {{"projection", "perspective"}, {"position", {-1.0, 3.0 + 0.01 * k, 1.0}}};
  if (k % 5 == 2) {
    body["scene"] = "three-cubes";
  } else if (k % 5 == 4) {
    json objects = json::array({{{"type", "plane"}, {"center", {0, 0, 0}}, {"size", {10, 10}}}});
    for (int i = 0; i < 1 + k % 13; ++i) {
      const json center = {i - 6.0, 0.5, 0.3 * i};
      if (i % 2)
        objects.push_back({{"type", "box"}, {"center", center}, {"size", {0.5, 1.0, 0.5}}});
      else
        objects.push_back({{"type", "sphere"}, {"center", center}, {"radius", 0.4}});
    }
    body["scene"] = {{"objects", objects}};
  }
  if (k == 17) return R"({"width": 0})";          // 400
  if (k == 41) return R"({"light": {"color": )";  // truncated: 400
  return body.dump();
}

TEST(Memory, FiveThousandMixedRequestsHoldResidentMemorySteady) {
#ifdef UMBRA_SANITIZED
  GTEST_SKIP() << "AddressSanitizer holds freed memory in quarantine by design: resident memory is measured in the "
                  "normal build";
#endif
  const int total = std::getenv("UMBRA_RSS_REQUESTS") ? std::atoi(std::getenv("UMBRA_RSS_REQUESTS")) : 5000;
  // Without fresh GL contexts: this test looks for memory that grows with
  // the number of requests, which a renewal at one measurement and not the
  // other would hide or fake (ResidentMemoryReturnsNearBaseline... tests
  // the renewals).
  ServerProcess server = start({"--fresh-context-mib", "0"});
  std::atomic<int> failures{0};
  const auto send = [&](httplib::Client& c, int n) {
    const std::string body = mixed_body(n);
    const bool scenes = n % 97 == 0;
    auto res = scenes ? c.Get("/api/scenes") : c.Post("/api/render", body, "application/json");
    const int expected = !scenes && body.size() < 40 ? 400 : 200;
    if ((!res || res->status != expected) && failures.fetch_add(1) < 5)
      ADD_FAILURE() << "request " << n << ": " << (res ? std::to_string(res->status) + " " + res->body : "no answer")
                    << "\n" << body;
  };
  // Requests [from, to) from two clients at once.
  const auto run = [&](int from, int to) {
    std::atomic<int> next{from};
    const auto work = [&] {
      httplib::Client c = client(server);
      for (int n; (n = next.fetch_add(1)) < to;) send(c, n);
    };
    std::thread a(work), b(work);
    a.join();
    b.join();
  };
  // What is resident depends on the last few requests (map and image sizes,
  // the scene held): the same 60 requests in the same order before each
  // measurement make the two comparable. The server releases what it keeps
  // after 1.5 s without work; on a busy machine that can come later, so wait
  // at least 3 s and then until resident memory has held still for 1.5 s
  // (at most 15 s in all).
  const auto settled_resident_kib = [&] {
    httplib::Client c = client(server);
    for (int n = 0; n < 60; ++n) send(c, n);
    std::this_thread::sleep_for(std::chrono::seconds(3));
    long last = server.resident_kib();
    int still = 0;
    for (int tick = 0; tick < 24 && still < 3; ++tick) {
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
      const long now = server.resident_kib();
      still = std::labs(now - last) <= last / 100 ? still + 1 : 0;
      last = now;
    }
    auto health = c.Get("/api/health");
    EXPECT_TRUE(health && json::parse(health->body).value("gl_context_renewals", std::uint64_t(1)) == 0)
        << "--fresh-context-mib 0 made a fresh GL context all the same";
    return last;
  };
  // Each point is measured three times, the least kept: memory that a
  // later replay gives back was held by those requests, not kept for good
  // (one measurement alone varied from -1 % to +17 % between runs of this
  // same test), while memory that grows with the requests is never given
  // back and shows in all three.
  const auto least_resident_kib = [&] {
    long least = settled_resident_kib();
    for (int k = 0; k < 2; ++k) least = std::min(least, settled_resident_kib());
    return least;
  };
  run(0, 500);
  const long after_500 = least_resident_kib();
  run(500, total);
  const long after_all = least_resident_kib();
  std::printf("resident memory: %ld KiB after 500 requests, %ld KiB after %d (%+.1f %%)\n", after_500, after_all, total,
              100.0 * double(after_all - after_500) / double(after_500));
  EXPECT_EQ(failures.load(), 0);
  ASSERT_GT(after_500, 0);
  EXPECT_LE(double(after_all), 1.10 * double(after_500));
  server.send_signal(SIGTERM);
  EXPECT_EQ(server.wait(), 0);
}

// A scene of 999 spheres in a grid (about 280 MB of mesh once uploaded);
// `variant` shifts them a little, so each variant is a distinct scene.
json thousand_spheres(int variant) {
  json objects = json::array({{{"type", "plane"}, {"center", {0, 0, 0}}, {"size", {60, 60}}}});
  for (int i = 0; i < 999; ++i)
    objects.push_back({{"type", "sphere"},
                       {"center", {-29.0 + 1.8 * (i % 32) + 0.01 * variant, 0.5, -27.0 + 1.8 * (i / 32)}},
                       {"radius", 0.45}});
  return {{"objects", objects}};
}

// POSTs a render to the server and returns the PNG, failing the test (with
// the answer) unless it is a 200.
std::string render_ok(httplib::Client& c, const json& body) {
  auto res = c.Post("/api/render", body.dump(), "application/json");
  EXPECT_TRUE(res && res->status == 200) << (res ? std::to_string(res->status) + " " + res->body : "no answer") << "\n"
                                         << body.dump().substr(0, 200);
  return res && res->status == 200 ? res->body : std::string();
}

// Issue 11 item 2: a few heavy requests used to leave gigabytes resident
// for good (cached scenes, a 4096^2 frame's framebuffers, an 8192^2 map and
// preview). Measured on the 2-core reference machine after this mix: 1.29 GB
// idle before the memory budget, 0.20 GB with it, and since the GL context
// is made anew when idle, 0.10 GB, the baseline (peak 1.3 GB either way);
// the margin leaves room for a noisy machine, and is far below one cached
// scene.
TEST(Memory, ResidentMemoryReturnsNearBaselineOnceIdleAfterAHeavyMix) {
#ifdef UMBRA_SANITIZED
  GTEST_SKIP() << "AddressSanitizer holds freed memory in quarantine by design: resident memory is measured in the "
                  "normal build";
#endif
  // Before the fresh context: 162-184 MB idle against 110 with the spheres
  // partly hidden, 259-296 MB seen whole.
  constexpr long kMarginKib = 64 * 1024;
  ServerProcess server = start();
  httplib::Client c = client(server);
  const auto render = [&](const json& body) { render_ok(c, body); };
  // Warm-up: the default frame's variants and buffers, as a client's first
  // requests make them. More than a second idle lets the server settle.
  for (int n = 0; n < 10; ++n) render({{"width", 320}, {"height", 180}, {"time", 0.1 * n}});
  std::this_thread::sleep_for(std::chrono::seconds(3));
  const long baseline = server.resident_kib();
  ASSERT_GT(baseline, 0);

  // The default camera sees each scene whole (a custom scene's far plane
  // reaches its bounds): llvmpipe keeps most of such scenes' memory after
  // they are deleted, until the context is made anew.
  for (int variant = 0; variant < 3; ++variant)
    render({{"width", 640}, {"height", 360}, {"scene", thousand_spheres(variant)}});
  render({{"width", 4096}, {"height", 4096}, {"output", "shadow"}});
  render({{"width", 4096}, {"height", 4096}, {"output", "color"}, {"time", 1.0}});
  render({{"width", 256}, {"height", 256}, {"shadow", {{"map_size", 8192}}}});
  render({{"width", 256}, {"height", 256}, {"output", "depth"}, {"shadow", {{"map_size", 8192}}}});
  render({{"width", 480},
          {"height", 270},
          {"output", "exact"},
          {"scene", thousand_spheres(3)}});
  const long busy = server.resident_kib();
  // The renderer releases what it keeps after 1.5 s without work.
  std::this_thread::sleep_for(std::chrono::seconds(4));
  const long idle = server.resident_kib();
  std::printf("resident memory: %ld KiB baseline, %ld KiB after the heavy mix, %ld KiB idle after it\n", baseline,
              busy, idle);
  EXPECT_LE(idle, baseline + kMarginKib);
  server.send_signal(SIGTERM);
  EXPECT_EQ(server.wait(), 0);
}

// llvmpipe keeps a render target it drew into, other than the last, until
// its GL context goes: a shadow map of four 8192^2 cascades (1 GiB) used to
// stay resident for as long as the server ran. Once idle, the server makes
// its context anew, and the frames after it are the same frames.
TEST(Memory, AMultiLayerShadowMapIsGivenBackOnceIdleAndFramesStayTheSame) {
#ifdef UMBRA_SANITIZED
  GTEST_SKIP() << "AddressSanitizer holds freed memory in quarantine by design: resident memory is measured in the "
                  "normal build";
#endif
  constexpr long kMarginKib = 64 * 1024;
  ServerProcess server = start();
  httplib::Client c = client(server);
  const auto render = [&](const json& body) { return render_ok(c, body); };
  const auto health = [&] {
    auto res = c.Get("/api/health");
    return res ? json::parse(res->body) : json::object();
  };
  const auto renewals = [&] { return health().value("gl_context_renewals", std::uint64_t(0)); };
  const json small = {{"width", 320}, {"height", 180}, {"shadow", {{"cascades", 2}}}};
  std::string before;
  for (int n = 0; n < 5; ++n) before = render(small);
  std::this_thread::sleep_for(std::chrono::seconds(3));
  const long baseline = server.resident_kib();
  const std::uint64_t renewals_before = renewals();
  auto cascades = c.Post("/api/render", json({{"width", 256}, {"height", 256}, {"shadow", {{"map_size", 8192}, {"cascades", 4}}}}).dump(),
                         "application/json");
  ASSERT_TRUE(cascades && cascades->status == 200);
  EXPECT_EQ(cascades->get_header_value("Umbra-Shadow-Views"), "cascades; views=4; size=8192");
  render({{"width", 256},
          {"height", 256},
          {"shadow", {{"map_size", 4096}}},
          {"light", {{"projection", "perspective"}, {"position", {0, 2, 0}}}}});
  const long busy = server.resident_kib();
  std::this_thread::sleep_for(std::chrono::seconds(4));
  const long idle = server.resident_kib();
  std::printf("resident memory: %ld KiB baseline, %ld KiB after four 8192^2 cascades and a 4096^2 cube, %ld KiB idle\n",
              baseline, busy, idle);
  // llvmpipe holds the maps in process memory; a GPU in its own (an H100
  // left resident memory at +3 MB), where only the renewal can be checked.
  const std::string gl_renderer = health().value("gl_renderer", std::string());
  ASSERT_FALSE(gl_renderer.empty()) << "no GL renderer in /api/health";
  if (gl_renderer.find("llvmpipe") != std::string::npos) {
    EXPECT_GT(busy, baseline + 256 * 1024) << "the maps did not take the memory they should";
  }
  EXPECT_LE(idle, baseline + kMarginKib);
  EXPECT_EQ(renewals(), renewals_before + 1);
  // The fresh context draws the very same PNG.
  EXPECT_TRUE(render(small) == before) << "a frame after the GL context was made anew differs from before";
  server.send_signal(SIGTERM);
  EXPECT_EQ(server.wait(), 0);
}

// umbra-server with `args` until it exits (it must, by itself): its exit
// status and what it wrote on stderr.
struct Exit {
  int status = -1;
  std::string said;
};

Exit run_to_exit(const std::string& args) {
  const std::string command = std::string(UMBRA_SERVER_BINARY) + " --port 0 " + args + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  Exit exit;
  if (!pipe) return exit;
  char buffer[512];
  while (fgets(buffer, sizeof buffer, pipe)) exit.said += buffer;
  const int status = pclose(pipe);
  exit.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return exit;
}

std::string temp_file(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + "umbra-" + std::to_string(getpid()) + "-" + name;
  std::ofstream(path) << text;
  return path;
}

// Issue 29's finding 8: anyone who could reach the port could upload and
// read /metrics. A non-loopback address now needs tokens, or the operator
// saying so.
TEST(Access, ANonLoopbackHostWithoutTokensRefusesToStart) {
  for (const char* host : {"0.0.0.0", "::", "render.example"}) {
    const Exit refused = run_to_exit(std::string("--quiet --host ") + host);
    EXPECT_EQ(refused.status, 2) << host << ": " << refused.said;
    EXPECT_NE(refused.said.find("is not a loopback address: give --tokens FILE"), std::string::npos) << refused.said;
    EXPECT_NE(refused.said.find("--no-auth"), std::string::npos) << refused.said;
  }
  const Exit both = run_to_exit("--quiet --host 0.0.0.0 --no-auth --tokens /dev/null");
  EXPECT_EQ(both.status, 2) << both.said;
  // --no-auth: it serves, and says which Host names it answers for.
  ServerProcess open_server(UMBRA_SERVER_BINARY, {"--quiet", "--host", "0.0.0.0", "--no-auth"});
  EXPECT_NE(open_server.log().find("only requests naming localhost, 127.0.0.1 or [::1]"), std::string::npos)
      << open_server.log();
  auto res = client(open_server).Get("/api/scenes");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  open_server.send_signal(SIGTERM);
  EXPECT_EQ(open_server.wait(), 0);
}

TEST(Access, AMalformedTokensFileRefusesToStartNamingTheLine) {
  const std::string file = temp_file("tokens-bad", "# ops\nsecret-token-0000000001 render\nsecret-token-0000000002 admin\n");
  const Exit refused = run_to_exit("--quiet --tokens " + file);
  std::remove(file.c_str());
  EXPECT_EQ(refused.status, 2) << refused.said;
  EXPECT_NE(refused.said.find("line 3: unknown scope 'admin'"), std::string::npos) << refused.said;
  EXPECT_EQ(refused.said.find("secret-token"), std::string::npos) << refused.said;
  const Exit missing = run_to_exit("--quiet --tokens /nonexistent/tokens");
  EXPECT_EQ(missing.status, 2) << missing.said;
  EXPECT_NE(missing.said.find("cannot read"), std::string::npos) << missing.said;
  const Exit bad_hosts = run_to_exit("--quiet --allowed-hosts render.example:8080");
  EXPECT_EQ(bad_hosts.status, 2) << bad_hosts.said;
}

TEST(Access, TokensAreNeverLoggedOnlyTheirPrincipal) {
  const std::string render = "Rend3r-s3cret-t0ken-AAAA", upload = "Upl0ad-s3cret-t0ken-BBBB";
  const std::string file = temp_file("tokens", render + " render\n" + upload + " render,upload\n");
  ServerProcess server(UMBRA_SERVER_BINARY, {"--tokens", file, "--host", "0.0.0.0"});  // logging every request
  std::remove(file.c_str());
  httplib::Client c = client(server);
  const auto bearer = [](const std::string& token) { return httplib::Headers{{"Authorization", "Bearer " + token}}; };
  auto ok = c.Get("/api/scenes", bearer(render));
  ASSERT_TRUE(ok);
  EXPECT_EQ(ok->status, 200);
  auto forbidden = c.Post("/api/models", bearer(render), "x", "model/gltf-binary");
  ASSERT_TRUE(forbidden);
  EXPECT_EQ(forbidden->status, 403);
  auto uploaded = c.Post("/api/models", bearer(upload), "x", "model/gltf-binary");
  ASSERT_TRUE(uploaded);
  EXPECT_EQ(uploaded->status, 400);  // the upload scope is enough; the body is no glTF
  auto unknown = c.Get("/api/scenes", bearer(render + "X"));
  ASSERT_TRUE(unknown);
  EXPECT_EQ(unknown->status, 401);
  for (const auto* res : {&ok, &forbidden, &uploaded, &unknown})
    EXPECT_EQ((*res)->body.find("s3cret"), std::string::npos) << (*res)->body;
  server.send_signal(SIGTERM);
  EXPECT_EQ(server.wait(), 0);
  const std::string log = server.log();
  EXPECT_EQ(log.find("s3cret"), std::string::npos) << log;
  EXPECT_NE(log.find("GET /api/scenes 200"), std::string::npos) << log;
  // Who asked, by principal: 12 hex digits of the token's SHA-256.
  const std::regex principal(R"(GET /api/scenes 200 [\d.]+ ms token:[0-9a-f]{12}\n)");
  EXPECT_TRUE(std::regex_search(log, principal)) << log;
}

}  // namespace
}  // namespace umbra::testing
