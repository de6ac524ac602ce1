#include "http_api.hpp"

#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <map>
#include <utility>

#include <nlohmann/json.hpp>

#include "client_socket.hpp"
#include "assets/folder_file.hpp"
#include "assets/gltf_loader.hpp"
#include "assets/model_import.hpp"
#include "assets/cityjson_loader.hpp"
#include "assets/glb_writer.hpp"
#include "png.hpp"
#include "request_fields.hpp"
#include "request_parser.hpp"
#include "sun_hours_answer.hpp"
#include "sun_hours_parser.hpp"
#include "core/scene.hpp"
#include "core/sun_position.hpp"
#include "web_assets.hpp"

namespace umbra {

namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

void send_error(HttpResponse& res, int status, const std::string& message, const std::string& field) {
  res.status = status;
  // Replace, not throw, should a message ever carry invalid UTF-8.
  res.set_content(json{{"error", message}, {"field", field}}.dump(-1, ' ', false, json::error_handler_t::replace),
                  "application/json");
}

bool starts_with_ci(const std::string& s, const char* prefix) {
  const std::size_t n = std::char_traits<char>::length(prefix);
  return s.size() >= n && equal_ci(std::string_view(s).substr(0, n), prefix);
}


json vec3_json(const glm::dvec3& v) { return json::array({v.x, v.y, v.z}); }

// How GET /api/models and POST /api/models describe one model.
json model_json(const HeldModel& held) {
  const TriangleModel& model = *held.model;
  json j = {{"id", held.id},
            {"triangles", model.triangle_count()},
            {"bounds", {{"min", vec3_json(model.bounds.min)}, {"max", vec3_json(model.bounds.max)}}},
            {"parts", model.parts.size()},
            {"closed", model.closed},
            {"skipped_primitives", model.skipped_primitives},
            {"bytes", held.bytes}};
  // What a mesh object's "animation" may name (in the file's order).
  j["animations"] = json::array();
  for (const ModelAnimation& animation : model_animations(model))
    j["animations"].push_back({{"index", animation.index},
                               {"name", animation.name},
                               {"duration_s", animation.duration_s},
                               {"channels", animation.channels}});
  if (!held.name.empty()) j["name"] = held.name;
  j["pinned"] = held.pinned;
  return j;
}

// What formatting a sun-hours answer reads of its request: all but the
// scene, whose models (and poses of animated ones) a finished job would
// otherwise hold for as long as its result is kept (a red-team pass: five
// finished jobs' poses filled the pose bound for ten minutes).
SunHoursRequest answer_part(const SunHoursRequest& request) {
  SunHoursRequest part = request;
  part.view.scene.objects.clear();
  part.view.scene.objects.shrink_to_fit();
  return part;
}

// Whether any mesh object names an animation (then it is posed first).
bool has_animations(const Scene& scene) {
  return std::any_of(scene.objects.begin(), scene.objects.end(),
                     [](const SceneObject& o) { return o.animation.has_value(); });
}

std::string content_type_for(const std::string& path) {
  const auto ends_with = [&](const char* suffix) {
    const std::string s(suffix);
    return path.size() >= s.size() && path.compare(path.size() - s.size(), s.size(), s) == 0;
  };
  if (ends_with(".html")) return "text/html; charset=utf-8";
  if (ends_with(".js")) return "text/javascript; charset=utf-8";
  if (ends_with(".css")) return "text/css; charset=utf-8";
  if (ends_with(".svg")) return "image/svg+xml";
  if (ends_with(".png")) return "image/png";
  return "application/octet-stream";
}

// Umbra-Sun: where a sun light's sun stood for this image (docs/api.md), so
// that clients and tests read what was used; "" for an orbiting light.
std::string sun_header(const RenderRequest& request) {
  return request.light.sun ? format_sun_angles(sun_at(*request.light.sun, request.time)) : "";
}

std::string server_timing(const FrameTimings& t, double encode_ms, double queue_ms) {
  char buffer[256];
  std::snprintf(buffer, sizeof buffer, "shadow;dur=%.3f, main;dur=%.3f, readback;dur=%.3f, encode;dur=%.3f, queue;dur=%.3f",
                t.shadow_ms, t.main_ms, t.readback_ms, encode_ms, queue_ms);
  std::string timing = buffer;
  // Its own stage: it runs beside the GL passes, so adding it to one of
  // them would make the stages sum to more than the request took.
  if (t.ray_cast_ms) {
    std::snprintf(buffer, sizeof buffer, ", raycast;dur=%.3f", *t.ray_cast_ms);
    timing += buffer;
  }
  // Filter "exact": the ray cast of the pixels the maps left uncertain, on
  // the GL thread after the passes.
  if (t.settle_ms) {
    std::snprintf(buffer, sizeof buffer, ", settle;dur=%.3f", *t.settle_ms);
    timing += buffer;
  }
  return timing;
}


// One byte range of a file of `size` bytes, from a Range header (RFC 9110
// §14.1.2): "bytes=a-b", "bytes=a-" or "bytes=-n". Several ranges, other
// units and malformed values are ignored (the file goes whole, never
// larger than it is), which §14.2 allows. Unsatisfiable: 416.
enum class RangeAnswer { Whole, Part, Unsatisfiable };

RangeAnswer byte_range(const std::string& header, std::size_t size, std::size_t& first, std::size_t& last) {
  if (header.rfind("bytes=", 0) != 0) return RangeAnswer::Whole;
  const std::string spec = header.substr(6);
  const std::size_t dash = spec.find('-');
  if (dash == std::string::npos || spec.find(',') != std::string::npos) return RangeAnswer::Whole;
  const std::string a = spec.substr(0, dash), b = spec.substr(dash + 1);
  const auto digits = [](const std::string& t) {
    return !t.empty() && t.size() <= 18 && t.find_first_not_of("0123456789") == std::string::npos;
  };
  if (a.empty()) {  // the last n bytes
    if (!digits(b)) return RangeAnswer::Whole;
    const std::size_t n = std::stoull(b);
    if (n == 0 || size == 0) return RangeAnswer::Unsatisfiable;
    first = size - std::min(n, size);
    last = size - 1;
    return RangeAnswer::Part;
  }
  if (!digits(a) || (!b.empty() && !digits(b))) return RangeAnswer::Whole;
  first = std::stoull(a);
  last = b.empty() ? size - 1 : std::min<std::size_t>(std::stoull(b), size - 1);
  if (!b.empty() && std::stoull(b) < first) return RangeAnswer::Whole;
  if (first >= size) return RangeAnswer::Unsatisfiable;
  return RangeAnswer::Part;
}

}  // namespace

bool valid_cors_origin(const std::string& origin) {
  if (origin == "*") return true;
  std::string rest;
  if (origin.rfind("http://", 0) == 0)
    rest = origin.substr(7);
  else if (origin.rfind("https://", 0) == 0)
    rest = origin.substr(8);
  else
    return false;
  if (rest.empty()) return false;
  for (char c : rest)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == ':' || c == '[' || c == ']'))
      return false;
  return true;
}


// The route table: what each API path does. A known path with another
// method is 405; every other GET is a file of the web panel.
// With --tokens, each needs a token with its scope; health needs none, so
// that probes (HAProxy's, a load balancer's) work without one.
const HttpApi::Route HttpApi::kRoutes[] = {
    {"GET", "/api/health", &HttpApi::health, false, 0},
    {"GET", "/api/scenes", &HttpApi::scenes, false, kScopeRender},
    {"GET", "/api/openapi.json", &HttpApi::openapi_document, false, kScopeRender},
    {"POST", "/api/render", &HttpApi::render_color, true, kScopeRender},
    {"POST", "/api/depth", &HttpApi::render_depth, true, kScopeRender},
    {"POST", "/api/sun-hours", &HttpApi::sun_hours, true, kScopeRender},
    {"GET", "/api/sun-hours/jobs/", &HttpApi::sun_hours_job, false, kScopeRender, true},
    {"DELETE", "/api/sun-hours/jobs/", &HttpApi::cancel_sun_hours_job, true, kScopeRender, true},
    {"GET", "/api/models", &HttpApi::list_models, false, kScopeRender},
    {"POST", "/api/models", &HttpApi::upload_model, true, kScopeUpload},
    // On a worker: a model not held may be read from --model-store.
    {"GET", "/api/models/", &HttpApi::get_model, true, kScopeRender, true},
    {"GET", "/metrics", &HttpApi::metrics, false, kScopeMetrics},
};

struct HttpApi::ModelPlan {
  std::map<std::string, std::shared_ptr<const HeldModel>> held;  // by the key the scene names
  struct ToLoad {
    ModelArchive::Found found;
    ModelStore::Reservation room;
  };
  std::map<std::string, ToLoad> to_load;  // by id
};

ModelStore::Limits model_store_limits(const ServerOptions& options) {
  ModelStore::Limits limits;
  limits.max_bytes = options.models_budget_bytes;
  limits.share_bytes = options.upload_share_bytes ? options.upload_share_bytes : options.models_budget_bytes / 4;
  return limits;
}

// Each owner's share of the --model-store folder: the same fraction of it
// as --upload-quota-mib is of --models-budget-mib (a quarter by default).
ModelArchive::Limits model_archive_limits(const ServerOptions& options) {
  const ModelStore::Limits memory = model_store_limits(options);
  ModelArchive::Limits limits;
  limits.max_bytes = options.model_store_max_bytes;
  const auto fraction_of = [&](std::uint64_t whole) {
    if (memory.max_bytes == 0 || memory.share_bytes >= memory.max_bytes) return whole;
    return std::max<std::uint64_t>(1, std::uint64_t(static_cast<long double>(whole) * memory.share_bytes / memory.max_bytes));
  };
  limits.share_bytes = fraction_of(limits.max_bytes);
  limits.share_files = fraction_of(limits.max_files);
  return limits;
}

HttpApi::HttpApi(RenderService& renderer, ServerOptions options)
    : HttpApi(renderer, std::make_shared<ModelStore>(model_store_limits(options)), options) {}

// Not owned: an aliasing pointer with no control block.
HttpApi::HttpApi(RenderService& renderer, ModelStore& models, ServerOptions options)
    : HttpApi(renderer, std::shared_ptr<ModelStore>(std::shared_ptr<ModelStore>(), &models), std::move(options)) {}

HttpApi::HttpApi(RenderService& renderer, std::shared_ptr<ModelStore> models, ServerOptions options)
    : renderer_(renderer),
      options_(std::move(options)),
      allowed_hosts_(options_.host, options_.allowed_hosts),
      models_(std::move(models)),
      jobs_(std::make_unique<SunHoursJobs>(options_.jobs, options_.name)),
      started_(Clock::now()) {
  if (!options_.model_store_dir.empty())
    archive_ = std::make_unique<ModelArchive>(options_.model_store_dir, model_archive_limits(options_));
  HttpServerOptions connections = options_.connections;
  connections.host = options_.host;
  connections.port = options_.port;
  connections.limits.max_body_bytes = kMaxBodyBytes;
  // Only an upload may be larger; judged from the head, so a larger body
  // anywhere else is still refused at the byte past 1 MiB.
  const std::size_t max_model_bytes = options_.max_model_bytes;
  connections.limits.body_limit_for = [max_model_bytes](const HttpRequest& head) {
    return head.method == "POST" && head.path == "/api/models" ? max_model_bytes : kMaxBodyBytes;
  };
  connections.limits.max_target_bytes = kMaxUriBytes;
  connections.limits.max_header_count = kMaxHeaderCount;
  connections.limits.max_header_bytes = kMaxHeaderBytes;
  // A render's worker waits for the renderer: enough workers for a full
  // render queue and two encoding PNGs, so that the queue (which answers
  // 503 at once when full, and at its deadline) is what bounds the waiting.
  connections.worker_threads = renderer_.limits().queue_capacity + 2;
  connections.max_waiting_requests = renderer_.limits().queue_capacity;
  HttpHandlers handlers;
  handlers.blocks = [this](const HttpRequest& req) { return blocks(req); };
  handlers.admit = [this](const HttpRequest& head) { return admit(head); };
  handlers.handle = [this](const HttpRequest& req, HttpResponse& res) {
    handle(req, res);
    add_cors_headers(res);
  };
  handlers.error = [this](int status, const std::string& message) { return error_response(status, message); };
  handlers.log = [this](const HttpRequest& req, const HttpResponse& res, double ms) {
    metrics_.request_answered(route_label(req), res.status, ms / 1000.0);
    // Who asked, by principal: never the token itself.
    if (options_.log_requests)
      std::fprintf(stderr, "%s %s %d %.1f ms%s%s\n", req.method.empty() ? "-" : req.method.c_str(),
                   req.path.empty() ? "-" : req.path.c_str(), res.status, ms, req.principal.empty() ? "" : " ",
                   req.principal.c_str());
  };
  http_ = std::make_unique<HttpServer>(std::move(connections), std::move(handlers));
}

HttpApi::~HttpApi() = default;

bool HttpApi::bind() { return http_->bind(); }

void HttpApi::serve() { http_->serve(); }

bool HttpApi::serving() const { return http_->serving(); }

void HttpApi::stop() { http_->stop(); }

HttpResponse HttpApi::error_response(int status, const std::string& message) const {
  HttpResponse res;
  send_error(res, status, message, "");
  add_cors_headers(res);
  return res;
}

std::string HttpApi::uploader_of(const HttpRequest& req) const { return options_.tokens ? req.principal : ""; }

Admission HttpApi::admit(const HttpRequest& head) const {
  Admission admission;
  if (const AccessRefusal host = allowed_hosts_.check(head)) {
    admission.refusal = error_response(host.status, host.message);
    return admission;
  }
  if (!options_.tokens) return admission;
  // No token for the panel's files (the page must load to ask for one),
  // health, and CORS preflights (a browser never sends credentials with one).
  std::string allow;
  const Route* route = find_route(head, allow);
  const bool api = head.path == "/api" || head.path.rfind("/api/", 0) == 0;
  const bool panel_file = !route && !api && (head.method == "GET" || head.method == "HEAD");
  if ((route && route->scope == 0) || panel_file || head.method == "OPTIONS") return admission;
  // Elsewhere (an unknown API path, a wrong method) any known token will
  // do: the 404 or 405 then says more than a 403 would.
  const std::string what = route ? head.method + " " + route->path + (route->prefix ? "{id}" : "") : "this path";
  const AccessRefusal refused =
      authorize(*options_.tokens, head, route ? route->scope : 0, what, admission.principal);
  if (!refused) return admission;
  HttpResponse res = error_response(refused.status, refused.message);
  // RFC 6750 §3: how to authenticate, and why this failed.
  if (refused.status == 401)
    res.set_header("WWW-Authenticate", head.has_header("Authorization")
                                           ? "Bearer realm=\"umbra\", error=\"invalid_token\""
                                           : "Bearer realm=\"umbra\"");
  else if (refused.status == 403)
    res.set_header("WWW-Authenticate",
                   "Bearer realm=\"umbra\", error=\"insufficient_scope\", scope=\"" + scope_names(route->scope) + "\"");
  admission.refusal = std::move(res);
  return admission;
}

void HttpApi::add_cors_headers(HttpResponse& res) const {
  if (options_.cors_origin.empty()) return;
  // Every response, errors included, so a page can read why it failed.
  res.set_header("Access-Control-Allow-Origin", options_.cors_origin);
  res.set_header("Vary", "Origin");
  res.set_header("Access-Control-Expose-Headers",
                 "Server-Timing, Retry-After, Umbra-Unused-Fields, Umbra-Shadow-Views, Umbra-Shadow-Error, Umbra-Sun, "
                 "Umbra-Certified, WWW-Authenticate, Umbra-Sun-Hours, Location, Umbra-CityJSON");
  res.set_header("Timing-Allow-Origin", options_.cors_origin);
}

const HttpApi::Route* HttpApi::find_route(const HttpRequest& req, std::string& allow) const {
  // HEAD is GET without the body (RFC 9110 §9.3.2).
  const std::string method = req.method == "HEAD" ? "GET" : req.method;
  allow.clear();
  for (const Route& route : kRoutes) {
    const std::size_t n = std::char_traits<char>::length(route.path);
    const bool match = route.prefix ? req.path.size() > n && req.path.compare(0, n, route.path) == 0 : req.path == route.path;
    if (!match) continue;
    if (method == route.method) return &route;
    allow += (allow.empty() ? "" : ", ") + std::string(route.method);
  }
  return nullptr;
}

std::string HttpApi::route_label(const HttpRequest& req) const {
  std::string allow;
  if (const Route* route = find_route(req, allow)) return std::string(route->path) + (route->prefix ? "{id}" : "");
  const bool api = req.path == "/api" || req.path.rfind("/api/", 0) == 0;
  if (!api && (req.method == "GET" || req.method == "HEAD")) return "static";
  return "other";
}

bool HttpApi::blocks(const HttpRequest& req) const {
  std::string allow;
  const Route* route = find_route(req, allow);
  return route && route->blocks;
}

void HttpApi::handle(const HttpRequest& req, HttpResponse& res) {
  std::string allow;
  if (const Route* route = find_route(req, allow)) return (this->*route->handler)(req, res);
  if (req.method == "OPTIONS" && !options_.cors_origin.empty()) return preflight(req, res);
  if (!allow.empty()) {
    res.set_header("Allow", allow);
    return send_error(res, 405, "method " + req.method + " not allowed here; use " + allow, "");
  }
  const bool api = req.path == "/api" || req.path.rfind("/api/", 0) == 0;
  if (!api && (req.method == "GET" || req.method == "HEAD")) return static_file(req, res);
  // A file of the panel is a known path too: another method is 405.
  std::string bytes;
  if (!api && read_static_file(req.path == "/" ? "index.html" : req.path.substr(1), bytes)) {
    res.set_header("Allow", "GET");
    return send_error(res, 405, "method " + req.method + " not allowed here; use GET", "");
  }
  send_error(res, 404, "no such path", "");
}

// The preflight a browser sends before a cross-origin JSON POST.
void HttpApi::preflight(const HttpRequest&, HttpResponse& res) {
  res.status = 204;
  res.set_header("Access-Control-Allow-Methods", "GET, POST, DELETE");
  res.set_header("Access-Control-Allow-Headers", "Content-Type, Authorization");
  res.set_header("Access-Control-Max-Age", "600");
}

// The server's state, read once for /api/health and /metrics alike.
MetricsGauges HttpApi::state() const {
  const RendererInfo& info = renderer_.info();
  const HttpServerStats connections = http_->stats();
  MetricsGauges g;
  g.gl_renderer = info.gl_renderer;
  g.gl_version = info.gl_version;
  g.egl_source = info.egl_source;
  g.uptime_s = std::chrono::duration<double>(Clock::now() - started_).count();
  g.frames_rendered = renderer_.frames_rendered();
  g.shadow_map_reuses = renderer_.shadow_cache_hits();
  g.scene_uploads = renderer_.scene_uploads();
  g.context_renewals = renderer_.context_renewals();
  g.queue_depth = renderer_.queue_depth();
  g.queue_capacity = renderer_.limits().queue_capacity;
  g.rejected = renderer_.rejected();
  g.expired = renderer_.expired();
  g.abandoned = renderer_.abandoned();
  g.too_costly = renderer_.too_costly();
  g.overran = renderer_.overran();
  g.cached_bytes = renderer_.cached_bytes();
  g.models = models_->count();
  g.model_bytes = models_->bytes();
  g.model_budget_bytes = models_->max_bytes();
  g.model_live_bytes = models_->live_bytes();
  g.model_share_bytes = models_->share_bytes();
  g.models_loaded = models_loaded_.load();
  if (archive_) {
    g.model_store_bytes = archive_->bytes_on_disk();
    g.model_store_budget_bytes = archive_->max_bytes();
    g.model_store_evicted = archive_->evicted();
  }
  g.connections_open = connections.connections_open;
  g.connections_evicted = connections.connections_evicted;
  g.connections_refused = connections.connections_refused;
  g.connections_stalled = connections.connections_stalled;
  g.requests_timed_out = connections.requests_timed_out;
  g.bodies_refused = connections.bodies_refused;
  return g;
}

void HttpApi::health(const HttpRequest&, HttpResponse& res) {
  const MetricsGauges g = state();
  res.set_content(json{{"status", "ok"},
                       {"gl_renderer", g.gl_renderer},
                       {"gl_version", g.gl_version},
                       {"egl_source", g.egl_source},
                       {"uptime_s", g.uptime_s},
                       {"frames_rendered", g.frames_rendered},
                       {"shadow_cache_hits", g.shadow_map_reuses},
                       {"scene_uploads", g.scene_uploads},
                       {"gl_context_renewals", g.context_renewals},
                       {"queue_depth", g.queue_depth},
                       {"queue_capacity", g.queue_capacity},
                       {"rejected", g.rejected},
                       {"expired", g.expired},
                       {"abandoned", g.abandoned},
                       {"too_costly", g.too_costly},
                       {"overran", g.overran},
                       {"cached_bytes", g.cached_bytes},
                       {"models", g.models},
                       {"model_bytes", g.model_bytes},
                       {"connections_open", g.connections_open},
                       {"connections_evicted", g.connections_evicted},
                       {"connections_refused", g.connections_refused},
                       {"connections_stalled", g.connections_stalled},
                       {"requests_timed_out", g.requests_timed_out},
                       {"bodies_refused", g.bodies_refused}}
                      .dump(),
                  "application/json");
}

void HttpApi::metrics(const HttpRequest&, HttpResponse& res) {
  res.set_header("Cache-Control", "no-store");
  res.set_content(metrics_.exposition(state()), "text/plain; version=0.0.4; charset=utf-8");
}

void HttpApi::scenes(const HttpRequest&, HttpResponse& res) {
  json scenes = json::array();
  for (const auto& s : builtin_scenes()) {
    json objects = json::array();
    for (const auto& o : s.objects) objects.push_back(write_object(o));
    scenes.push_back({{"name", s.name},
                      {"description", s.description},
                      {"objects", objects},
                      {"camera", {{"position", vec3_json(s.camera_position)}, {"target", vec3_json(s.camera_target)}}},
                      {"light", {{"position", vec3_json(s.light_position)}, {"target", vec3_json({0, 0, 0})}}}});
  }
  res.set_content(json{{"scenes", scenes}}.dump(), "application/json");
}

// docs/openapi.json as the repository holds it, built in (api_document).
void HttpApi::openapi_document(const HttpRequest&, HttpResponse& res) {
  res.set_content(std::string(api_document("openapi.json")), "application/json");
}

void HttpApi::render_color(const HttpRequest& req, HttpResponse& res) { render(req, res, false); }

void HttpApi::render_depth(const HttpRequest& req, HttpResponse& res) { render(req, res, true); }

// The body is taken whatever its Content-Type (none, text/plain, JSON and
// curl -d's form type alike), except multipart/* (curl -F): a set of parts,
// not one JSON document.
void HttpApi::render(const HttpRequest& req, HttpResponse& res, bool depth_route) {
  // Counted however the request ends (every refusal returns early).
  struct FrameRecord {
    FrameRecord(Metrics& m, const HttpResponse& r) : metrics(m), res(r) {}
    ~FrameRecord() { metrics.frame_answered(output, res.status, timings ? &*timings : nullptr, encode_ms, queue_ms); }
    Metrics& metrics;
    const HttpResponse& res;
    std::string output = "invalid";
    std::optional<FrameTimings> timings;
    double encode_ms = 0.0, queue_ms = 0.0;
  } record(metrics_, res);
  const std::string type = req.header("Content-Type");
  if (starts_with_ci(type, "multipart/"))
    return send_error(res, 415, "unsupported Content-Type " + type.substr(0, type.find(';')) +
                                    "; send the JSON body as it is (application/json, or any type but multipart/*)",
                      "");
  // No body at all reads as {}, all defaults, like an empty one. The
  // parser sets a depth route's output itself, so that Umbra-Unused-Fields
  // is judged against the depth map.
  // The models the scene names are counted against the budget before any
  // is loaded (plan_models), then found or loaded as the parser asks.
  ModelPlan plan;
  const std::string owner = uploader_of(req);
  const ModelsNamed named = [&](const std::vector<std::string>& keys) { plan_models(plan, keys, owner); };
  const ModelLookup lookup = model_lookup(plan);
  ParsedRequest parsed;
  try {
    parsed = parse_render_request(req.body, depth_route ? umbra::Route::Depth : umbra::Route::Render, lookup, named);
  } catch (const ModelLoadsBusy&) {
    return send_models_busy(res);
  } catch (const ModelsRefused& refused) {
    return send_models_refused(res, refused);
  }
  plan = ModelPlan{};  // what was reserved and not used goes back; the request holds its models
  if (!parsed.ok()) return send_error(res, 400, parsed.error.message, parsed.error.field);
  RenderRequest request = std::move(*parsed.request);
  record.output = to_string(request.output);
  if (has_animations(request.scene)) {
    // Priced on the rest pose before any pose is made (the posed scene is
    // priced again when it is submitted).
    try {
      renderer_.check_cost(request);
    } catch (...) {
      return send_service_error(res, std::current_exception());
    }
    if (!pose_animations(request.scene, request.time, req, res)) return;
  }
  const std::string sun = sun_header(request);
  const auto queued = Clock::now();
  // Asked just before the job's turn: a client that has gone costs no render.
  const int socket = req.socket;
  RenderResult result;
  try {
    result = renderer_.submit(std::move(request), [socket] { return peer_closed(socket); }).get();
  } catch (const ClientGone& e) {
    // Nobody will read this; the log shows 499 (nginx's "client closed request").
    return send_error(res, 499, e.what(), "");
  } catch (const QueueFull& e) {
    // Refused at once: the client may retry after about one frame.
    res.set_header("Retry-After", "1");
    return send_error(res, 503, std::string(e.what()) + " (" + std::to_string(renderer_.limits().queue_capacity) +
                                    " requests); retry later", "");
  } catch (const DeadlineExceeded& e) {
    res.set_header("Retry-After", "1");
    return send_error(res, 503, std::string(e.what()) + " (" + std::to_string(renderer_.limits().deadline.count()) +
                                    " ms); retry later", "");
  } catch (const RequestTooCostly& e) {
    // Valid by the API, but more work than this server takes per request.
    return send_error(res, 422, e.what(), e.field);
  } catch (const RunTimeExceeded& e) {
    return send_error(res, 503, e.what(), e.field);
  }
  const double total_ms = std::chrono::duration<double, std::milli>(Clock::now() - queued).count();
  const FrameTimings& t = result.timings;
  const double queue_ms = std::max(0.0, total_ms - t.shadow_ms - t.main_ms - t.readback_ms);
  const auto encode_start = Clock::now();
  std::string png = encode_png(result.image);
  const double encode_ms = std::chrono::duration<double, std::milli>(Clock::now() - encode_start).count();
  record.timings = t;
  record.encode_ms = encode_ms;
  record.queue_ms = queue_ms;
  res.set_header("Server-Timing", server_timing(t, encode_ms, queue_ms));
  res.set_header("Cache-Control", "no-store");
  if (!parsed.unused_fields.empty()) {
    std::string list;
    for (const auto& f : parsed.unused_fields) list += (list.empty() ? "" : ", ") + f;
    res.set_header("Umbra-Unused-Fields", list);
  }
  if (!result.shadow_views.empty()) res.set_header("Umbra-Shadow-Views", result.shadow_views);
  if (!sun.empty()) res.set_header("Umbra-Sun", sun);
  if (result.certified) {
    const CertifiedShare& c = *result.certified;
    char buffer[160];
    std::snprintf(buffer, sizeof buffer, "uncertain=%.4f%%, ray_cast=%zu, pixels=%zu, path=%s",
                  c.pixels > 0 ? 100.0 * double(c.ray_cast) / double(c.pixels) : 0.0, c.ray_cast, c.pixels,
                  result.certified_path.c_str());
    res.set_header("Umbra-Certified", buffer);
  }
  if (result.error) {
    const ShadowError& e = *result.error;
    // New fields go last, so that clients parsing the first ones keep working.
    char buffer[256];
    std::snprintf(buffer, sizeof buffer,
                  "mae=%.5f, wrong=%.4f%%, false_shadow=%.4f%%, false_light=%.4f%%, pixels=%zu, artifacts=%.4f%%, "
                  "interior_pixels=%zu",
                  e.mae, 100.0 * e.wrong, 100.0 * e.false_shadow, 100.0 * e.false_light, e.pixels,
                  100.0 * e.artifacts, e.interior_pixels);
    res.set_header("Umbra-Shadow-Error", buffer);
  }
  res.set_content(std::move(png), "image/png");
}

// Hours of direct sun over a grid of points (core/sun_hours.hpp): the
// body's scene as /api/render reads it, models and all; the answer in the
// format Accept asks for (sun_hours_answer.hpp). Within the cost budget it
// is answered at once; over it, up to --max-job-ms, it runs as a job
// (202; sun_hours_jobs.hpp).
void HttpApi::sun_hours(const HttpRequest& req, HttpResponse& res) {
  const std::string type = req.header("Content-Type");
  if (starts_with_ci(type, "multipart/"))
    return send_error(res, 415, "unsupported Content-Type " + type.substr(0, type.find(';')) +
                                    "; send the JSON body as it is (application/json, or any type but multipart/*)",
                      "");
  const std::optional<SunHoursFormat> format = sun_hours_format(req.header("Accept"));
  if (!format)
    return send_error(res, 406,
                      "Accept names no format this route answers in: application/json, text/csv or image/png", "");
  ModelPlan plan;
  const std::string owner = uploader_of(req);
  const ModelsNamed named = [&](const std::vector<std::string>& keys) { plan_models(plan, keys, owner); };
  const ModelLookup lookup = model_lookup(plan);
  ParsedSunHours parsed;
  try {
    parsed = parse_sun_hours_request(req.body, lookup, named);
  } catch (const ModelLoadsBusy&) {
    return send_models_busy(res);
  } catch (const ModelsRefused& refused) {
    return send_models_refused(res, refused);
  }
  plan = ModelPlan{};
  if (!parsed.ok()) return send_error(res, 400, parsed.error.message, parsed.error.field);
  // The picture's fields serve image/png; a grid serves JSON and CSV.
  parsed.request->picture = *format == SunHoursFormat::Png;
  if (!parsed.request->picture && !parsed.grid_given)
    return send_error(res, 400, "is required for a JSON or CSV answer (an image/png answer needs none)", "grid");
  // Animated models stand as they are at the start of their animation
  // (the route has no `time`) all period: posed once the body is known good.
  if (!pose_animations(parsed.request->view.scene, parsed.request->view.time, req, res)) return;
  // Fields that cannot change this answer are named, never dropped in
  // silence: the picture's for JSON and CSV, and "exact": false (every
  // path is exact: there is no step to skip).
  std::vector<std::string> unused;
  if (!parsed.request->picture) unused = parsed.picture_fields;
  unused.insert(unused.end(), parsed.colour_fields.begin(), parsed.colour_fields.end());
  if (!parsed.request->exact) unused.push_back("exact");
  if (parsed.request->include_samples && *format != SunHoursFormat::Json) unused.push_back("include_samples");
  // A picture shows a grid only as its pass share: without require_hours
  // the grid changes nothing, and is not computed.
  if (parsed.request->picture && parsed.grid_given && !parsed.request->require_hours) {
    unused.push_back("grid");
    parsed.request->grid.columns = parsed.request->grid.rows = 0;
  }
  std::sort(unused.begin(), unused.end());
  if (!unused.empty()) {
    std::string list;
    for (const auto& f : unused) list += (list.empty() ? "" : ", ") + f;
    res.set_header("Umbra-Unused-Fields", list);
  }
  const SunHoursPlan estimate = renderer_.plan_sun_hours(*parsed.request);
  if (estimate.estimate.cost.total_ms > double(renderer_.limits().max_request_cost.count()))
    return start_sun_hours_job(res, std::move(*parsed.request), estimate);
  const SunHoursRequest request = answer_part(*parsed.request);
  const auto queued = Clock::now();
  const int socket = req.socket;
  SunHoursResult result;
  try {
    result = renderer_
                 .submit_sun_hours(std::move(*parsed.request), [socket] { return peer_closed(socket); }, false, {},
                                   estimate)
                 .get();
  } catch (...) {
    return send_service_error(res, std::current_exception());
  }
  const double total_ms = std::chrono::duration<double, std::milli>(Clock::now() - queued).count();
  send_sun_hours(res, *format, request, result, std::max(0.0, total_ms - result.elapsed_ms));
}

void HttpApi::send_sun_hours(HttpResponse& res, SunHoursFormat format, const SunHoursRequest& request,
                             const SunHoursResult& result, double queue_ms, SunHoursJob* job) {
  const auto encode_start = Clock::now();
  const auto encode = [&] {
    return format == SunHoursFormat::Csv   ? sun_hours_csv(request, result)
           : format == SunHoursFormat::Png ? encode_png(sun_hours_image(request, result))
                                           : sun_hours_json(request, result);
  };
  std::string body;
  if (job) {
    // A finished job's answer in the format asked last is kept: fetched
    // again, it is copied, not encoded again.
    std::lock_guard<std::mutex> lock(job->encoded_mutex);
    if (job->encoded_format != format) {
      job->encoded = encode();
      job->encoded_format = format;
    }
    body = job->encoded;
  } else {
    body = encode();
  }
  const double encode_ms = std::chrono::duration<double, std::milli>(Clock::now() - encode_start).count();
  char timing[160];
  std::snprintf(timing, sizeof timing, "queue;dur=%.3f, sun_hours;dur=%.3f, encode;dur=%.3f", queue_ms,
                result.elapsed_ms, encode_ms);
  res.set_header("Server-Timing", timing);
  res.set_header("Cache-Control", "no-store");
  res.set_header("Umbra-Sun-Hours", std::string("path=") + result.path + ", pairs=" + std::to_string(result.pairs) +
                                        ", by_maps=" + std::to_string(result.pairs_by_maps) +
                                        ", ray_cast=" + std::to_string(result.pairs_ray_cast));
  res.set_content(std::move(body), format == SunHoursFormat::Csv   ? "text/csv; charset=utf-8"
                                  : format == SunHoursFormat::Png ? "image/png"
                                                                  : "application/json");
}

// What a sun-hours analysis that did not finish answers.
void HttpApi::send_service_error(HttpResponse& res, std::exception_ptr error) const {
  try {
    std::rethrow_exception(error);
  } catch (const ClientGone& e) {
    send_error(res, 499, e.what(), "");
  } catch (const QueueFull& e) {
    res.set_header("Retry-After", "1");
    send_error(res, 503, std::string(e.what()) + " (" + std::to_string(renderer_.limits().queue_capacity) +
                             " requests); retry later", "");
  } catch (const DeadlineExceeded& e) {
    res.set_header("Retry-After", "1");
    send_error(res, 503, std::string(e.what()) + " (" + std::to_string(renderer_.limits().deadline.count()) +
                             " ms); retry later", "");
  } catch (const RequestTooCostly& e) {
    send_error(res, 422, e.what(), e.field);
  } catch (const RunTimeExceeded& e) {
    send_error(res, 503, e.what(), e.field);
  }
}

void HttpApi::start_sun_hours_job(HttpResponse& res, SunHoursRequest request, const SunHoursPlan& plan) {
  auto job = std::make_shared<SunHoursJob>();
  job->id = jobs_->new_id();
  job->request = answer_part(request);
  job->progress = std::make_shared<SunHoursProgress>();
  job->created = Clock::now();
  job->estimate_ms = plan.estimate.cost.total_ms;
  // The result, and its last answer kept encoded (send_sun_hours): about
  // 96 bytes of text a point, 112 a listed sample, 3 a pixel of picture.
  const std::uint64_t pixels = request.picture ? std::uint64_t(request.view.width) * std::uint64_t(request.view.height) : 0;
  job->result_bytes = std::uint64_t(request.grid.points()) * (sizeof(PointTally) + 96) +
                      plan.samples * (sizeof(SunSample) + (request.include_samples ? 112 : 0)) + pixels * (4 + 3);
  try {
    job->result = renderer_.submit_sun_hours(std::move(request), {}, true, job->progress, plan).share();
  } catch (...) {
    return send_service_error(res, std::current_exception());
  }
  if (!jobs_->add(job)) {
    job->progress->cancel = true;
    res.set_header("Retry-After", "10");
    return send_error(res, 503,
                      "this server holds " + std::to_string(jobs_->limits().max_jobs) +
                          " sun-hours jobs not yet fetched or expired; retry later, or DELETE one you no longer need",
                      "");
  }
  const std::string location = "/api/sun-hours/jobs/" + job->id;
  res.status = 202;
  res.set_header("Location", location);
  res.set_header("Cache-Control", "no-store");
  res.set_content(json{{"job", job->id},
                       {"state", "queued"},
                       {"location", location},
                       {"estimated_ms", std::llround(job->estimate_ms)},
                       {"keep_s", jobs_->limits().keep.count()}}
                      .dump(),
                  "application/json");
}

// GET /api/sun-hours/jobs/{id}: 202 with progress while it runs, then the
// result (200, by Accept) or what stopped it.
void HttpApi::sun_hours_job(const HttpRequest& req, HttpResponse& res) {
  const std::string id = req.path.substr(std::char_traits<char>::length("/api/sun-hours/jobs/"));
  const std::shared_ptr<SunHoursJob> job = jobs_->find(id);
  if (!job)
    return send_error(res, 404,
                      "no sun-hours job '" + id.substr(0, 64) + "' is held here (it ended more than " +
                          std::to_string(jobs_->limits().keep.count()) +
                          " s ago, was cancelled, or its server restarted)",
                      "");
  if (!job->ready()) {
    const SunHoursProgress& p = *job->progress;
    const double elapsed_s = std::chrono::duration<double>(Clock::now() - job->created).count();
    const std::uint64_t total = p.pairs_total, done = p.pairs_done;
    const double fraction = total > 0 ? double(done) / double(total) : 0.0;
    json progress = {{"job", job->id},
                     {"state", p.started ? "running" : "queued"},
                     {"fraction_done", fraction},
                     {"pairs_done", done},
                     {"pairs_total", total},
                     {"elapsed_s", elapsed_s},
                     {"estimated_ms", std::llround(job->estimate_ms)}};
    if (p.started && done > 0 && elapsed_s > 0.0) {
      progress["pairs_per_second"] = double(done) / elapsed_s;
      progress["seconds_left"] = double(total - done) / (double(done) / elapsed_s);
    }
    res.status = 202;
    res.set_header("Retry-After", "1");
    res.set_header("Cache-Control", "no-store");
    return res.set_content(progress.dump(), "application/json");
  }
  // A job posted for a picture answers with it; one posted for a grid, as
  // JSON or CSV by this GET's Accept.
  std::optional<SunHoursFormat> format = sun_hours_format(req.header("Accept"), false);
  if (job->request.picture) format = SunHoursFormat::Png;
  if (!format)
    return send_error(res, 406,
                      "Accept names no format this job answers in: application/json or text/csv (a job posted "
                      "with Accept: image/png answers with its picture)",
                      "");
  try {
    const SunHoursResult& result = job->result.get();
    send_sun_hours(res, *format, job->request, result, 0.0, job.get());
  } catch (...) {
    send_service_error(res, std::current_exception());
  }
}

void HttpApi::cancel_sun_hours_job(const HttpRequest& req, HttpResponse& res) {
  const std::string id = req.path.substr(std::char_traits<char>::length("/api/sun-hours/jobs/"));
  const std::shared_ptr<SunHoursJob> job = jobs_->remove(id);
  if (!job) return send_error(res, 404, "no sun-hours job '" + id.substr(0, 64) + "' is held here", "");
  const bool finished = job->ready();
  res.set_content(json{{"job", id}, {"state", finished ? "removed" : "cancelled"}}.dump(), "application/json");
}

void HttpApi::list_models(const HttpRequest&, HttpResponse& res) {
  json models = json::array();
  for (const auto& held : models_->list()) models.push_back(model_json(*held));
  res.set_content(json{{"models", models},
                       {"count", models.size()},
                       {"bytes", models_->bytes()},
                       {"budget_bytes", models_->max_bytes()}}
                      .dump(),
                  "application/json");
}

void HttpApi::get_model(const HttpRequest& req, HttpResponse& res) {
  const std::string key = req.path.substr(std::char_traits<char>::length("/api/models/"));
  std::shared_ptr<const HeldModel> held;
  try {
    ModelPlan plan;
    plan_models(plan, {key}, uploader_of(req), "the model");
    held = find_model(plan, key);
  } catch (const ModelLoadsBusy&) {
    return send_models_busy(res);
  } catch (const ModelsRefused& refused) {
    return send_models_refused(res, refused);
  }
  if (!held)
    return send_error(res, 404,
                      "no model '" + key.substr(0, 100) +
                          "' is held; upload it with POST /api/models (GET /api/models lists those held)",
                      "");
  res.set_content(model_json(*held).dump(), "application/json");
}

// Requests posing animated models at once: each is up to a few seconds of
// one core, in places of their own so that uploads and loads from the
// store keep theirs.
constexpr int kMaxConcurrentPoses = 2;

bool HttpApi::pose_animations(Scene& scene, double time, const HttpRequest& req, HttpResponse& res) {
  if (!has_animations(scene)) return true;
  std::optional<PoseRefused> refused;
  const int socket = req.socket;
  const bool ran = in_place(poses_making_, kMaxConcurrentPoses, [&] {
    try {
      poses_.pose_scene(scene, time, [socket] { return socket >= 0 && peer_closed(socket); });
    } catch (const PoseRefused& e) {
      refused = e;
    } catch (const std::bad_alloc&) {
      refused = PoseRefused(503, "the server is short of memory for the poses now; retry");
    }
  });
  if (!ran) {
    res.set_header("Retry-After", "1");
    send_error(res, 503,
               "already posing animated models for " + std::to_string(kMaxConcurrentPoses) +
                   " requests; retry (a pose asked before is shared at once)",
               "");
    return false;
  }
  if (refused) {
    if (refused->status == 503) res.set_header("Retry-After", "1");
    send_error(res, refused->status, refused->what(), refused->field);
    return false;
  }
  return true;
}

bool HttpApi::in_place(int& busy, int most, const std::function<void()>& work) {
  {
    std::lock_guard<std::mutex> lock(model_loads_mutex_);
    if (busy >= most) return false;
    ++busy;
  }
  struct Release {
    HttpApi& api;
    int& busy;
    ~Release() {
      std::lock_guard<std::mutex> lock(api.model_loads_mutex_);
      --busy;
    }
  } release{*this, busy};
  work();
  return true;
}

bool HttpApi::in_load_place(const std::function<void()>& work) {
  return in_place(model_loads_, kMaxConcurrentModelLoads, work);
}

std::optional<LoadResult> HttpApi::load_model(const std::string& body, const LoadOptions& options) {
  std::optional<LoadResult> result;
  if (!in_load_place([&] { result = load_gltf(body, options); })) return std::nullopt;
  if (result->ok()) models_loaded_.fetch_add(1);
  return result;
}

void HttpApi::send_models_busy(HttpResponse& res) const {
  res.set_header("Retry-After", "1");
  send_error(res, 503, "already loading " + std::to_string(kMaxConcurrentModelLoads) + " models; retry later", "");
}

namespace {

// Rounded up; saturating (a record may claim up to 2^64 - 1 bytes).
std::string mib(std::uint64_t bytes) { return std::to_string((bytes >> 20) + ((bytes & ((1 << 20) - 1)) != 0)) + " MiB"; }

// The end of every refusal of models that can never fit together.
std::string over_upload_budget(std::uint64_t upload_max_bytes) {
  return "more than the " + mib(upload_max_bytes) +
         " this server holds for models beside those of --models DIR (--models-budget-mib)";
}

// "sha256:0123456789ab..." : enough of an id to tell models apart in a message.
std::string short_id(const std::string& id) { return id.size() > 19 ? id.substr(0, 19) + "..." : id; }

}  // namespace

HttpApi::ModelsRefused HttpApi::room_refusal(ModelStore::Room room, std::uint64_t bytes, const std::string& what,
                                             int no_room_status) const {
  switch (room) {
    case ModelStore::Room::OverShare:
      return {422, what + " " + mib(bytes) + " once loaded, more than the " + mib(models_->share_bytes()) +
                       " share of model memory each client has (--upload-quota-mib)"};
    case ModelStore::Room::OverBudget:
      return {422, what + " " + mib(bytes) + " once loaded, " + over_upload_budget(models_->upload_max_bytes())};
    default:
      return {no_room_status,
              what + " " + mib(bytes) + " once loaded, and the " + mib(models_->max_bytes()) +
                  " for models (--models-budget-mib) are held now by other clients' models within their share, "
                  "by models being drawn and by loads under way; retry later"};
  }
}

void HttpApi::send_models_refused(HttpResponse& res, const ModelsRefused& refused) const {
  if (refused.status == 503 || refused.status == 507) res.set_header("Retry-After", "5");
  send_error(res, refused.status, refused.message, "");
}

// Before anything is loaded: the named models that are held are kept (a
// render holds them), and those in the folder get room for what their
// records say they hold. All of them must fit the budget together, and
// each one loaded for this owner its share.
void HttpApi::plan_models(ModelPlan& plan, const std::vector<std::string>& keys, const std::string& owner,
                          const std::string& subject) {
  std::uint64_t held_bytes = 0, to_load_bytes = 0;
  std::string listed;
  for (const std::string& key : keys) {
    if (auto held = models_->find(key)) {
      if (!held->pinned) held_bytes += held->bytes;
      if (archive_) archive_->touch(held->id);  // used: the folder keeps it longest
      plan.held.emplace(key, std::move(held));
      continue;
    }
    if (!archive_ || plan.to_load.count(key)) continue;
    std::optional<ModelArchive::Found> found = archive_->find(key);
    if (!found) continue;  // unknown: the parser says so
    // Without a record (an older server wrote it), the loader's own bound
    // is admitted before the model is built (find_model).
    const std::uint64_t bytes = found->record ? found->record->bytes_bound : 0;
    to_load_bytes += bytes;
    if (listed.size() < 200)
      listed += (listed.empty() ? "" : ", ") + short_id(key) + " " + mib(bytes);
    else if (listed.back() != '.')
      listed += ", ...";
    plan.to_load.emplace(key, ModelPlan::ToLoad{*found, {}});
  }
  if (plan.to_load.empty()) return;
  const std::uint64_t for_uploads = models_->upload_max_bytes();
  if (held_bytes + to_load_bytes > for_uploads)
    throw ModelsRefused{422, subject + (subject == "the model" ? " needs " : " need ") + mib(held_bytes + to_load_bytes) +
                                 " once loaded together (" + mib(held_bytes) + " held; " + std::to_string(plan.to_load.size()) +
                                 " to load: " + listed + "), " + over_upload_budget(for_uploads)};
  for (auto& [key, load] : plan.to_load) {
    const std::uint64_t bytes = load.found.record ? load.found.record->bytes_bound : 0;
    // Each one within the owner's share; together they may borrow beyond it.
    ModelStore::RoomResult room = models_->reserve(owner, bytes);
    if (room.outcome != ModelStore::Room::Made)
      throw room_refusal(room.outcome, bytes, "the model " + short_id(key) + " needs", 503);
    load.room = std::move(room.reservation);
  }
}

// How a parser finds the models a scene names: through `plan`, which must
// outlive the lookup.
ModelLookup HttpApi::model_lookup(ModelPlan& plan) {
  return [this, &plan](const std::string& id_or_name) -> std::optional<FoundModel> {
    const auto held = find_model(plan, id_or_name);
    if (!held) return std::nullopt;
    return FoundModel{held->id, drawn_model(held)};
  };
}

std::shared_ptr<const HeldModel> HttpApi::find_model(ModelPlan& plan, const std::string& id_or_name) {
  if (const auto held = plan.held.find(id_or_name); held != plan.held.end()) return held->second;
  const auto planned = plan.to_load.find(id_or_name);
  if (planned == plan.to_load.end()) return nullptr;  // neither held nor stored when planned
  ModelPlan::ToLoad& load = planned->second;
  const auto keep = [&](std::shared_ptr<const HeldModel> held) {
    plan.held.emplace(id_or_name, held);
    plan.to_load.erase(planned);
    return held;
  };
  if (auto held = models_->find(id_or_name)) return keep(std::move(held));  // loaded meanwhile
  std::string why;
  const std::optional<ModelArchive::Stored> stored = archive_->load(id_or_name, options_.max_model_bytes, why);
  if (!stored) {
    if (!why.empty()) std::fprintf(stderr, "umbra-server: --model-store: %s\n", why.c_str());
    return nullptr;
  }
  LoadOptions load_options;  // as an upload: nothing outside the body is read
  load_options.format = stored->format;
  // What it holds is known before it is built: counted first. More than its
  // record said (or no record): the reservation grows, or the load stops.
  std::optional<ModelsRefused> refused;
  load_options.admit = [&](std::uint64_t bytes, std::size_t, std::string& message) {
    // With the scene's models already found, can it ever fit? (Known here
    // only for a model without a record.)
    std::uint64_t together = bytes;
    for (const auto& [key, held] : plan.held)
      if (!held->pinned) together += held->bytes;
    const std::uint64_t for_uploads = models_->upload_max_bytes();
    if (together > for_uploads) {
      refused = ModelsRefused{422, "the scene's models need at least " + mib(together) + " once loaded together, " +
                                       over_upload_budget(for_uploads)};
      message = refused->message;
      return 422;
    }
    const ModelStore::Room room = models_->grow(load.room, bytes);
    if (room == ModelStore::Room::Made) return 0;
    refused = room_refusal(room, bytes, "the model " + short_id(id_or_name) + " needs", 503);
    message = refused->message;
    return refused->status;
  };
  std::optional<LoadResult> result = load_model(stored->body, load_options);
  if (!result) throw ModelLoadsBusy();
  LoadResult& loaded = *result;
  if (refused) throw *refused;
  if (!loaded.ok()) {
    std::fprintf(stderr, "umbra-server: --model-store: %s: %s\n", id_or_name.c_str(), loaded.error.c_str());
    return nullptr;
  }
  const std::size_t triangles = loaded.model->triangle_count();
  const ModelStore::AddResult added = models_->add_upload(id_or_name, std::move(loaded.model), load.room);
  if (!added.held) throw room_refusal(ModelStore::Room::NoRoomNow, loaded.bytes_bound, "the model " + short_id(id_or_name) + " needs", 503);
  // Measured now: the next server to need it counts it before loading it.
  if (!load.found.record || load.found.record->bytes_bound != loaded.bytes_bound)
    archive_->write_record(id_or_name, {loaded.bytes_bound, triangles, load.found.owner});
  return keep(added.held);
}

namespace {

// What an upload is: a glTF (by Content-Type, or ?format=glb|gltf), or a
// format umbra-model-import converts (by ?format=obj... or a media type
// that names one), with its conventions (?up=, ?unit=). Sends the 400 or
// 415 itself and answers nullopt when the request says none of these.
struct UploadKind {
  LoadOptions::Format gltf = LoadOptions::Format::Binary;
  const ImportFormat* imported = nullptr;
  bool cityjson = false;  ///< read here (assets/cityjson_loader.hpp), at `lod`
  std::string up = "file", unit = "file", lod;
};

std::string import_format_list() {
  std::string list;
  for (const ImportFormat& f : import_formats()) list += (list.empty() ? "" : ", ") + std::string(f.extension);
  return list;
}

std::optional<UploadKind> upload_kind(const HttpRequest& req, HttpResponse& res) {
  std::vector<std::pair<std::string, std::string>> params;
  if (!query_params(req.target, params)) {
    send_error(res, 400, "malformed query: a bad %-escape", "");
    return std::nullopt;
  }
  UploadKind kind;
  std::string format;
  bool conventions = false;
  for (std::size_t i = 0; i < params.size(); ++i) {
    const auto& [name, value] = params[i];
    // One meaning per parameter: `?format=obj&format=` let the second win.
    for (std::size_t j = 0; j < i; ++j)
      if (params[j].first == name) {
        send_error(res, 400, "is given twice in the query", name.substr(0, 40));
        return std::nullopt;
      }
    if (name == "format") {
      if (value.empty()) {
        send_error(res, 400, "is empty: name a format (glb, gltf, cityjson, " + import_format_list() + ")", "format");
        return std::nullopt;
      }
      format = value;
    } else if (name == "lod") {
      if (value.empty() || value.size() > 8 || value.find_first_not_of("0123456789.") != std::string::npos) {
        send_error(res, 400, "must be a level of detail such as 2 or 2.2, not '" + value.substr(0, 40) + "'", "lod");
        return std::nullopt;
      }
      kind.lod = value;
    } else if (name == "up" || name == "unit") {
      const std::vector<std::string> allowed = name == "up" ? std::vector<std::string>{"file", "y", "z"}
                                                            : std::vector<std::string>{"file", "m", "cm", "mm", "in", "ft"};
      if (std::find(allowed.begin(), allowed.end(), value) == allowed.end()) {
        std::string list;
        for (const std::string& a : allowed) list += (list.empty() ? "" : ", ") + a;
        send_error(res, 400, "must be one of " + list + ", not '" + value.substr(0, 40) + "'", name);
        return std::nullopt;
      }
      (name == "up" ? kind.up : kind.unit) = value;
      conventions = true;
    } else {
      send_error(res, 400, "unknown query parameter (expected format, lod, up or unit)", name.substr(0, 40));
      return std::nullopt;
    }
  }
  const std::string full_type = req.header("Content-Type");
  std::string type = full_type.substr(0, full_type.find(';'));
  while (!type.empty() && (type.back() == ' ' || type.back() == '\t')) type.pop_back();
  kind.cityjson = format.empty() ? equal_ci(type, "application/city+json") : equal_ci(format, "cityjson");
  if (!kind.lod.empty() && !kind.cityjson) {
    send_error(res, 400, "applies to CityJSON only (?format=cityjson or Content-Type application/city+json)", "lod");
    return std::nullopt;
  }
  if (kind.cityjson) {
    if (conventions) {
      send_error(res, 400, "does not apply to CityJSON (its reference system is in metres, z up: see docs/api.md)",
                 std::find_if(params.begin(), params.end(), [](const auto& p) { return p.first == "up" || p.first == "unit"; })->first);
      return std::nullopt;
    }
    return kind;
  }
  const bool glb = format.empty() ? equal_ci(type, "model/gltf-binary") : equal_ci(format, "glb");
  const bool gltf = format.empty() ? equal_ci(type, "model/gltf+json") : equal_ci(format, "gltf");
  if (glb || gltf) {
    kind.gltf = glb ? LoadOptions::Format::Binary : LoadOptions::Format::Json;
    if (conventions) {
      send_error(res, 400, "applies to formats other than glTF (glTF is Y up, in metres, by its specification)",
                 std::find_if(params.begin(), params.end(), [](const auto& p) { return p.first != "format"; })->first);
      return std::nullopt;
    }
    return kind;
  }
  kind.imported = import_format_named(format.empty() ? type : format);
  if (kind.imported) return kind;
  if (!format.empty()) {
    send_error(res, 400, "'" + format.substr(0, 40) + "' is not a format this server reads (glb, gltf, cityjson, " +
                             import_format_list() + ")", "format");
    return std::nullopt;
  }
  send_error(res, 415,
             "unsupported Content-Type " + (type.empty() ? std::string("(none)") : type.substr(0, 100)) +
                 "; send a .glb as model/gltf-binary, a self-contained .gltf as model/gltf+json, CityJSON as "
                 "application/city+json, or another format named by ?format= (" + import_format_list() + ")",
             "");
  return std::nullopt;
}

}  // namespace

// A .glb or a self-contained .gltf, or a file of another format converted
// to a .glb (CityJSON here, the others by umbra-model-import); its id is
// the SHA-256 of the body (of the .glb, when converted), so the same upload
// twice is one model (the second answered 200 at once). Its
// room is reserved before it is built (it may hold at most
// max_loaded_bytes of its body, and its owner's share); it is held, then
// written to --model-store (a converted model as its .glb): nothing
// refused is written.
void HttpApi::upload_model(const HttpRequest& req, HttpResponse& res) {
  const std::optional<UploadKind> kind = upload_kind(req, res);
  if (!kind) return;
  LoadOptions options;  // no external folder: nothing outside the body is read
  const bool converted_here = kind->imported || kind->cityjson;
  options.format = converted_here ? LoadOptions::Format::Binary : kind->gltf;
  // What is loaded and stored: the body, or the .glb converted from it (in
  // one of the places loads run in). A converted model's id is its .glb's
  // SHA-256: the store checks a file against its name, and the same .glb
  // is the same model whatever it was made from.
  std::string converted;
  if (converted_here) {
    int status = 0;
    std::string why, field;
    const bool ran = in_load_place([&] {
      if (kind->imported) {
        ImportOptions convert;
        convert.importer = options_.model_importer.empty() ? default_importer_path() : options_.model_importer;
        convert.up = kind->up;
        convert.unit = kind->unit;
        convert.max_output_bytes =
            std::min<std::uint64_t>(max_loaded_bytes(req.body.size()), std::uint64_t(256) << 20);
        convert.max_seconds = import_cpu_seconds(req.body.size(), convert.max_seconds);
        const int socket = req.socket;
        if (socket >= 0) convert.stop = [socket] { return peer_closed(socket); };
        ImportResult imported = import_model(req.body, *kind->imported, convert);
        status = imported.status, why = std::move(imported.error), converted = std::move(imported.glb);
        return;
      }
      CityJsonOptions read;
      read.lod = kind->lod;
      // At most what an upload of this body may hold once loaded (its
      // .glb's load reserves the room).
      read.admit = [&](std::uint64_t bytes, std::size_t, std::string& message) {
        if (bytes <= max_loaded_bytes(req.body.size())) return 0;
        message = "the city model would hold up to " + mib(bytes) + " once loaded, more than an upload of " +
                  std::to_string(req.body.size()) + " bytes may (" + mib(max_loaded_bytes(req.body.size())) + ")";
        return 422;
      };
      const CityJsonResult city = load_cityjson(req.body, read);
      if (!city.ok()) {
        status = city.status, why = city.error, field = city.status == 422 && !kind->lod.empty() ? "lod" : "";
        return;
      }
      converted = write_glb(*city.model);
      std::string lods;
      for (const std::string& l : city.lods) lods += (lods.empty() ? "" : ",") + l;
      res.set_header("Umbra-CityJSON", "objects=" + std::to_string(city.objects) + "; lods=" + lods +
                                           "; lod=" + (kind->lod.empty() ? std::string("highest") : kind->lod) +
                                           "; left_out=" + std::to_string(city.left_out) +
                                           "; fanned=" + std::to_string(city.fell_back));
    });
    if (!ran) return send_models_busy(res);
    if (status) return send_error(res, status, why, field);
  }
  const std::string* stored_body = converted_here ? &converted : &req.body;
  const std::string id = model_id_for(*stored_body);

  // Every server of a cluster must find a model it is told of: it is in
  // the shared folder before the upload is answered, also when this server
  // held it already (another server may have evicted the file).
  const auto archived = [&](const std::optional<ModelArchive::Record>& record) {
    std::string why;
    if (!archive_) return true;
    const ModelArchive::Saved saved = archive_->save(id, options.format, *stored_body, why, record);
    if (saved) return true;
    if (!saved.detail.empty()) std::fprintf(stderr, "umbra-server: --model-store: %s\n", saved.detail.c_str());
    switch (saved.status) {
      case ModelArchive::Status::TooLarge:  // retrying can never succeed
        send_error(res, 422, "the model cannot be written to --model-store: " + why, "");
        break;
      case ModelArchive::Status::NoRoomNow:
      case ModelArchive::Status::NoSpace:
        res.set_header("Retry-After", "5");
        send_error(res, 507, "the model could not be written to --model-store: " + why, "");
        break;
      default:
        send_error(res, 503, "the model could not be written to --model-store: " + why, "");
    }
    return false;
  };
  const std::string owner = uploader_of(req);
  if (const auto held = models_->find(id)) {
    if (archived(ModelArchive::Record{held->bytes, held->model->triangle_count(), owner}))
      res.set_content(model_json(*held).dump(), "application/json");
    return;
  }
  ModelStore::Reservation room;
  options.admit = [&](std::uint64_t bytes, std::size_t, std::string& why) {
    const std::uint64_t most = max_loaded_bytes(req.body.size());
    if (bytes > most) {
      why = "the model would hold up to " + mib(bytes) + " once loaded, more than an upload of " +
            std::to_string(req.body.size()) + " bytes may: " + std::to_string(kUploadExpansion) +
            " times its body + " + mib(kUploadAllowance) + " (" + mib(most) +
            "); instancing one mesh under many nodes builds each copy out";
      return 422;
    }
    ModelStore::RoomResult reserved = models_->reserve(owner, bytes);
    if (reserved.outcome == ModelStore::Room::Made) {
      room = std::move(reserved.reservation);
      return 0;
    }
    const ModelsRefused refused = room_refusal(reserved.outcome, bytes, "the model needs", 507);
    if (refused.status == 507) res.set_header("Retry-After", "5");
    why = refused.message;
    return refused.status;
  };
  std::optional<LoadResult> result = load_model(*stored_body, options);
  if (!result) return send_models_busy(res);
  LoadResult& loaded = *result;
  if (!loaded.ok()) return send_error(res, loaded.status, loaded.error, "");
  const std::size_t triangles = loaded.model->triangle_count();
  const ModelStore::AddResult added = models_->add_upload(id, std::move(loaded.model), room);
  switch (added.outcome) {
    case ModelStore::Outcome::Added:
      if (!archived(ModelArchive::Record{loaded.bytes_bound, triangles, owner})) {
        models_->remove_upload(id);  // refused: neither held nor written
        return;
      }
      res.status = 201;
      res.set_header("Location", "/api/models/" + id);
      break;
    case ModelStore::Outcome::AlreadyHeld:  // uploaded meanwhile by another request
      if (!archived(ModelArchive::Record{loaded.bytes_bound, triangles, owner})) return;
      break;
    case ModelStore::Outcome::TooLarge:
    case ModelStore::Outcome::NameTaken:  // uploads have no name: cannot happen
    case ModelStore::Outcome::NoRoom:
      send_models_refused(res, room_refusal(added.outcome == ModelStore::Outcome::NoRoom ? ModelStore::Room::NoRoomNow
                                                                                          : ModelStore::Room::OverBudget,
                                            loaded.bytes_bound, "the model needs", 507));
      return;
  }
  res.set_content(model_json(*added.held).dump(), "application/json");
}

// A file of the web panel; one byte range of it on request (a resumed
// download). An API answer never takes a range: a render is made for its
// request, there is nothing to resume.
void HttpApi::static_file(const HttpRequest& req, HttpResponse& res) {
  const std::string name = req.path == "/" ? "index.html" : req.path.substr(1);
  std::string bytes;
  if (!read_static_file(name, bytes)) return send_error(res, 404, "no such path", "");
  res.set_header("Accept-Ranges", "bytes");
  std::size_t first = 0, last = 0;
  switch (req.has_header("Range") ? byte_range(req.header("Range"), bytes.size(), first, last) : RangeAnswer::Whole) {
    case RangeAnswer::Whole:
      break;
    case RangeAnswer::Unsatisfiable:
      res.set_header("Content-Range", "bytes */" + std::to_string(bytes.size()));
      return send_error(res, 416, "range not satisfiable: the file has " + std::to_string(bytes.size()) + " bytes", "");
    case RangeAnswer::Part:
      res.status = 206;
      res.set_header("Content-Range", "bytes " + std::to_string(first) + "-" + std::to_string(last) + "/" +
                                          std::to_string(bytes.size()));
      bytes = bytes.substr(first, last - first + 1);
      break;
  }
  res.set_content(std::move(bytes), content_type_for(name));
}

bool HttpApi::read_static_file(const std::string& name, std::string& bytes) const {
  if (options_.web_dir.empty()) {
    // Embedded: only the files that were built in, by exact name.
    for (std::string_view asset : web_asset_names()) {
      if (asset != name) continue;
      bytes = std::string(web_asset(asset));
      return true;
    }
    return false;
  }
  // A folder: only a regular file inside it (the server has already
  // decoded %2e%2e into "..", which the check resolves).
  std::string file_path;
  if (!file_inside_folder(options_.web_dir, options_.web_dir + "/" + name, file_path)) return false;
  std::ifstream in(file_path, std::ios::binary);
  if (!in) return false;
  bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return bool(in) || in.eof();
}

}  // namespace umbra
