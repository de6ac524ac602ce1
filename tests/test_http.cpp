// The real server on an ephemeral loopback port, driven over HTTP.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <thread>

#include <httplib.h>
#include <nlohmann/json.hpp>
#include <stb_image.h>

#include "http_api.hpp"
#include "render_service.hpp"

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
    options.log_requests = false;
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
};

Decoded decode_png(const std::string& bytes) {
  Decoded d;
  unsigned char* pixels = stbi_load_from_memory(reinterpret_cast<const unsigned char*>(bytes.data()), int(bytes.size()),
                                                &d.width, &d.height, &d.channels, 0);
  EXPECT_NE(pixels, nullptr) << "not a PNG";
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
}

TEST(Http, ScenesListsTheBuiltInsInCustomSceneForm) {
  auto res = client().Get("/api/scenes");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  const json j = json::parse(res->body);
  ASSERT_EQ(j["scenes"].size(), 2u);
  EXPECT_EQ(j["scenes"][0]["name"], "cube-on-plane");
  // The object list is usable as a custom scene as it is.
  const json body = {{"width", 64}, {"height", 64}, {"scene", {{"objects", j["scenes"][1]["objects"]}}}};
  auto render = client().Post("/api/render", body.dump(), "application/json");
  ASSERT_TRUE(render);
  EXPECT_EQ(render->status, 200) << render->body;
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
    EXPECT_FALSE(res->get_header_value("Server-Timing").empty());
    const std::string measures = res->get_header_value("Umbra-Shadow-Error");
    if (std::string(c.output) == "error")
      EXPECT_NE(measures.find("false_light="), std::string::npos) << measures;
    else
      EXPECT_TRUE(measures.empty()) << c.output;
  }
}

TEST(Http, DepthRouteIsTheDepthOutput) {
  auto res = client().Post("/api/depth", R"({"shadow": {"map_size": 128}})", "application/json");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  const Decoded d = decode_png(res->body);
  EXPECT_EQ(d.width, 128);
  EXPECT_EQ(d.height, 128);
  expect_json_error(client().Post("/api/depth", R"({"output": "shadow"})", "application/json"), 400, "output");
}

// A render slow enough on llvmpipe (about a second) to hold the queue.
const char* kSlowBody = R"({"width": 2048, "height": 2048, "output": "shadow", "shadow": {"pcf_radius": 8}})";

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

TEST(Http, UnusedFieldsAreReportedNotIgnored) {
  auto res = client().Post("/api/render", R"({"width": 32, "height": 32, "shadow": {"near": 2}})", "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_EQ(res->get_header_value("Umbra-Unused-Fields"), "shadow.near");
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
}

TEST(Http, BodyOverOneMebibyteIs413) {
  const std::string body = R"({"scene": ")" + std::string((1 << 20) + 10, 'x') + R"("})";
  expect_json_error(client().Post("/api/render", body, "application/json"), 413, "");
  // And the server still answers.
  auto res = client().Get("/api/health");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
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

}  // namespace
}  // namespace umbra

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  testing::AddGlobalTestEnvironment(new umbra::ServerEnvironment);
  return RUN_ALL_TESTS();
}
