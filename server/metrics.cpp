#include "metrics.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace umbra {

namespace {

// Shortest round-trip text of a sample value ("0.25", "1e-05", "3").
std::string number(double v) {
  char buffer[32];
  // Counts and whole bounds as integers ("30", not %g's "3e+01").
  if (v == std::floor(v) && std::fabs(v) < 1e15) {
    std::snprintf(buffer, sizeof buffer, "%.0f", v);
    return buffer;
  }
  // %.17g prints 0.1 as 0.10000000000000001: the fewest digits that read back.
  for (int digits = 1; digits <= 17; ++digits) {
    std::snprintf(buffer, sizeof buffer, "%.*g", digits, v);
    if (std::strtod(buffer, nullptr) == v) break;
  }
  return buffer;
}

void header(std::string& out, const char* name, const char* type, const char* help) {
  out += std::string("# HELP ") + name + " " + help + "\n# TYPE " + name + " " + type + "\n";
}

void sample(std::string& out, const std::string& name, const std::string& labels, double value) {
  out += name + (labels.empty() ? "" : "{" + labels + "}") + " " + number(value) + "\n";
}

void single(std::string& out, const char* name, const char* type, const char* help, double value) {
  header(out, name, type, help);
  sample(out, name, "", value);
}

}  // namespace

std::string escape_label_value(const std::string& value) {
  std::string escaped;
  for (char c : value) {
    if (c == '\\') escaped += "\\\\";
    else if (c == '"') escaped += "\\\"";
    else if (c == '\n') escaped += "\\n";
    else escaped += c;
  }
  return escaped;
}

void LatencyHistogram::observe(double seconds) {
  std::size_t i = 0;
  while (i < kBounds.size() && seconds > kBounds[i]) ++i;
  ++counts_[i];
  sum_ += seconds;
  ++count_;
}

void LatencyHistogram::write(std::string& out, const std::string& name, const std::string& labels) const {
  const std::string prefix = labels.empty() ? "" : labels + ",";
  std::uint64_t cumulative = 0;
  for (std::size_t i = 0; i < kBounds.size(); ++i) {
    cumulative += counts_[i];
    sample(out, name + "_bucket", prefix + "le=\"" + number(kBounds[i]) + "\"", double(cumulative));
  }
  sample(out, name + "_bucket", prefix + "le=\"+Inf\"", double(count_));
  sample(out, name + "_sum", labels, sum_);
  sample(out, name + "_count", labels, double(count_));
}

void Metrics::request_answered(const std::string& route, int status, double seconds) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++requests_[{route, status}];
  request_seconds_[route].observe(seconds);
}

void Metrics::frame_answered(const std::string& output, int status, const FrameTimings* timings, double encode_ms,
                             double queue_ms) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++frames_[{output, status}];
  if (timings == nullptr) return;
  stage_seconds_["shadow"].observe(timings->shadow_ms / 1000.0);
  stage_seconds_["main"].observe(timings->main_ms / 1000.0);
  stage_seconds_["readback"].observe(timings->readback_ms / 1000.0);
  stage_seconds_["encode"].observe(encode_ms / 1000.0);
  stage_seconds_["queue"].observe(queue_ms / 1000.0);
  if (timings->ray_cast_ms) stage_seconds_["raycast"].observe(*timings->ray_cast_ms / 1000.0);
  if (timings->settle_ms) stage_seconds_["settle"].observe(*timings->settle_ms / 1000.0);
}

std::string Metrics::exposition(const MetricsGauges& g) const {
  std::string out;
  header(out, "umbra_info", "gauge", "The renderer this server draws with (value 1).");
  sample(out, "umbra_info",
         "gl_renderer=\"" + escape_label_value(g.gl_renderer) + "\",gl_version=\"" + escape_label_value(g.gl_version) +
             "\",egl_source=\"" + escape_label_value(g.egl_source) + "\"",
         1.0);
  single(out, "umbra_uptime_seconds", "gauge", "Seconds since the server started.", g.uptime_s);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    header(out, "umbra_http_requests_total", "counter", "Responses by route and HTTP status.");
    for (const auto& [key, n] : requests_)
      sample(out, "umbra_http_requests_total",
             "route=\"" + escape_label_value(key.first) + "\",status=\"" + std::to_string(key.second) + "\"", double(n));
    header(out, "umbra_http_request_duration_seconds", "histogram",
           "Time in the server per request, from its first byte to its response, by route.");
    for (const auto& [route, h] : request_seconds_)
      h.write(out, "umbra_http_request_duration_seconds", "route=\"" + escape_label_value(route) + "\"");
    header(out, "umbra_frames_total", "counter",
           "POST /api/render and /api/depth answers by output and HTTP status (output \"invalid\": refused before "
           "its output was known).");
    for (const auto& [key, n] : frames_)
      sample(out, "umbra_frames_total",
             "output=\"" + escape_label_value(key.first) + "\",status=\"" + std::to_string(key.second) + "\"", double(n));
    header(out, "umbra_render_stage_seconds", "histogram",
           "Each stage of the frames rendered: shadow, main, readback, encode, queue, for exact and error "
           "raycast (beside the GL passes), and for filter exact settle (the ray cast of uncertain pixels).");
    for (const auto& [stage, h] : stage_seconds_)
      h.write(out, "umbra_render_stage_seconds", "stage=\"" + stage + "\"");
  }
  // The renderer's and the connections' own counters and gauges, read at
  // scrape time.
  const struct {
    const char* name;
    const char* type;
    const char* help;
    double value;
  } scalars[] = {
      {"umbra_frames_rendered_total", "counter", "Frames the GL thread has drawn.", double(g.frames_rendered)},
      {"umbra_shadow_map_reuses_total", "counter", "Frames served from an earlier frame's shadow map.",
       double(g.shadow_map_reuses)},
      {"umbra_scene_uploads_total", "counter", "Scenes whose meshes had to be uploaded to GL.",
       double(g.scene_uploads)},
      {"umbra_gl_context_renewals_total", "counter",
       "Fresh GL contexts made when idle, to give back GL memory the driver kept.", double(g.context_renewals)},
      {"umbra_rejected_total", "counter", "Requests refused at once with 503: the queue was full.", double(g.rejected)},
      {"umbra_expired_total", "counter", "Requests that waited past the deadline (503).", double(g.expired)},
      {"umbra_abandoned_total", "counter", "Requests whose client left before they were answered.",
       double(g.abandoned)},
      {"umbra_too_costly_total", "counter", "Requests refused with 422: estimated over the cost budget.",
       double(g.too_costly)},
      {"umbra_overran_total", "counter", "Frames and ray casts stopped at the run-time limit (503).", double(g.overran)},
      {"umbra_queue_depth", "gauge", "Requests queued or being rendered.", double(g.queue_depth)},
      {"umbra_queue_capacity", "gauge", "Requests the queue holds before it answers 503.", double(g.queue_capacity)},
      {"umbra_scene_cache_bytes", "gauge", "Bytes of scenes the renderer keeps for reuse.", double(g.cached_bytes)},
      {"umbra_models", "gauge", "Models held (uploads, --models files and the built-in ones).", double(g.models)},
      {"umbra_model_bytes", "gauge", "Bytes of the models held.", double(g.model_bytes)},
      {"umbra_model_budget_bytes", "gauge", "--models-budget-mib in bytes.", double(g.model_budget_bytes)},
      {"umbra_model_live_bytes", "gauge",
       "Bytes the model budget counts: models held, models dropped but still drawn, room reserved for loads.",
       double(g.model_live_bytes)},
      {"umbra_model_share_bytes", "gauge", "Each client's share of the model budget (--upload-quota-mib) in bytes.",
       double(g.model_share_bytes)},
      {"umbra_models_loaded_total", "counter", "glTF bodies built into models: uploads and --model-store reads.",
       double(g.models_loaded)},
      {"umbra_model_store_bytes", "gauge", "Bytes in the --model-store folder when this server last counted them.",
       double(g.model_store_bytes)},
      {"umbra_model_store_budget_bytes", "gauge", "--model-store-max-gib in bytes (0: no --model-store).",
       double(g.model_store_budget_bytes)},
      {"umbra_model_store_evicted_total", "counter",
       "Model files this server deleted from --model-store, least recently used first, to stay under its bound.",
       double(g.model_store_evicted)},
      {"umbra_connections_open", "gauge", "Client connections open.", double(g.connections_open)},
      {"umbra_connections_evicted_total", "counter", "Connections closed to make room for new ones at --max-connections.",
       double(g.connections_evicted)},
      {"umbra_connections_refused_total", "counter", "Connections refused with 503 at --max-connections.",
       double(g.connections_refused)},
      {"umbra_connections_stalled_total", "counter", "Connections closed: the client read none of its answer for --send-stall-ms.",
       double(g.connections_stalled)},
      {"umbra_requests_timed_out_total", "counter", "Requests not received whole in time (408).",
       double(g.requests_timed_out)},
      {"umbra_bodies_refused_total", "counter", "Requests answered 503 because 256 MiB of bodies were held already.",
       double(g.bodies_refused)},
  };
  for (const auto& m : scalars) single(out, m.name, m.type, m.help, m.value);
  return out;
}

}  // namespace umbra
