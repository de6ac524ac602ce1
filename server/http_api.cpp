#include "http_api.hpp"

#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <sstream>
#include <utility>

#include <httplib.h>
#include <nlohmann/json.hpp>
#include <sys/stat.h>

#include "client_socket.hpp"
#include "png.hpp"
#include "request_parser.hpp"
#include "scene.hpp"
#include "web_assets.hpp"

namespace umbra {

namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

void send_error(httplib::Response& res, int status, const std::string& message, const std::string& field) {
  res.status = status;
  // Replace, not throw, should a message ever carry invalid UTF-8.
  res.set_content(json{{"error", message}, {"field", field}}.dump(-1, ' ', false, json::error_handler_t::replace),
                  "application/json");
}

// For a request whose framing cannot be trusted (RFC 9112 §6.3: the server
// must answer 400 and close), so that no byte after its headers is ever read
// as the next request. cpp-httplib 0.11 gives a handler no way to close the
// connection; a content provider that reports failure once it has written
// the whole body makes it close after the response. The body is send_error's.
void send_error_and_close(httplib::Response& res, int status, const std::string& message, const std::string& field) {
  send_error(res, status, message, field);
  auto body = std::make_shared<std::string>(std::move(res.body));
  res.body.clear();
  res.headers.erase("Content-Type");  // set again below, once
  res.set_header("Connection", "close");
  res.set_content_provider(body->size(), "application/json",
                           [body](std::size_t offset, std::size_t length, httplib::DataSink& sink) {
                             sink.write(body->data() + offset, length);
                             return false;  // written whole: now close
                           });
}

bool starts_with_ci(const std::string& s, const char* prefix) {
  const std::size_t n = std::char_traits<char>::length(prefix);
  if (s.size() < n) return false;
  for (std::size_t i = 0; i < n; ++i)
    if (std::tolower(static_cast<unsigned char>(s[i])) != std::tolower(static_cast<unsigned char>(prefix[i])))
      return false;
  return true;
}

// RFC 9112 §6.3: a Content-Length must be a non-empty string of digits, and
// several must agree; Transfer-Encoding (whose final coding must be chunked,
// the only one cpp-httplib reads) excludes Content-Length. Anything else
// leaves the body's length unknown. cpp-httplib would read "0x10" as 0 and
// "-1" as 2^64 - 1 (waiting for that body), and take the first of several.
// Empty: the framing is sound; else the error, naming the header.
std::string framing_error(const httplib::Request& req) {
  const std::size_t lengths = req.get_header_value_count("Content-Length");
  const std::size_t codings = req.get_header_value_count("Transfer-Encoding");
  if (lengths > 0 && codings > 0) return "Content-Length and Transfer-Encoding together";
  const std::string coding = req.get_header_value("Transfer-Encoding");
  if (codings > 1 || (codings == 1 && !(coding.size() == 7 && starts_with_ci(coding, "chunked"))))
    return "Transfer-Encoding other than chunked";
  for (std::size_t i = 0; i < lengths; ++i) {
    const std::string value = req.get_header_value("Content-Length", i);
    if (value.empty() || value.find_first_not_of("0123456789") != std::string::npos)
      return "Content-Length is not a decimal number of bytes";
    if (value != req.get_header_value("Content-Length", 0)) return "several different Content-Length values";
  }
  return "";
}

// RFC 9112 §6.3: a request with neither Content-Length nor Transfer-Encoding
// has no body. cpp-httplib would read one until the client closes (or its
// read timeout), so such a request is not given to it to read.
bool has_body(const httplib::Request& req) {
  return req.has_header("Content-Length") || req.has_header("Transfer-Encoding");
}

// Reads a body only to throw it away, so that the connection can serve its
// next request. multipart/form-data goes through cpp-httplib's own parser
// (the plain reader would call an empty callback there); the 1 MiB limit
// applies either way. False: cpp-httplib has set the status (413 or 400).
bool discard_body(const httplib::Request& req, const httplib::ContentReader& content_reader) {
  if (!has_body(req)) return true;
  const auto ignore = [](const char*, std::size_t) { return true; };
  if (req.is_multipart_form_data())
    return content_reader([](const httplib::MultipartFormData&) { return true; }, ignore);
  return content_reader(ignore);
}

// cpp-httplib answers any Range itself (206 and a slice; several ranges
// each repeat the headers, so thousands of them multiply the response). An
// API answer is always whole: a render is made for this request, there is
// nothing to resume. A static file may take one range (a resumed download);
// several are ignored, which RFC 9110 §14.2 allows, and the file is sent
// whole, never larger than it is. The handler's Request is const, but
// cpp-httplib's own object is not, and it reads the ranges only later.
void ignore_unsafe_ranges(httplib::Request& req) {
  const bool api = req.path.rfind("/api/", 0) == 0 || req.path == "/api";
  const bool file_read = req.method == "GET" || req.method == "HEAD";
  if (api || !file_read || req.ranges.size() > 1) req.ranges.clear();
}

json vec3_json(const glm::dvec3& v) { return json::array({v.x, v.y, v.z}); }

// Same form as a custom scene's object in a request body.
json object_json(const SceneObject& o) {
  switch (o.type) {
    case SceneObject::Type::Plane:
      return {{"type", "plane"}, {"center", vec3_json(o.center)}, {"size", {o.size.x, o.size.z}}, {"color", vec3_json(o.color)}};
    case SceneObject::Type::Box:
      return {{"type", "box"}, {"center", vec3_json(o.center)}, {"size", vec3_json(o.size)},
              {"rotation_y_deg", o.rotation_y_deg}, {"color", vec3_json(o.color)}};
    case SceneObject::Type::Sphere:
      return {{"type", "sphere"}, {"center", vec3_json(o.center)}, {"radius", o.radius}, {"color", vec3_json(o.color)}};
  }
  return {};
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

std::string server_timing(const FrameTimings& t, double encode_ms, double queue_ms) {
  char buffer[256];
  std::snprintf(buffer, sizeof buffer, "shadow;dur=%.3f, main;dur=%.3f, readback;dur=%.3f, encode;dur=%.3f, queue;dur=%.3f",
                t.shadow_ms, t.main_ms, t.readback_ms, encode_ms, queue_ms);
  return buffer;
}

// The time the current request started, per worker thread: cpp-httplib
// serves one connection per thread, one request at a time.
thread_local Clock::time_point request_started{};

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

HttpApi::HttpApi(RenderService& renderer, ServerOptions options)
    : renderer_(renderer), options_(std::move(options)), http_(std::make_unique<httplib::Server>()),
      started_(Clock::now()) {
  install_routes();
}

HttpApi::~HttpApi() = default;

bool HttpApi::bind() {
  if (options_.port == 0) {
    port_ = http_->bind_to_any_port(options_.host);
    return port_ > 0;
  }
  port_ = options_.port;
  return http_->bind_to_port(options_.host, options_.port);
}

void HttpApi::serve() { http_->listen_after_bind(); }

bool HttpApi::serving() const { return http_->is_running(); }

void HttpApi::stop() { http_->stop(); }

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
  // A folder: the file's real path (every "..", "//" and symlink resolved;
  // cpp-httplib has already decoded %2e%2e into "..") must lie inside the
  // folder's real path, and be a regular file.
  if (name.find('\0') != std::string::npos) return false;
  char* root = realpath(options_.web_dir.c_str(), nullptr);
  char* file = realpath((options_.web_dir + "/" + name).c_str(), nullptr);
  const std::string root_path = root ? root : "", file_path = file ? file : "";
  std::free(root);
  std::free(file);
  if (root_path.empty() || file_path.size() <= root_path.size() + 1 ||
      file_path.compare(0, root_path.size() + 1, root_path + "/") != 0)
    return false;
  struct stat info {};
  if (stat(file_path.c_str(), &info) != 0 || !S_ISREG(info.st_mode)) return false;
  std::ifstream in(file_path, std::ios::binary);
  if (!in) return false;
  bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return bool(in) || in.eof();
}

void HttpApi::install_routes() {
  httplib::Server& http = *http_;
  http.set_payload_max_length(kMaxBodyBytes);
  // One worker per connection (cpp-httplib's model): enough for a full
  // render queue plus a few for health checks and the panel's files, so
  // that the render queue, not a hidden backlog of accepted connections,
  // is what bounds the waiting.
  const std::size_t workers = std::max<std::size_t>(8, renderer_.limits().queue_capacity + 4);
  http.new_task_queue = [workers] { return new httplib::ThreadPool(workers); };
  // An animation loop reuses its connection; an idle one is closed after
  // 2 s, which is also the longest it can hold up a graceful stop.
  // A response goes out as headers, then body: with Nagle's algorithm the
  // body would wait for the client's delayed ACK of the headers (~40 ms).
  http.set_tcp_nodelay(true);
  http.set_keep_alive_max_count(1000);
  http.set_keep_alive_timeout(2);
  http.set_read_timeout(10, 0);
  http.set_write_timeout(10, 0);
  // cpp-httplib's default also sets SO_REUSEPORT, which lets a second server
  // start on a port that is already serving and silently take half of its
  // connections. SO_REUSEADDR alone still allows a quick restart.
  http.set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });

  if (!options_.cors_origin.empty()) {
    // Every response, errors included, so a page can read why it failed.
    http.set_default_headers({{"Access-Control-Allow-Origin", options_.cors_origin},
                              {"Vary", "Origin"},
                              {"Access-Control-Expose-Headers",
                               "Server-Timing, Retry-After, Umbra-Unused-Fields, Umbra-Shadow-Views, Umbra-Shadow-Error"},
                              {"Timing-Allow-Origin", options_.cors_origin}});
    // The preflight a browser sends before a cross-origin JSON POST.
    http.Options(R"(/.*)", [](const httplib::Request&, httplib::Response& res) {
      res.status = 204;
      res.set_header("Access-Control-Allow-Methods", "GET, POST");
      res.set_header("Access-Control-Allow-Headers", "Content-Type");
      res.set_header("Access-Control-Max-Age", "600");
    });
  }
  http.set_pre_routing_handler([](const httplib::Request& req, httplib::Response& res) {
    request_started = Clock::now();
    if (req.target.size() > kMaxUriBytes) {
      send_error(res, 414, "request URI longer than " + std::to_string(kMaxUriBytes) + " bytes", "");
      return httplib::Server::HandlerResponse::Handled;
    }
    std::size_t header_bytes = 0;
    for (const auto& [name, value] : req.headers) header_bytes += name.size() + value.size();
    if (req.headers.size() > kMaxHeaderCount || header_bytes > kMaxHeaderBytes) {
      send_error(res, 431,
                 "request headers too large (at most " + std::to_string(kMaxHeaderCount) + " fields and " +
                     std::to_string(kMaxHeaderBytes) + " bytes)",
                 "");
      return httplib::Server::HandlerResponse::Handled;
    }
    const std::string framing = framing_error(req);
    if (!framing.empty()) {
      send_error_and_close(res, 400, "malformed request framing: " + framing, "");
      return httplib::Server::HandlerResponse::Handled;
    }
    ignore_unsafe_ranges(const_cast<httplib::Request&>(req));
    return httplib::Server::HandlerResponse::Unhandled;
  });
  // Errors raised inside cpp-httplib itself (413, 400 on a bad request line,
  // unmatched routes) get the same JSON form as ours; ours already have a body.
  http.set_error_handler(httplib::Server::HandlerWithResponse([](const httplib::Request&, httplib::Response& res) {
    if (!res.body.empty() || res.content_provider_) return httplib::Server::HandlerResponse::Unhandled;
    switch (res.status) {
      case 404: send_error(res, 404, "no such path", ""); break;
      case 413: send_error(res, 413, "request body larger than 1 MiB", ""); break;
      case 414: send_error(res, 414, "request URI too long", ""); break;
      case 431: send_error(res, 431, "request headers too large", ""); break;
      default: send_error(res, res.status, "malformed HTTP request", ""); break;
    }
    return httplib::Server::HandlerResponse::Handled;
  }));
  // cpp-httplib adds Keep-Alive to every response it does not close itself;
  // one that send_error_and_close closes says only "Connection: close".
  http.set_post_routing_handler([](const httplib::Request&, httplib::Response& res) {
    if (res.get_header_value("Connection") == "close") res.headers.erase("Keep-Alive");
  });
  http.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr error) {
    std::string what = "internal error";
    try {
      if (error) std::rethrow_exception(error);
    } catch (const std::exception& e) {
      what = std::string("internal error: ") + e.what();
    } catch (...) {
    }
    send_error(res, 500, what, "");
  });
  if (options_.log_requests) {
    http.set_logger([](const httplib::Request& req, const httplib::Response& res) {
      const bool timed = request_started != Clock::time_point{};
      const double ms = timed ? std::chrono::duration<double, std::milli>(Clock::now() - request_started).count() : 0.0;
      std::fprintf(stderr, "%s %s %d %.1f ms\n", req.method.c_str(), req.path.c_str(), res.status, ms);
      request_started = Clock::time_point{};
    });
  }

  http.Get("/api/health", [this](const httplib::Request&, httplib::Response& res) {
    const RendererInfo& info = renderer_.info();
    const double uptime = std::chrono::duration<double>(Clock::now() - started_).count();
    res.set_content(json{{"status", "ok"},
                         {"gl_renderer", info.gl_renderer},
                         {"gl_version", info.gl_version},
                         {"egl_source", info.egl_source},
                         {"uptime_s", uptime},
                         {"frames_rendered", renderer_.frames_rendered()},
                         {"shadow_cache_hits", renderer_.shadow_cache_hits()},
                         {"scene_uploads", renderer_.scene_uploads()},
                         {"queue_depth", renderer_.queue_depth()},
                         {"queue_capacity", renderer_.limits().queue_capacity},
                         {"rejected", renderer_.rejected()},
                         {"expired", renderer_.expired()},
                         {"abandoned", renderer_.abandoned()}}
                        .dump(),
                    "application/json");
  });

  http.Get("/api/scenes", [](const httplib::Request&, httplib::Response& res) {
    json scenes = json::array();
    for (const auto& s : builtin_scenes()) {
      json objects = json::array();
      for (const auto& o : s.objects) objects.push_back(object_json(o));
      scenes.push_back({{"name", s.name},
                        {"description", s.description},
                        {"objects", objects},
                        {"camera", {{"position", vec3_json(s.camera_position)}, {"target", vec3_json(s.camera_target)}}},
                        {"light", {{"position", vec3_json(s.light_position)}, {"target", vec3_json({0, 0, 0})}}}});
    }
    res.set_content(json{{"scenes", scenes}}.dump(), "application/json");
  });

  const auto render = [this](const httplib::Request& req, httplib::Response& res, const std::string& body,
                             bool depth_route) {
    // The parser sets a depth route's output itself, so that Umbra-Unused-Fields is judged against the depth map.
    ParsedRequest parsed = parse_render_request(body, depth_route ? Route::Depth : Route::Render);
    if (!parsed.ok()) return send_error(res, 400, parsed.error.message, parsed.error.field);
    RenderRequest request = std::move(*parsed.request);
    const auto queued = Clock::now();
    // Asked just before the job's turn: a client that has gone costs no render.
    const int socket = find_client_socket(req.remote_addr, req.remote_port, req.local_port);
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
    res.set_header("Server-Timing", server_timing(t, encode_ms, queue_ms));
    res.set_header("Cache-Control", "no-store");
    if (!parsed.unused_fields.empty()) {
      std::string list;
      for (const auto& f : parsed.unused_fields) list += (list.empty() ? "" : ", ") + f;
      res.set_header("Umbra-Unused-Fields", list);
    }
    if (!result.shadow_views.empty()) res.set_header("Umbra-Shadow-Views", result.shadow_views);
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
  };
  // The body is read through a content reader, whatever its Content-Type
  // (none, text/plain, JSON alike): cpp-httplib would otherwise parse a body
  // sent as application/x-www-form-urlencoded (curl -d's default) as a form
  // and refuse it above 8 KiB. The 1 MiB limit still applies. multipart/*
  // (curl -F) is a set of parts, not one JSON document: 415.
  const auto read_then_render = [render](const httplib::Request& req, httplib::Response& res,
                                        const httplib::ContentReader& content_reader, bool depth_route) {
    if (starts_with_ci(req.get_header_value("Content-Type"), "multipart/")) {
      const std::string type = req.get_header_value("Content-Type");
      if (discard_body(req, content_reader))
        send_error(res, 415, "unsupported Content-Type " + type.substr(0, type.find(';')) +
                                 "; send the JSON body as it is (application/json, or any type but multipart/*)",
                   "");
      return;  // else cpp-httplib's 413 or 400, written by the error handler
    }
    std::string body;  // none at all reads as {}, all defaults, like an empty one
    const bool whole = !has_body(req) || content_reader([&body](const char* data, std::size_t length) {
      body.append(data, length);
      return true;
    });
    // Never render from part of a body. Too large: cpp-httplib has set 413,
    // and the error handler above writes its JSON. Else the connection
    // failed mid-way.
    if (!whole) {
      if (res.status != 413) send_error(res, 400, "the request body could not be read whole", "");
      return;
    }
    render(req, res, body, depth_route);
  };
  http.Post("/api/render", [read_then_render](const httplib::Request& req, httplib::Response& res,
                                              const httplib::ContentReader& content_reader) {
    read_then_render(req, res, content_reader, false);
  });
  http.Post("/api/depth", [read_then_render](const httplib::Request& req, httplib::Response& res,
                                             const httplib::ContentReader& content_reader) {
    read_then_render(req, res, content_reader, true);
  });

  // A known path with the wrong method is 405, not 404.
  struct Route {
    const char* path;
    const char* allow;
  };
  static const Route routes[] = {{"/api/health", "GET"}, {"/api/scenes", "GET"}, {"/api/render", "POST"},
                                 {"/api/depth", "POST"}};
  for (const Route& route : routes) {
    const std::string allow = route.allow;
    const auto not_allowed = [allow](const httplib::Request& req, httplib::Response& res) {
      res.set_header("Allow", allow);
      send_error(res, 405, "method " + req.method + " not allowed here; use " + allow, "");
    };
    // With a content reader, so that a request without a body is not waited
    // on (cpp-httplib would read one until the client closes); a body there
    // is is read and dropped, so that the connection stays usable.
    const auto not_allowed_with_body = [not_allowed](const httplib::Request& req, httplib::Response& res,
                                                     const httplib::ContentReader& content_reader) {
      if (discard_body(req, content_reader)) not_allowed(req, res);
    };
    if (allow != "GET") http.Get(route.path, not_allowed);
    if (allow != "POST") http.Post(route.path, not_allowed_with_body);
    http.Put(route.path, not_allowed_with_body);
    http.Delete(route.path, not_allowed_with_body);
    http.Patch(route.path, not_allowed_with_body);
  }

  // Static files last, so that every API route (and its 405) is matched first.
  http.Get(R"(/.*)", [this](const httplib::Request& req, httplib::Response& res) {
    const std::string name = req.path == "/" ? "index.html" : req.path.substr(1);
    std::string bytes;
    if (!read_static_file(name, bytes)) return send_error(res, 404, "no such path", "");
    res.set_content(std::move(bytes), content_type_for(name).c_str());
  });
}

}  // namespace umbra
