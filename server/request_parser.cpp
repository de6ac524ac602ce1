#include "request_parser.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <set>
#include <utility>

#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include "core/builtin_models.hpp"
#include "core/light_math.hpp"
#include "core/mesh_instance.hpp"
#include "core/scene.hpp"
#include "core/sun_position.hpp"

namespace umbra {

namespace {

using json = nlohmann::json;

// Thrown while reading; turned into a RequestError at the top.
struct Rejection {
  std::string field;
  std::string message;
};

// nlohmann quotes the bytes it stopped at, which may be invalid UTF-8 or
// control characters: escaped as \xNN, the message is always printable.
std::string printable(const std::string& text) {
  std::string out;
  for (unsigned char c : text) {
    if (c >= 0x20 && c < 0x7f) {
      out += char(c);
    } else {
      char escaped[5];
      std::snprintf(escaped, sizeof escaped, "\\x%02X", c);
      out += escaped;
    }
  }
  return out;
}

// A client's own text as an error quotes it: printable, and cut after
// RequestLimits::kMaxQuotedBytes so that a megabyte string does not come
// back as a megabyte error.
std::string quote_text(const std::string& text) {
  if (text.size() <= RequestLimits::kMaxQuotedBytes) return "\"" + printable(text) + "\"";
  return "\"" + printable(text.substr(0, RequestLimits::kMaxQuotedBytes)) + "\"... (" + std::to_string(text.size()) +
         " bytes)";
}

// A field path or message built from a client's keys: the same cut, so the
// answer stays small whatever the body held.
std::string shortened(const std::string& text) {
  constexpr std::size_t kMaxBytes = 4 * RequestLimits::kMaxQuotedBytes;
  if (text.size() <= kMaxBytes) return text;
  return printable(text.substr(0, kMaxBytes)) + "... (" + std::to_string(text.size()) + " bytes)";
}

std::string join(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }
std::string index(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }

// ---------------------------------------------------------------------------
// Syntax: a SAX builder that knows where it is, so that even a syntax error
// (NaN, 1e400, bad UTF-8) names the field it happened in, and that stops at
// duplicate keys and absurd nesting before building anything.
class LocatingBuilder : public nlohmann::json_sax<json> {
 public:
  explicit LocatingBuilder(json& root) : root_(root) {}

  bool null() override { return add(json(nullptr)); }
  bool boolean(bool v) override { return add(json(v)); }
  bool number_integer(number_integer_t v) override { return add(json(v)); }
  bool number_unsigned(number_unsigned_t v) override { return add(json(v)); }
  bool number_float(number_float_t v, const string_t&) override { return add(json(v)); }
  bool string(string_t& v) override { return add(json(std::move(v))); }
  bool binary(binary_t&) override { return fail("binary values are not JSON", current_path()); }

  bool start_object(std::size_t) override { return open(json::object()); }
  bool start_array(std::size_t) override { return open(json::array()); }
  bool end_object() override { return close(); }
  bool end_array() override { return close(); }

  bool key(string_t& k) override {
    json& object = *frames_.back().value;
    if (object.contains(k)) return fail("duplicate key " + quote_text(k), join(frames_.back().path, k));
    frames_.back().key = k;
    return true;
  }

  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception& e) override {
    std::string what = e.what();
    // nlohmann prefixes "[json.exception.parse_error.101] parse error at line 1, column 7: ".
    const auto colon = what.find(": ");
    std::string detail = printable(colon == std::string::npos ? what : what.substr(colon + 2));
    if (e.id == 406) detail = "number out of range (not a finite double)";
    return fail("malformed JSON: " + detail, current_path());
  }

  const std::optional<Rejection>& rejection() const { return rejection_; }

 private:
  struct Frame {
    json* value;
    std::string path;
    std::string key;  // objects: the key whose value comes next
  };

  std::string current_path() const {
    if (frames_.empty()) return "";
    const Frame& f = frames_.back();
    if (f.value->is_array()) return index(f.path, f.value->size());
    return f.key.empty() ? f.path : join(f.path, f.key);
  }

  bool fail(std::string message, std::string field) {
    if (!rejection_) rejection_ = Rejection{std::move(field), std::move(message)};
    return false;
  }

  // Places v where the parser is, returning where it went.
  json* place(json&& v) {
    if (frames_.empty()) {
      root_ = std::move(v);
      return &root_;
    }
    json& parent = *frames_.back().value;
    if (parent.is_array()) {
      parent.push_back(std::move(v));
      return &parent.back();
    }
    json& slot = parent[frames_.back().key];
    slot = std::move(v);
    frames_.back().key.clear();  // an error before the next key is the object's
    return &slot;
  }

  bool add(json&& v) {
    place(std::move(v));
    return true;
  }

  bool open(json&& container) {
    if (int(frames_.size()) >= RequestLimits::kMaxNesting)
      return fail("nested deeper than " + std::to_string(RequestLimits::kMaxNesting) + " levels", current_path());
    std::string path = current_path();
    json* slot = place(std::move(container));
    frames_.push_back({slot, std::move(path), {}});
    return true;
  }

  bool close() {
    frames_.pop_back();
    return true;
  }

  json& root_;
  std::vector<Frame> frames_;
  std::optional<Rejection> rejection_;
};

// ---------------------------------------------------------------------------
// Values: typed readers that reject with the field's path.

const char* type_name(const json& j) {
  if (j.is_number()) return "a number";
  if (j.is_string()) return "a string";
  if (j.is_boolean()) return "a boolean";
  if (j.is_null()) return "null";
  if (j.is_array()) return "an array";
  return "an object";
}

[[noreturn]] void reject(const std::string& field, const std::string& message) { throw Rejection{field, message}; }

std::string format_number(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%g", v);
  return buffer;
}

double read_number(const json& j, const std::string& path) {
  if (!j.is_number()) reject(path, std::string("must be a number, not ") + type_name(j));
  const double v = j.get<double>();
  if (!std::isfinite(v)) reject(path, "must be a finite number");
  return v;
}

// A number in [lo, hi] (or (lo, hi) where `open` says so).
double read_number(const json& j, const std::string& path, double lo, double hi, bool open_lo = false,
                   bool open_hi = false) {
  const double v = read_number(j, path);
  const bool below = open_lo ? v <= lo : v < lo;
  const bool above = open_hi ? v >= hi : v > hi;
  if (below || above)
    reject(path, "must be in " + std::string(open_lo ? "(" : "[") + format_number(lo) + ", " + format_number(hi) +
                     (open_hi ? ")" : "]") + ", got " + format_number(v));
  return v;
}

int read_integer(const json& j, const std::string& path, int lo, int hi) {
  const double v = read_number(j, path);
  if (v != std::floor(v)) reject(path, "must be an integer, got " + format_number(v));
  if (v < lo || v > hi)
    reject(path, "must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " +
                     format_number(v));
  return int(v);
}

// The depth output's bits per sample: exactly 8 or 16, the two depths a grey
// PNG sample can take that an 8- or 16-bit texture reads back as.
int read_depth_bits(const json& j, const std::string& path) {
  const double v = read_number(j, path);
  if (v != 8.0 && v != 16.0) reject(path, "must be 8 or 16, got " + format_number(v));
  return int(v);
}

bool read_boolean(const json& j, const std::string& path) {
  if (!j.is_boolean()) reject(path, std::string("must be true or false, not ") + type_name(j));
  return j.get<bool>();
}

// One of `choices`; returns its position.
std::size_t read_choice(const json& j, const std::string& path, std::initializer_list<const char*> choices) {
  std::string list;
  for (const char* c : choices) list += std::string(list.empty() ? "" : ", ") + "\"" + c + "\"";
  if (!j.is_string()) reject(path, "must be one of " + list + ", not " + type_name(j));
  const std::string& s = j.get_ref<const std::string&>();
  std::size_t i = 0;
  for (const char* c : choices) {
    if (s == c) return i;
    ++i;
  }
  reject(path, "must be one of " + list + ", got " + quote_text(s));
}

glm::dvec3 read_vec3(const json& j, const std::string& path, double lo, double hi) {
  if (!j.is_array() || j.size() != 3)
    reject(path, "must be an array of 3 numbers" + std::string(j.is_array() ? ", got " + std::to_string(j.size()) : ""));
  glm::dvec3 v;
  for (std::size_t i = 0; i < 3; ++i) v[int(i)] = read_number(j[i], index(path, i), lo, hi);
  return v;
}

glm::dvec3 read_position(const json& j, const std::string& path) {
  return read_vec3(j, path, -RequestLimits::kMaxCoordinate, RequestLimits::kMaxCoordinate);
}

// [r, g, b] each in [0, 1], or "#rrggbb" (each byte / 255).
glm::dvec3 read_color(const json& j, const std::string& path) {
  if (j.is_string()) {
    const std::string& s = j.get_ref<const std::string&>();
    const bool shaped = s.size() == 7 && s[0] == '#' &&
                        std::all_of(s.begin() + 1, s.end(), [](char c) { return std::isxdigit((unsigned char)c); });
    if (!shaped) reject(path, "must be \"#rrggbb\" or [r, g, b], got " + quote_text(s));
    glm::dvec3 c;
    for (int i = 0; i < 3; ++i) c[i] = std::stoi(s.substr(1 + 2 * i, 2), nullptr, 16) / 255.0;
    return c;
  }
  return read_vec3(j, path, 0.0, 1.0);
}

double read_extent(const json& j, const std::string& path) {
  return read_number(j, path, RequestLimits::kMinExtent, RequestLimits::kMaxExtent);
}

// Walks an object's members, rejecting any key not in `allowed`, and records
// which fields the client sent.
class ObjectReader {
 public:
  ObjectReader(const json& j, std::string path, std::initializer_list<const char*> allowed,
               std::set<std::string>& sent)
      : object_(j), path_(std::move(path)), sent_(sent) {
    if (!j.is_object()) reject(path_, std::string("must be an object, not ") + type_name(j));
    for (const auto& item : j.items()) {
      const std::string& key = item.key();
      const bool known = std::any_of(allowed.begin(), allowed.end(), [&](const char* a) { return key == a; });
      if (!known) {
        std::string list;
        for (const char* a : allowed) list += std::string(list.empty() ? "" : ", ") + a;
        reject(join(path_, key), "unknown field (expected one of: " + list + ")");
      }
      sent_.insert(join(path_, key));
    }
  }

  const json* get(const char* key) const {
    const auto it = object_.find(key);
    return it == object_.end() ? nullptr : &*it;
  }
  std::string path(const char* key) const { return join(path_, key); }

 private:
  const json& object_;
  std::string path_;
  std::set<std::string>& sent_;
};

// ---------------------------------------------------------------------------
// The request, section by section.

// A mesh object: an instance of a model the server holds.
void read_mesh(const json& j, const std::string& path, std::set<std::string>& sent, const ModelLookup& find_model,
               SceneObject& o) {
  o.type = SceneObject::Type::Mesh;
  ObjectReader r(j, path, {"type", "model", "position", "rotation_deg", "scale", "color"}, sent);
  // Written only for a refusal: up to 1000 mesh objects are read per request.
  const auto how_to_upload = [] {
    std::string builtins;
    for (const BuiltinModel& m : builtin_models()) builtins += (builtins.empty() ? "" : ", ") + quote_text(m.name);
    return "upload it with POST /api/models (a .glb or .gltf body) and name it by the \"id\" that returns, "
           "or by its file name if the server loaded it with --models DIR, or name a built-in model (" +
           builtins + ")";
  };
  const json* model = r.get("model");
  if (model == nullptr) reject(r.path("model"), "is required: a model's id or name; " + how_to_upload());
  if (!model->is_string())
    reject(r.path("model"), std::string("must be a string (a model's id or name), not ") + type_name(*model));
  const std::string& key = model->get_ref<const std::string&>();
  std::optional<FoundModel> found = find_model ? find_model(key) : std::nullopt;
  // The built-in models, when the server's store does not answer for that
  // name (a --models folder may hold its own "teapot"; then that one wins).
  if (!found || !found->model)
    if (const BuiltinModel* builtin = find_builtin_model(key)) found = FoundModel{builtin->id, builtin->model};
  if (!found || !found->model)
    reject(r.path("model"), "unknown model " + quote_text(key) + ": " + how_to_upload());
  o.model = std::move(found->model);
  o.model_id = std::move(found->id);
  if (auto v = r.get("position")) o.center = read_position(*v, r.path("position"));
  if (auto v = r.get("rotation_deg")) o.rotation_deg = read_vec3(*v, r.path("rotation_deg"), -36000.0, 36000.0);
  if (auto v = r.get("scale")) {
    if (v->is_number())
      o.mesh_scale = glm::dvec3(read_extent(*v, r.path("scale")));
    else if (v->is_array())
      o.mesh_scale = read_vec3(*v, r.path("scale"), RequestLimits::kMinExtent, RequestLimits::kMaxExtent);
    else
      reject(r.path("scale"), std::string("must be a number or an array of 3 numbers, not ") + type_name(*v));
  }
  if (auto v = r.get("color")) {
    o.color = read_color(*v, r.path("color"));
    o.mesh_color_override = true;
  }
  // The placed model must stay where float precision holds, like any position.
  const Aabb bounds = mesh_bounds(o);
  if (!bounds.empty()) {
    const glm::dvec3 far_corner = glm::max(glm::abs(bounds.min), glm::abs(bounds.max));
    const double reach = std::max({far_corner.x, far_corner.y, far_corner.z});
    if (reach > RequestLimits::kMaxCoordinate)
      reject(path, "the model placed with this position, rotation_deg and scale reaches coordinate " +
                       format_number(reach) + ", beyond the limit " + format_number(RequestLimits::kMaxCoordinate));
  }
}

SceneObject read_object(const json& j, const std::string& path, std::set<std::string>& sent,
                        const ModelLookup& find_model) {
  if (!j.is_object()) reject(path, std::string("must be an object, not ") + type_name(j));
  const auto type_it = j.find("type");
  if (type_it == j.end()) reject(join(path, "type"), "is required: \"plane\", \"box\", \"sphere\" or \"mesh\"");
  SceneObject o;
  switch (read_choice(*type_it, join(path, "type"), {"plane", "box", "sphere", "mesh"})) {
    case 0: {
      o.type = SceneObject::Type::Plane;
      ObjectReader r(j, path, {"type", "center", "size", "color"}, sent);
      o.size = {10.0, 0.0, 10.0};
      if (auto v = r.get("size")) {
        if (!v->is_array() || v->size() != 2) reject(r.path("size"), "must be an array of 2 numbers [sx, sz]");
        o.size = {read_extent((*v)[0], index(r.path("size"), 0)), 0.0, read_extent((*v)[1], index(r.path("size"), 1))};
      }
      if (auto v = r.get("center")) o.center = read_position(*v, r.path("center"));
      if (auto v = r.get("color")) o.color = read_color(*v, r.path("color"));
      break;
    }
    case 1: {
      o.type = SceneObject::Type::Box;
      ObjectReader r(j, path, {"type", "center", "size", "rotation_y_deg", "color"}, sent);
      if (auto v = r.get("size")) o.size = read_vec3(*v, r.path("size"), RequestLimits::kMinExtent, RequestLimits::kMaxExtent);
      if (auto v = r.get("rotation_y_deg")) o.rotation_y_deg = read_number(*v, r.path("rotation_y_deg"), -36000.0, 36000.0);
      if (auto v = r.get("center")) o.center = read_position(*v, r.path("center"));
      if (auto v = r.get("color")) o.color = read_color(*v, r.path("color"));
      break;
    }
    case 3:
      read_mesh(j, path, sent, find_model, o);
      break;
    default: {
      o.type = SceneObject::Type::Sphere;
      ObjectReader r(j, path, {"type", "center", "radius", "color"}, sent);
      if (auto v = r.get("radius")) o.radius = read_extent(*v, r.path("radius"));
      if (auto v = r.get("center")) o.center = read_position(*v, r.path("center"));
      if (auto v = r.get("color")) o.color = read_color(*v, r.path("color"));
      break;
    }
  }
  return o;
}

// Returns the scene and, for a built-in one, its own camera and light.
Scene read_scene(const json* j, const BuiltinScene*& builtin, std::set<std::string>& sent,
                 const ModelLookup& find_model) {
  Scene scene;
  builtin = nullptr;
  if (j == nullptr || j->is_string()) {
    const std::string name = j == nullptr ? "cube-on-plane" : j->get<std::string>();
    builtin = find_builtin_scene(name);
    if (builtin == nullptr) {
      std::string list;
      for (const auto& s : builtin_scenes()) list += std::string(list.empty() ? "" : ", ") + "\"" + s.name + "\"";
      reject("scene", "unknown scene " + quote_text(name) + " (built-in scenes: " + list + ")");
    }
    scene.name = builtin->name;
    scene.objects = builtin->objects;
    return scene;
  }
  ObjectReader r(*j, "scene", {"objects"}, sent);
  const json* objects = r.get("objects");
  if (objects == nullptr) reject("scene.objects", "is required for a custom scene");
  if (!objects->is_array()) reject("scene.objects", std::string("must be an array, not ") + type_name(*objects));
  if (objects->size() > RequestLimits::kMaxObjects)
    reject("scene.objects", "at most " + std::to_string(RequestLimits::kMaxObjects) + " objects, got " +
                                std::to_string(objects->size()));
  for (std::size_t i = 0; i < objects->size(); ++i)
    scene.objects.push_back(read_object((*objects)[i], index("scene.objects", i), sent, find_model));
  return scene;
}

void read_camera(const json* j, Camera& c, std::set<std::string>& sent) {
  if (j == nullptr) return;
  ObjectReader r(*j, "camera", {"position", "target", "up", "fov_y_deg", "near", "far"}, sent);
  if (auto v = r.get("position")) c.position = read_position(*v, r.path("position"));
  if (auto v = r.get("target")) c.target = read_position(*v, r.path("target"));
  if (auto v = r.get("up")) c.up = read_vec3(*v, r.path("up"), -RequestLimits::kMaxCoordinate, RequestLimits::kMaxCoordinate);
  if (auto v = r.get("fov_y_deg"))
    c.fov_y_deg = read_number(*v, r.path("fov_y_deg"), RequestLimits::kMinFovDeg, 180.0, false, true);
  if (auto v = r.get("near")) c.near_plane = read_number(*v, r.path("near"), 0.0, RequestLimits::kMaxExtent, true);
  if (auto v = r.get("far")) c.far_plane = read_number(*v, r.path("far"), 0.0, 1e9, true);
}

// light.sun: where and when the sun is seen. Latitude, longitude and utc
// are required: a sun at a default place would be a guess.
SunClock read_sun(const json& j, std::set<std::string>& sent) {
  ObjectReader r(j, "light.sun", {"latitude", "longitude", "utc", "north_deg"}, sent);
  SunClock sun;
  const auto required = [&](const char* key) {
    const json* v = r.get(key);
    if (v == nullptr) reject(r.path(key), "is required for a sun light");
    return v;
  };
  sun.latitude_deg = read_number(*required("latitude"), r.path("latitude"), -90.0, 90.0);
  sun.longitude_deg = read_number(*required("longitude"), r.path("longitude"), -180.0, 180.0);
  const json& utc = *required("utc");
  if (!utc.is_string())
    reject(r.path("utc"), std::string("must be an RFC 3339 date-time string such as \"2026-12-21T14:00:00Z\", not ") +
                              type_name(utc));
  std::string why;
  const std::optional<double> instant = parse_utc(utc.get_ref<const std::string&>(), &why);
  if (!instant) reject(r.path("utc"), quote_text(utc.get<std::string>()) + " is not an RFC 3339 date-time: " + why);
  // The offset applied, the instant itself must lie in those years (UTC).
  if (*instant < RequestLimits::kMinSunUnixSeconds || *instant >= RequestLimits::kMaxSunUnixSeconds)
    reject(r.path("utc"), "years 0001 to " + std::to_string(RequestLimits::kMaxSunYear) + " (UTC) are supported");
  sun.utc_unix_s = *instant;
  if (auto v = r.get("north_deg")) sun.north_deg = read_number(*v, r.path("north_deg"), -360.0, 360.0);
  return sun;
}

void read_light(const json* j, Light& l, std::set<std::string>& sent) {
  if (j == nullptr) return;
  ObjectReader r(*j, "light",
                 {"position", "target", "color", "ambient", "projection", "fov_y_deg", "size", "orbit_deg_per_s", "sun"},
                 sent);
  if (auto v = r.get("position")) l.position = read_position(*v, r.path("position"));
  if (auto v = r.get("target")) l.target = read_position(*v, r.path("target"));
  if (auto v = r.get("color")) l.color = read_color(*v, r.path("color"));
  if (auto v = r.get("ambient")) l.ambient = read_number(*v, r.path("ambient"), 0.0, 1.0);
  if (auto v = r.get("projection"))
    l.projection = read_choice(*v, r.path("projection"), {"orthographic", "perspective"}) == 0
                       ? LightProjection::Orthographic
                       : LightProjection::Perspective;
  if (auto v = r.get("fov_y_deg"))
    l.fov_y_deg = read_number(*v, r.path("fov_y_deg"), RequestLimits::kMinFovDeg, 180.0, false, true);
  if (auto v = r.get("size")) {
    const bool perspective = l.projection == LightProjection::Perspective;
    l.size = read_number(*v, r.path("size"), 0.0,
                         perspective ? RequestLimits::kMaxExtent : RequestLimits::kMaxLightAngularSize);
  }
  if (auto v = r.get("orbit_deg_per_s"))
    l.orbit_deg_per_s = read_number(*v, r.path("orbit_deg_per_s"), -RequestLimits::kMaxOrbitSpeed, RequestLimits::kMaxOrbitSpeed);
  if (auto v = r.get("sun")) {
    if (!v->is_object()) reject(r.path("sun"), std::string("must be an object, not ") + type_name(*v));
    l.sun = read_sun(*v, sent);
    if (l.projection == LightProjection::Perspective)
      reject(r.path("projection"), "a sun light is directional: \"orthographic\" (or leave projection out)");
  }
}

void read_shadow(const json* j, ShadowSettings& s, std::set<std::string>& sent) {
  if (j == nullptr) return;
  ObjectReader r(*j, "shadow",
                 {"enabled", "map_size", "filter", "pcf_radius", "bias", "cull", "fit", "cascades", "ortho_half_size", "near",
                  "far"},
                 sent);
  if (auto v = r.get("enabled")) s.enabled = read_boolean(*v, r.path("enabled"));
  if (auto v = r.get("map_size")) s.map_size = read_integer(*v, r.path("map_size"), 64, 8192);
  if (auto v = r.get("filter"))
    s.filter = ShadowFilter(read_choice(*v, r.path("filter"), {"hard", "pcf", "pcss"}));
  if (auto v = r.get("pcf_radius")) s.pcf_radius = read_integer(*v, r.path("pcf_radius"), 0, 8);
  if (auto v = r.get("bias")) {
    if (v->is_string()) {
      read_choice(*v, r.path("bias"), {"auto"});
    } else {
      ObjectReader b(*v, r.path("bias"), {"constant", "slope", "normal_offset"}, sent);
      s.bias.automatic = false;
      if (auto c = b.get("constant")) s.bias.constant = read_number(*c, b.path("constant"), 0.0, 1.0);
      if (auto c = b.get("slope")) s.bias.slope = read_number(*c, b.path("slope"), 0.0, 1.0);
      if (auto c = b.get("normal_offset")) s.bias.normal_offset = read_number(*c, b.path("normal_offset"), 0.0, 64.0);
    }
  }
  if (auto v = r.get("cull")) s.cull = CullMode(read_choice(*v, r.path("cull"), {"front", "back", "none"}));
  if (auto v = r.get("fit")) s.fit = FrustumFit(read_choice(*v, r.path("fit"), {"scene", "fixed"}));
  if (auto v = r.get("cascades")) {
    if (v->is_string())
      read_choice(*v, r.path("cascades"), {"auto"});
    else
      s.cascades = read_integer(*v, r.path("cascades"), 1, kMaxCascades);
  }
  if (auto v = r.get("ortho_half_size")) s.ortho_half_size = read_extent(*v, r.path("ortho_half_size"));
  if (auto v = r.get("near"))
    s.near_plane = read_number(*v, r.path("near"), -RequestLimits::kMaxExtent, RequestLimits::kMaxExtent);
  if (auto v = r.get("far"))
    s.far_plane = read_number(*v, r.path("far"), -RequestLimits::kMaxExtent, RequestLimits::kMaxExtent);
}

// Rules that involve several fields.
void check_consistency(const RenderRequest& q, const std::set<std::string>& sent) {
  const auto coincide = [](const glm::dvec3& a, const glm::dvec3& b) {
    const double scale = std::max({1.0, glm::length(a), glm::length(b)});
    return glm::length(a - b) <= 1e-12 * scale;
  };
  if (q.camera.far_plane <= q.camera.near_plane)
    reject("camera.far", "must be greater than camera.near (" + format_number(q.camera.near_plane) + ")");
  if (coincide(q.camera.position, q.camera.target))
    reject("camera.position", "equals camera.target: the view direction is undefined");
  if (glm::length(q.camera.up) == 0.0) reject("camera.up", "must not be the zero vector");
  if (coincide(q.light.position, q.light.target))
    reject("light.position", "equals light.target: the light direction is undefined");
  const ShadowSettings& s = q.shadow;
  if (s.fit == FrustumFit::Fixed) {
    if (q.light.projection == LightProjection::Perspective && s.near_plane <= 0.0)
      reject("shadow.near", "must be > 0 for a perspective light");
    if (s.far_plane <= s.near_plane)
      reject("shadow.far", "must be greater than shadow.near (" + format_number(s.near_plane) + ")");
  }
  if (s.cascades > 1 && s.fit == FrustumFit::Fixed)
    reject("shadow.cascades", "cascades are fitted to the camera: they need shadow.fit \"scene\"");
  if (s.cascades > 1 && q.light.projection == LightProjection::Perspective)
    reject("shadow.cascades",
           "cascades split an orthographic light's map; a perspective light uses one cone or cube faces by itself");
  if (q.light.size > 0.0 && s.filter != ShadowFilter::Pcss && sent.count("shadow.filter"))
    reject("shadow.filter", "an area light (light.size > 0) needs \"pcss\"; \"hard\" and \"pcf\" model an ideal light");
}

// Fields that were sent but cannot change this output.
std::vector<std::string> unused_fields(const RenderRequest& q, const std::set<std::string>& sent) {
  std::vector<std::string> unused;
  const auto mark = [&](const std::string& field) {
    if (sent.count(field)) unused.push_back(field);
  };
  const bool depth = q.output == Output::Depth;
  // A sun below the horizon lights nothing directly: its frame draws no
  // shadow, as if shadows were off (the depth output still draws the map).
  // So these fields may come and go from the list while Play crosses sunset.
  const bool sun_down = q.light.sun && !light_at(q.light, q.time).direct;
  const bool shadowed = q.shadow.enabled && !sun_down;
  const bool shadow_pass = shadowed || depth;
  const bool fixed = q.shadow.fit == FrustumFit::Fixed;
  const bool perspective = q.light.projection == LightProjection::Perspective;
  if (!fixed || !perspective) mark("light.fov_y_deg");
  // A sun places the light: it does not orbit, and only the position's
  // distance from the target is kept, which fit "fixed" measures near and
  // far from.
  if (q.light.sun) {
    mark("light.orbit_deg_per_s");
    if (!fixed || !shadow_pass) mark("light.position");
    if (sun_down && !depth) mark("shadow.enabled");
  }
  if (!fixed || perspective) mark("shadow.ortho_half_size");
  if (!fixed || !shadow_pass) mark("shadow.near"), mark("shadow.far");
  if (fixed || perspective) mark("shadow.cascades");
  if (!shadow_pass) {
    for (const char* f : {"shadow.map_size", "shadow.cull", "shadow.fit", "shadow.cascades", "shadow.ortho_half_size"})
      mark(f);
  }
  const bool filtering = shadowed && !depth;
  const bool pcf_used = q.shadow.filter == ShadowFilter::Pcf ||
                        (q.shadow.filter == ShadowFilter::Pcss && q.light.size == 0.0);
  if (!filtering || !pcf_used) mark("shadow.pcf_radius");
  if (!filtering) {
    for (const char* f : {"shadow.filter", "shadow.bias", "shadow.bias.constant", "shadow.bias.slope",
                          "shadow.bias.normal_offset", "light.size"})
      mark(f);
  }
  // An orthographic light fitted to the scene is fitted to what the camera
  // sees: then the camera and image size shape even the depth map.
  const bool camera_fitted = !fixed && !perspective;
  if (!depth) mark("depth_bits");
  if (depth) {
    for (const char* f : {"light.color", "light.ambient"}) mark(f);
    if (!camera_fitted) {
      for (const char* f : {"width", "height", "camera", "camera.position", "camera.target", "camera.up",
                            "camera.fov_y_deg", "camera.near", "camera.far"})
        mark(f);
    }
  }
  std::sort(unused.begin(), unused.end());
  unused.erase(std::unique(unused.begin(), unused.end()), unused.end());
  return unused;
}

RenderRequest read_request(const json& root, Route route, std::set<std::string>& sent, const ModelLookup& find_model,
                           bool& output_overridden) {
  ObjectReader r(root, "", {"width", "height", "scene", "camera", "light", "time", "shadow", "output", "depth_bits"},
                 sent);
  RenderRequest q;
  const BuiltinScene* builtin = nullptr;
  q.scene = read_scene(r.get("scene"), builtin, sent, find_model);
  // Defaults that depend on the scene: a built-in scene's own camera and
  // light, or ones derived from a custom scene's bounds.
  if (builtin != nullptr) {
    q.camera.position = builtin->camera_position;
    q.camera.target = builtin->camera_target;
    q.light.position = builtin->light_position;
  } else {
    const SceneViewDefaults d = default_view_for(q.scene);
    q.camera.position = d.camera_position;
    q.camera.target = d.camera_target;
    q.light.position = d.light_position;
    q.light.target = d.light_target;
  }
  if (auto v = r.get("width")) q.width = read_integer(*v, "width", 16, 4096);
  if (auto v = r.get("height")) q.height = read_integer(*v, "height", 16, 4096);
  read_camera(r.get("camera"), q.camera, sent);
  // A custom scene without a camera.far is seen whole: far reaches the far
  // side of its bounds from wherever the camera stands (the fixed 100 cut
  // away a 200 x 200 floor, and half of three-cubes' when posted back).
  if (builtin == nullptr && !sent.count("camera.far")) {
    const Aabb bounds = scene_bounds(q.scene);
    if (!bounds.empty()) {
      const double reach = glm::length(q.camera.position - bounds.center()) + 0.5 * glm::length(bounds.extent());
      q.camera.far_plane = std::max(q.camera.far_plane, 1.01 * reach);
    }
  }
  // The light's projection decides the range of light.size: read it first.
  read_light(r.get("light"), q.light, sent);
  if (auto v = r.get("time")) q.time = read_number(*v, "time", -RequestLimits::kMaxTime, RequestLimits::kMaxTime);
  // A sun's clock reads utc + time: that instant, not utc alone, must lie
  // in the years the sun's position is computed for.
  if (q.light.sun) {
    const double clock = q.light.sun->utc_unix_s + q.time;
    if (clock < RequestLimits::kMinSunUnixSeconds || clock >= RequestLimits::kMaxSunUnixSeconds)
      reject("time", "light.sun.utc + time must lie in years 0001 to " + std::to_string(RequestLimits::kMaxSunYear) +
                         " (UTC); it is " + format_utc(clock));
  }
  read_shadow(r.get("shadow"), q.shadow, sent);
  // An area light with no filter named gets the filter that models it.
  if (q.light.size > 0.0 && !sent.count("shadow.filter")) q.shadow.filter = ShadowFilter::Pcss;
  if (auto v = r.get("output"))
    q.output = Output(read_choice(*v, "output", {"color", "depth", "shadow", "exact", "error"}));
  // POST /api/depth takes the same body as /api/render (docs/api.md) and
  // always draws the depth map: any output /api/render takes is accepted,
  // and one other than "depth" is reported unused (Umbra-Unused-Fields),
  // never silently dropped.
  if (route == Route::Depth) {
    output_overridden = sent.count("output") && q.output != Output::Depth;
    q.output = Output::Depth;
  }
  if (auto v = r.get("depth_bits")) q.depth_bits = read_depth_bits(*v, "depth_bits");
  check_consistency(q, sent);
  return q;
}

// The distinct "model" strings of a custom scene's mesh objects, in order;
// whatever else is wrong is left to read_request.
std::vector<std::string> named_models(const json& root) {
  std::vector<std::string> keys;
  if (!root.is_object()) return keys;
  const auto scene = root.find("scene");
  if (scene == root.end() || !scene->is_object()) return keys;
  const auto objects = scene->find("objects");
  if (objects == scene->end() || !objects->is_array() || objects->size() > RequestLimits::kMaxObjects) return keys;
  for (const json& o : *objects) {
    if (!o.is_object()) continue;
    const auto type = o.find("type"), model = o.find("model");
    if (type == o.end() || *type != "mesh" || model == o.end() || !model->is_string()) continue;
    const std::string& key = model->get_ref<const std::string&>();
    if (std::find(keys.begin(), keys.end(), key) == keys.end()) keys.push_back(key);
  }
  return keys;
}

}  // namespace

ParsedRequest parse_render_request(std::string_view body, Route route, const ModelLookup& find_model,
                                   const ModelsNamed& models_named) {
  ParsedRequest result;
  json root;
  LocatingBuilder builder(root);
  // An empty body means "all defaults", like {}.
  const bool all_space = std::all_of(body.begin(), body.end(), [](char c) { return std::isspace((unsigned char)c); });
  if (!all_space) {
    const bool parsed = json::sax_parse(body.begin(), body.end(), &builder, json::input_format_t::json, true);
    if (!parsed || builder.rejection()) {
      const Rejection r = builder.rejection().value_or(Rejection{"", "malformed JSON"});
      result.error = {shortened(r.message), shortened(r.field)};
      return result;
    }
  } else {
    root = json::object();
  }
  if (models_named) {
    const std::vector<std::string> keys = named_models(root);
    if (!keys.empty()) models_named(keys);
  }
  std::set<std::string> sent;
  try {
    bool output_overridden = false;
    result.request = read_request(root, route, sent, find_model, output_overridden);
    result.unused_fields = unused_fields(*result.request, sent);
    if (output_overridden) {
      result.unused_fields.push_back("output");
      std::sort(result.unused_fields.begin(), result.unused_fields.end());
    }
  } catch (const Rejection& r) {
    result.error = {shortened(r.message), shortened(r.field)};
  }
  return result;
}

}  // namespace umbra
