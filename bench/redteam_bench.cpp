// umbra-redteam-bench: the second red team's findings (issue 29), each
// reproduced against a real umbra-server process as the red team did it,
// with what the server answered, how long it took and what it held. Run it
// on an older binary (--server PATH) to see the findings, on the current
// one to see them closed. Writes bench/results/redteam.md.
//
//   umbra-redteam-bench [--server PATH] [--out FILE] [--seconds 10] [--only 1,4]
//
// --seconds: how long the non-reading clients' attack is probed; --only:
// just those findings' rows.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
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

#include <glm/vec3.hpp>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include "gltf_builder.hpp"
#include "server_process.hpp"

namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;
using umbra::testing::ServerProcess;

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }


// ---- Models, built in code as the red team built them. ----

// `count` 40 x 40 quads stacked 1 mm apart, one mesh: every pixel under
// them is drawn `count` times.
std::string stacked_quads(int count) {
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices;
  for (int q = 0; q < count; ++q) {
    const float y = 0.001f * float(q);
    const std::uint32_t b = std::uint32_t(positions.size());
    positions.insert(positions.end(), {{-20, y, -20}, {20, y, -20}, {20, y, 20}, {-20, y, 20}});
    indices.insert(indices.end(), {b, b + 3, b + 2, b, b + 2, b + 1});
  }
  umbra::test::GltfBuilder g;
  g.scene({g.node({{"mesh", g.mesh(g.vec3s(positions), g.indices_u32(indices))}})});
  return g.glb();
}

// A side x side grid of quads instanced by `instances` nodes; `salt` moves
// one vertex so that each call's file (and id) is distinct.
std::string instanced_grid(int side, int instances, int salt) {
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices;
  for (int z = 0; z <= side; ++z)
    for (int x = 0; x <= side; ++x) positions.push_back({x * 0.01f, 0.0f, z * 0.01f});
  positions[0].y = 1e-4f * float(salt);
  for (int z = 0; z < side; ++z)
    for (int x = 0; x < side; ++x) {
      const std::uint32_t a = std::uint32_t(z * (side + 1) + x), b = a + 1, c = a + side + 1, d = c + 1;
      indices.insert(indices.end(), {a, c, b, b, c, d});
    }
  umbra::test::GltfBuilder g;
  const int mesh = g.mesh(g.vec3s(positions), g.indices_u32(indices));
  std::vector<int> roots;
  for (int i = 0; i < instances; ++i)
    roots.push_back(g.node({{"mesh", mesh}, {"translation", {(i % 100) * 0.5, 0.0, (i / 100) * 0.5}}}));
  g.scene(roots);
  return g.glb();
}

// `triangles` separate triangles scattered in a 2 x 1 x 2 box, drawn once
// each (no instancing: loaded, about its body's size again); `salt` makes
// each call's file distinct.
std::string triangle_soup(int triangles, int salt) {
  std::vector<glm::vec3> positions;
  std::uint32_t state = 2463534242u + std::uint32_t(salt);
  const auto next = [&] {
    state ^= state << 13, state ^= state >> 17, state ^= state << 5;
    return float(state % 100000) / 100000.0f;
  };
  for (int t = 0; t < triangles; ++t) {
    const glm::vec3 corner(2 * next() - 1, next(), 2 * next() - 1);
    positions.insert(positions.end(), {corner, corner + glm::vec3(0.05f, 0, 0), corner + glm::vec3(0, 0.05f, 0)});
  }
  umbra::test::GltfBuilder g;
  g.scene({g.node({{"mesh", g.mesh(g.vec3s(positions))}})});
  return g.glb();
}

// A unit cube and `padding` bytes of buffer no accessor reads: a large
// upload that holds almost no geometry. `salt` makes each distinct.
std::string padded_cube(std::size_t padding, int salt) {
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices;
  umbra::test::unit_cube(positions, indices, 0.5f + 1e-3f * float(salt));
  umbra::test::GltfBuilder g;
  g.scene({g.node({{"mesh", g.mesh(g.vec3s(positions), g.indices_u32(indices))}})});
  g.view(std::string(padding, '\0'));
  return g.glb();
}

// ---- Rows. ----

struct Row {
  std::string finding, attack, answer;
  double seconds = 0;
  long peak_rss_mib = -1;
};

// The server's resident memory, sampled every 20 ms while `work` runs.
template <class Work>
long peak_rss_during(const ServerProcess& server, Work&& work) {
  std::atomic<bool> done{false};
  std::atomic<long> peak{server.resident_kib()};
  std::thread sampler([&] {
    while (!done) {
      peak = std::max(peak.load(), server.resident_kib());
      std::this_thread::sleep_for(milliseconds(20));
    }
  });
  work();
  done = true;
  sampler.join();
  return peak / 1024;
}

std::string status_of(const httplib::Result& r) {
  if (!r) return "no answer (" + httplib::to_string(r.error()) + ")";
  std::string s = std::to_string(r->status);
  if (r->status >= 400) {
    std::string message = r->body;
    try {
      message = json::parse(r->body).value("error", r->body);
    } catch (...) {
    }
    if (message.size() > 90) message = message.substr(0, 90) + "...";
    s += " \"" + message + "\"";
  }
  return s;
}

httplib::Client client_for(int port, int timeout_s = 600) {
  httplib::Client c("127.0.0.1", port);
  c.set_read_timeout(timeout_s, 0);
  c.set_write_timeout(timeout_s, 0);
  return c;
}

std::string upload_id(httplib::Client& c, const std::string& glb, std::string* answer = nullptr,
                      const httplib::Headers& headers = {}) {
  auto r = c.Post("/api/models", headers, glb, "model/gltf-binary");
  if (answer) *answer = status_of(r);
  if (!r || r->status != 201) return "";
  return json::parse(r->body).value("id", "");
}

json mesh_scene(const std::vector<std::string>& models, int size) {
  json objects = json::array({{{"type", "plane"}, {"size", {60, 60}}}});
  for (const std::string& id : models) objects.push_back({{"type", "mesh"}, {"model", id}, {"position", {0, 0.5, 0}}});
  return {{"width", size}, {"height", size}, {"scene", {{"objects", objects}}}};
}

// The same, seen from above so that the models fill the frame.
json mesh_scene_from_above(const std::vector<std::string>& models, int size) {
  json body = mesh_scene(models, size);
  body["camera"] = {{"position", {0, 30, 0.01}}, {"target", {0, 0, 0}}};
  return body;
}

// A server with `args`, and `optional` too if the binary knows them (an
// older build does not: then without, and `note` says so).
std::unique_ptr<ServerProcess> start_server(const std::string& binary, std::vector<std::string> args,
                                            const std::vector<std::string>& optional, std::string& note) {
  std::vector<std::string> all = args;
  all.insert(all.end(), optional.begin(), optional.end());
  try {
    return std::make_unique<ServerProcess>(binary, all);
  } catch (const std::exception& e) {
    if (std::string(e.what()).find("unknown option") == std::string::npos) throw;
    note = "(this binary has no " + optional.front() + ") ";
    return std::make_unique<ServerProcess>(binary, args);
  }
}

// Finding 1: one small upload whose one mesh is thousands of layers deep.
Row mesh_overdraw(const std::string& binary) {
  Row row{"1. GL time", "4,000 stacked 40 x 40 quads (" + std::to_string(stacked_quads(4000).size() / 1024) +
                            " KiB upload), then a 512 x 512 render of them from above; a 160 x 90 default render 1 s later",
          ""};
  ServerProcess server(binary, {"--quiet"});
  auto c = client_for(server.port());
  std::string answer;
  const std::string id = upload_id(c, stacked_quads(4000), &answer);
  if (id.empty()) return row.answer = "upload: " + answer, row;
  std::string big, small;
  double small_s = 0;
  const auto start = Clock::now();
  row.peak_rss_mib = peak_rss_during(server, [&] {
    std::thread second([&] {
      std::this_thread::sleep_for(std::chrono::seconds(1));
      auto s = client_for(server.port());
      const auto sent = Clock::now();
      small = status_of(s.Post("/api/render", R"({"width": 160, "height": 90})", "application/json"));
      small_s = seconds_since(sent);
    });
    big = status_of(c.Post("/api/render", mesh_scene_from_above({id}, 512).dump(), "application/json"));
    row.seconds = seconds_since(start);
    second.join();
  });
  char line[160];
  std::snprintf(line, sizeof line, "; the small render: %s after %.1f s", small.c_str(), small_s);
  row.answer = big + line;
  return row;
}

// Finding 2: models in the store, each large once loaded, all named by one
// small render. `glb(m)` is the m-th distinct model.
Row store_models_over_budget(const std::string& binary, const std::string& finding, const std::string& what,
                             int models, const std::function<std::string(int)>& glb, const std::string& budget_mib) {
  Row row{finding, "", ""};
  const fs::path store = fs::temp_directory_path() / ("umbra-redteam-store-" + std::to_string(getpid()));
  fs::remove_all(store);
  fs::create_directories(store);
  std::vector<std::string> ids;
  std::size_t upload_bytes = 0;
  {
    ServerProcess uploader(binary, {"--quiet", "--model-store", store.string()});
    auto c = client_for(uploader.port());
    for (int m = 0; m < models; ++m) {
      const std::string file = glb(m);
      upload_bytes = file.size();
      std::string answer;
      ids.push_back(upload_id(c, file, &answer));
      if (ids.back().empty()) {
        row.attack = std::to_string(models) + " distinct uploads (" + std::to_string(upload_bytes / 1024) +
                     " KiB each: " + what + ") to a --model-store";
        row.answer = "upload " + std::to_string(m + 1) + ": " + answer;
        fs::remove_all(store);
        return row;
      }
    }
  }
  const std::string body = mesh_scene(ids, 64).dump();
  row.attack = std::to_string(models) + " distinct uploads (" + std::to_string(upload_bytes / 1024) + " KiB each: " +
               what + ") in a --model-store; a fresh server on it with --models-budget-mib " + budget_mib +
               " gets one " + std::to_string(body.size()) + "-byte render naming all";
  ServerProcess server(binary, {"--quiet", "--model-store", store.string(), "--models-budget-mib", budget_mib});
  auto c = client_for(server.port());
  const auto start = Clock::now();
  row.peak_rss_mib =
      peak_rss_during(server, [&] { row.answer = status_of(c.Post("/api/render", body, "application/json")); });
  row.seconds = seconds_since(start);
  fs::remove_all(store);
  return row;
}

// Finding 3: a model of many node instances.
Row many_instances(const std::string& binary) {
  // As many triangles an instance as the upload ratio (16 x body + 32 MiB
  // once loaded) lets 10,000 instances have.
  const std::string glb = instanced_grid(6, 10000, 0);
  Row row{"3. load time", "upload of a 6 x 6 grid (72 triangles) in 10,000 nodes (" + std::to_string(glb.size() / 1024) + " KiB)", ""};
  ServerProcess server(binary, {"--quiet"});
  auto c = client_for(server.port());
  const auto start = Clock::now();
  row.peak_rss_mib = peak_rss_during(server, [&] { upload_id(c, glb, &row.answer); });
  row.seconds = seconds_since(start);
  return row;
}

int connect_small_buffer(int port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  const int kib = 1024;
  setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &kib, sizeof kib);
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

// Finding 4: connections that ask for much and never read, each opened
// again (and its requests sent again) as soon as the server closes it.
Row non_readers(const std::string& binary, double seconds) {
  Row row{"4. connections",
          "256 connections with a 1 KiB receive buffer, 60 pipelined GET /api/openapi.json each, never read, each "
          "reopened when closed; GET /api/health probed every 250 ms on a fresh connection",
          ""};
  ServerProcess server(binary, {"--quiet"});
  std::string pipelined;
  for (int k = 0; k < 60; ++k) pipelined += "GET /api/openapi.json HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
  const auto open_one = [&] {
    const int fd = connect_small_buffer(server.port());
    if (fd < 0) return fd;
    timeval one{1, 0};
    setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &one, sizeof one);
    send(fd, pipelined.data(), pipelined.size(), MSG_NOSIGNAL);
    return fd;
  };
  std::atomic<bool> quit{false};
  std::atomic<int> opened{0};
  std::thread attacker([&] {
    std::vector<int> fds(256, -1);
    while (!quit) {
      for (int& fd : fds) {
        pollfd p{fd, POLLRDHUP, 0};
        if (fd >= 0 && poll(&p, 1, 0) == 0) continue;  // still open
        if (fd >= 0) close(fd);
        fd = open_one();
        ++opened;
      }
      std::this_thread::sleep_for(milliseconds(50));
    }
    for (int fd : fds)
      if (fd >= 0) close(fd);
  });
  std::this_thread::sleep_for(std::chrono::seconds(1));
  int probes = 0, answered = 0;
  std::string first_failure;
  const auto start = Clock::now();
  row.peak_rss_mib = peak_rss_during(server, [&] {
    while (seconds_since(start) < seconds) {
      auto c = client_for(server.port(), 5);
      const auto sent = Clock::now();
      auto r = c.Get("/api/health");
      ++probes;
      answered += r && r->status == 200;
      if (!(r && r->status == 200) && first_failure.empty()) {
        char after[32];
        std::snprintf(after, sizeof after, " after %.1f s", seconds_since(sent));
        first_failure = status_of(r) + after;
      }
      std::this_thread::sleep_for(milliseconds(250));
    }
  });
  row.seconds = seconds_since(start);
  quit = true;
  attacker.join();
  row.answer = std::to_string(answered) + " of " + std::to_string(probes) + " health probes answered 200 (" +
               std::to_string(opened.load()) + " attacking connections opened)" +
               (first_failure.empty() ? "" : "; the first failure: " + first_failure);
  return row;
}

// Finding 6: many large uploads into the shared folder.
Row store_disk(const std::string& binary) {
  constexpr int kUploads = 24;
  const fs::path store = fs::temp_directory_path() / ("umbra-redteam-disk-" + std::to_string(getpid()));
  fs::remove_all(store);
  fs::create_directories(store);
  Row row{"6. disk",
          std::to_string(kUploads) + " distinct 64 MiB uploads (a cube and unread buffer bytes) to a server with " +
              "--model-store and --model-store-max-gib 1",
          ""};
  {
    std::string note;
    auto started = start_server(binary, {"--quiet", "--model-store", store.string(), "--max-model-mib", "65"},
                                {"--model-store-max-gib", "1"}, note);
    ServerProcess& server = *started;
    auto c = client_for(server.port());
    int created = 0;
    std::string last;
    const auto start = Clock::now();
    row.peak_rss_mib = peak_rss_during(server, [&] {
      for (int k = 0; k < kUploads; ++k) created += !upload_id(c, padded_cube((std::size_t(64) << 20) - 4096, k), &last).empty();
    });
    row.seconds = seconds_since(start);
    std::uintmax_t bytes = 0;
    for (const auto& f : fs::recursive_directory_iterator(store))
      if (f.is_regular_file()) bytes += f.file_size();
    row.answer = note + std::to_string(created) + " x 201; the folder holds " + std::to_string(bytes >> 20) + " MiB";
    if (created < kUploads) row.answer += "; last: " + last;
  }
  fs::remove_all(store);
  return row;
}

// Finding 7: one client's uploads against another's model.
Row eviction(const std::string& binary, const std::string& finding, const std::string& what, int uploads,
             const std::function<std::string(int)>& glb, const std::string& budget_mib) {
  const fs::path tokens = fs::temp_directory_path() / ("umbra-redteam-tokens-" + std::to_string(getpid()));
  std::ofstream(tokens) << "token-of-alice-0123456789 render,upload\ntoken-of-mallory-0123456789 render,upload\n";
  Row row{finding,
          "with --tokens and --models-budget-mib " + budget_mib + ", Alice uploads a cube; Mallory uploads " +
              std::to_string(uploads) + " distinct " + std::to_string(glb(0).size() / 1024) + " KiB models (" + what +
              "); Alice renders her cube",
          ""};
  std::string note;
  auto started = start_server(binary, {"--quiet", "--models-budget-mib", budget_mib}, {"--tokens", tokens.string()}, note);
  ServerProcess& server = *started;
  auto c = client_for(server.port());
  httplib::Headers alice{{"Authorization", "Bearer token-of-alice-0123456789"}},
      mallory{{"Authorization", "Bearer token-of-mallory-0123456789"}};
  if (!note.empty()) alice.clear(), mallory.clear();
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices;
  umbra::test::unit_cube(positions, indices, 0.5f);
  umbra::test::GltfBuilder g;
  g.scene({g.node({{"mesh", g.mesh(g.vec3s(positions), g.indices_u32(indices))}})});
  std::string answer;
  const std::string cube = upload_id(c, g.glb(), &answer, alice);
  if (cube.empty()) return row.answer = "Alice's upload: " + answer, fs::remove(tokens), row;
  int accepted = 0;
  std::string last;
  const auto start = Clock::now();
  row.peak_rss_mib = peak_rss_during(server, [&] {
    for (int k = 0; k < uploads; ++k) accepted += !upload_id(c, glb(k), &last, mallory).empty();
  });
  row.seconds = seconds_since(start);
  auto r = c.Post("/api/render", alice, mesh_scene({cube}, 64).dump(), "application/json");
  row.answer = note + "Mallory: " + std::to_string(accepted) + " of " + std::to_string(uploads) + " accepted (last: " +
               last + "); Alice's render: " + status_of(r);
  fs::remove(tokens);
  return row;
}

// Finding 8: Host headers a browser under DNS rebinding, or no browser, sends.
Row hosts(const std::string& binary) {
  Row row{"8. Host", "POST /api/models and GET /metrics with Host: evil.example; GET /api/health with no Host, and with two", ""};
  ServerProcess server(binary, {"--quiet"});
  auto raw = [&](const std::string& head) {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(std::uint16_t(server.port()));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    std::string answer;
    if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0) {
      send(fd, head.data(), head.size(), MSG_NOSIGNAL);
      char buffer[4096];
      for (ssize_t n; (n = recv(fd, buffer, sizeof buffer, 0)) > 0;) answer.append(buffer, std::size_t(n));
    }
    close(fd);
    return answer.size() >= 12 ? answer.substr(9, 3) : std::string("no answer");
  };
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices;
  umbra::test::unit_cube(positions, indices, 0.5f);
  umbra::test::GltfBuilder g;
  g.scene({g.node({{"mesh", g.mesh(g.vec3s(positions), g.indices_u32(indices))}})});
  const std::string glb = g.glb();
  const auto start = Clock::now();
  row.answer = "upload " +
               raw("POST /api/models HTTP/1.1\r\nHost: evil.example\r\nConnection: close\r\nContent-Type: "
                   "model/gltf-binary\r\nContent-Length: " +
                   std::to_string(glb.size()) + "\r\n\r\n" + glb) +
               ", metrics " + raw("GET /metrics HTTP/1.1\r\nHost: evil.example\r\nConnection: close\r\n\r\n") +
               ", no Host " + raw("GET /api/health HTTP/1.1\r\nConnection: close\r\n\r\n") + ", two Hosts " +
               raw("GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n");
  row.seconds = seconds_since(start);
  return row;
}

// Finding 9: a sun clock past the supported years.
Row sun_clock(const std::string& binary) {
  Row row{"9. sun clock", "light.sun.utc 5000-12-31T00:00:00Z with time 1e9 s (year 5032)", ""};
  ServerProcess server(binary, {"--quiet"});
  auto c = client_for(server.port());
  const auto start = Clock::now();
  row.answer = status_of(c.Post(
      "/api/render",
      R"({"width": 64, "height": 64, "time": 1e9, "light": {"sun": {"latitude": 0, "longitude": 0, "utc": "5000-12-31T00:00:00Z"}}})",
      "application/json"));
  row.seconds = seconds_since(start);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  std::string binary = UMBRA_SERVER_BINARY;
  std::string out = std::string(UMBRA_RESULTS_DIR) + "/redteam.md";
  double seconds = 10;
  std::string only;  // ",1,4,": just those findings
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--server" && i + 1 < argc)
      binary = argv[++i];
    else if (arg == "--out" && i + 1 < argc)
      out = argv[++i];
    else if (arg == "--seconds" && i + 1 < argc)
      seconds = std::atof(argv[++i]);
    else if (arg == "--only" && i + 1 < argc)
      only = "," + std::string(argv[++i]) + ",";
    else {
      std::fprintf(stderr, "usage: umbra-redteam-bench [--server PATH] [--out FILE] [--seconds 10] [--only 1,4]\n");
      return 2;
    }
  }
  const std::vector<std::pair<const char*, std::function<Row()>>> findings = {
      {"1", [&] { return mesh_overdraw(binary); }},
      {"2", [&] {
         return store_models_over_budget(binary, "2. memory (amplified)", "a 20 x 20 grid in 5,000 nodes, 4M triangles",
                                         4, [](int m) { return instanced_grid(20, 5000, m); }, "512");
       }},
      {"2", [&] {
         return store_models_over_budget(binary, "2. memory", "100,000 separate triangles", 6,
                                         [](int m) { return triangle_soup(100000, m); }, "32");
       }},
      {"3", [&] { return many_instances(binary); }},
      {"4", [&] { return non_readers(binary, seconds); }},
      {"6", [&] { return store_disk(binary); }},
      {"7", [&] {
         return eviction(binary, "7. eviction (amplified)", "a 25 x 25 grid in 1,000 nodes", 7,
                         [](int k) { return instanced_grid(25, 1000, k + 1); }, "1024");
       }},
      {"7", [&] {
         return eviction(binary, "7. eviction", "200,000 separate triangles", 12,
                         [](int k) { return triangle_soup(200000, k + 1); }, "128");
       }},
      {"8", [&] { return hosts(binary); }},
      {"9", [&] { return sun_clock(binary); }},
  };
  std::vector<Row> rows;
  for (const auto& [number, run] : findings) {
    if (!only.empty() && only.find("," + std::string(number) + ",") == std::string::npos) continue;
    Row row;
    try {
      row = run();
    } catch (const std::exception& e) {
      // A flag the binary does not know: it exits before listening.
      std::string why = e.what();
      const auto unknown = why.find("unknown option");
      row.finding = number;
      row.answer = unknown != std::string::npos ? why.substr(unknown, why.find('\n', unknown) - unknown)
                                                : "the server did not start";
    }
    std::fprintf(stderr, "%-16s %7.1f s  %6ld MiB  %s\n", row.finding.c_str(), row.seconds, row.peak_rss_mib,
                 row.answer.c_str());
    rows.push_back(row);
  }
  std::ostringstream md;
  md << "# The second red team's findings (issue 29), reproduced\n\n"
     << "`umbra-redteam-bench` on " << umbra::testing::machine_summary() << ", `" << binary << "`. Each row starts fresh servers at their "
     << "defaults but for the flags it names. Finding 5 (the cluster script) is `tests/test_cluster.cpp`. "
     << "Peak RSS: the server's resident memory, sampled every 20 ms while the attack ran.\n\n"
     << "| finding | attack | answer | s | peak RSS MiB |\n|---|---|---|---:|---:|\n";
  for (const Row& r : rows) {
    char numbers[64];
    std::snprintf(numbers, sizeof numbers, "%.1f | %s", r.seconds,
                  r.peak_rss_mib < 0 ? "" : std::to_string(r.peak_rss_mib).c_str());
    md << "| " << r.finding << " | " << r.attack << " | " << r.answer << " | " << numbers << " |\n";
  }
  std::ofstream(out) << md.str();
  std::fprintf(stderr, "wrote %s\n", out.c_str());
  return 0;
}
