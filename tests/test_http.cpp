// The real server on an ephemeral loopback port, driven over HTTP.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdio>
#include <chrono>
#include <memory>
#include <regex>
#include <thread>
#include <vector>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <httplib.h>
#include <nlohmann/json.hpp>
#include <stb_image.h>

#include "core/builtin_models.hpp"
#include "gltf_builder.hpp"
#include "assets/gltf_loader.hpp"
#include "http_api.hpp"
#include "sun_hours_parser.hpp"
#include "assets/model_store.hpp"
#include "service/render_service.hpp"
#include "core/sun_position.hpp"

namespace umbra {
namespace {

using json = nlohmann::json;

// One renderer and one server for the whole binary.
class ServerEnvironment : public testing::Environment {
 public:
  void SetUp() override {
    renderer = std::make_unique<RenderService>();
    ServerOptions options;
    options.port = 0;
    options.log_requests = std::getenv("UMBRA_TEST_LOG") != nullptr;  // the server log, when debugging a test
    options.model_importer = UMBRA_MODEL_IMPORTER;  // beside the server in build/server, not beside this test
    api = std::make_unique<HttpApi>(*renderer, options);
    ASSERT_TRUE(api->bind());
    thread = std::thread([] { api->serve(); });
    while (!api->serving()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  void TearDown() override {
    api->stop();
    thread.join();
    api.reset();
    renderer.reset();
  }
  static inline std::unique_ptr<RenderService> renderer;
  static inline std::unique_ptr<HttpApi> api;
  static inline std::thread thread;
};

httplib::Client client() {
  httplib::Client c("127.0.0.1", ServerEnvironment::api->port());
  c.set_read_timeout(120, 0);
  return c;
}

struct Decoded {
  int width = 0, height = 0, channels = 0;
  std::vector<unsigned char> pixels;
};

Decoded decode_png(const std::string& bytes) {
  Decoded d;
  unsigned char* pixels = stbi_load_from_memory(reinterpret_cast<const unsigned char*>(bytes.data()), int(bytes.size()),
                                                &d.width, &d.height, &d.channels, 0);
  EXPECT_NE(pixels, nullptr) << "not a PNG";
  if (pixels) d.pixels.assign(pixels, pixels + std::size_t(d.width) * std::size_t(d.height) * std::size_t(d.channels));
  stbi_image_free(pixels);
  return d;
}

void expect_json_error(const httplib::Result& res, int status, const std::string& field) {
  ASSERT_TRUE(res) << "no response";
  EXPECT_EQ(res->status, status) << res->body;
  EXPECT_EQ(res->get_header_value("Content-Type"), "application/json");
  const json body = json::parse(res->body);
  EXPECT_TRUE(body.contains("error"));
  EXPECT_FALSE(body["error"].get<std::string>().empty());
  EXPECT_EQ(body["field"], field) << res->body;
}

TEST(Http, HealthReportsTheGlContextAndCounters) {
  auto res = client().Get("/api/health");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  const json j = json::parse(res->body);
  EXPECT_EQ(j["status"], "ok");
  EXPECT_FALSE(j["gl_renderer"].get<std::string>().empty());
  EXPECT_FALSE(j["gl_version"].get<std::string>().empty());
  EXPECT_TRUE(j["uptime_s"].is_number());
  EXPECT_TRUE(j["frames_rendered"].is_number_unsigned());
  EXPECT_TRUE(j["queue_depth"].is_number_unsigned());
  EXPECT_TRUE(j["shadow_cache_hits"].is_number_unsigned());
  EXPECT_TRUE(j["scene_uploads"].is_number_unsigned());
  EXPECT_TRUE(j["abandoned"].is_number_unsigned());
}

TEST(Http, ScenesListsTheBuiltInsInCustomSceneForm) {
  auto res = client().Get("/api/scenes");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  const json j = json::parse(res->body);
  ASSERT_EQ(j["scenes"].size(), 4u);
  EXPECT_EQ(j["scenes"][0]["name"], "cube-on-plane");
  EXPECT_EQ(j["scenes"][2]["name"], "teapot");
  // Each object list is usable as a custom scene as it is: the built-in
  // models' meshes name them by id.
  for (const json& scene : j["scenes"]) {
    const json body = {{"width", 64}, {"height", 64}, {"scene", {{"objects", scene["objects"]}}}};
    auto render = client().Post("/api/render", body.dump(), "application/json");
    ASSERT_TRUE(render);
    EXPECT_EQ(render->status, 200) << scene["name"] << ": " << render->body;
  }
  EXPECT_EQ(j["scenes"][2]["objects"][1]["model"], find_builtin_model("teapot")->id);
}

TEST(Http, RenderReturnsAPngFrameWithServerTiming) {
  auto res = client().Post("/api/render", "{}", "application/json");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(res->get_header_value("Content-Type"), "image/png");
  const std::string timing = res->get_header_value("Server-Timing");
  for (const char* stage : {"shadow;dur=", "main;dur=", "readback;dur=", "encode;dur="})
    EXPECT_NE(timing.find(stage), std::string::npos) << timing;
  const Decoded d = decode_png(res->body);
  EXPECT_EQ(d.width, 960);
  EXPECT_EQ(d.height, 540);
  EXPECT_EQ(d.channels, 3);
}

// Filter "exact": Umbra-Certified says how many pixels were ray cast and
// how the frame was certified (docs/api.md "Umbra-Certified"): on llvmpipe,
// where the server prices the paths, a box close up at 960 x 540 by the
// maps, and the default scene at 160 x 90 by proving the floor and casting
// the rest (a small image costs less to cast than to map); the maps
// elsewhere. The PNGs are the same shadow term as the exact output's either
// way.
TEST(Http, TheCertifiedHeaderNamesThePathTaken) {
  const std::regex header("uncertain=[0-9.]+%, ray_cast=[0-9]+, pixels=([0-9]+), path=(maps|proofs|ray-cast)");
  const std::string close_up =
      R"({"width": 960, "height": 540, "output": "shadow", "shadow": {"filter": "exact"}, "scene": {"objects": [{"type": "plane", "center": [0, 0, 0], "size": [20, 20]}, {"type": "box", "center": [0, 0.5, 0], "size": [1, 1, 1], "rotation_y_deg": 20}]}, "camera": {"position": [1.25, 0.22, 1.45], "target": [0.45, 0.0, 0.45], "near": 0.01}, "light": {"position": [-3, 2, -2], "target": [0, 0, 0]}})";
  for (const auto& [body, path, pixels] :
       {std::tuple{close_up, "maps", "518400"},
        std::tuple{std::string(R"({"width": 160, "height": 90, "output": "shadow", "shadow": {"filter": "exact"}})"), "proofs", "14400"}}) {
    auto res = client().Post("/api/render", body, "application/json");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200) << res->body;
    const std::string certified = res->get_header_value("Umbra-Certified");
    std::smatch m;
    ASSERT_TRUE(std::regex_match(certified, m, header)) << certified;
    EXPECT_EQ(m[1], pixels);
    // Elsewhere than llvmpipe, always the maps.
    const bool llvmpipe =
        json::parse(client().Get("/api/health")->body)["gl_renderer"].get<std::string>().find("llvmpipe") != std::string::npos;
    EXPECT_EQ(m[2], llvmpipe ? path : "maps") << body;
    std::string exact_body = body;
    exact_body.replace(exact_body.find("\"output\": \"shadow\""), 18, "\"output\": \"exact\"");
    auto exact = client().Post("/api/render", exact_body, "application/json");
    ASSERT_TRUE(exact);
    ASSERT_EQ(exact->status, 200) << exact->body;
    EXPECT_EQ(decode_png(res->body).pixels, decode_png(exact->body).pixels) << body;
  }
}

TEST(Http, EveryOutputDecodesToTheRightSize) {
  struct Case {
    const char* output;
    int width, height, channels;
  };
  for (const Case& c : {Case{"color", 200, 100, 3}, Case{"shadow", 200, 100, 1}, Case{"depth", 256, 256, 1},
                        Case{"exact", 200, 100, 1}, Case{"error", 200, 100, 3}}) {
    const json body = {{"width", 200}, {"height", 100}, {"shadow", {{"map_size", 256}}}, {"output", c.output}};
    auto res = client().Post("/api/render", body.dump(), "application/json");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200) << c.output << ": " << res->body;
    const Decoded d = decode_png(res->body);
    EXPECT_EQ(d.width, c.width) << c.output;
    EXPECT_EQ(d.height, c.height) << c.output;
    EXPECT_EQ(d.channels, c.channels) << c.output;
    // The ray cast is a stage of its own, beside the GL passes (it was once
    // added into "main", which then exceeded the whole request).
    const std::string timing = res->get_header_value("Server-Timing");
    const bool cast = std::string(c.output) == "exact" || std::string(c.output) == "error";
    EXPECT_EQ(timing.find("raycast;dur=") != std::string::npos, cast) << c.output << ": " << timing;
    if (std::string(c.output) == "exact") {
      EXPECT_NE(timing.find("main;dur=0.000"), std::string::npos) << timing;
    }
    if (std::string(c.output) == "error") {
      std::smatch main_ms;
      ASSERT_TRUE(std::regex_search(timing, main_ms, std::regex("main;dur=([0-9.]+)"))) << timing;
      EXPECT_GT(std::stod(main_ms[1]), 0.0) << "the GL pass of the shadow term: " << timing;
    }
    const std::string measures = res->get_header_value("Umbra-Shadow-Error");
    if (std::string(c.output) == "error") {
      // The fields clients already parse first, in their order; new ones after.
      const std::regex format(
          "mae=[0-9.]+, wrong=[0-9.]+%, false_shadow=[0-9.]+%, false_light=[0-9.]+%, pixels=[0-9]+, "
          "artifacts=[0-9.]+%, interior_pixels=([0-9]+)");
      std::smatch match;
      ASSERT_TRUE(std::regex_match(measures, match, format)) << measures;
      EXPECT_GT(std::stoul(match[1]), 0u) << "the lit floor far from the cube is interior: " << measures;
    } else {
      EXPECT_TRUE(measures.empty()) << c.output;
    }
  }
}

TEST(Http, DepthRouteIsTheDepthOutput) {
  auto res = client().Post("/api/depth", R"({"shadow": {"map_size": 128}})", "application/json");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  const Decoded d = decode_png(res->body);
  EXPECT_EQ(d.width, 128);
  EXPECT_EQ(d.height, 128);
  // The same body as /api/render: any output is taken, the depth map drawn,
  // and an output other than "depth" named as unused.
  for (const char* output : {"color", "shadow", "exact", "error"}) {
    const std::string body = std::string(R"({"shadow": {"map_size": 128}, "output": ")") + output + "\"}";
    auto other = client().Post("/api/depth", body, "application/json");
    ASSERT_TRUE(other);
    ASSERT_EQ(other->status, 200) << body << ": " << other->body;
    EXPECT_EQ(other->body, res->body) << body;
    EXPECT_EQ(other->get_header_value("Umbra-Unused-Fields"), "output") << body;
  }
  auto named = client().Post("/api/depth", R"({"shadow": {"map_size": 128}, "output": "depth"})", "application/json");
  ASSERT_TRUE(named);
  EXPECT_EQ(named->status, 200);
  EXPECT_FALSE(named->has_header("Umbra-Unused-Fields"));
  expect_json_error(client().Post("/api/depth", R"({"output": "normals"})", "application/json"), 400, "output");
}

TEST(Http, DepthBits16GivesA16BitGreyPng) {
  auto res = client().Post("/api/depth", R"({"depth_bits": 16, "shadow": {"map_size": 128}})", "application/json");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(res->get_header_value("Umbra-Unused-Fields"), "");
  // The signature, then IHDR: length, "IHDR", width, height (big-endian), bit depth, colour type.
  const std::string& png = res->body;
  ASSERT_GE(png.size(), 26u);
  EXPECT_EQ(png.substr(0, 8), "\x89PNG\r\n\x1a\n");
  EXPECT_EQ(png.substr(12, 4), "IHDR");
  const auto byte = [&](std::size_t i) { return int(static_cast<unsigned char>(png[i])); };
  EXPECT_EQ((byte(16) << 24) | (byte(17) << 16) | (byte(18) << 8) | byte(19), 128);
  EXPECT_EQ((byte(20) << 24) | (byte(21) << 16) | (byte(22) << 8) | byte(23), 128);
  EXPECT_EQ(byte(24), 16) << "bit depth";
  EXPECT_EQ(byte(25), 0) << "colour type: grey";
  EXPECT_TRUE(stbi_is_16_bit_from_memory(reinterpret_cast<const unsigned char*>(png.data()), int(png.size())));
  // Without the field: the 8-bit grey PNG clients rely on.
  auto plain = client().Post("/api/depth", R"({"shadow": {"map_size": 128}})", "application/json");
  ASSERT_TRUE(plain);
  ASSERT_EQ(plain->status, 200);
  ASSERT_GE(plain->body.size(), 26u);
  EXPECT_EQ(int(static_cast<unsigned char>(plain->body[24])), 8);
  EXPECT_EQ(int(static_cast<unsigned char>(plain->body[25])), 0);
  // Any other output takes it and says it had no effect.
  auto color = client().Post("/api/render", R"({"width": 32, "height": 32, "depth_bits": 16})", "application/json");
  ASSERT_TRUE(color);
  EXPECT_EQ(color->status, 200);
  EXPECT_EQ(color->get_header_value("Umbra-Unused-Fields"), "depth_bits");
  expect_json_error(client().Post("/api/depth", R"({"depth_bits": 12})", "application/json"), 400, "depth_bits");
}

// A render slow enough on llvmpipe (about a second) to hold the queue: a
// wide kernel over a frame filled with the cube's shadow and its edges
// (far from any caster the filter is skipped).
const char* kSlowBody = R"({"width": 3072, "height": 3072, "output": "shadow", "shadow": {"pcf_radius": 8}, "camera": {"position": [0.5, 1.2, 1.5], "target": [0, 0, 0]}})";

TEST(Http, AFullQueueAnswers503WithRetryAfterAtOnce) {
  // A server of its own with room for one render.
  ServiceLimits limits;
  limits.queue_capacity = 1;
  RenderService renderer(limits);
  ServerOptions options;
  options.port = 0;
  options.log_requests = false;
  HttpApi api(renderer, options);
  ASSERT_TRUE(api.bind());
  std::thread server([&api] { api.serve(); });
  while (!api.serving()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  httplib::Client c("127.0.0.1", api.port());
  c.set_read_timeout(120, 0);

  int slow_status = 0;
  std::thread slow([&] {
    httplib::Client other("127.0.0.1", api.port());
    other.set_read_timeout(120, 0);
    auto res = other.Post("/api/render", kSlowBody, "application/json");
    slow_status = res ? res->status : -1;
  });
  while (renderer.queue_depth() == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  const auto start = std::chrono::steady_clock::now();
  auto res = c.Post("/api/render", R"({"width": 32, "height": 32})", "application/json");
  const double waited_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  const bool slow_still_running = renderer.queue_depth() == 1;
  slow.join();
  ASSERT_TRUE(res);
  if (slow_still_running) {  // else the machine was fast enough to finish first: nothing to judge
    EXPECT_EQ(res->status, 503);
    EXPECT_EQ(res->get_header_value("Retry-After"), "1");
    EXPECT_EQ(json::parse(res->body)["field"], "");
    EXPECT_LT(waited_ms, 500.0) << "refused at once, not after waiting";
    EXPECT_EQ(renderer.rejected(), 1u);
    auto health = json::parse(c.Get("/api/health")->body);
    EXPECT_EQ(health["rejected"], 1);
    EXPECT_EQ(health["queue_capacity"], 1);
  }
  EXPECT_EQ(slow_status, 200);
  // Room again: served.
  res = c.Post("/api/render", R"({"width": 32, "height": 32})", "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  api.stop();
  server.join();
}

// Sends `request` on a new connection and returns the socket, unread.
int send_raw(int port, const std::string& request) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(std::uint16_t(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  EXPECT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
  EXPECT_EQ(send(fd, request.data(), request.size(), 0), ssize_t(request.size()));
  return fd;
}

std::string post_request(const std::string& path, const std::string& body) {
  return "POST " + path + " HTTP/1.1\r\nHost: localhost\r\nContent-Type: application/json\r\nContent-Length: " +
         std::to_string(body.size()) + "\r\n\r\n" + body;
}

TEST(Http, AClientThatLeftBeforeItsTurnCostsNoRender) {
  RenderService& renderer = *ServerEnvironment::renderer;
  const std::uint64_t frames_before = renderer.frames_rendered();
  std::thread slow([] {
    auto res = client().Post("/api/render", kSlowBody, "application/json");
    EXPECT_TRUE(res && res->status == 200);
  });
  while (renderer.queue_depth() < 1) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  // Two clients queue behind it and hang up: one for a frame, one for an
  // "error" image (whose GL half waits its turn; its ray cast does not).
  const int gl_client = send_raw(ServerEnvironment::api->port(), post_request("/api/render", R"({"width": 64, "height": 64})"));
  const int cast_client = send_raw(ServerEnvironment::api->port(),
                                   post_request("/api/render", R"({"width": 64, "height": 64, "output": "error"})"));
  while (renderer.queue_depth() < 3) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  close(gl_client);
  close(cast_client);
  // Judged after the clients left: the slow render must end after that,
  // or the next job's turn (and its check) may come while they are there.
  const bool slow_still_running = renderer.frames_rendered() == frames_before;
  slow.join();
  while (renderer.queue_depth() > 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  if (!slow_still_running) GTEST_SKIP() << "the slow render finished before the clients left";
  EXPECT_EQ(renderer.abandoned(), 2u);
  EXPECT_EQ(renderer.frames_rendered(), frames_before + 1) << "only the slow render ran";
  EXPECT_EQ(json::parse(client().Get("/api/health")->body)["abandoned"], 2);
}

// Sends a whole request on its own connection and reads the whole answer
// (the request should say "Connection: close").
std::string raw_exchange(int port, const std::string& request) {
  const int fd = send_raw(port, request);
  std::string answer;
  char buffer[4096];
  for (ssize_t n; (n = recv(fd, buffer, sizeof buffer, 0)) > 0;) answer.append(buffer, std::size_t(n));
  close(fd);
  return answer;
}

int status_of(const std::string& answer) {
  return answer.size() > 12 && answer.rfind("HTTP/1.1 ", 0) == 0 ? std::atoi(answer.c_str() + 9) : -1;
}

std::string get_request(const std::string& target) {
  return "GET " + target + " HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n";
}

// A server of its own on the shared renderer, with other options.
struct OwnServer {
  explicit OwnServer(ServerOptions options) : api(*ServerEnvironment::renderer, prepared(std::move(options))) { start(); }
  OwnServer(ServerOptions options, ModelStore& models)
      : api(*ServerEnvironment::renderer, models, prepared(std::move(options))) {
    start();
  }
  void start() {
    EXPECT_TRUE(api.bind());
    thread = std::thread([this] { api.serve(); });
    while (!api.serving()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ~OwnServer() {
    api.stop();
    thread.join();
  }
  static ServerOptions prepared(ServerOptions o) {
    o.port = 0;
    o.log_requests = false;
    o.model_importer = UMBRA_MODEL_IMPORTER;
    return o;
  }
  HttpApi api;
  std::thread thread;
};

// Paths that try to leave the web folder, as a client could send them.
const char* const kEscapes[] = {"/../secret.txt", "/%2e%2e/secret.txt", "/%2E%2E%2Fsecret.txt", "/..%2fsecret.txt",
                                "/sub/../../secret.txt", "//etc/passwd", "/etc/passwd", "/link.txt",
                                "/sub/up/secret.txt", "/%00index.html", "/sub"};

TEST(Http, StaticFilesNeverLeaveTheWebFolder) {
  namespace fs = std::filesystem;
  const fs::path base = fs::temp_directory_path() / ("umbra-web-" + std::to_string(getpid()));
  fs::remove_all(base);
  fs::create_directories(base / "web" / "sub");
  std::ofstream(base / "web" / "index.html") << "<p>panel</p>";
  std::ofstream(base / "web" / "sub" / "inner.css") << "p{}";
  std::ofstream(base / "secret.txt") << "secret";
  fs::create_symlink(base / "secret.txt", base / "web" / "link.txt");
  fs::create_directory_symlink(base, base / "web" / "sub" / "up");
  fs::create_symlink(base / "web" / "index.html", base / "web" / "alias.html");
  {
    ServerOptions options;
    options.web_dir = (base / "web").string();
    OwnServer server(options);
    const int port = server.api.port();
    for (const char* path : {"/", "/index.html", "/sub/inner.css", "/alias.html"})
      EXPECT_EQ(status_of(raw_exchange(port, get_request(path))), 200) << path;
    for (const char* path : kEscapes) {
      const std::string answer = raw_exchange(port, get_request(path));
      EXPECT_EQ(status_of(answer), 404) << path;
      EXPECT_EQ(answer.find("secret\n"), std::string::npos) << path;
    }
  }
  fs::remove_all(base);
  // The embedded panel too.
  for (const char* path : kEscapes)
    EXPECT_EQ(status_of(raw_exchange(ServerEnvironment::api->port(), get_request(path))), 404) << path;
}

TEST(Http, ExplicitLimitsOnUriAndHeaders) {
  const int port = ServerEnvironment::api->port();
  const std::string long_uri = "/api/health?" + std::string(HttpApi::kMaxUriBytes, 'a');
  std::string answer = raw_exchange(port, get_request(long_uri));
  EXPECT_EQ(status_of(answer), 414);
  EXPECT_NE(answer.find("\"field\":\"\""), std::string::npos) << answer;
  std::string many = "GET /api/health HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n";
  for (std::size_t i = 0; i <= HttpApi::kMaxHeaderCount; ++i) many += "X-" + std::to_string(i) + ": 1\r\n";
  EXPECT_EQ(status_of(raw_exchange(port, many + "\r\n")), 431);
  std::string big = "GET /api/health HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n";
  for (int i = 0; i < 8; ++i) big += "X-" + std::to_string(i) + ": " + std::string(HttpApi::kMaxHeaderBytes / 8, 'b') + "\r\n";
  EXPECT_EQ(status_of(raw_exchange(port, big + "\r\n")), 431);
  // Still answering.
  EXPECT_EQ(status_of(raw_exchange(port, get_request("/api/health"))), 200);
}

TEST(Http, NoCorsUnlessAskedFor) {
  auto res = client().Get("/api/health");
  ASSERT_TRUE(res);
  EXPECT_FALSE(res->has_header("Access-Control-Allow-Origin"));
  const std::string preflight =
      "OPTIONS /api/render HTTP/1.1\r\nHost: localhost\r\nOrigin: https://elsewhere.example\r\n"
      "Access-Control-Request-Method: POST\r\nConnection: close\r\n\r\n";
  const std::string answer = raw_exchange(ServerEnvironment::api->port(), preflight);
  EXPECT_NE(status_of(answer), 204);
  EXPECT_EQ(answer.find("Access-Control-Allow-Origin"), std::string::npos);
}

TEST(Http, CorsForTheOneOriginGiven) {
  ServerOptions options;
  options.cors_origin = "https://app.example";
  OwnServer server(options);
  httplib::Client c("127.0.0.1", server.api.port());
  c.set_read_timeout(60, 0);
  auto ok = c.Post("/api/render", R"({"width": 16, "height": 16})", "application/json");
  auto bad = c.Post("/api/render", R"({"width": -1})", "application/json");
  ASSERT_TRUE(ok && bad);
  for (const auto* res : {&ok, &bad}) {
    EXPECT_EQ((*res)->get_header_value("Access-Control-Allow-Origin"), "https://app.example");
    EXPECT_NE((*res)->get_header_value("Access-Control-Expose-Headers").find("Server-Timing"), std::string::npos);
  }
  const std::string preflight =
      "OPTIONS /api/render HTTP/1.1\r\nHost: localhost\r\nOrigin: https://app.example\r\n"
      "Access-Control-Request-Method: POST\r\nAccess-Control-Request-Headers: content-type\r\n"
      "Connection: close\r\n\r\n";
  const std::string answer = raw_exchange(server.api.port(), preflight);
  EXPECT_EQ(status_of(answer), 204) << answer;
  EXPECT_NE(answer.find("Access-Control-Allow-Methods: GET, POST"), std::string::npos) << answer;
  EXPECT_NE(answer.find("Access-Control-Allow-Headers: Content-Type"), std::string::npos) << answer;
}

TEST(Http, CorsOriginsAreChecked) {
  for (const char* good : {"*", "https://app.example", "http://localhost:3000", "http://[::1]:8080"})
    EXPECT_TRUE(valid_cors_origin(good)) << good;
  for (const char* bad : {"", "app.example", "https://", "https://a.example/path", "ftp://a.example",
                          "https://a.example\r\nX-Evil: 1", "https://a b"})
    EXPECT_FALSE(valid_cors_origin(bad)) << bad;
}

// Hostile bodies: every one gets its 4xx with a JSON error, and the server
// keeps answering.
TEST(Http, HostileBodiesGetTheRight4xxAndTheServerStaysUp) {
  struct Case {
    std::string name, body;
    int status;
    const char* field;  // nullptr: any
  };
  std::vector<Case> cases;
  const std::string full =
      R"({"width": 64, "height": 48, "light": {"color": [1, 0.5, 0.25], "position": [-2, 4, -1]}, "shadow": {"filter": "pcf"}})";
  // (An empty body is all defaults, like {}: not truncated.)
  for (std::size_t n = 1; n < full.size(); n += 7)
    cases.push_back({"truncated at " + std::to_string(n), full.substr(0, n), 400, nullptr});
  cases.push_back({"10000-deep arrays", "{\"width\": " + std::string(10000, '[') + std::string(10000, ']') + "}", 400, nullptr});
  std::string deep_objects;
  for (int i = 0; i < 10000; ++i) deep_objects += "{\"a\": ";
  cases.push_back({"10000-deep objects", deep_objects + "1" + std::string(10000, '}'), 400, nullptr});
  cases.push_back({"a million unclosed arrays", std::string(1000000, '['), 400, nullptr});
  cases.push_back({"10^400", R"({"width": 1e400})", 400, "width"});
  cases.push_back({"-10^400", R"({"camera": {"position": [0, -1e400, 5]}})", 400, "camera.position[1]"});
  cases.push_back({"NaN string", R"({"width": "NaN"})", 400, "width"});
  cases.push_back({"NaN string in a colour", R"({"light": {"color": ["NaN", 0, 0]}})", 400, "light.color[0]"});
  cases.push_back({"bare NaN", R"({"time": NaN})", 400, "time"});
  cases.push_back({"Infinity string", R"({"time": "Infinity"})", 400, "time"});
  std::string million = R"({"scene": {"objects": [)";
  for (int i = 0; i < 1000000; ++i) million += i ? ",{}" : "{}";
  cases.push_back({"10^6 objects (3 MB)", million + "]}}", 413, ""});
  std::string many = R"({"scene": {"objects": [)";
  for (int i = 0; i < 300000; ++i) many += i ? ",{}" : "{}";
  cases.push_back({"300000 objects (under 1 MiB)", many + "]}}", 400, "scene.objects"});
  cases.push_back({"invalid UTF-8", "{\"scene\": \"\xff\xfe\"}", 400, "scene"});
  cases.push_back({"overlong UTF-8", "{\"scene\": \"\xc0\xaf\"}", 400, "scene"});
  cases.push_back({"lone surrogate", R"({"scene": "\ud800"})", 400, "scene"});
  cases.push_back({"invalid UTF-8 key", "{\"w\xff\": 1}", 400, nullptr});
  cases.push_back({"2 MiB body", "{\"scene\": \"" + std::string(2 << 20, 'x') + "\"}", 413, ""});
  for (const char* not_object : {"null", "[]", "42", "\"text\"", "true"})
    cases.push_back({std::string("top level ") + not_object, not_object, 400, ""});
  cases.push_back({"huge integer", R"({"width": 1000000000000000000000})", 400, "width"});
  cases.push_back({"fractional width", R"({"width": 16.5})", 400, "width"});
  std::string keys = "{";
  for (int i = 0; i < 50000; ++i) keys += (i ? ",\"k" : "\"k") + std::to_string(i) + "\": 0";
  cases.push_back({"50000 unknown keys", keys + "}", 400, nullptr});
  cases.push_back({"NUL in a string", std::string("{\"scene\": \"a\0b\"}", 17), 400, "scene"});

  httplib::Client c = client();
  for (const Case& k : cases) {
    auto res = c.Post("/api/render", k.body, "application/json");
    ASSERT_TRUE(res) << k.name << ": no answer";
    EXPECT_EQ(res->status, k.status) << k.name << ": " << res->body.substr(0, 200);
    const json error = json::parse(res->body, nullptr, false);
    ASSERT_TRUE(error.is_object()) << k.name << ": " << res->body.substr(0, 200);
    EXPECT_TRUE(error.contains("error") && error.contains("field")) << k.name;
    if (k.field) {
      EXPECT_EQ(error["field"], k.field) << k.name << ": " << res->body;
    }
    ASSERT_EQ(client().Get("/api/health")->status, 200) << "after " << k.name;
  }
  auto frame = c.Post("/api/render", full, "application/json");
  ASSERT_TRUE(frame);
  EXPECT_EQ(frame->status, 200);
}

TEST(Http, TheLargestRequestTheApiAllowsIsRenderedWhole) {
  // docs/api.md allows width and height up to 4096 and map_size up to 8192 each,
  // so all three at once is a valid request, not a hostile one: it is
  // rendered (the map layers are capped at 4 x 8192^2 texels in all).
  auto res = client().Post("/api/render", R"({"width": 4096, "height": 4096, "shadow": {"map_size": 8192}})",
                           "application/json");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  const Decoded d = decode_png(res->body);
  EXPECT_EQ(d.width, 4096);
  EXPECT_EQ(d.height, 4096);
  EXPECT_EQ(client().Get("/api/health")->status, 200);
}

TEST(Http, ARequestOverTheCostBudgetIs422AtOnceNamingWhatToLower) {
  // Issue 11's 109 KB request: 999 overlapping spheres, map 8192, 4
  // cascades, PCF radius 8, 4096^2. It held the GL thread for 142 s.
  json objects = json::array();
  for (int i = 0; i < 999; ++i)
    objects.push_back({{"type", "sphere"},
                       {"center", {(i * 37 % 10) * 0.4 - 2.0, (i * 53 % 10) * 0.4 - 2.0, (i * 71 % 10) * 0.4 - 2.0}},
                       {"radius", 1.0}});
  const json body = {{"width", 4096}, {"height", 4096}, {"scene", {{"objects", objects}}},
                     {"shadow", {{"map_size", 8192}, {"cascades", 4}, {"pcf_radius", 8}}}};
  const std::uint64_t frames_before = ServerEnvironment::renderer->frames_rendered();
  const auto start = std::chrono::steady_clock::now();
  auto res = client().Post("/api/render", body.dump(), "application/json");
  const double waited_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  expect_json_error(res, 422, "shadow.map_size");
  EXPECT_LT(waited_ms, 1000.0);
  const std::string message = json::parse(res->body)["error"];
  EXPECT_NE(message.find("shadow-map fill"), std::string::npos) << message;
  EXPECT_NE(message.find("budget of 4000 ms"), std::string::npos) << message;
  EXPECT_EQ(ServerEnvironment::renderer->frames_rendered(), frames_before);
  // The same scene within the budget renders.
  const json small = {{"width", 64}, {"height", 64}, {"scene", {{"objects", objects}}}, {"shadow", {{"map_size", 256}}}};
  res = client().Post("/api/render", small.dump(), "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200) << res->body;
}

TEST(Http, ABodyOver8KiBIsTakenWhateverItsContentType) {
  // curl -d sends application/x-www-form-urlencoded; cpp-httplib alone
  // would refuse such a body above 8 KiB (413) and parse it as a form.
  json objects = json::array({{{"type", "plane"}, {"center", {0, 0, 0}}, {"size", {20, 20}}}});
  for (int i = 0; i < 300; ++i)
    objects.push_back({{"type", "sphere"}, {"center", {i % 20 - 10.0, 0.5, i / 20 - 7.0}}, {"radius", 0.3}});
  const std::string body =
      json{{"width", 64}, {"height", 48}, {"shadow", {{"map_size", 256}}}, {"scene", {{"objects", objects}}}}.dump();
  ASSERT_GT(body.size(), 8u << 10);
  for (const char* type : {"application/x-www-form-urlencoded", "application/json", "text/plain"}) {
    auto res = client().Post("/api/render", body, type);
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 200) << type << ": " << res->body;
  }
}

TEST(Http, TheShadowLayoutIsReported) {
  auto res = client().Post("/api/render", R"({"width": 32, "height": 32, "shadow": {"map_size": 256, "cascades": 3}})",
                           "application/json");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200);
  EXPECT_EQ(res->get_header_value("Umbra-Shadow-Views"), "cascades; views=3; size=256");
  res = client().Post("/api/render", R"({"width": 32, "height": 32, "shadow": {"map_size": 256},
                                          "light": {"projection": "perspective", "position": [0, 2, 0]}})",
                      "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->get_header_value("Umbra-Shadow-Views"), "cube; views=6; size=256");
  res = client().Post("/api/render", R"({"width": 32, "height": 32, "shadow": {"enabled": false}})", "application/json");
  ASSERT_TRUE(res);
  EXPECT_FALSE(res->has_header("Umbra-Shadow-Views"));
}

// The "shadow" entry of a Server-Timing header, in milliseconds.
double shadow_duration(const std::string& server_timing) {
  const std::string key = "shadow;dur=";
  const std::size_t at = server_timing.find(key);
  EXPECT_NE(at, std::string::npos) << server_timing;
  return at == std::string::npos ? -1.0 : std::stod(server_timing.substr(at + key.size()));
}

TEST(Http, ACameraOnlyChangeSkipsTheShadowPass) {
  httplib::Client c = client();
  const std::string light = R"("light": {"projection": "perspective", "position": [-1, 5, 2]})";
  auto first = c.Post("/api/render", R"({"width": 64, "height": 48, )" + light + "}", "application/json");
  ASSERT_TRUE(first);
  ASSERT_EQ(first->status, 200);
  const auto hits_before = json::parse(c.Get("/api/health")->body)["shadow_cache_hits"].get<std::uint64_t>();
  auto moved = c.Post("/api/render", R"({"width": 64, "height": 48, "camera": {"position": [4, 4, 7]}, )" + light + "}",
                      "application/json");
  ASSERT_TRUE(moved);
  ASSERT_EQ(moved->status, 200);
  EXPECT_EQ(shadow_duration(moved->get_header_value("Server-Timing")), 0.0);
  const auto hits_after = json::parse(c.Get("/api/health")->body)["shadow_cache_hits"].get<std::uint64_t>();
  EXPECT_EQ(hits_after, hits_before + 1);
  // The light moved: a new shadow pass.
  auto relit = c.Post("/api/render", R"({"width": 64, "height": 48, "light": {"projection": "perspective", "position": [1, 5, 2]}})",
                      "application/json");
  ASSERT_TRUE(relit);
  EXPECT_GT(shadow_duration(relit->get_header_value("Server-Timing")), 0.0);
}

// What Umbra-Sun should say for a sun at Paris, `seconds` after `utc`.
std::string paris_sun_header(double utc_unix_s) { return format_sun_angles(solar_position(48.85, 2.35, utc_unix_s)); }

TEST(Http, ASunLightSaysWhereTheSunStoodOnEveryImage) {
  const std::string sun = R"("sun": {"latitude": 48.85, "longitude": 2.35, "utc": "2026-12-21T14:00:00Z"})";
  const double afternoon = 1797861600.0;  // 2026-12-21T14:00:00Z
  auto res = client().Post("/api/render", R"({"width": 32, "height": 32, "light": {)" + sun + "}}", "application/json");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  const std::string header = res->get_header_value("Umbra-Sun");
  EXPECT_TRUE(std::regex_match(header, std::regex(R"(azimuth_deg=\d{1,3}\.\d{4}; elevation_deg=-?\d{1,2}\.\d{4})"))) << header;
  EXPECT_EQ(header, paris_sun_header(afternoon));
  // time advances the clock; the depth map carries it too.
  res = client().Post("/api/depth", R"({"time": 5400, "shadow": {"map_size": 64}, "light": {)" + sun + "}}",
                      "application/json");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(res->get_header_value("Umbra-Sun"), paris_sun_header(afternoon + 5400));
  // At night: a frame of ambient light only, with no shadow pass.
  res = client().Post("/api/render", R"({"width": 32, "height": 32, "time": 32400, "light": {)" + sun + "}}",
                      "application/json");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  EXPECT_NE(res->get_header_value("Umbra-Sun").find("elevation_deg=-"), std::string::npos) << res->get_header_value("Umbra-Sun");
  EXPECT_FALSE(res->has_header("Umbra-Shadow-Views"));
  // An orbiting light has no sun to report.
  res = client().Post("/api/render", R"({"width": 32, "height": 32})", "application/json");
  ASSERT_TRUE(res);
  EXPECT_FALSE(res->has_header("Umbra-Sun"));
  expect_json_error(client().Post("/api/render", R"({"light": {"sun": {"latitude": 48.85, "longitude": 2.35, "utc": "21/12/2026"}}})",
                                  "application/json"),
                    400, "light.sun.utc");
}

TEST(Http, UnusedFieldsAreReportedNotIgnored) {
  auto res = client().Post("/api/render", R"({"width": 32, "height": 32, "shadow": {"near": 2}})", "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_EQ(res->get_header_value("Umbra-Unused-Fields"), "shadow.near");
  // /api/depth draws the depth map, which the ambient light does not shape, though the body names no output.
  auto depth = client().Post("/api/depth", R"({"shadow": {"map_size": 64}, "light": {"ambient": 0.5}})", "application/json");
  ASSERT_TRUE(depth);
  EXPECT_EQ(depth->status, 200) << depth->body;
  EXPECT_EQ(depth->get_header_value("Umbra-Unused-Fields"), "light.ambient");
}

TEST(Http, BadBodiesAre400WithTheField) {
  expect_json_error(client().Post("/api/render", "{", "application/json"), 400, "");
  expect_json_error(client().Post("/api/render", R"({"width": "wide"})", "application/json"), 400, "width");
  expect_json_error(client().Post("/api/render", R"({"light": {"color": [1, NaN, 1]}})", "application/json"), 400,
                    "light.color[1]");
  expect_json_error(client().Post("/api/render", R"({"scene": "nowhere"})", "application/json"), 400, "scene");
  expect_json_error(client().Post("/api/render", R"({"camera": {"position": [0,0,0], "target": [0,0,0]}})", "application/json"),
                    400, "camera.position");
  expect_json_error(client().Post("/api/depth", R"({"bogus": 1})", "application/json"), 400, "bogus");
}

TEST(Http, UnknownPathIs404AndWrongMethodIs405) {
  expect_json_error(client().Get("/api/nothing"), 404, "");
  expect_json_error(client().Post("/api/nothing", "{}", "application/json"), 404, "");
  auto get_render = client().Get("/api/render");
  expect_json_error(get_render, 405, "");
  EXPECT_EQ(get_render->get_header_value("Allow"), "POST");
  expect_json_error(client().Post("/api/health", "{}", "application/json"), 405, "");
  expect_json_error(client().Delete("/api/scenes"), 405, "");
  expect_json_error(client().Put("/api/depth", "{}", "application/json"), 405, "");
  // The panel's files are known paths too; a path that is no file stays 404.
  for (const char* path : {"/", "/index.html", "/app.js"}) {
    auto post = client().Post(path, "{}", "application/json");
    expect_json_error(post, 405, "");
    EXPECT_EQ(post->get_header_value("Allow"), "GET") << path;
  }
  expect_json_error(client().Post("/no-such-file.html", "{}", "application/json"), 404, "");
}

// POST /api/sun-hours: hours per grid point, as JSON or CSV by Accept.
json sun_hours_body() {
  return {{"scene", "cube-on-plane"},
          {"site", {{"latitude", 51.5}, {"longitude", -0.12}}},
          {"period", {{"start", "2026-03-21T00:00:00Z"}, {"end", "2026-03-22T00:00:00Z"}, {"step_minutes", 10}}},
          {"grid", {{"center", {0, -0.49, 0}}, {"size", {4, 4}}, {"spacing", 0.5}}},
          {"require_hours", 2}};
}

TEST(Http, SunHoursAnswersJsonOrCsvByAccept) {
  auto res = client().Post("/api/sun-hours", sun_hours_body().dump(), "application/json");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(res->get_header_value("Content-Type"), "application/json");
  EXPECT_NE(res->get_header_value("Server-Timing").find("sun_hours;dur="), std::string::npos);
  const std::string share = res->get_header_value("Umbra-Sun-Hours");
  EXPECT_EQ(share.rfind("path=", 0), 0u) << share;
  const json answer = json::parse(res->body);
  ASSERT_EQ(answer["hours"].size(), 64u);
  EXPECT_EQ(answer["grid"]["columns"], 8);
  EXPECT_EQ(answer["samples_count"], 144);
  EXPECT_EQ(answer["pairs"], 64 * answer["samples_up"].get<int>());
  EXPECT_EQ(answer["pairs_by_maps"].get<std::uint64_t>() + answer["pairs_ray_cast"].get<std::uint64_t>(),
            answer["pairs"].get<std::uint64_t>());
  EXPECT_EQ(answer["exact"], true);
  // The four points inside the cube never see the sun; the row south of it always does.
  EXPECT_EQ(answer["hours"][3 * 8 + 3], 0.0);
  EXPECT_DOUBLE_EQ(answer["hours"][63].get<double>(), answer["samples_up"].get<int>() * 10.0 / 60.0);
  EXPECT_GT(answer["pass_share"].get<double>(), 0.5);
  EXPECT_LT(answer["pass_share"].get<double>(), 1.0);

  httplib::Headers csv_accept = {{"Accept", "text/csv"}};
  auto csv = client().Post("/api/sun-hours", csv_accept, sun_hours_body().dump(), "application/json");
  ASSERT_TRUE(csv);
  ASSERT_EQ(csv->status, 200) << csv->body;
  EXPECT_EQ(csv->get_header_value("Content-Type"), "text/csv; charset=utf-8");
  EXPECT_EQ(csv->body.rfind("x,y,z,hours,longest_run_hours\n", 0), 0u);
  EXPECT_EQ(std::count(csv->body.begin(), csv->body.end(), '\n'), 65);

  httplib::Headers xml_accept = {{"Accept", "application/xml"}};
  expect_json_error(client().Post("/api/sun-hours", xml_accept, sun_hours_body().dump(), "application/json"), 406, "");
  // The picture: the camera's view coloured by hours; no grid needed.
  json picture_body = sun_hours_body();
  picture_body.erase("grid");
  picture_body["width"] = 320;
  picture_body["height"] = 180;
  httplib::Headers png_accept = {{"Accept", "image/png"}};
  auto png = client().Post("/api/sun-hours", png_accept, picture_body.dump(), "application/json");
  ASSERT_TRUE(png);
  ASSERT_EQ(png->status, 200) << png->body;
  EXPECT_EQ(png->get_header_value("Content-Type"), "image/png");
  const Decoded decoded = decode_png(png->body);
  EXPECT_EQ(decoded.width, 320);
  EXPECT_EQ(decoded.height, 180);
  EXPECT_EQ(decoded.channels, 3);
  // Without a grid there is nothing to answer as JSON; the picture's fields
  // are reported unused there.
  expect_json_error(client().Post("/api/sun-hours", picture_body.dump(), "application/json"), 400, "grid");
  picture_body["grid"] = sun_hours_body()["grid"];
  auto unused = client().Post("/api/sun-hours", picture_body.dump(), "application/json");
  ASSERT_TRUE(unused);
  EXPECT_EQ(unused->status, 200);
  EXPECT_EQ(unused->get_header_value("Umbra-Unused-Fields"), "height, width");
  // An object's colour changes no answer (the picture colours by hours).
  json coloured = sun_hours_body();
  coloured["scene"] = json::parse(R"({"objects": [{"type": "box", "center": [0, 0.5, 0]},
      {"type": "sphere", "center": [3, 1, 0], "color": "#ff0000"}]})");
  auto colour = client().Post("/api/sun-hours", coloured.dump(), "application/json");
  ASSERT_TRUE(colour);
  EXPECT_EQ(colour->status, 200) << colour->body;
  EXPECT_EQ(colour->get_header_value("Umbra-Unused-Fields"), "scene.objects[1].color");
  auto get = client().Get("/api/sun-hours");
  expect_json_error(get, 405, "");
  EXPECT_EQ(get->get_header_value("Allow"), "POST");
}

// A year of half-minute steps over 2048 x 2048 points under a roof of 20 x
// 20 tiles: every pair is proved dark by the tiles' cores, but the walk
// draws 800 hulls and crosses 60,000 rows of their shadows a sample, a
// million samples: far over any budget (a roof of one box is not: its
// points are touched at sunrise and sunset only).
json roofed_year_body() {
  json body = sun_hours_body();
  json tiles = json::array();
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j)
      tiles.push_back({{"type", "box"}, {"center", {-1425 + 150 * i, 5, -1425 + 150 * j}}, {"size", {150, 1, 150}}});
  body["scene"] = {{"objects", tiles}};
  body["period"] = {{"start", "2026-01-01T00:00:00Z"}, {"end", "2027-01-01T00:00:00Z"}, {"step_minutes", 0.5}};
  body["grid"] = {{"center", {0, 0, 0}}, {"size", {2048, 2048}}, {"spacing", 1}};
  return body;
}

TEST(Http, SunHoursRefusesBadInputNamingTheFieldOrTheCost) {
  json body = sun_hours_body();
  body["period"]["end"] = "2026-03-20T00:00:00Z";
  expect_json_error(client().Post("/api/sun-hours", body.dump(), "application/json"), 400, "period.end");
  body = sun_hours_body();
  body["period"]["step_minutes"] = 0;
  expect_json_error(client().Post("/api/sun-hours", body.dump(), "application/json"), 400, "period.step_minutes");
  body = sun_hours_body();  // 10^9 samples
  body["period"] = {{"start", "2026-01-01T00:00:00Z"}, {"end", "3926-01-01T00:00:00Z"}, {"step_minutes", 1}};
  expect_json_error(client().Post("/api/sun-hours", body.dump(), "application/json"), 400, "period.step_minutes");
  body = sun_hours_body();  // 10^12 points
  body["grid"] = {{"size", {1e6, 1e6}}, {"spacing", 1}};
  expect_json_error(client().Post("/api/sun-hours", body.dump(), "application/json"), 400, "grid.spacing");
  body = sun_hours_body();
  body["scene"] = {{"objects", {{{"type", "pyramid"}}}}};
  expect_json_error(client().Post("/api/sun-hours", body.dump(), "application/json"), 400, "scene.objects[0].type");
  // Valid, but a year of half-minute steps over four million points under
  // a roof of 400 tiles that shades them all: refused at once, naming what
  // to lower.
  body = roofed_year_body();
  const auto start = std::chrono::steady_clock::now();
  auto res = client().Post("/api/sun-hours", body.dump(), "application/json");
  expect_json_error(res, 422, "grid.spacing");
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 2.0);
  // The roof's core proves every pair dark without a ray: what costs is
  // the footprints' walk over four million points a sample.
  EXPECT_NE(json::parse(res->body)["error"].get<std::string>().find("sun-hours footprints"), std::string::npos)
      << res->body;
  // A roof that is a plane has no core: every pair under it is a ray.
  body["scene"] = json::parse(R"({"objects": [{"type": "plane", "center": [0, 5, 0], "size": [3000, 3000]}]})");
  res = client().Post("/api/sun-hours", body.dump(), "application/json");
  expect_json_error(res, 422, "grid.spacing");
  EXPECT_NE(json::parse(res->body)["error"].get<std::string>().find("sun-hours rays"), std::string::npos) << res->body;
}

// Over --max-request-ms, a sun-hours analysis runs as a job: 202, progress,
// then the very answer the synchronous route gives; DELETE cancels.
TEST(Http, ASunHoursJobGivesProgressThenTheSameAnswer) {
  ServiceLimits limits;
  limits.max_request_cost = std::chrono::milliseconds(1);  // every analysis is a job
  RenderService renderer(limits);
  ServerOptions options;
  options.port = 0;
  options.log_requests = false;
  options.name = "r7";
  HttpApi api(renderer, options);
  ASSERT_TRUE(api.bind());
  std::thread server([&api] { api.serve(); });
  while (!api.serving()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  httplib::Client c("127.0.0.1", api.port());
  c.set_read_timeout(120, 0);

  json body = sun_hours_body();
  body["grid"] = {{"center", {0, -0.49, 0}}, {"size", {8, 8}}, {"spacing", 0.05}};
  auto posted = c.Post("/api/sun-hours", body.dump(), "application/json");
  ASSERT_TRUE(posted);
  ASSERT_EQ(posted->status, 202) << posted->body;
  const json accepted = json::parse(posted->body);
  const std::string id = accepted["job"];
  EXPECT_EQ(id.rfind("r7.", 0), 0u) << id;
  EXPECT_EQ(posted->get_header_value("Location"), "/api/sun-hours/jobs/" + id);
  EXPECT_EQ(accepted["location"], "/api/sun-hours/jobs/" + id);
  int status = 0;
  std::string done_body;
  for (int tries = 0;; ++tries) {
    auto done = c.Get("/api/sun-hours/jobs/" + id);
    ASSERT_TRUE(done);
    status = done->status;
    done_body = done->body;
    if (done->status != 202) break;
    const json progress = json::parse(done->body);
    EXPECT_TRUE(progress["state"] == "queued" || progress["state"] == "running") << done->body;
    EXPECT_GE(progress["fraction_done"].get<double>(), 0.0);
    EXPECT_LE(progress["fraction_done"].get<double>(), 1.0);
    EXPECT_EQ(done->get_header_value("Retry-After"), "1");
    ASSERT_LT(tries, 1200);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_EQ(status, 200) << done_body;
  // The same body, answered at once by the shared server (default budget).
  auto direct = client().Post("/api/sun-hours", body.dump(), "application/json");
  ASSERT_TRUE(direct);
  ASSERT_EQ(direct->status, 200) << direct->body;
  EXPECT_EQ(json::parse(done_body)["hours"], json::parse(direct->body)["hours"]);
  EXPECT_EQ(json::parse(done_body)["longest_run_hours"], json::parse(direct->body)["longest_run_hours"]);
  // Fetched again (its answer kept encoded: the same bytes), as CSV (the
  // kept answer changes format), and as JSON again; then removed.
  auto again = c.Get("/api/sun-hours/jobs/" + id);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->body, done_body);
  httplib::Headers csv_accept = {{"Accept", "text/csv"}};
  auto csv = c.Get("/api/sun-hours/jobs/" + id, csv_accept);
  ASSERT_TRUE(csv);
  EXPECT_EQ(csv->status, 200);
  EXPECT_EQ(csv->get_header_value("Content-Type"), "text/csv; charset=utf-8");
  auto json_again = c.Get("/api/sun-hours/jobs/" + id);
  ASSERT_TRUE(json_again);
  EXPECT_EQ(json_again->body, done_body);
  EXPECT_EQ(std::count(csv->body.begin(), csv->body.end(), '\n'), 160 * 160 + 1);
  // The picture is passed over for a grid job: the best of JSON and CSV,
  // and a malformed weight (q=nan, which once chose the picture: 500) is 0.
  httplib::Headers png_first = {{"Accept", "image/png, text/csv;q=0.5"}};
  auto passed_over = c.Get("/api/sun-hours/jobs/" + id, png_first);
  ASSERT_TRUE(passed_over);
  EXPECT_EQ(passed_over->status, 200);
  EXPECT_EQ(passed_over->get_header_value("Content-Type"), "text/csv; charset=utf-8");
  httplib::Headers nan_weight = {{"Accept", "image/png;q=nan, application/json;q=nan"}};
  expect_json_error(c.Get("/api/sun-hours/jobs/" + id, nan_weight), 406, "");
  auto removed = c.Delete("/api/sun-hours/jobs/" + id);
  ASSERT_TRUE(removed);
  EXPECT_EQ(json::parse(removed->body)["state"], "removed");
  expect_json_error(c.Get("/api/sun-hours/jobs/" + id), 404, "");
  expect_json_error(c.Get("/api/sun-hours/jobs/nonesuch"), 404, "");
  expect_json_error(c.Delete("/api/sun-hours/jobs/nonesuch"), 404, "");

  // A long job (a month of minutes: a day's was done within 200 ms on a
  // quiet machine, and the second job was already running) and one
  // waiting behind it: both cancelled at once.
  body = sun_hours_body();
  body["scene"] = "three-cubes";
  body["period"] = {{"start", "2026-03-01T00:00:00Z"}, {"end", "2026-03-31T00:00:00Z"}, {"step_minutes", 1}};
  body["grid"] = {{"center", {0, 0.01, 0}}, {"size", {20, 20}}, {"spacing", 0.02}};
  const std::string first = json::parse(c.Post("/api/sun-hours", body.dump(), "application/json")->body)["job"];
  const std::string second = json::parse(c.Post("/api/sun-hours", body.dump(), "application/json")->body)["job"];
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  auto waiting = c.Get("/api/sun-hours/jobs/" + second);
  ASSERT_TRUE(waiting);
  if (waiting->status == 202) {  // else the machine finished both already: nothing to cancel
    EXPECT_EQ(json::parse(waiting->body)["state"], "queued") << waiting->body;
    // Only the running job holds a place in the queue: jobs waiting leave
    // it to renders (sixteen of them once filled it: renders got 503).
    EXPECT_LE(renderer.queue_depth(), 1u);
    const auto start = std::chrono::steady_clock::now();
    EXPECT_EQ(json::parse(c.Delete("/api/sun-hours/jobs/" + second)->body)["state"], "cancelled");
    EXPECT_EQ(c.Delete("/api/sun-hours/jobs/" + first)->status, 200);
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 2.0);
    // The cores are free again: a new job runs at once.
    for (int tries = 0; renderer.queue_depth() > 0; ++tries) {
      ASSERT_LT(tries, 200) << "the cancelled jobs still hold the queue";
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  // Over --max-job-ms: 422, as a request over the budget is.
  body = roofed_year_body();
  auto refused = c.Post("/api/sun-hours", body.dump(), "application/json");
  expect_json_error(refused, 422, "grid.spacing");
  EXPECT_NE(refused->body.find("--max-job-ms"), std::string::npos) << refused->body;
  api.stop();
  server.join();
}

// Three turned cubes over a million points, every minute from `start` to
// `end`: a job that runs for seconds at least.
ParsedSunHours long_sun_hours_job(const std::string& start, const std::string& end) {
  json body = sun_hours_body();
  body["scene"] = "three-cubes";
  body["period"] = {{"start", start}, {"end", end}, {"step_minutes", 1}};
  body["grid"] = {{"center", {0, 0.01, 0}}, {"size", {20, 20}}, {"spacing", 0.02}};
  return parse_sun_hours_request(body.dump());
}

// Sun-hours jobs waiting for their turn hold no place in the queue: four
// long jobs on a queue of two leave room for a request beside the running
// one (jobs waiting once took a place each, and renders got 503).
TEST(Http, WaitingSunHoursJobsLeaveTheQueueToOthers) {
  ServiceLimits limits;
  limits.queue_capacity = 2;
  RenderService renderer(limits);
  // Long jobs: a month of minutes (a day's took 0.4 s once the footprints
  // lost their spare cells, and the first was done before the cancel).
  const ParsedSunHours long_job = long_sun_hours_job("2026-03-01T00:00:00Z", "2026-03-31T00:00:00Z");
  ASSERT_TRUE(long_job.ok()) << long_job.error.message;
  std::vector<std::shared_ptr<SunHoursProgress>> progress;
  std::vector<std::future<SunHoursResult>> jobs;
  for (int i = 0; i < 4; ++i) {
    progress.push_back(std::make_shared<SunHoursProgress>());
    jobs.push_back(renderer.submit_sun_hours(*long_job.request, {}, true, progress.back()));
  }
  while (!progress[0]->started) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_EQ(renderer.queue_depth(), 1u);
  const ParsedSunHours small = parse_sun_hours_request(sun_hours_body().dump());
  ASSERT_TRUE(small.ok());
  std::future<SunHoursResult> beside;
  ASSERT_NO_THROW(beside = renderer.submit_sun_hours(*small.request));
  EXPECT_EQ(beside.get().tally.size(), small.request->grid.points());
  for (auto& p : progress) p->cancel = true;
  // The running job is cancelled if it still runs (on a busy machine it
  // may have finished: once, beside a build on the same cores, it had);
  // those waiting never ran.
  try {
    EXPECT_EQ(jobs[0].get().tally.size(), long_job.request->grid.points());
  } catch (const ClientGone&) {
  }
  for (std::size_t j = 1; j < jobs.size(); ++j) EXPECT_THROW(jobs[j].get(), ClientGone) << "job " << j;
  EXPECT_EQ(renderer.queue_depth(), 0u);
}

// Jobs take their turns in the order they were submitted, whatever order
// their threads start in (each thread polling one mutex let any in first).
TEST(Http, SunHoursJobsRunInTheOrderSubmitted) {
  RenderService renderer;
  // Jobs far longer than the polling below: a year of minutes over a
  // million points (each is cancelled as soon as it starts).
  const ParsedSunHours long_job = long_sun_hours_job("2026-01-01T00:00:00Z", "2027-01-01T00:00:00Z");
  ASSERT_TRUE(long_job.ok()) << long_job.error.message;
  for (int round = 0; round < 3; ++round) {
    std::vector<std::shared_ptr<SunHoursProgress>> progress;
    std::vector<std::future<SunHoursResult>> jobs;
    for (int i = 0; i < 6; ++i) {
      progress.push_back(std::make_shared<SunHoursProgress>());
      jobs.push_back(renderer.submit_sun_hours(*long_job.request, {}, true, progress.back()));
    }
    for (std::size_t next = 0; next < jobs.size(); ++next) {
      while (!progress[next]->started) std::this_thread::sleep_for(std::chrono::milliseconds(2));
      for (std::size_t later = next + 1; later < jobs.size(); ++later)
        EXPECT_FALSE(progress[later]->started) << "job " << later << " ran before job " << next;
      progress[next]->cancel = true;
      EXPECT_THROW(jobs[next].get(), ClientGone) << "job " << next;
    }
  }
  EXPECT_EQ(renderer.queue_depth(), 0u);
}

TEST(Http, BodyOverOneMebibyteIs413) {
  const std::string body = R"({"scene": ")" + std::string((1 << 20) + 10, 'x') + R"("})";
  expect_json_error(client().Post("/api/render", body, "application/json"), 413, "");
  // And the server still answers.
  auto res = client().Get("/api/health");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
}

// Sends `request` and reads the answer until the server closes or `seconds`
// pass; the time taken goes to `waited_ms`.
std::string timed_exchange(int port, const std::string& request, double& waited_ms, int seconds = 5) {
  const auto start = std::chrono::steady_clock::now();
  const int fd = send_raw(port, request);
  timeval timeout{seconds, 0};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  std::string answer;
  char buffer[4096];
  for (ssize_t n; (n = recv(fd, buffer, sizeof buffer, 0)) > 0;) answer.append(buffer, std::size_t(n));
  close(fd);
  waited_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return answer;
}

std::string body_of(const std::string& answer) {
  const std::size_t at = answer.find("\r\n\r\n");
  return at == std::string::npos ? "" : answer.substr(at + 4);
}

TEST(Http, AMalformedContentLengthIs400AtOnceAndCloses) {
  // RFC 9112 §6.3: the body's length is unknown, so the connection cannot
  // carry another request. Each is answered without waiting for a body, and
  // the connection is closed (the read ends well before its 5 s timeout).
  // (An empty "Content-Length:" is not here: cpp-httplib drops a header line
  // with an empty value before Umbra sees it, so it reads as no body.)
  const char* const framings[] = {
      "Content-Length: 0x10\r\n",  // was read as 0: the body ignored, the default frame rendered
      "Content-Length: -1\r\n",    // was read as 2^64 - 1: a 413 after the 10 s read timeout
      "Content-Length: 1e3\r\n",
      "Content-Length: 16\r\nContent-Length: 2\r\n",  // was: the first one taken
      "Content-Length: 2\r\nTransfer-Encoding: chunked\r\n",
      "Transfer-Encoding: gzip\r\n",
  };
  const int port = ServerEnvironment::api->port();
  for (const char* framing : framings) {
    double waited_ms = 0;
    const std::string answer = timed_exchange(
        port, std::string("POST /api/render HTTP/1.1\r\nHost: localhost\r\n") + framing + "\r\n{\"width\": 16}", waited_ms);
    EXPECT_EQ(status_of(answer), 400) << framing << answer.substr(0, 300);
    EXPECT_LT(waited_ms, 1000.0) << framing;
    EXPECT_NE(answer.find("Connection: close\r\n"), std::string::npos) << framing << answer.substr(0, 300);
    const json error = json::parse(body_of(answer), nullptr, false);
    ASSERT_TRUE(error.is_object()) << framing << answer.substr(0, 300);
    EXPECT_EQ(error["field"], "") << framing;
    const std::string header = std::string(framing).find("Transfer-Encoding") != std::string::npos ? "Transfer-Encoding"
                                                                                                   : "Content-Length";
    EXPECT_NE(error["error"].get<std::string>().find(header), std::string::npos) << framing << answer;
  }
  // The same value twice is one length, as RFC 9112 allows.
  double waited_ms = 0;
  const std::string twice = timed_exchange(
      port, "POST /api/render HTTP/1.1\r\nHost: localhost\r\nContent-Length: 29\r\nContent-Length: 29\r\n"
            "Connection: close\r\n\r\n{\"width\": 16, \"height\": 16}  ", waited_ms, 60);
  EXPECT_EQ(status_of(twice), 200) << twice.substr(0, 300);
  EXPECT_EQ(status_of(raw_exchange(port, get_request("/api/health"))), 200);
}

TEST(Http, ABodilessPostRendersTheDefaultFrame) {
  // No Content-Length and no Transfer-Encoding: no body (RFC 9112 §6.3),
  // the same as {}. It was waited on until the read timeout, then a 400.
  double waited_ms = 0;
  const std::string answer = timed_exchange(
      ServerEnvironment::api->port(), "POST /api/render HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n",
      waited_ms, 60);
  ASSERT_EQ(status_of(answer), 200) << answer.substr(0, 300);
  const Decoded d = decode_png(body_of(answer));
  EXPECT_EQ(d.width, 960);
  EXPECT_EQ(d.height, 540);
}

TEST(Http, AWrongMethodIs405AtOnceWithOrWithoutABody) {
  const int port = ServerEnvironment::api->port();
  for (const char* path : {"/api/health", "/api/scenes"}) {
    for (const char* method : {"POST", "PUT", "PATCH", "DELETE"}) {
      for (const char* body : {"", "Content-Length: 2\r\n\r\n{}"}) {
        const std::string request = std::string(method) + " " + path +
                                    " HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n" + (*body ? body : "\r\n");
        double waited_ms = 0;
        const std::string answer = timed_exchange(port, request, waited_ms);
        EXPECT_EQ(status_of(answer), 405) << request << answer;
        EXPECT_LT(waited_ms, 1000.0) << request;
        EXPECT_NE(answer.find("Allow: GET\r\n"), std::string::npos) << answer;
        EXPECT_TRUE(json::parse(body_of(answer), nullptr, false).contains("error")) << answer;
      }
    }
  }
  // A body sent with a wrong method is read and dropped: the connection goes on.
  httplib::Client c = client();
  expect_json_error(c.Put("/api/health", std::string(4000, ' '), "text/plain"), 405, "");
  auto health = c.Get("/api/health");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
}

TEST(Http, MultipartIs415NamingWhatIsAccepted) {
  // curl -F: cpp-httplib's plain reader called an empty callback (500 bad_function_call).
  httplib::Client c = client();
  for (const char* path : {"/api/render", "/api/depth"}) {
    httplib::MultipartFormDataItems items = {{"a", "{}", "", ""}};
    auto res = c.Post(path, items);
    expect_json_error(res, 415, "");
    EXPECT_NE(res->body.find("application/json"), std::string::npos) << res->body;
    EXPECT_NE(res->body.find("multipart/form-data"), std::string::npos) << res->body;
  }
  expect_json_error(c.Post("/api/render", "--x\r\n\r\n{}\r\n--x--\r\n", "multipart/mixed; boundary=x"), 415, "");
  // The body was read and dropped: the same connection still renders.
  auto res = c.Post("/api/render", R"({"width": 16, "height": 16})", "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
}

TEST(Http, RangeIsIgnoredOnTheApiAndSeveralRangesOnFiles) {
  httplib::Client c = client();
  const std::string body = R"({"width": 32, "height": 32})";
  auto whole = c.Post("/api/render", body, "application/json");
  ASSERT_TRUE(whole);
  ASSERT_EQ(whole->status, 200);
  for (const char* range : {"bytes=0-9", "bytes=0-9,20-29", "bytes=-5"}) {
    auto res = c.Post("/api/render", {{"Range", range}}, body, "application/json");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 200) << range;
    EXPECT_EQ(res->body, whole->body) << range;
    EXPECT_FALSE(res->has_header("Content-Range")) << range;
  }
  auto error = c.Post("/api/render", {{"Range", "bytes=0-3"}}, R"({"width": -1})", "application/json");
  expect_json_error(error, 400, "width");
  auto health = c.Get("/api/health", {{"Range", "bytes=0-3"}});
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
  EXPECT_TRUE(json::parse(health->body, nullptr, false).is_object());

  // A static file: one range is served (a resumed download); several are
  // ignored and the file comes whole, so 2,000 ranges cannot multiply it.
  auto index = c.Get("/");
  ASSERT_TRUE(index);
  auto one = c.Get("/", {{"Range", "bytes=0-9"}});
  ASSERT_TRUE(one);
  EXPECT_EQ(one->status, 206);
  EXPECT_EQ(one->body, index->body.substr(0, 10));
  std::string many = "bytes=0-0";
  for (int i = 1; i < 1000; ++i) many += ",0-" + std::to_string(i);
  auto several = c.Get("/", {{"Range", many}});
  ASSERT_TRUE(several);
  EXPECT_EQ(several->status, 200);
  EXPECT_EQ(several->body, index->body);
}

TEST(Http, ServesTheWebPanel) {
  auto index = client().Get("/");
  ASSERT_TRUE(index);
  EXPECT_EQ(index->status, 200);
  EXPECT_NE(index->get_header_value("Content-Type").find("text/html"), std::string::npos);
  EXPECT_NE(index->body.find("app.js"), std::string::npos);
  for (const char* path : {"/app.js", "/style.css"}) {
    auto res = client().Get(path);
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 200) << path;
    EXPECT_FALSE(res->body.empty()) << path;
  }
}

TEST(Http, ASecondServerCannotTakeTheSamePort) {
  ServerOptions options;
  options.port = ServerEnvironment::api->port();
  options.log_requests = false;
  HttpApi second(*ServerEnvironment::renderer, options);
  EXPECT_FALSE(second.bind());
}

TEST(Http, EightParallelClientsFiveRequestsEach) {
  std::atomic<int> ok{0};
  std::vector<std::thread> clients;
  for (int c = 0; c < 8; ++c) {
    clients.emplace_back([c, &ok] {
      httplib::Client http = client();
      for (int i = 0; i < 5; ++i) {
        const json body = {{"width", 96 + 8 * c}, {"height", 64}, {"time", 0.1 * i}, {"shadow", {{"map_size", 512}}},
                           {"output", i % 2 ? "shadow" : "color"}};
        auto res = http.Post("/api/render", body.dump(), "application/json");
        if (res && res->status == 200 && decode_png(res->body).width == 96 + 8 * c) ++ok;
      }
    });
  }
  for (auto& t : clients) t.join();
  EXPECT_EQ(ok.load(), 40);
}

// --- The user's models: POST/GET /api/models --------------------------------

// A cube of edge `size` under a node: a small valid model; each size is
// a different body, so a different id.
test::GltfBuilder cube_model(float size) {
  test::GltfBuilder b;
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices;
  test::unit_cube(positions, indices, size / 2);
  const int p = b.vec3s(positions);
  const int i = b.indices_u32(indices);
  b.scene({b.node({{"mesh", b.mesh(p, i)}})});
  return b;
}

// A square grid of n x n vertices: 2 (n - 1)^2 triangles, 12 n^2 + 24 (n - 1)^2 bytes.
std::string grid_glb(int n) {
  test::GltfBuilder b;
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices;
  for (int z = 0; z < n; ++z)
    for (int x = 0; x < n; ++x) positions.push_back({float(x), 0.0f, float(-z)});
  for (int z = 0; z + 1 < n; ++z)
    for (int x = 0; x + 1 < n; ++x) {
      const std::uint32_t a = std::uint32_t(z * n + x), c = a + std::uint32_t(n);
      indices.insert(indices.end(), {a, a + 1, c + 1, a, c + 1, c});
    }
  const int p = b.vec3s(positions);
  const int i = b.indices_u32(indices);
  b.scene({b.node({{"mesh", b.mesh(p, i)}})});
  return b.glb();
}

TEST(Http, AnUploadedGlbIsHeldListedAndFound) {
  const std::string glb = cube_model(2.0f).glb();
  auto res = client().Post("/api/models", glb, "model/gltf-binary");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 201) << res->body;
  const json created = json::parse(res->body);
  const std::string id = model_id_for(glb);
  EXPECT_EQ(created["id"], id);
  EXPECT_EQ(created["triangles"], 12);
  EXPECT_EQ(created["bounds"]["min"], json::array({-1.0, -1.0, -1.0}));
  EXPECT_EQ(created["bounds"]["max"], json::array({1.0, 1.0, 1.0}));
  EXPECT_EQ(created["closed"], true);
  EXPECT_EQ(res->get_header_value("Location"), "/api/models/" + id);

  // The same body again: 200, the same answer.
  res = client().Post("/api/models", glb, "model/gltf-binary");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_EQ(json::parse(res->body), created);

  res = client().Get("/api/models");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200);
  const json list = json::parse(res->body);
  bool listed = false;
  for (const json& m : list["models"]) listed |= m["id"] == id;
  EXPECT_TRUE(listed) << res->body;
  EXPECT_GE(list["count"].get<int>(), 1);
  EXPECT_GT(list["bytes"].get<std::uint64_t>(), 0u);

  res = client().Get("/api/models/" + id);
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_EQ(json::parse(res->body), created);

  const json health = json::parse(client().Get("/api/health")->body);
  EXPECT_GE(health["models"].get<int>(), 1);
  EXPECT_GT(health["model_bytes"].get<std::uint64_t>(), 0u);
}

TEST(Http, ASelfContainedGltfUploads) {
  auto res = client().Post("/api/models", cube_model(3.0f).gltf(), "model/gltf+json; charset=utf-8");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 201) << res->body;
}

TEST(Http, ModelErrors) {
  expect_json_error(client().Get("/api/models/sha256:0000"), 404, "");
  EXPECT_NE(client().Get("/api/models/nope")->body.find("POST /api/models"), std::string::npos);
  // The wrong type: 415 naming the accepted ones.
  auto res = client().Post("/api/models", cube_model(4.0f).glb(), "application/octet-stream");
  expect_json_error(res, 415, "");
  EXPECT_NE(res->body.find("model/gltf-binary"), std::string::npos);
  EXPECT_NE(res->body.find("model/gltf+json"), std::string::npos);
  // Broken and refused files: the loader's message, whole.
  res = client().Post("/api/models", "glTF but no more", "model/gltf-binary");
  expect_json_error(res, 400, "");
  EXPECT_NE(res->body.find("glTF binary"), std::string::npos) << res->body;
  test::GltfBuilder lines = cube_model(5.0f);
  lines.doc["meshes"][0]["primitives"][0]["mode"] = 1;
  res = client().Post("/api/models", lines.glb(), "model/gltf-binary");
  expect_json_error(res, 422, "");
  EXPECT_NE(res->body.find("the model has no triangles"), std::string::npos) << res->body;
  EXPECT_NE(res->body.find("1 primitives of points or lines were left out"), std::string::npos) << res->body;
  // Lines beside triangles: the triangles are held, the lines counted.
  test::GltfBuilder mixed = cube_model(5.5f);
  json line = mixed.doc["meshes"][0]["primitives"][0];
  line["mode"] = 1;
  mixed.doc["meshes"][0]["primitives"].push_back(line);
  res = client().Post("/api/models", mixed.glb(), "model/gltf-binary");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 201) << res->body;
  EXPECT_EQ(json::parse(res->body)["skipped_primitives"], 1);
  EXPECT_EQ(json::parse(res->body)["triangles"], 12);
  res = client().Post("/api/models", cube_model(6.0f).gltf_external("/etc/passwd"), "model/gltf+json");
  expect_json_error(res, 422, "");
  EXPECT_NE(res->body.find("self-contained"), std::string::npos) << res->body;
  // Routes: a wrong method on either path is 405 with Allow.
  res = client().Delete("/api/models/" + model_id_for("x"));
  expect_json_error(res, 405, "");
  EXPECT_EQ(res->get_header_value("Allow"), "GET");
  res = client().Put("/api/models", "{}", "application/json");
  expect_json_error(res, 405, "");
  EXPECT_EQ(res->get_header_value("Allow"), "GET, POST");
  EXPECT_EQ(client().Get("/api/health")->status, 200);
}

// Models as architects' tools write them: OBJ by its media type, IFC by
// ?format=, converted by umbra-model-import and held as any upload; the
// house renders under the Karlsruhe sun, and its exact error is small.
TEST(Http, OtherFormatsAreConvertedAndRender) {
  const std::string house = "/usr/share/assimp/models/IFC/AC14-FZK-Haus.ifc";
  const std::string box = "/usr/share/assimp/models/OBJ/box.obj";
  ASSERT_TRUE(std::filesystem::exists(house)) << "needs Debian's assimp-testmodels (scripts/install-deps.sh)";
  const auto read = [](const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  };
  auto obj = client().Post("/api/models", read(box), "model/obj");
  ASSERT_TRUE(obj);
  ASSERT_EQ(obj->status, 201) << obj->body;
  EXPECT_EQ(json::parse(obj->body)["triangles"], 12);
  auto ifc = client().Post("/api/models?format=ifc", read(house), "application/octet-stream");
  ASSERT_TRUE(ifc);
  ASSERT_EQ(ifc->status, 201) << ifc->body;
  const json held = json::parse(ifc->body);
  EXPECT_GT(held["triangles"].get<int>(), 30000);
  EXPECT_NEAR(held["bounds"]["max"][1].get<double>(), 6.32, 0.05);  // Y up, metres
  // The same body again: the same model (200); told another unit: another.
  auto again = client().Post("/api/models?format=ifc", read(house), "application/octet-stream");
  ASSERT_TRUE(again);
  EXPECT_EQ(again->status, 200);
  EXPECT_EQ(json::parse(again->body)["id"], held["id"]);
  auto in_mm = client().Post("/api/models?format=obj&unit=mm", read(box), "application/octet-stream");
  ASSERT_TRUE(in_mm);
  ASSERT_EQ(in_mm->status, 201) << in_mm->body;
  EXPECT_NE(json::parse(in_mm->body)["id"], json::parse(obj->body)["id"]);
  EXPECT_NEAR(json::parse(in_mm->body)["bounds"]["max"][0].get<double>(), 0.0005, 1e-9);
  // Refusals name what is wrong.
  expect_json_error(client().Post("/api/models?format=dwg", "x", "application/octet-stream"), 400, "format");
  expect_json_error(client().Post("/api/models?format=obj&up=x", "x", "application/octet-stream"), 400, "up");
  expect_json_error(client().Post("/api/models?format=obj&colour=red", "x", "application/octet-stream"), 400, "colour");
  // One value per parameter, and a format named (the red-team pass: the
  // empty second `format` won and the answer was a 415).
  expect_json_error(client().Post("/api/models?format=obj&format=", "x", "application/octet-stream"), 400, "format");
  expect_json_error(client().Post("/api/models?format=", "x", "model/gltf-binary"), 400, "format");
  expect_json_error(client().Post("/api/models?format=obj&up=y&up=z", "x", "text/plain"), 400, "up");
  expect_json_error(client().Post("/api/models?unit=mm", read(box), "model/gltf-binary"), 400, "unit");
  auto points = client().Post("/api/models?format=obj", read("/usr/share/assimp/models/OBJ/testpoints.obj"), "text/plain");
  expect_json_error(points, 422, "");
  EXPECT_NE(points->body.find("no triangles"), std::string::npos) << points->body;
  auto unsupported = client().Post("/api/models", read(box), "application/octet-stream");
  expect_json_error(unsupported, 415, "");
  EXPECT_NE(unsupported->body.find("?format= (obj, stl, ply, dae, fbx, 3ds, ifc)"), std::string::npos) << unsupported->body;
  // Rendered: the house on a plane in the Karlsruhe sun, the exact error.
  const json body = {
      {"scene", {{"objects", {{{"type", "plane"}, {"center", {6, -1.01, -5}}, {"size", {60, 60}}},
                              {{"type", "mesh"}, {"model", held["id"]}}}}}},
      {"light", {{"sun", {{"latitude", 49.01}, {"longitude", 8.4}, {"utc", "2026-06-21T10:00:00Z"}}}}},
      {"camera", {{"position", {30, 25, 30}}, {"target", {6, 0, -5}}}},
      {"width", 160}, {"height", 90}, {"output", "error"}};
  auto rendered = client().Post("/api/render", body.dump(), "application/json");
  ASSERT_TRUE(rendered);
  ASSERT_EQ(rendered->status, 200) << rendered->body;
  const std::string error = rendered->get_header_value("Umbra-Shadow-Error");
  EXPECT_NE(error.find("mae="), std::string::npos) << error;
  EXPECT_LT(std::stod(error.substr(error.find("mae=") + 4)), 0.01) << error;
}

// A CityJSON city model (one building as a box solid at LoD 1 and 2, in a
// national grid), read by the server: held as its .glb, one model per LoD.
TEST(Http, CityJsonIsReadAtTheLevelOfDetailAsked) {
  const json box = {{{{0, 3, 2, 1}}, {{4, 5, 6, 7}}, {{0, 1, 5, 4}}, {{1, 2, 6, 5}}, {{2, 3, 7, 6}}, {{3, 0, 4, 7}}}};
  const json city = {
      {"type", "CityJSON"}, {"version", "2.0"},
      {"transform", {{"scale", {0.01, 0.01, 0.01}}, {"translate", {85000, 446000, 0}}}},
      {"CityObjects", {{"b1", {{"type", "Building"},
                               {"geometry", {{{"type", "Solid"}, {"lod", "1"}, {"boundaries", box}},
                                             {{"type", "Solid"}, {"lod", "2"}, {"boundaries", box}}}}}}}},
      {"vertices", {{0, 0, 0}, {1000, 0, 0}, {1000, 600, 0}, {0, 600, 0},
                    {0, 0, 900}, {1000, 0, 900}, {1000, 600, 900}, {0, 600, 900}}}};
  auto res = client().Post("/api/models?format=cityjson", city.dump(), "application/json");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 201) << res->body;
  EXPECT_EQ(res->get_header_value("Umbra-CityJSON"), "objects=1; lods=1,2; lod=highest; left_out=0; fanned=0");
  const json held = json::parse(res->body);
  EXPECT_EQ(held["triangles"], 12);
  EXPECT_EQ(held["closed"], true);
  EXPECT_NEAR(held["bounds"]["max"][1].get<double>(), 9.0, 1e-4);  // 9 m tall, y up
  EXPECT_NEAR(held["bounds"]["max"][0].get<double>(), 5.0, 1e-4);  // centred on its plan
  // Its LoD 1 is the same box: the same .glb, so the same model (its id is
  // the .glb's hash); a LoD 1 that differs is another model.
  auto lod1 = client().Post("/api/models?lod=1", city.dump(), "application/city+json");
  ASSERT_TRUE(lod1);
  ASSERT_EQ(lod1->status, 200) << lod1->body;
  EXPECT_EQ(json::parse(lod1->body)["id"], held["id"]);
  json lower = city;
  lower["CityObjects"]["b1"]["geometry"][0]["boundaries"] = {{{{0, 3, 2, 1}}, {{0, 1, 5, 4}}, {{1, 2, 6, 5}}}};
  auto other = client().Post("/api/models?lod=1", lower.dump(), "application/city+json");
  ASSERT_TRUE(other);
  ASSERT_EQ(other->status, 201) << other->body;
  EXPECT_NE(json::parse(other->body)["id"], held["id"]);
  expect_json_error(client().Post("/api/models?format=cityjson&lod=3", city.dump(), "application/json"), 422, "lod");
  expect_json_error(client().Post("/api/models?format=cityjson&lod=x", city.dump(), "application/json"), 400, "lod");
  expect_json_error(client().Post("/api/models?format=cityjson&up=z", city.dump(), "application/json"), 400, "up");
  expect_json_error(client().Post("/api/models?format=obj&lod=2", "v 0 0 0", "application/json"), 400, "lod");
  // It renders as any model.
  const json body = {{"scene", {{"objects", {{{"type", "plane"}, {"size", {40, 40}}},
                                             {{"type", "mesh"}, {"model", held["id"]}}}}}},
                     {"width", 64}, {"height", 48}};
  auto rendered = client().Post("/api/render", body.dump(), "application/json");
  ASSERT_TRUE(rendered);
  EXPECT_EQ(rendered->status, 200) << rendered->body;
}

TEST(Http, OnlyModelUploadsMayBeLargerThanOneMebibyte) {
  ServerOptions options;
  options.max_model_bytes = std::size_t(4) << 20;
  OwnServer server(options);
  httplib::Client c("127.0.0.1", server.api.port());
  c.set_read_timeout(60, 0);
  const std::string big = grid_glb(250);  // about 2.2 MB, 124 002 triangles
  ASSERT_GT(big.size(), std::size_t(2) << 20);
  auto res = c.Post("/api/models", big, "model/gltf-binary");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 201) << res->body;
  EXPECT_EQ(json::parse(res->body)["triangles"], 2 * 249 * 249);
  // The same size to the render route: still 413.
  const std::string render_body = R"({"scene": ")" + std::string(std::size_t(2) << 20, 'x') + R"("})";
  expect_json_error(c.Post("/api/render", render_body, "application/json"), 413, "");
  // Over the model limit: 413 from the head alone, before any body byte.
  double waited_ms = 0;
  const std::string answer =
      timed_exchange(server.api.port(),
                     "POST /api/models HTTP/1.1\r\nHost: localhost\r\nContent-Type: model/gltf-binary\r\n"
                     "Content-Length: " + std::to_string((std::size_t(4) << 20) + 1) + "\r\n\r\n",
                     waited_ms);
  EXPECT_EQ(status_of(answer), 413) << answer;
  EXPECT_LT(waited_ms, 1000.0);
  EXPECT_EQ(c.Get("/api/health")->status, 200);
}

TEST(Http, ModelsFromAFolderAreListedByName) {
  namespace fs = std::filesystem;
  const fs::path root = fs::temp_directory_path() / ("umbra-http-models-" + std::to_string(getpid()));
  fs::remove_all(root);
  fs::create_directories(root / "models");
  const test::GltfBuilder b = cube_model(1.0f);
  std::ofstream(root / "models" / "crate.bin", std::ios::binary) << b.bin;
  std::ofstream(root / "models" / "crate.gltf") << b.gltf_external("crate.bin");
  std::ofstream(root / "outside.bin", std::ios::binary) << b.bin;
  std::ofstream(root / "models" / "escape.gltf") << b.gltf_external("../outside.bin");
  ModelStore store(std::uint64_t(64) << 20);
  FolderLoad loaded;
  std::string error;
  ASSERT_TRUE(load_model_folder((root / "models").string(), store, 64 << 20, loaded, error)) << error;
  ASSERT_EQ(loaded.refused.size(), 1u);
  OwnServer server(ServerOptions{}, store);
  httplib::Client c("127.0.0.1", server.api.port());
  auto res = c.Get("/api/models/crate");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  const json crate = json::parse(res->body);
  EXPECT_EQ(crate["name"], "crate");
  EXPECT_EQ(crate["pinned"], true);
  EXPECT_EQ(crate["triangles"], 12);
  EXPECT_EQ(c.Get("/api/models/" + crate["id"].get<std::string>())->status, 200);
  const json list = json::parse(c.Get("/api/models")->body);
  ASSERT_EQ(list["count"], 1);
  EXPECT_EQ(list["models"][0]["name"], "crate");
  EXPECT_EQ(c.Get("/api/models/escape")->status, 404);
  fs::remove_all(root);
}

// Two instances of one model (the second with its own colour) over a floor.
std::string mesh_scene_body(const std::string& model, const char* output) {
  const json objects = {
      {{"type", "mesh"}, {"model", model}, {"position", {0, 0.5, 0}}, {"rotation_deg", {0, 30, 0}}, {"scale", 0.5}},
      {{"type", "mesh"}, {"model", model}, {"position", {1.5, 0.5, 0}}, {"color", {0.2, 0.4, 0.9}}},
      {{"type", "plane"}, {"center", {0, -1, 0}}}};
  return json{{"width", 64}, {"height", 48}, {"output", output}, {"scene", {{"objects", objects}}}}.dump();
}

TEST(Http, AMeshObjectRendersAnUploadedModelByIdAndAFolderModelByName) {
  ModelStore store(std::uint64_t(64) << 20);
  const std::string named_glb = cube_model(0.8f).glb();
  LoadResult loaded = load_gltf(named_glb, LoadOptions{});
  ASSERT_TRUE(loaded.ok()) << loaded.error;
  ASSERT_EQ(store.add(model_id_for(named_glb), "crate", std::move(loaded.model), true).outcome,
            ModelStore::Outcome::Added);
  OwnServer server(ServerOptions{}, store);
  httplib::Client c("127.0.0.1", server.api.port());
  const std::string glb = cube_model(1.5f).glb();
  auto uploaded = c.Post("/api/models", glb, "model/gltf-binary");
  ASSERT_TRUE(uploaded);
  ASSERT_EQ(uploaded->status, 201) << uploaded->body;
  const std::string id = json::parse(uploaded->body)["id"];
  for (const std::string& model : {id, std::string("crate")}) {
    for (const char* output : {"color", "shadow"}) {
      auto res = c.Post("/api/render", mesh_scene_body(model, output), "application/json");
      ASSERT_TRUE(res);
      EXPECT_EQ(res->status, 200) << model << " " << output << ": " << res->body;
      EXPECT_EQ(res->get_header_value("Content-Type"), "image/png");
      const Decoded d = decode_png(res->body);
      EXPECT_EQ(d.width, 64);
      EXPECT_EQ(d.height, 48);
    }
  }
  auto res = c.Post("/api/render", mesh_scene_body("kettle", "color"), "application/json");
  expect_json_error(res, 400, "scene.objects[0].model");
  EXPECT_NE(res->body.find("POST /api/models"), std::string::npos) << res->body;
  // The exact reference ray casts meshes (Embree): an image, not a refusal.
  for (const char* output : {"exact", "error"}) {
    res = c.Post("/api/render", mesh_scene_body(id, output), "application/json");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 200) << output << ": " << res->body;
    EXPECT_EQ(res->get_header_value("Content-Type"), "image/png");
    const Decoded d = decode_png(res->body);
    EXPECT_EQ(d.width, 64);
    EXPECT_EQ(d.height, 48);
  }
}

std::string animated_body(const std::string& model, double time, const json& animation, const char* output = "shadow",
                          const char* filter = "pcf") {
  json cube = {{"type", "mesh"}, {"model", model}, {"position", {0, 0.5, 0}}};
  if (!animation.is_null()) cube["animation"] = animation;
  const json objects = {cube, {{"type", "plane"}, {"center", {0, 0, 0}}, {"size", {12, 12}}}};
  return json{{"width", 96},
              {"height", 64},
              {"time", time},
              {"output", output},
              {"light", {{"orbit_deg_per_s", 0}}},
              {"shadow", {{"filter", filter}}},
              {"camera", {{"position", {0, 6, 8}}, {"target", {0, 0, 0}}}},
              {"scene", {{"objects", objects}}}}
      .dump();
}

// Issue 33: a mesh object's "animation" poses its model at the request's
// time; the frame, the exact reference and the certified filter all see
// the same pose.
TEST(Http, AnAnimatedModelIsPosedAtTheRequestsTime) {
  ModelStore store(std::uint64_t(64) << 20);
  OwnServer server(ServerOptions{}, store);
  httplib::Client c("127.0.0.1", server.api.port());
  auto uploaded = c.Post("/api/models", test::sliding_cube(), "model/gltf-binary");
  ASSERT_TRUE(uploaded);
  ASSERT_EQ(uploaded->status, 201) << uploaded->body;
  const json model = json::parse(uploaded->body);
  const std::string id = model["id"];
  ASSERT_EQ(model["animations"].size(), 1u) << uploaded->body;
  EXPECT_EQ(model["animations"][0]["name"], "slide");
  EXPECT_EQ(model["animations"][0]["duration_s"], 2.0);
  EXPECT_EQ(model["animations"][0]["channels"], 2);
  const auto render = [&](const std::string& body) {
    auto res = c.Post("/api/render", body, "application/json");
    EXPECT_TRUE(res);
    if (!res) return std::string();
    EXPECT_EQ(res->status, 200) << res->body;
    return res->body;
  };
  // At its first key the pose is the rest model's.
  const std::string rest = render(animated_body(id, 0.0, nullptr));
  EXPECT_EQ(render(animated_body(id, 0.0, "slide")), rest);
  // Later it has moved: another frame (shadow and all).
  const std::string at1 = render(animated_body(id, 1.0, "slide"));
  const std::string at15 = render(animated_body(id, 1.5, "slide"));
  EXPECT_NE(at1, rest);
  EXPECT_NE(at15, at1);
  // By index; at half speed time 2 is the animation's 1 s; looping (2 s
  // long), time 5 is its 1 s too and time 4 its start again; held, time 9
  // is its end, as time 2 is.
  EXPECT_EQ(render(animated_body(id, 1.0, 0)), at1);
  EXPECT_EQ(render(animated_body(id, 2.0, {{"name", "slide"}, {"speed", 0.5}})), at1);
  EXPECT_EQ(render(animated_body(id, 5.0, {{"index", 0}, {"loop", true}})), at1);
  EXPECT_EQ(render(animated_body(id, 4.0, "slide")), rest);
  const std::string end = render(animated_body(id, 2.0, {{"index", 0}, {"loop", false}}));
  EXPECT_NE(end, rest);
  EXPECT_EQ(render(animated_body(id, 9.0, {{"index", 0}, {"loop", false}})), end);
  // Backwards: time 0.5 at speed -1 is the animation's 1.5 s (looping).
  EXPECT_EQ(render(animated_body(id, 0.5, {{"index", 0}, {"speed", -1}})), render(animated_body(id, 1.5, "slide")));
  // The certified filter's shadow term equals the exact reference's, byte
  // for byte, in the pose: both ray cast the posed cube.
  EXPECT_EQ(render(animated_body(id, 1.5, "slide", "shadow", "exact")), render(animated_body(id, 1.5, "slide", "exact")));
  // A model without animations, a name or index it has not, bad fields.
  auto cube = c.Post("/api/models", cube_model(1.0f).glb(), "model/gltf-binary");
  ASSERT_TRUE(cube);
  const std::string still = json::parse(cube->body)["id"];
  EXPECT_EQ(json::parse(cube->body)["animations"], json::array());
  auto res = c.Post("/api/render", animated_body(still, 1.0, 0), "application/json");
  expect_json_error(res, 400, "scene.objects[0].animation");
  EXPECT_NE(res->body.find("has no animations"), std::string::npos) << res->body;
  res = c.Post("/api/render", animated_body(id, 1.0, "walk"), "application/json");
  expect_json_error(res, 400, "scene.objects[0].animation");
  EXPECT_NE(res->body.find("it has 0 \\\"slide\\\""), std::string::npos) << res->body;
  expect_json_error(c.Post("/api/render", animated_body(id, 1.0, 1), "application/json"), 400, "scene.objects[0].animation");
  expect_json_error(c.Post("/api/render", animated_body(id, 1.0, {{"index", 0}, {"speed", 2000}}), "application/json"), 400,
                    "scene.objects[0].animation.speed");
  expect_json_error(c.Post("/api/render", animated_body(id, 1.0, {{"index", 0}, {"name", "slide"}}), "application/json"),
                    400, "scene.objects[0].animation");
  expect_json_error(c.Post("/api/render", animated_body(id, 1.0, {{"index", 0}, {"loops", true}}), "application/json"),
                    400, "scene.objects[0].animation.loops");
  expect_json_error(c.Post("/api/render", animated_body(id, 1.0, true), "application/json"), 400,
                    "scene.objects[0].animation");
}

// --model-store: two servers, as behind a load balancer, share a folder.
// A model uploaded to one renders on the other, which never saw the upload;
// a body that did not load is never written there.
// Issue 29: one 288 KB upload of 4,000 stacked 40 x 40 quads, then a
// 512^2 render of it: the bounds made it 18 ms, and it held the GL thread
// for 22.8 s. Its triangles' overdraw is counted now: 422 at once, naming
// the objects, nothing rendered.
TEST(Http, AMeshOfStackedQuadsIsRefusedForItsOverdrawBeforeRendering) {
  auto res = client().Post("/api/models", test::stacked_quads_glb(4000), "model/gltf-binary");
  ASSERT_TRUE(res);
  ASSERT_TRUE(res->status == 201 || res->status == 200) << res->body;
  const std::string id = json::parse(res->body)["id"];
  const json body = {{"width", 512}, {"height", 512}, {"scene", {{"objects", {{{"type", "mesh"}, {"model", id}}}}}}};
  const std::uint64_t frames_before = ServerEnvironment::renderer->frames_rendered();
  const auto start = std::chrono::steady_clock::now();
  res = client().Post("/api/render", body.dump(), "application/json");
  const double waited_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  expect_json_error(res, 422, "scene.objects");
  EXPECT_LT(waited_ms, 2000.0);
  const std::string message = json::parse(res->body)["error"];
  EXPECT_NE(message.find("mesh overdraw"), std::string::npos) << message;
  EXPECT_NE(message.find("layers deep"), std::string::npos) << message;
  EXPECT_EQ(ServerEnvironment::renderer->frames_rendered(), frames_before);
}

TEST(Http, AModelUploadedToOneServerRendersOnAnotherThroughTheSharedStore) {
  namespace fs = std::filesystem;
  const fs::path folder = fs::temp_directory_path() / ("umbra-http-store-" + std::to_string(getpid()));
  fs::remove_all(folder);
  fs::create_directories(folder);
  ServerOptions options;
  options.model_store_dir = folder.string();
  ModelStore store_a(std::uint64_t(64) << 20), store_b(std::uint64_t(64) << 20);
  OwnServer a(options, store_a), b(options, store_b);
  httplib::Client to_a("127.0.0.1", a.api.port()), to_b("127.0.0.1", b.api.port());

  const std::string glb = cube_model(0.7f).glb();
  auto res = to_a.Post("/api/models", glb, "model/gltf-binary");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 201) << res->body;
  const std::string id = json::parse(res->body)["id"];
  EXPECT_TRUE(fs::exists(folder / (id.substr(7) + ".glb")));
  EXPECT_EQ(store_b.count(), 0u);
  // B has not seen it: it loads it from the folder to answer.
  res = to_b.Post("/api/render", mesh_scene_body(id, "color"), "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(store_b.count(), 1u);
  EXPECT_EQ(to_b.Get("/api/models/" + id)->status, 200);
  // By id only: a name is never looked for in the folder.
  EXPECT_EQ(to_b.Get("/api/models/" + id.substr(7))->status, 404);
  // A converted model is stored as its .glb, named by the .glb's hash, so
  // B finds and checks it (the original body's hash named it once: B
  // refused the file as cut short).
  const std::string obj = "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nv 0 2 0\nf 1 2 5\nf 2 3 5\nf 3 4 5\nf 4 1 5\nf 1 4 3 2\n";
  res = to_a.Post("/api/models?format=obj", obj, "text/plain");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 201) << res->body;
  const std::string pyramid = json::parse(res->body)["id"];
  res = to_b.Post("/api/render", mesh_scene_body(pyramid, "color"), "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(to_b.Get("/api/models/" + pyramid)->status, 200);

  // A body that does not load is refused and not written.
  res = to_a.Post("/api/models", "glTF but no more", "model/gltf-binary");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 400);
  EXPECT_FALSE(fs::exists(folder / (model_id_for("glTF but no more").substr(7) + ".glb")));
  // A file changed on the shared disk is not taken: unknown, as before.
  const std::string other = cube_model(0.4f).glb();
  ASSERT_EQ(to_a.Post("/api/models", other, "model/gltf-binary")->status, 201);
  const std::string other_id = model_id_for(other);
  std::ofstream(folder / (other_id.substr(7) + ".glb"), std::ios::binary | std::ios::trunc) << other.substr(0, 40);
  res = to_b.Post("/api/render", mesh_scene_body(other_id, "color"), "application/json");
  ASSERT_TRUE(res);
  expect_json_error(res, 400, "scene.objects[0].model");
  fs::remove_all(folder);
}

// --- Models' memory, the store's disk, and owners (issue 29) ----------------

// A grid of n x n vertices (2 (n - 1)^2 triangles) under `nodes` nodes, side
// by side: instancing, which the loader builds out copy by copy.
std::string instanced_grid_glb(int n, int nodes) {
  test::GltfBuilder b;
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices;
  for (int z = 0; z < n; ++z)
    for (int x = 0; x < n; ++x) positions.push_back({float(x) / float(n), 0.0f, -float(z) / float(n)});
  for (int z = 0; z + 1 < n; ++z)
    for (int x = 0; x + 1 < n; ++x) {
      const std::uint32_t a = std::uint32_t(z * n + x), c = a + std::uint32_t(n);
      indices.insert(indices.end(), {a, a + 1, c + 1, a, c + 1, c});
    }
  const int mesh = b.mesh(b.vec3s(positions), b.indices_u32(indices));
  std::vector<int> roots;
  for (int i = 0; i < nodes; ++i) roots.push_back(b.node({{"mesh", mesh}, {"translation", {1.5 * i, 0, 0}}}));
  b.scene(roots);
  return b.glb();
}

double metric(httplib::Client& c, const std::string& name) {
  const std::string page = c.Get("/metrics")->body;
  const std::size_t at = page.find("\n" + name + " ");
  if (at == std::string::npos) return -1.0;
  return std::stod(page.substr(at + name.size() + 2));
}

struct StoreFolder {
  std::filesystem::path path;
  explicit StoreFolder(const std::string& name) {
    path = std::filesystem::temp_directory_path() / ("umbra-http-" + name + "-" + std::to_string(getpid()));
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~StoreFolder() { std::filesystem::remove_all(path); }
  std::vector<std::string> files() const {
    std::vector<std::string> names;
    for (const auto& e : std::filesystem::directory_iterator(path)) names.push_back(e.path().filename());
    return names;
  }
  std::uint64_t bytes() const {
    std::uint64_t total = 0;
    for (const auto& e : std::filesystem::directory_iterator(path)) total += e.file_size();
    return total;
  }
};

// Finding 2: a scene naming stored models that cannot fit together is
// refused before any of them is loaded, with their sizes; one that fits
// renders, and the budget holds throughout.
TEST(Http, AStoreSceneOverTheModelBudgetIs422BeforeAnyModelIsLoaded) {
  StoreFolder folder("budget");
  ServerOptions options;
  options.model_store_dir = folder.path.string();
  ModelStore big(std::uint64_t(64) << 20);
  OwnServer uploader(options, big);
  httplib::Client to_uploader("127.0.0.1", uploader.api.port());
  std::vector<std::string> ids;
  std::uint64_t each = 0;
  for (int n : {60, 61, 62}) {
    auto res = to_uploader.Post("/api/models", grid_glb(n), "model/gltf-binary");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 201) << res->body;
    ids.push_back(json::parse(res->body)["id"]);
    each = std::max<std::uint64_t>(each, json::parse(res->body)["bytes"].get<std::uint64_t>());
  }
  // Room for two of them, not three.
  ModelStore small(2 * each + each / 2);
  OwnServer renderer(options, small);
  httplib::Client to_renderer("127.0.0.1", renderer.api.port());
  json objects = json::array();
  for (std::size_t i = 0; i < ids.size(); ++i)
    objects.push_back({{"type", "mesh"}, {"model", ids[i]}, {"position", {2.0 * i, 0, 0}}});
  const std::string all = json{{"width", 64}, {"height", 48}, {"scene", {{"objects", objects}}}}.dump();
  auto res = to_renderer.Post("/api/render", all, "application/json");
  expect_json_error(res, 422, "");
  EXPECT_NE(res->body.find("--models-budget-mib"), std::string::npos) << res->body;
  EXPECT_NE(res->body.find(ids[0].substr(0, 19)), std::string::npos) << res->body;  // names the models and sizes
  EXPECT_EQ(metric(to_renderer, "umbra_models_loaded_total"), 0.0);
  EXPECT_EQ(small.count(), 0u);
  // Without the records beside the files (written by an older server):
  // refused all the same, before the model past the budget is built.
  for (const std::string& id : ids) std::filesystem::remove(folder.path / (id.substr(7) + ".json"));
  res = to_renderer.Post("/api/render", all, "application/json");
  expect_json_error(res, 422, "");
  EXPECT_LE(metric(to_renderer, "umbra_models_loaded_total"), 2.0);
  EXPECT_LE(small.live_bytes(), small.max_bytes());
  // Two of them fit: rendered.
  objects.erase(objects.end() - 1);
  res = to_renderer.Post("/api/render", json{{"width", 64}, {"height", 48}, {"scene", {{"objects", objects}}}}.dump(),
                         "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200) << res->body;
  EXPECT_LE(small.live_bytes(), small.max_bytes());
}

// Finding 2 and 7: an upload may hold at most 16 times its body + 32 MiB
// once loaded; past it, 422 before the model is built, and nothing written.
TEST(Http, AnUploadThatGrowsPastItsRatioIsRefusedBeforeItIsBuilt) {
  StoreFolder folder("ratio");
  ServerOptions options;
  options.model_store_dir = folder.path.string();
  OwnServer server(options);
  httplib::Client c("127.0.0.1", server.api.port());
  const std::string glb = instanced_grid_glb(33, 1000);  // ~100 KB: 2 048 000 triangles, ~48 MiB once loaded
  ASSERT_LT(glb.size(), std::size_t(200) << 10);
  auto res = c.Post("/api/models", glb, "model/gltf-binary");
  expect_json_error(res, 422, "");
  EXPECT_NE(res->body.find("16 times its body"), std::string::npos) << res->body;
  EXPECT_EQ(metric(c, "umbra_models_loaded_total"), 0.0);
  EXPECT_TRUE(folder.files().empty());
  // The same instancing, smaller: within the allowance, taken.
  res = c.Post("/api/models", instanced_grid_glb(33, 100), "model/gltf-binary");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 201) << res->body;
}

// Finding 6: a refused upload is never written; the folder is bounded by
// --model-store-max-gib, least recently used files deleted first.
TEST(Http, TheStoreFolderIsBoundedAndARefusedUploadLeavesNoFile) {
  StoreFolder folder("disk");
  ServerOptions options;
  options.model_store_dir = folder.path.string();
  const std::string first = grid_glb(40);
  options.model_store_max_bytes = 3 * first.size() + first.size() / 2;
  ModelStore store(std::uint64_t(64) << 20);
  OwnServer server(options, store);
  httplib::Client c("127.0.0.1", server.api.port());
  std::vector<std::string> ids;
  for (int n : {40, 41, 39, 38, 37}) {
    const std::string glb = grid_glb(n);
    auto res = c.Post("/api/models", glb, "model/gltf-binary");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 201) << res->body;
    ids.push_back(model_id_for(glb));
    EXPECT_LE(folder.bytes(), options.model_store_max_bytes) << n;
    // Distinct mtimes: the order of use is the order of upload.
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_FALSE(std::filesystem::exists(folder.path / (ids[0].substr(7) + ".glb")));
  EXPECT_TRUE(std::filesystem::exists(folder.path / (ids[4].substr(7) + ".glb")));
  EXPECT_GE(metric(c, "umbra_model_store_evicted_total"), 1.0);
  // Held here, so still drawn here; uploaded again, written again.
  ASSERT_EQ(c.Post("/api/models", first, "model/gltf-binary")->status, 200);
  EXPECT_TRUE(std::filesystem::exists(folder.path / (ids[0].substr(7) + ".glb")));
  EXPECT_LE(folder.bytes(), options.model_store_max_bytes);

  // Over the models' budget: 422, and not on disk.
  StoreFolder other("refused");
  ServerOptions tight;
  tight.model_store_dir = other.path.string();
  ModelStore tiny(std::uint64_t(64) << 10);
  OwnServer refusing(tight, tiny);
  httplib::Client r("127.0.0.1", refusing.api.port());
  auto res = r.Post("/api/models", grid_glb(80), "model/gltf-binary");
  expect_json_error(res, 422, "");
  EXPECT_NE(res->body.find("--models-budget-mib"), std::string::npos) << res->body;
  EXPECT_TRUE(other.files().empty());
}

// Finding 7: one owner's uploads never evict another owner's model.
TEST(Http, OneOwnersUploadsCannotEvictAnothersModel) {
  const std::string alice_glb = grid_glb(50);
  LoadResult probe = load_gltf(alice_glb, LoadOptions{});
  ASSERT_TRUE(probe.ok());
  const std::uint64_t each = probe.model->bytes();
  ModelStore::Limits limits;
  limits.max_bytes = 4 * each;
  limits.share_bytes = 2 * each;
  ModelStore store(limits);
  ServerOptions options;
  options.port = 0;
  options.log_requests = false;
  // Each --tokens token is an owner.
  std::string error;
  const auto tokens = TokenTable::parse("alice-token-0123456789 render,upload\nbob-token-0123456789 render,upload\n", error);
  ASSERT_TRUE(tokens) << error;
  options.tokens = std::make_shared<const TokenTable>(*tokens);
  HttpApi api(*ServerEnvironment::renderer, store, options);
  ASSERT_TRUE(api.bind());
  std::thread serving([&] { api.serve(); });
  while (!api.serving()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  httplib::Client c("127.0.0.1", api.port());
  const httplib::Headers alice = {{"Authorization", "Bearer alice-token-0123456789"}},
                         bob = {{"Authorization", "Bearer bob-token-0123456789"}};
  auto res = c.Post("/api/models", alice, alice_glb, "model/gltf-binary");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 201) << res->body;
  const std::string id = json::parse(res->body)["id"];
  // Bob uploads ten models of the same size: each drops his own oldest.
  int bob_ok = 0;
  for (int i = 0; i < 10; ++i) {
    res = c.Post("/api/models", bob, grid_glb(40 + i), "model/gltf-binary");
    ASSERT_TRUE(res);
    bob_ok += res->status == 201;
  }
  EXPECT_EQ(bob_ok, 10);
  EXPECT_NE(store.find(id), nullptr);
  res = c.Post("/api/render", alice, mesh_scene_body(id, "color"), "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200) << res->body;
  // A model over his share: 422 naming it.
  res = c.Post("/api/models", bob, grid_glb(110), "model/gltf-binary");
  expect_json_error(res, 422, "");
  EXPECT_NE(res->body.find("--upload-quota-mib"), std::string::npos) << res->body;
  api.stop();
  serving.join();
}

// Round 2, finding 2: one token's uploads never delete another token's
// file from --model-store within its share (a quarter of the folder, as
// --upload-quota-mib is of --models-budget-mib); another server still
// finds it there.
TEST(Http, OneTokensUploadsCannotEvictAnothersStoredModel) {
  StoreFolder folder("owners");
  ServerOptions options;
  options.model_store_dir = folder.path.string();
  const auto on_disk = [](const std::string& glb) { return (glb.size() + 4095) / 4096 * 4096 + 4096; };
  options.model_store_max_bytes = 8 * on_disk(grid_glb(49));
  std::string error;
  const auto tokens = TokenTable::parse("alice-token-0123456789 render,upload\nbob-token-0123456789 render,upload\n", error);
  ASSERT_TRUE(tokens) << error;
  options.tokens = std::make_shared<const TokenTable>(*tokens);
  ModelStore memory(std::uint64_t(256) << 20);
  OwnServer server(options, memory);
  httplib::Client c("127.0.0.1", server.api.port());
  const httplib::Headers alice = {{"Authorization", "Bearer alice-token-0123456789"}},
                         bob = {{"Authorization", "Bearer bob-token-0123456789"}};
  const std::string alice_glb = grid_glb(30);
  auto res = c.Post("/api/models", alice, alice_glb, "model/gltf-binary");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 201) << res->body;
  const std::string id = model_id_for(alice_glb);
  for (int n = 40; n < 58; ++n) {
    res = c.Post("/api/models", bob, grid_glb(n), "model/gltf-binary");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 201) << n << ": " << res->body;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));  // distinct mtimes
  }
  EXPECT_TRUE(std::filesystem::exists(folder.path / (id.substr(7) + ".glb"))) << "alice's file was evicted";
  EXPECT_FALSE(std::filesystem::exists(folder.path / (model_id_for(grid_glb(40)).substr(7) + ".glb")));
  // Another server of the cluster (holding nothing) still finds it.
  ModelStore other_memory(std::uint64_t(256) << 20);
  OwnServer other(options, other_memory);
  httplib::Client o("127.0.0.1", other.api.port());
  res = o.Get("/api/models/" + id, alice);
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200) << res->body;
}

// Round 2, finding 4: a model larger than the whole folder may hold is 422
// (retrying never helps), naming the bound; a write error names the model
// and the error, never the server's path; 507 has its reason phrase.
TEST(Http, AModelOverTheWholeStoreIs422AndStoreErrorsNameNoPath) {
  EXPECT_STREQ(reason_phrase(507), "Insufficient Storage");
  EXPECT_STREQ(reason_phrase(421), "Misdirected Request");
  StoreFolder folder("whole");
  ServerOptions options;
  options.model_store_dir = folder.path.string();
  options.model_store_max_bytes = 64 << 10;
  OwnServer server(options);
  httplib::Client c("127.0.0.1", server.api.port());
  const std::string glb = grid_glb(80);
  ASSERT_GT(glb.size(), std::size_t(64) << 10);
  auto res = c.Post("/api/models", glb, "model/gltf-binary");
  expect_json_error(res, 422, "");
  EXPECT_NE(res->body.find("--model-store-max-gib"), std::string::npos) << res->body;
  EXPECT_FALSE(res->has_header("Retry-After"));
  // The folder is gone: 503, naming the id and the error only.
  std::filesystem::remove_all(folder.path);
  res = c.Post("/api/models", grid_glb(20), "model/gltf-binary");
  expect_json_error(res, 503, "");
  EXPECT_EQ(res->body.find(folder.path.string()), std::string::npos) << res->body;
  EXPECT_NE(res->body.find(model_id_for(grid_glb(20)).substr(0, 19)), std::string::npos) << res->body;
  std::filesystem::create_directories(folder.path);
}

}  // namespace
}  // namespace umbra

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  testing::AddGlobalTestEnvironment(new umbra::ServerEnvironment);
  return RUN_ALL_TESTS();
}
