#include "request_parser.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <stdexcept>
#include <utility>

#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include "core/builtin_models.hpp"
#include "core/scene.hpp"
#include "core/sun_position.hpp"
#include "request_fields.hpp"

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

// One of `numbers` (depth_bits: 8 or 16, the two depths a grey PNG sample
// can take that an 8- or 16-bit texture reads back as).
double read_one_of(const json& j, const std::string& path, const std::vector<double>& numbers) {
  const double v = read_number(j, path);
  if (std::find(numbers.begin(), numbers.end(), v) != numbers.end()) return v;
  std::string list;
  for (std::size_t i = 0; i < numbers.size(); ++i)
    list += (i == 0 ? "" : i + 1 == numbers.size() ? " or " : ", ") + format_number(numbers[i]);
  reject(path, "must be " + list + ", got " + format_number(v));
}

bool read_boolean(const json& j, const std::string& path) {
  if (!j.is_boolean()) reject(path, std::string("must be true or false, not ") + type_name(j));
  return j.get<bool>();
}

// One of `choices`; returns its position.
std::size_t read_choice(const json& j, const std::string& path, const std::vector<std::string>& choices) {
  std::string list;
  for (const std::string& c : choices) list += std::string(list.empty() ? "" : ", ") + "\"" + c + "\"";
  if (!j.is_string()) reject(path, "must be one of " + list + ", not " + type_name(j));
  const std::string& s = j.get_ref<const std::string&>();
  const auto it = std::find(choices.begin(), choices.end(), s);
  if (it != choices.end()) return std::size_t(it - choices.begin());
  reject(path, "must be one of " + list + ", got " + quote_text(s));
}

glm::dvec3 read_vec3(const json& j, const std::string& path, double lo, double hi) {
  if (!j.is_array() || j.size() != 3)
    reject(path, "must be an array of 3 numbers" + std::string(j.is_array() ? ", got " + std::to_string(j.size()) : ""));
  glm::dvec3 v;
  for (std::size_t i = 0; i < 3; ++i) v[int(i)] = read_number(j[i], index(path, i), lo, hi);
  return v;
}

// [r, g, b] each in [lo, hi] ([0, 1]), or "#rrggbb" (each byte / 255).
glm::dvec3 read_color(const json& j, const std::string& path, double lo, double hi) {
  if (j.is_string()) {
    const std::string& s = j.get_ref<const std::string&>();
    const bool shaped = s.size() == 7 && s[0] == '#' &&
                        std::all_of(s.begin() + 1, s.end(), [](char c) { return std::isxdigit((unsigned char)c); });
    if (!shaped) reject(path, "must be \"#rrggbb\" or [r, g, b], got " + quote_text(s));
    glm::dvec3 c;
    for (int i = 0; i < 3; ++i) c[i] = std::stoi(s.substr(1 + 2 * i, 2), nullptr, 16) / 255.0;
    return c;
  }
  return read_vec3(j, path, lo, hi);
}

// A row's value, read as its type says, each number in the row's range.
// (Text, Object, Scene and ObjectList rows are read by the sections below.)
template <class Target>
FieldValue read_value(const json& j, const std::string& path, const FieldRow<Target>& row, const Target& target) {
  FieldValue value;
  if (!row.word.empty() && j.is_string()) {
    read_choice(j, path, {row.word});
    value.word = true;
    return value;
  }
  const FieldRange range = row.range_rule ? row.range_rule(target) : row.range;
  switch (row.type) {
    case FieldType::Integer:
      value.number = read_integer(j, path, int(range.min), int(range.max));
      break;
    case FieldType::IntegerChoice:
      value.number = read_one_of(j, path, row.numbers);
      break;
    case FieldType::Number:
      value.number = read_number(j, path, range.min, range.max, range.open_min, range.open_max);
      break;
    case FieldType::Boolean:
      value.flag = read_boolean(j, path);
      break;
    case FieldType::Choice:
      value.choice = read_choice(j, path, row.choices);
      break;
    case FieldType::Vec3:
      value.vec = read_vec3(j, path, range.min, range.max);
      break;
    case FieldType::Size2:
      if (!j.is_array() || j.size() != 2) reject(path, "must be an array of 2 numbers [sx, sz]");
      value.vec.x = read_number(j[0], index(path, 0), range.min, range.max);
      value.vec.y = 0.0;
      value.vec.z = read_number(j[1], index(path, 1), range.min, range.max);
      break;
    case FieldType::Color:
      value.vec = read_color(j, path, range.min, range.max);
      break;
    case FieldType::NumberOrVec3:
      if (j.is_number())
        value.vec = glm::dvec3(read_number(j, path, range.min, range.max));
      else if (j.is_array())
        value.vec = read_vec3(j, path, range.min, range.max);
      else
        reject(path, std::string("must be a number or an array of 3 numbers, not ") + type_name(j));
      break;
    case FieldType::Text:
    case FieldType::Animation:
    case FieldType::Object:
    case FieldType::Scene:
    case FieldType::ObjectList:
      throw std::logic_error("request_parser: " + row.path + " is read by its own section");
  }
  return value;
}

// A row's default stored in its member, read as a sent value would be.
template <class Target>
void apply_default(const FieldRow<Target>& row, Target& target) {
  if (row.default_value.is_null() || row.set == nullptr) return;
  FieldValue value;
  if (row.type == FieldType::Object)
    value.word = true;  // an object's default is its word ("auto")
  else
    value = read_value(row.default_value, row.path, row, target);
  row.set(target, value);
}

// ", "-joined, for a message.
std::string listed(const std::vector<std::string>& keys) {
  std::string list;
  for (const std::string& k : keys) list += (list.empty() ? "" : ", ") + k;
  return list;
}

// Walks an object's members, rejecting any key not in `allowed`, and records
// which fields the client sent.
class ObjectReader {
 public:
  ObjectReader(const json& j, std::string path, const std::vector<std::string>& allowed, std::set<std::string>& sent)
      : object_(j), path_(std::move(path)), sent_(sent) {
    if (!j.is_object()) reject(path_, std::string("must be an object, not ") + type_name(j));
    for (const auto& item : j.items()) {
      const std::string& key = item.key();
      if (std::find(allowed.begin(), allowed.end(), key) == allowed.end())
        reject(join(path_, key), "unknown field (expected one of: " + listed(allowed) + ")");
      sent_.insert(join(path_, key));
    }
  }

  const json* get(const std::string& key) const {
    const auto it = object_.find(key);
    return it == object_.end() ? nullptr : &*it;
  }
  std::string path(const std::string& key) const { return join(path_, key); }

 private:
  const json& object_;
  std::string path_;
  std::set<std::string>& sent_;
};

// ---------------------------------------------------------------------------
// The request, section by section, through its rows (request_fields.hpp).

// The keys the object at `parent` takes, in the rows' order.
const std::vector<std::string>& keys_in(const std::string& parent) {
  static const std::map<std::string, std::vector<std::string>> keys = [] {
    std::map<std::string, std::vector<std::string>> m;
    for (const RequestField& row : request_fields()) m[row.parent()].push_back(row.key());
    return m;
  }();
  return keys.at(parent);
}

// A scene object's keys, per type: "type" and the type's rows.
const std::vector<std::string>& keys_of(std::size_t shape) {
  static const std::vector<std::vector<std::string>> keys = [] {
    std::vector<std::vector<std::string>> all;
    for (const ShapeFields& s : shape_fields()) {
      all.push_back({"type"});
      for (const ObjectField& row : s.rows) all.back().push_back(row.key());
    }
    return all;
  }();
  return keys[shape];
}

const std::vector<std::string>& shape_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const ShapeFields& s : shape_fields()) n.push_back(s.type);
    return n;
  }();
  return names;
}

// Every body field's default that holds whatever else is sent, in order
// (not the rows of an object that is absent unless sent: light.sun).
void apply_request_defaults(RenderRequest& q) {
  static const std::vector<const RequestField*> rows = [] {
    std::vector<const RequestField*> r;
    std::set<std::string> optional;
    for (const RequestField& row : request_fields()) {
      if (optional.count(row.parent())) {
        if (row.type == FieldType::Object) optional.insert(row.path);
        continue;
      }
      if (row.optional_object) optional.insert(row.path);
      else r.push_back(&row);
    }
    return r;
  }();
  for (const RequestField* row : rows) apply_default(*row, q);
}

void read_field(const json& j, const RequestField& row, RenderRequest& q, std::set<std::string>& sent);

// The object at `parent` ("camera", "light.sun"): its keys checked, then each
// row's value read in order.
void read_rows(const json& j, const std::string& parent, RenderRequest& q, std::set<std::string>& sent) {
  ObjectReader r(j, parent, keys_in(parent), sent);
  for (const RequestField* row : request_fields_in(parent)) {
    const json* v = r.get(row->key());
    if (v == nullptr) {
      if (!row->required.empty()) reject(row->path, row->required);
      continue;
    }
    read_field(*v, *row, q, sent);
  }
}

// light.sun.utc: an RFC 3339 text, the instant in the years the sun's
// position is computed for.
double read_utc(const json& utc, const std::string& path) {
  if (!utc.is_string())
    reject(path, std::string("must be an RFC 3339 date-time string such as \"2026-12-21T14:00:00Z\", not ") +
                     type_name(utc));
  std::string why;
  const std::optional<double> instant = parse_utc(utc.get_ref<const std::string&>(), &why);
  if (!instant) reject(path, quote_text(utc.get<std::string>()) + " is not an RFC 3339 date-time: " + why);
  // The offset applied, the instant itself must lie in those years (UTC).
  if (*instant < RequestLimits::kMinSunUnixSeconds || *instant >= RequestLimits::kMaxSunUnixSeconds)
    reject(path, "years 0001 to " + std::to_string(RequestLimits::kMaxSunYear) + " (UTC) are supported");
  return *instant;
}

void read_field(const json& j, const RequestField& row, RenderRequest& q, std::set<std::string>& sent) {
  switch (row.type) {
    case FieldType::Object: {
      FieldValue value;
      if (!row.word.empty() && j.is_string()) {
        read_choice(j, row.path, {row.word});
        value.word = true;
        row.set(q, value);
        return;
      }
      if (row.set) row.set(q, value);
      if (row.optional_object)
        for (const RequestField* below : request_fields_in(row.path)) apply_default(*below, q);
      read_rows(j, row.path, q, sent);
      return;
    }
    case FieldType::Text: {
      FieldValue value;
      value.number = read_utc(j, row.path);  // light.sun.utc, the body's one Text row
      row.set(q, value);
      return;
    }
    default:
      row.set(q, read_value(j, row.path, row, q));
  }
}

// Reads the body's field `key` (a row at the root) if it was sent.
void read_sent(const ObjectReader& r, const char* key, RenderRequest& q, std::set<std::string>& sent) {
  if (const json* v = r.get(key)) read_field(*v, request_field(key), q, sent);
}

// A mesh object's "model": an instance of a model the server holds.
void read_model(const json* model, const ObjectField& row, const std::string& path, const ModelLookup& find_model,
                SceneObject& o) {
  // Written only for a refusal: up to 1000 mesh objects are read per request.
  const auto how_to_upload = [] {
    std::string builtins;
    for (const BuiltinModel& m : builtin_models()) builtins += (builtins.empty() ? "" : ", ") + quote_text(m.name);
    return "upload it with POST /api/models (a .glb or .gltf body) and name it by the \"id\" that returns, "
           "or by its file name if the server loaded it with --models DIR, or name a built-in model (" +
           builtins + ")";
  };
  if (model == nullptr) reject(path, row.required + how_to_upload());
  if (!model->is_string())
    reject(path, std::string("must be a string (a model's id or name), not ") + type_name(*model));
  const std::string& key = model->get_ref<const std::string&>();
  std::optional<FoundModel> found = find_model ? find_model(key) : std::nullopt;
  // The built-in models, when the server's store does not answer for that
  // name (a --models folder may hold its own "teapot"; then that one wins).
  if (!found || !found->model)
    if (const BuiltinModel* builtin = find_builtin_model(key)) found = FoundModel{builtin->id, builtin->model};
  if (!found || !found->model) reject(path, "unknown model " + quote_text(key) + ": " + how_to_upload());
  o.model = std::move(found->model);
  o.model_id = std::move(found->id);
}

// A mesh object's "animation": a name, an index, or an object naming one
// and how it plays. The model (read before) must have it.
void read_animation(const json& j, const std::string& path, SceneObject& o) {
  const std::vector<ModelAnimation> animations = o.model ? model_animations(*o.model) : std::vector<ModelAnimation>{};
  if (animations.empty())
    reject(path, "model " + quote_text(o.model_id) + " has no animations (a glTF file's \"animations\" are what play)");
  const auto names = [&] {
    std::string list;
    for (std::size_t a = 0; a < animations.size() && a < 20; ++a)
      list += (a ? ", " : "") + std::to_string(a) +
              (animations[a].name.empty() ? std::string() : " " + quote_text(animations[a].name));
    return list + (animations.size() > 20 ? ", ..." : "");
  };
  SceneObject::Animation animation;
  const auto by_name = [&](const json& name, const std::string& where) {
    const std::string& text = name.get_ref<const std::string&>();
    const auto found = std::find_if(animations.begin(), animations.end(),
                                    [&](const ModelAnimation& a) { return a.name == text; });
    if (found == animations.end())
      reject(where, "the model has no animation named " + quote_text(text) + " (it has " + names() + ")");
    animation.index = found->index;
    animation.name = text;
  };
  const auto by_index = [&](const json& index, const std::string& where) {
    const double i = read_number(index, where, 0.0, double(animations.size()) - 1.0);
    if (i != std::floor(i)) reject(where, "must be a whole number");
    animation.index = std::size_t(i);
  };
  if (j.is_string()) {
    by_name(j, path);
  } else if (j.is_number()) {
    by_index(j, path);
  } else if (j.is_object()) {
    for (const auto& item : j.items())
      if (item.key() != "name" && item.key() != "index" && item.key() != "speed" && item.key() != "loop")
        reject(join(path, item.key()), "is not a field of an animation (name, index, speed, loop)");
    const auto name = j.find("name"), index = j.find("index");
    if ((name == j.end()) == (index == j.end())) reject(path, "needs one of \"name\" or \"index\"");
    if (name != j.end()) {
      if (!name->is_string()) reject(join(path, "name"), std::string("must be a string, not ") + type_name(*name));
      by_name(*name, join(path, "name"));
    } else {
      by_index(*index, join(path, "index"));
    }
    if (const auto speed = j.find("speed"); speed != j.end())
      animation.speed = read_number(*speed, join(path, "speed"), -RequestLimits::kMaxAnimationSpeed,
                                    RequestLimits::kMaxAnimationSpeed);
    if (const auto loop = j.find("loop"); loop != j.end()) {
      if (!loop->is_boolean()) reject(join(path, "loop"), std::string("must be true or false, not ") + type_name(*loop));
      animation.loop = loop->get<bool>();
    }
  } else {
    reject(path, std::string("must be an animation's name or index, or an object {\"name\" or \"index\", "
                             "\"speed\", \"loop\"}, not ") + type_name(j));
  }
  o.animation = animation;
}

// The placed model must stay where float precision holds, like any position.
void check_mesh_reach(const SceneObject& o, const std::string& path) {
  const Aabb bounds = object_bounds(o);  // a mesh's: mesh_bounds
  if (bounds.empty()) return;
  const double reach = bounds.reach();
  if (reach > RequestLimits::kMaxCoordinate)
    reject(path, "the model placed with this position, rotation_deg and scale reaches coordinate " +
                     format_number(reach) + ", beyond the limit " + format_number(RequestLimits::kMaxCoordinate));
}

// A scene object: its type's rows (shape_fields), the type's own first, then
// the late ones (center, color), each default applied before.
SceneObject read_object(const json& j, const std::string& path, std::set<std::string>& sent,
                        const ModelLookup& find_model) {
  if (!j.is_object()) reject(path, std::string("must be an object, not ") + type_name(j));
  const auto type_it = j.find("type");
  if (type_it == j.end()) {
    std::string list;
    const std::vector<std::string>& names = shape_names();
    for (std::size_t i = 0; i < names.size(); ++i)
      list += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + ("\"" + names[i] + "\"");
    reject(join(path, "type"), "is required: " + list);
  }
  const std::size_t type = read_choice(*type_it, join(path, "type"), shape_names());
  const ShapeFields& shape = shape_fields()[type];
  SceneObject o;
  o.type = shape.kind;
  ObjectReader r(j, path, keys_of(type), sent);
  for (const ObjectField& row : shape.rows) apply_default(row, o);
  for (const bool late : {false, true}) {
    for (const ObjectField& row : shape.rows) {
      if (row.read_late != late) continue;
      const json* v = r.get(row.key());
      if (row.type == FieldType::Text) {
        read_model(v, row, r.path(row.key()), find_model, o);  // a mesh's "model", the objects' one Text row
        continue;
      }
      if (row.type == FieldType::Animation) {
        if (v) read_animation(*v, r.path(row.key()), o);
        continue;
      }
      if (v == nullptr) {
        if (!row.required.empty()) reject(r.path(row.key()), row.required);
        continue;
      }
      row.set(o, read_value(*v, r.path(row.key()), row, o));
    }
  }
  if (o.type == SceneObject::Type::Mesh) check_mesh_reach(o, path);
  return o;
}

// Returns the scene and, for a built-in one, its own camera and light.
Scene read_scene(const json* j, const BuiltinScene*& builtin, std::set<std::string>& sent,
                 const ModelLookup& find_model) {
  Scene scene;
  builtin = nullptr;
  if (j == nullptr || j->is_string()) {
    const std::string name = j == nullptr ? request_field("scene").default_value.get<std::string>() : j->get<std::string>();
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
  ObjectReader r(*j, "scene", keys_in("scene"), sent);
  const json* objects = r.get("objects");
  if (objects == nullptr) reject("scene.objects", request_field("scene.objects").required);
  if (!objects->is_array()) reject("scene.objects", std::string("must be an array, not ") + type_name(*objects));
  if (objects->size() > RequestLimits::kMaxObjects)
    reject("scene.objects", "at most " + std::to_string(RequestLimits::kMaxObjects) + " objects, got " +
                                std::to_string(objects->size()));
  for (std::size_t i = 0; i < objects->size(); ++i)
    scene.objects.push_back(read_object((*objects)[i], index("scene.objects", i), sent, find_model));
  return scene;
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
    reject("shadow.filter", s.filter == ShadowFilter::Exact
                                ? "\"exact\" certifies hard shadows, of a light of no size (light.size 0); an area "
                                  "light (light.size > 0) needs \"pcss\""
                                : "an area light (light.size > 0) needs \"pcss\"; \"hard\" and \"pcf\" model an ideal light");
  if (s.filter == ShadowFilter::Exact && s.fit == FrustumFit::Fixed && q.light.projection == LightProjection::Perspective)
    reject("shadow.fit", "filter \"exact\" with a point light needs shadow.fit \"scene\": a fixed frustum's near "
                         "plane may cut casters off before the light");
}


// Fields that were sent but cannot change this output: each row's used_when.
std::vector<std::string> unused_fields(const RenderRequest& q, const std::set<std::string>& sent) {
  const bool sun_down = q.light.sun && !above_horizon(sun_at(*q.light.sun, q.time));
  const FieldUse use = field_use(q, sun_down);
  std::vector<std::string> unused;
  for (const RequestField& row : request_fields())
    if (!row.used(use) && sent.count(row.path)) unused.push_back(row.path);
  std::sort(unused.begin(), unused.end());
  return unused;
}

RenderRequest read_request(const json& root, Route route, std::set<std::string>& sent, const ModelLookup& find_model,
                           bool& output_overridden) {
  ObjectReader r(root, "", keys_in(""), sent);
  RenderRequest q;
  apply_request_defaults(q);
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
  read_sent(r, "width", q, sent);
  read_sent(r, "height", q, sent);
  read_sent(r, "camera", q, sent);
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
  // The light's projection decides the range of light.size: its row is read first.
  read_sent(r, "light", q, sent);
  if (q.light.sun && q.light.projection == LightProjection::Perspective)
    reject("light.projection", "a sun light is directional: \"orthographic\" (or leave projection out)");
  read_sent(r, "time", q, sent);
  // A sun's clock reads utc + time: that instant, not utc alone, must lie
  // in the years the sun's position is computed for.
  if (q.light.sun) {
    const double clock = q.light.sun->utc_unix_s + q.time;
    if (clock < RequestLimits::kMinSunUnixSeconds || clock >= RequestLimits::kMaxSunUnixSeconds)
      reject("time", "light.sun.utc + time must lie in years 0001 to " + std::to_string(RequestLimits::kMaxSunYear) +
                         " (UTC); it is " + format_utc(clock));
  }
  read_sent(r, "shadow", q, sent);
  // An area light with no filter named gets the filter that models it.
  if (q.light.size > 0.0 && !sent.count("shadow.filter")) q.shadow.filter = ShadowFilter::Pcss;
  read_sent(r, "output", q, sent);
  // POST /api/depth takes the same body as /api/render (docs/api.md) and
  // always draws the depth map: any output /api/render takes is accepted,
  // and one other than "depth" is reported unused (Umbra-Unused-Fields),
  // never silently dropped.
  if (route == Route::Depth) {
    output_overridden = sent.count("output") && q.output != Output::Depth;
    q.output = Output::Depth;
  }
  read_sent(r, "depth_bits", q, sent);
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

ParsedJson read_json_body(std::string_view body) {
  ParsedJson result;
  LocatingBuilder builder(result.value);
  // An empty body means "all defaults", like {}.
  const bool all_space = std::all_of(body.begin(), body.end(), [](char c) { return std::isspace((unsigned char)c); });
  if (all_space) {
    result.value = json::object();
    return result;
  }
  const bool parsed = json::sax_parse(body.begin(), body.end(), &builder, json::input_format_t::json, true);
  if (!parsed || builder.rejection()) {
    const Rejection r = builder.rejection().value_or(Rejection{"", "malformed JSON"});
    result.error = RequestError{shortened(r.message), shortened(r.field)};
  }
  return result;
}

ParsedRequest parse_render_request(std::string_view body, Route route, const ModelLookup& find_model,
                                   const ModelsNamed& models_named) {
  ParsedJson read = read_json_body(body);
  if (read.error) {
    ParsedRequest result;
    result.error = *read.error;
    return result;
  }
  return parse_render_json(read.value, route, find_model, models_named);
}

ParsedRequest parse_render_json(const nlohmann::json& root, Route route, const ModelLookup& find_model,
                                const ModelsNamed& models_named) {
  ParsedRequest result;
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
