// What one server has answered and how long it took, for Prometheus
// (GET /metrics, the text exposition format 0.0.4): counters of requests
// by route and status and of frames by output and status, histograms of
// each request's time in the server and of each render stage, and the
// gauges the server reads at scrape time. Pure and thread-safe: no HTTP,
// no GL. Unit tested in tests/test_metrics.cpp; the whole page is checked
// with promtool in tests/test_server_process.cpp.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <utility>

#include "core/image.hpp"

namespace umbra {

/// A Prometheus histogram in seconds: cumulative buckets, sum and count.
class LatencyHistogram {
 public:
  /// Upper bounds in seconds: a frame on a GPU (1 ms) to a long ray cast (30 s).
  static constexpr std::array<double, 14> kBounds = {0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1,
                                                     0.25,  0.5,    1.0,   2.5,  5.0,   10.0, 30.0};
  void observe(double seconds);
  /// Appends NAME_bucket{LABELS,le="..."} lines, NAME_sum and NAME_count.
  void write(std::string& out, const std::string& name, const std::string& labels) const;

 private:
  std::array<std::uint64_t, kBounds.size() + 1> counts_{};  // the last: above every bound
  double sum_ = 0.0;
  std::uint64_t count_ = 0;
};

/// What the server reads from its parts when it is scraped (and what
/// /api/health reports).
struct MetricsGauges {
  std::string gl_renderer, gl_version, egl_source;
  double uptime_s = 0.0;
  std::uint64_t frames_rendered = 0, shadow_map_reuses = 0, scene_uploads = 0, context_renewals = 0;
  std::uint64_t queue_depth = 0, queue_capacity = 0;
  std::uint64_t rejected = 0, expired = 0, abandoned = 0, too_costly = 0, overran = 0;
  std::uint64_t cached_bytes = 0, models = 0, model_bytes = 0, model_budget_bytes = 0;
  std::uint64_t model_live_bytes = 0, model_share_bytes = 0, models_loaded = 0;
  std::uint64_t model_store_bytes = 0, model_store_budget_bytes = 0, model_store_evicted = 0;
  std::uint64_t connections_open = 0, connections_evicted = 0, connections_refused = 0, connections_stalled = 0;
  std::uint64_t requests_timed_out = 0, bodies_refused = 0;
};

class Metrics {
 public:
  /// One response, as it starts to go out. `route` is a route of the
  /// table as it names it ("/api/render", "/api/models/{id}"), "static"
  /// for the panel's files or "other": a bounded set of labels, whatever
  /// paths clients send. `seconds`: from the request's first byte.
  void request_answered(const std::string& route, int status, double seconds);
  /// One POST /api/render or /api/depth answered: its output ("color", ...,
  /// or "invalid" for a body refused before its output was known), its
  /// status, and for a rendered frame its stages (`timings` null otherwise).
  void frame_answered(const std::string& output, int status, const FrameTimings* timings, double encode_ms,
                      double queue_ms);
  /// The whole page.
  std::string exposition(const MetricsGauges& gauges) const;

 private:
  mutable std::mutex mutex_;
  std::map<std::pair<std::string, int>, std::uint64_t> requests_, frames_;
  std::map<std::string, LatencyHistogram> request_seconds_;  // by route
  std::map<std::string, LatencyHistogram> stage_seconds_;    // by stage
};

/// A label value as the exposition format quotes it: \ " and newline escaped.
std::string escape_label_value(const std::string& value);

}  // namespace umbra
