// umbra-load-bench: the real umbra-server under concurrent clients.
//
// Starts build/server/umbra-server on a free loopback port (or uses --url),
// then for 1, 2, 4, 8 and 16 clients, each on its own keep-alive
// connection, posts animation frames of the default scene at 960x540 (time
// advancing 1/30 s per frame, so the light orbits and every frame needs its
// shadow pass) for --seconds, after a warm-up. Prints frames/s, latency
// percentiles and, from Server-Timing, the render-only time
// (shadow + main + readback); writes the table to bench/results/load.md.
//
//   umbra-load-bench [--seconds 10] [--clients 1,2,4,8,16] [--url HOST:PORT] [--out FILE]
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <iterator>

#include <httplib.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include "server_process.hpp"

namespace {

using Clock = std::chrono::steady_clock;
using json = nlohmann::json;

struct Sample {
  double total_ms;   // request sent -> whole response read, at the client
  double render_ms;  // shadow + main + readback, from Server-Timing
  double encode_ms;
  double queue_ms;
};

// "shadow;dur=1.5, main;dur=2.0, ..." -> the duration named `name`.
double timing(const std::string& header, const std::string& name) {
  const std::string key = name + ";dur=";
  const std::size_t at = header.find(key);
  return at == std::string::npos ? 0.0 : std::atof(header.c_str() + at + key.size());
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, std::size_t(p * double(v.size() - 1) + 0.5))];
}

// CPU seconds (user + system) the process has used so far; -1 if unknown.
double cpu_seconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t close = text.rfind(')');  // the command name may hold spaces
  if (close == std::string::npos) return -1.0;
  std::istringstream fields(text.substr(close + 2));
  std::string field;
  double utime = 0, stime = 0;
  for (int i = 3; i <= 15 && fields >> field; ++i) {
    if (i == 14) utime = std::atof(field.c_str());
    if (i == 15) stime = std::atof(field.c_str());
  }
  return (utime + stime) / double(sysconf(_SC_CLK_TCK));
}

struct Run {
  int clients;
  double server_cpu = -1.0;  // the server's CPU use while measuring, in cores (1.0 = one core busy)
  std::vector<Sample> samples;
  int refused = 0;  // 503
  int failed = 0;   // anything else
  double seconds = 0.0;
};

// "161 %", or "-" for a server this program did not start (--url): its
// CPU time cannot be read.
std::string cpu_text(double server_cpu) {
  if (server_cpu < 0.0) return "-";
  char text[32];
  std::snprintf(text, sizeof text, "%.0f %%", 100.0 * server_cpu);
  return text;
}

Run drive(const std::string& host, int port, int clients, double seconds, std::atomic<long>& frame_counter,
          pid_t server_pid) {
  Run run;
  run.clients = clients;
  std::mutex mutex;
  std::atomic<bool> measuring{false}, stop{false};
  std::vector<std::thread> threads;
  for (int c = 0; c < clients; ++c) {
    threads.emplace_back([&] {
      httplib::Client client(host, port);
      client.set_keep_alive(true);
      client.set_tcp_nodelay(true);  // as browsers do
      client.set_read_timeout(120, 0);
      while (!stop.load()) {
        const long frame = frame_counter.fetch_add(1);
        const std::string body = json{{"time", double(frame) / 30.0}}.dump();
        const auto start = Clock::now();
        auto res = client.Post("/api/render", body, "application/json");
        const double ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
        if (!measuring.load()) continue;
        std::lock_guard<std::mutex> lock(mutex);
        if (res && res->status == 200) {
          const std::string t = res->get_header_value("Server-Timing");
          run.samples.push_back({ms, timing(t, "shadow") + timing(t, "main") + timing(t, "readback"),
                                 timing(t, "encode"), timing(t, "queue")});
        } else if (res && res->status == 503) {
          ++run.refused;
        } else {
          ++run.failed;
        }
      }
    });
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // warm-up: connections, GL resources
  const auto start = Clock::now();
  const double cpu_start = server_pid > 0 ? cpu_seconds(server_pid) : -1.0;
  measuring.store(true);
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  measuring.store(false);
  run.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  if (server_pid > 0) run.server_cpu = (cpu_seconds(server_pid) - cpu_start) / run.seconds;
  stop.store(true);
  for (auto& t : threads) t.join();
  return run;
}

std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown CPU";
}

}  // namespace

int main(int argc, char** argv) {
  double seconds = 10.0;
  std::vector<int> counts = {1, 2, 4, 8, 16};
  std::string url, out = std::string(UMBRA_RESULTS_DIR) + "/load.md";
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "--seconds" && has_value) {
      seconds = std::max(1.0, std::atof(argv[++i]));
    } else if (arg == "--clients" && has_value) {
      counts.clear();
      std::stringstream list(argv[++i]);
      for (std::string item; std::getline(list, item, ',');) counts.push_back(std::max(1, std::atoi(item.c_str())));
    } else if (arg == "--url" && has_value) {
      url = argv[++i];
    } else if (arg == "--out" && has_value) {
      out = argv[++i];
    } else {
      std::fprintf(stderr, "usage: umbra-load-bench [--seconds S] [--clients 1,2,4,8,16] [--url HOST:PORT] [--out FILE]\n");
      return 2;
    }
  }
  std::unique_ptr<umbra::testing::ServerProcess> server;
  std::string host = "127.0.0.1";
  int port = 0;
  if (url.empty()) {
    server = std::make_unique<umbra::testing::ServerProcess>(UMBRA_SERVER_BINARY, std::vector<std::string>{"--quiet"});
    port = server->port();
  } else {
    host = url.substr(0, url.rfind(':'));
    port = std::atoi(url.c_str() + url.rfind(':') + 1);
  }
  httplib::Client probe(host, port);
  auto health_res = probe.Get("/api/health");
  if (!health_res || health_res->status != 200) {
    std::fprintf(stderr, "umbra-load-bench: no server at %s:%d\n", host.c_str(), port);
    return 1;
  }
  const json health = json::parse(health_res->body);
  const long deadline_ms = 10000;  // the server's default --deadline-ms (the one started here)

  std::atomic<long> frame_counter{0};
  std::vector<Run> runs;
  std::printf("%7s %9s %8s %8s %8s %8s %10s %9s %9s %5s %5s %8s\n", "clients", "requests", "frames/s", "p50 ms",
              "p99 ms", "max ms", "render ms", "encode ms", "queue ms", "503", "fail", "cpu");
  for (int clients : counts) {
    runs.push_back(drive(host, port, clients, seconds, frame_counter, server ? server->pid() : -1));
    const Run& r = runs.back();
    std::vector<double> total, render, encode, queue;
    for (const Sample& s : r.samples) {
      total.push_back(s.total_ms);
      render.push_back(s.render_ms);
      encode.push_back(s.encode_ms);
      queue.push_back(s.queue_ms);
    }
    std::printf("%7d %9zu %8.2f %8.1f %8.1f %8.1f %10.1f %9.1f %9.1f %5d %5d %8s\n", clients, r.samples.size(),
                double(r.samples.size()) / r.seconds, percentile(total, 0.5), percentile(total, 0.99),
                percentile(total, 1.0), percentile(render, 0.5), percentile(encode, 0.5), percentile(queue, 0.5),
                r.refused, r.failed, cpu_text(r.server_cpu).c_str());
  }

  // The verdicts the issue sets, from this one run.
  const auto fps = [&](int clients) {
    for (const Run& r : runs)
      if (r.clients == clients) return double(r.samples.size()) / r.seconds;
    return 0.0;
  };
  std::string verdicts;
  char line[512];
  for (const Run& r : runs) {
    if (r.clients != 1) continue;
    std::vector<double> ratio;
    for (const Sample& s : r.samples) ratio.push_back(s.total_ms / std::max(1e-9, s.render_ms));
    std::snprintf(line, sizeof line, "- end-to-end / render-only time at 1 client (median of per-request ratios): %.2f (target <= 1.3)\n",
                  percentile(ratio, 0.5));
    verdicts += line;
  }
  if (fps(1) > 0 && fps(8) > 0) {
    std::snprintf(line, sizeof line, "- throughput at 8 clients / at 1 client: %.2f (target >= 1.5)\n", fps(8) / fps(1));
    verdicts += line;
  }
  for (const Run& r : runs) {
    if (r.clients != 16) continue;
    std::vector<double> total, queue;
    for (const Sample& s : r.samples) total.push_back(s.total_ms), queue.push_back(s.queue_ms);
    std::snprintf(line, sizeof line,
                  "- 16 clients: p99 %.0f ms, longest wait for the GL thread %.0f ms, %d refused with 503 (deadline %ld ms)\n",
                  percentile(total, 0.99), percentile(queue, 1.0), r.refused, deadline_ms);
    verdicts += line;
  }
  std::printf("%s", verdicts.c_str());

  std::ofstream file(out);
  file << "# Load: the real server over loopback\n\n"
       << "`build/bench/umbra-load-bench --seconds " << seconds << "`: the default scene at 960x540, `time` advancing "
       << "1/30 s per frame (every frame draws its shadow map), each client on its own keep-alive connection, after "
       << "1.5 s of warm-up. Machine: " << std::thread::hardware_concurrency() << " cores, " << cpu_model() << "; "
       << health["gl_renderer"].get<std::string>() << ". Latencies are at the client; render is shadow + main + "
       << "readback from `Server-Timing`; server CPU is the server process's CPU time over wall time (100 % = one core "
       << "busy); all rows from one run.\n\n"
       << "| clients | requests | frames/s | p50 ms | p99 ms | max ms | render ms (p50) | encode ms (p50) | queue ms (p50) "
          "| 503 | server CPU |\n"
       << "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const Run& r : runs) {
    std::vector<double> total, render, encode, queue;
    for (const Sample& s : r.samples) total.push_back(s.total_ms), render.push_back(s.render_ms),
        encode.push_back(s.encode_ms), queue.push_back(s.queue_ms);
    std::snprintf(line, sizeof line, "| %d | %zu | %.2f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %d | %s |\n",
                  r.clients, r.samples.size(), double(r.samples.size()) / r.seconds, percentile(total, 0.5),
                  percentile(total, 0.99), percentile(total, 1.0), percentile(render, 0.5), percentile(encode, 0.5),
                  percentile(queue, 0.5), r.refused, cpu_text(r.server_cpu).c_str());
    file << line;
  }
  file << "\n" << verdicts;
  std::printf("wrote %s\n", out.c_str());
  if (server) {
    server->send_signal(SIGTERM);
    server->wait();
  }
  return 0;
}
