// The HTTP face of Umbra (docs/api.md): routes, errors, static files.
// Turns JSON into a typed request, hands it to the RenderService, turns the
// pixels into PNG. Knows nothing of GL.
#pragma once

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "assets/model_archive.hpp"
#include "assets/model_store.hpp"
#include "assets/pose_cache.hpp"
#include "service/render_service.hpp"

#include "access.hpp"
#include "http_server.hpp"
#include "metrics.hpp"
#include "request_parser.hpp"
#include "sun_hours_answer.hpp"
#include "sun_hours_jobs.hpp"

namespace umbra {

struct ServerOptions {
  std::string host = "127.0.0.1";  ///< loopback unless told otherwise
  int port = 8080;                 ///< 0: any free port (see HttpApi::port)
  std::string web_dir;             ///< empty: the web panel embedded at build time
  bool log_requests = true;        ///< one line per request on stderr
  /// Empty: no CORS headers, so browsers allow only same-origin pages to
  /// read responses. Else the one origin (e.g. "https://app.example", or
  /// "*") whose pages may call the API; see valid_cors_origin().
  std::string cors_origin;
  /// Connections, timeouts and workers (http_server.hpp). HttpApi sizes
  /// the workers to the render queue itself.
  HttpServerOptions connections;
  /// Body limit of POST /api/models only (--max-model-mib); every other
  /// request keeps HttpApi::kMaxBodyBytes. 413 above.
  std::size_t max_model_bytes = std::size_t(64) << 20;
  /// Geometry held (--models-budget-mib), for the store HttpApi makes when
  /// none is given to it.
  std::uint64_t models_budget_bytes = std::uint64_t(2048) << 20;
  /// --upload-quota-mib: what one owner's models (HttpApi::uploader_of)
  /// may hold without being dropped for other owners' (ModelStore::Limits::
  /// share_bytes). 0: a quarter of models_budget_bytes.
  std::uint64_t upload_share_bytes = 0;
  /// --model-store DIR: a folder shared with other servers where every
  /// upload is written, and where a model not held is looked for
  /// (model_archive.hpp). Empty: none.
  std::string model_store_dir;
  /// --model-store-max-gib: the most the folder holds; least recently used
  /// files are deleted first to stay under it.
  std::uint64_t model_store_max_bytes = ModelArchive::kDefaultMaxBytes;
  /// --allowed-hosts: names a request's Host may give besides the loopback
  /// names and `host` itself (AllowedHosts); "*": any. Another gets 421.
  std::vector<std::string> allowed_hosts;
  /// --tokens FILE: null, every request is served; else every route but
  /// GET /api/health, OPTIONS and the panel's files needs a bearer token
  /// with the route's scope (HttpApi::kRoutes).
  std::shared_ptr<const TokenTable> tokens;
  /// --name: this server's name in a cluster; sun-hours job ids begin with
  /// it, so that HAProxy sends a job's requests back to its server.
  std::string name;
  /// umbra-model-import, which converts OBJ, STL, IFC... uploads; empty:
  /// the one beside the server's executable (--model-importer).
  std::string model_importer;
  /// Sun-hours jobs held (--job-keep-s keeps finished ones).
  SunHoursJobs::Limits jobs;
};

/// The model store's limits for `options`: its budget, and each owner's share.
ModelStore::Limits model_store_limits(const ServerOptions& options);

/// "*", or scheme://host[:port] with scheme http or https and nothing after.
bool valid_cors_origin(const std::string& origin);

class HttpApi {
 public:
  // Explicit limits on what a request may be; above them it is refused
  // before any work, as soon as the byte that passes one arrives.
  static constexpr std::size_t kMaxBodyBytes = 1 << 20;     ///< 413 above this
  static constexpr std::size_t kMaxUriBytes = 4096;         ///< 414 above this
  static constexpr std::size_t kMaxHeaderCount = 100;       ///< 431 above this many header fields
  static constexpr std::size_t kMaxHeaderBytes = 32 << 10;  ///< 431 above this many bytes of names and values

  /// Models loaded at most this many at once (uploads, and files read
  /// from --model-store); more get 503 with Retry-After (a load holds
  /// several times its body in memory).
  static constexpr int kMaxConcurrentModelLoads = 2;

  /// With a model store of its own (options.models_budget_bytes).
  HttpApi(RenderService& renderer, ServerOptions options);
  /// With the server's model store (main.cpp fills it from --models DIR).
  HttpApi(RenderService& renderer, ModelStore& models, ServerOptions options);
  virtual ~HttpApi();

  /// Binds the socket; false (with errno set) if the address is unusable.
  bool bind();
  /// The bound port (after bind()).
  int port() const { return http_->port(); }
  /// Serves until stop(); call after bind().
  void serve();
  /// True once serve() is accepting connections (and until it returns).
  bool serving() const;
  /// Stops serve(): idle connections and requests still arriving are
  /// closed at once, requests already read are answered. Thread-safe.
  void stop();

  /// Whom the models `req` makes this server load are charged to (its
  /// uploads, and files it reads from --model-store for it): its principal
  /// ("token:" + 12 hex digits) with --tokens, else "" (every client is the
  /// same one). One owner's uploads never evict another owner's models
  /// within its share.
  std::string uploader_of(const HttpRequest& req) const;

 private:
  HttpApi(RenderService& renderer, std::shared_ptr<ModelStore> models, ServerOptions options);

  using Handler = void (HttpApi::*)(const HttpRequest&, HttpResponse&);
  struct Route {
    const char* method;
    const char* path;
    Handler handler;
    bool blocks;          ///< waits for the renderer or loads a model: runs on a worker thread
    unsigned scope;       ///< with --tokens, the Scope bits its token needs; 0: none (no token needed)
    bool prefix = false;  ///< `path` and at least one more character: "/api/models/" + id
  };
  static const Route kRoutes[];

  // Routes.
  void health(const HttpRequest& req, HttpResponse& res);
  void metrics(const HttpRequest& req, HttpResponse& res);
  /// The renderer's, the connections' and the store's counters now.
  MetricsGauges state() const;
  void scenes(const HttpRequest& req, HttpResponse& res);
  void openapi_document(const HttpRequest& req, HttpResponse& res);
  void render_color(const HttpRequest& req, HttpResponse& res);
  void render_depth(const HttpRequest& req, HttpResponse& res);
  void sun_hours(const HttpRequest& req, HttpResponse& res);
  void sun_hours_job(const HttpRequest& req, HttpResponse& res);
  void cancel_sun_hours_job(const HttpRequest& req, HttpResponse& res);
  void start_sun_hours_job(HttpResponse& res, SunHoursRequest request, const SunHoursPlan& plan);
  /// With `job`, its last encoded answer is reused when the format is the same.
  void send_sun_hours(HttpResponse& res, SunHoursFormat format, const SunHoursRequest& request,
                      const SunHoursResult& result, double queue_ms, SunHoursJob* job = nullptr);
  void send_service_error(HttpResponse& res, std::exception_ptr error) const;
  void static_file(const HttpRequest& req, HttpResponse& res);
  void preflight(const HttpRequest& req, HttpResponse& res);
  void list_models(const HttpRequest& req, HttpResponse& res);
  void upload_model(const HttpRequest& req, HttpResponse& res);
  void get_model(const HttpRequest& req, HttpResponse& res);

  void render(const HttpRequest& req, HttpResponse& res, bool depth_route);
  /// The models a request names, planned before any is loaded: those held
  /// (kept alive here), and those to load from --model-store, each with
  /// room already reserved for what its record says it holds.
  struct ModelPlan;
  /// Plans `keys` for `owner`. Throws ModelsRefused when what the held and
  /// stored ones need together can never fit (422) or has no room now (503).
  /// `subject` names the models in a refusal ("the scene's models", "the model").
  void plan_models(ModelPlan& plan, const std::vector<std::string>& keys, const std::string& owner,
                   const std::string& subject = "the scene's models");
  /// A planned model by id or name: held, or loaded from the folder into
  /// its reservation. Null if neither has it. Throws ModelLoadsBusy if it
  /// would have to load one with no place free, ModelsRefused if it holds
  /// more than its record said and no room is left for the rest.
  std::shared_ptr<const HeldModel> find_model(ModelPlan& plan, const std::string& id_or_name);
  /// Poses the scene's mesh objects that name an animation at `time`
  /// (PoseCache), in a place of its own (kMaxConcurrentPoses), stopped if
  /// the client goes. False: it could not, and `res` says why.
  bool pose_animations(Scene& scene, double time, const HttpRequest& req, HttpResponse& res);
  /// find_model as the request parsers take it (a ModelLookup over `plan`).
  ModelLookup model_lookup(ModelPlan& plan);
  /// load_gltf in one of kMaxConcurrentModelLoads places (a load holds a
  /// few times its body in memory): nullopt, unloaded, if none is free.
  std::optional<LoadResult> load_model(const std::string& body, const LoadOptions& options);
  /// Runs `work` (a load, or a conversion to a .glb) in one of the
  /// kMaxConcurrentModelLoads places; false when none is free.
  bool in_load_place(const std::function<void()>& work);
  /// Runs `work` while `busy` (one of the counters under
  /// model_loads_mutex_) is below `most`, counted in it; false when full.
  bool in_place(int& busy, int most, const std::function<void()>& work);
  /// 503 with Retry-After: every model-load place is taken.
  void send_models_busy(HttpResponse& res) const;
  struct ModelLoadsBusy {};
  /// The models a request names, or an upload, refused with this status
  /// (422: can never fit; 503 / 507: no room now, Retry-After) and message.
  struct ModelsRefused {
    int status;
    std::string message;
  };
  void send_models_refused(HttpResponse& res, const ModelsRefused& refused) const;
  /// What a refused reservation of `bytes` for `what` answers.
  ModelsRefused room_refusal(ModelStore::Room room, std::uint64_t bytes, const std::string& what,
                             int no_room_status) const;
  /// The route for `req`'s method and path, or null (with `allow` set to
  /// the path's methods, if the path is a route's).
  const Route* find_route(const HttpRequest& req, std::string& allow) const;
  void handle(const HttpRequest& req, HttpResponse& res);
  /// The route label of `req` in the metrics: a route's path as the table
  /// names it, "static" for the panel's files, or "other".
  std::string route_label(const HttpRequest& req) const;
  bool blocks(const HttpRequest& req) const;
  /// At the end of `head`: the Host check, then (with --tokens) the token
  /// and its scope. Refused before any of the body is read.
  Admission admit(const HttpRequest& head) const;
  HttpResponse error_response(int status, const std::string& message) const;
  void add_cors_headers(HttpResponse& res) const;
  /// The panel's file `name` (a path relative to the web folder): false if
  /// there is none, or if it lies outside the folder.
  bool read_static_file(const std::string& name, std::string& bytes) const;

  RenderService& renderer_;
  ServerOptions options_;
  AllowedHosts allowed_hosts_;
  std::shared_ptr<ModelStore> models_;  // owned, or the one given (not owned)
  std::mutex model_loads_mutex_;
  int model_loads_ = 0;  // uploads being loaded now
  std::atomic<std::uint64_t> models_loaded_{0};  // glTF bodies built into models
  std::unique_ptr<ModelArchive> archive_;  // --model-store, or null
  PoseCache poses_;  // animated mesh objects' poses
  int poses_making_ = 0;  // requests posing now (under model_loads_mutex_)
  Metrics metrics_;
  // Before http_: gone after the connections, cancelling what still runs.
  std::unique_ptr<SunHoursJobs> jobs_;
  std::unique_ptr<HttpServer> http_;
  std::chrono::steady_clock::time_point started_;
};

}  // namespace umbra
