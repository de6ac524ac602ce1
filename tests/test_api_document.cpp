// docs/openapi.json against the request parser. Every `default` the document
// states is what parse_render_request gives for a field left out, every
// default the parser applies is in the document, and every enum the document
// lists is exactly what the parser takes: a change on either side fails here.
// The sun-hours request's components (SunHours*) are held to
// parse_sun_hours_request alike: their defaults and numeric ranges.
//
// The document's path comes from CMake (UMBRA_OPENAPI_JSON): the repository's
// own file, the one the server embeds and serves at GET /api/openapi.json.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "request_fields.hpp"
#include "request_parser.hpp"
#include "sun_hours_parser.hpp"
#include "assets/gltf_loader.hpp"
#include "core/model.hpp"
#include "core/scene.hpp"
#include "gltf_builder.hpp"

namespace umbra {
namespace {

using json = nlohmann::json;

json load_document() {
  std::ifstream in(UMBRA_OPENAPI_JSON);
  EXPECT_TRUE(in) << "cannot read " << UMBRA_OPENAPI_JSON;
  return json::parse(in);
}

// Every `default` in a schema, keyed "<Component>.<property>.<property>...":
// properties are joined by '.', array items add "[]", and the branches of
// oneOf / anyOf / allOf keep their parent's path. A $ref is not followed:
// each component is walked under its own name.
void collect_defaults(const json& schema, const std::string& path, std::map<std::string, json>& out) {
  if (!schema.is_object()) return;
  if (schema.contains("default")) {
    EXPECT_FALSE(out.count(path)) << path << " has two defaults";
    out[path] = schema["default"];
  }
  if (schema.contains("properties"))
    for (const auto& [name, property] : schema["properties"].items()) collect_defaults(property, path + "." + name, out);
  if (schema.contains("items")) collect_defaults(schema["items"], path + "[]", out);
  for (const char* branches : {"oneOf", "anyOf", "allOf"})
    if (schema.contains(branches))
      for (const json& branch : schema[branches]) collect_defaults(branch, path, out);
}

std::map<std::string, json> document_defaults() {
  std::map<std::string, json> defaults;
  const json document = load_document();
  for (const auto& [name, schema] : document["components"]["schemas"].items())
    collect_defaults(schema, name, defaults);
  return defaults;
}

// A model with one animation (a cube sliding along +X over 2 s), found by
// the name "animated": the document's animation fields need a model that
// has one, and no built-in model does.
const ModelLookup& test_models() {
  static const std::shared_ptr<const TriangleModel> model = [] {
    const LoadResult r = load_gltf(test::sliding_cube(), {});
    EXPECT_TRUE(r.ok()) << r.error;
    return std::shared_ptr<const TriangleModel>(r.model);
  }();
  static const ModelLookup lookup = [](const std::string& key) -> std::optional<FoundModel> {
    if (key == "animated") return FoundModel{"sha256:animated", model};
    return std::nullopt;
  };
  return lookup;
}

RenderRequest parse_ok(const std::string& body) {
  const ParsedRequest p = parse_render_request(body, Route::Render, test_models());
  EXPECT_TRUE(p.ok()) << body << ": " << p.error.field << ": " << p.error.message;
  return p.ok() ? *p.request : RenderRequest{};
}

json vec(const glm::dvec3& v) { return json::array({v.x, v.y, v.z}); }

// The smallest valid POST /api/sun-hours body: a day at the equator over one
// point.
json sun_hours_body() {
  return {{"site", {{"latitude", 0}, {"longitude", 0}}},
          {"period", {{"start", "2000-01-01T00:00:00Z"}, {"end", "2000-01-02T00:00:00Z"}}},
          {"grid", {{"size", {1, 1}}, {"spacing", 1}}}};
}

const char* name_of(ShadowFilter f) {
  switch (f) {
    case ShadowFilter::Hard: return "hard";
    case ShadowFilter::Pcf: return "pcf";
    case ShadowFilter::Pcss: return "pcss";
    case ShadowFilter::Exact: return "exact";
  }
  return "?";
}
const char* name_of(CullMode c) { return c == CullMode::Front ? "front" : c == CullMode::Back ? "back" : "none"; }
const char* name_of(FrustumFit f) { return f == FrustumFit::Scene ? "scene" : "fixed"; }

// What the parser gives for every field it defaults, under the document's
// key for that field. Fields whose default depends on the scene (camera
// position and target, light position) have none in the document either.
std::map<std::string, json> parser_defaults() {
  const RenderRequest q = parse_ok("{}");
  const Camera& c = q.camera;
  const Light& l = q.light;
  const ShadowSettings& s = q.shadow;
  const DepthBias bias = parse_ok(R"({"shadow": {"bias": {}}})").shadow.bias;
  const SunClock sun =
      *parse_ok(R"({"light": {"sun": {"latitude": 0, "longitude": 0, "utc": "2000-01-01T00:00:00Z"}}})").light.sun;
  std::map<std::string, json> defaults = {
      {"RenderRequest.width", q.width},
      {"RenderRequest.height", q.height},
      {"RenderRequest.scene", q.scene.name},
      {"RenderRequest.time", q.time},
      {"RenderRequest.output", to_string(q.output)},
      {"RenderRequest.depth_bits", q.depth_bits},
      {"Camera.up", vec(c.up)},
      {"Camera.fov_y_deg", c.fov_y_deg},
      {"Camera.near", c.near_plane},
      {"Camera.far", c.far_plane},
      {"Light.target", vec(l.target)},
      {"Light.color", vec(l.color)},
      {"Light.ambient", l.ambient},
      {"Light.projection", to_string(l.projection)},
      {"Light.fov_y_deg", l.fov_y_deg},
      {"Light.size", l.size},
      {"Light.orbit_deg_per_s", l.orbit_deg_per_s},
      {"Sun.north_deg", sun.north_deg},
      {"Shadow.enabled", s.enabled},
      {"Shadow.map_size", s.map_size},
      {"Shadow.filter", name_of(s.filter)},
      {"Shadow.pcf_radius", s.pcf_radius},
      {"Shadow.bias", s.bias.automatic ? json("auto") : json::object()},
      {"Shadow.cull", name_of(s.cull)},
      {"Shadow.fit", name_of(s.fit)},
      {"Shadow.cascades", s.cascades == 0 ? json("auto") : json(s.cascades)},
      {"Shadow.ortho_half_size", s.ortho_half_size},
      {"Shadow.near", s.near_plane},
      {"Shadow.far", s.far_plane},
      {"BiasObject.constant", bias.constant},
      {"BiasObject.slope", bias.slope},
      {"BiasObject.normal_offset", bias.normal_offset},
  };
  // The sun-hours request's defaults (POST /api/sun-hours).
  const ParsedSunHours sun_hours = parse_sun_hours_request(sun_hours_body().dump());
  EXPECT_TRUE(sun_hours.ok()) << sun_hours.error.field << ": " << sun_hours.error.message;
  if (sun_hours.ok()) {
    const SunHoursRequest& h = *sun_hours.request;
    defaults["SunHoursRequest.scene"] = h.view.scene.name;
    defaults["SunHoursRequest.exact"] = h.exact;
    defaults["SunHoursRequest.include_samples"] = h.include_samples;
    // The picture's size, read by the render request's own parser.
    defaults["SunHoursRequest.width"] = h.view.width;
    defaults["SunHoursRequest.height"] = h.view.height;
    defaults["SunHoursSite.north_deg"] = h.site.north_deg;
    defaults["SunHoursPeriod.step_minutes"] = h.period.step_minutes;
    defaults["SunHoursGrid.center"] = vec(h.grid.center);
  }
  // Each object type: an object with only its type (a mesh needs its model),
  // as the parser fills it, written back by its rows (write_object).
  for (const ShapeFields& shape : shape_fields()) {
    json o = {{"type", shape.type}};
    if (shape.kind == SceneObject::Type::Mesh) o["model"] = "teapot";  // built in: found without a store
    const RenderRequest parsed = parse_ok(json{{"scene", {{"objects", json::array({o})}}}}.dump());
    const json written = write_object(parsed.scene.objects.at(0));
    if (shape.kind == SceneObject::Type::Mesh) {
      // An animation named by index alone: how it plays, by default.
      const json animated = {{"type", "mesh"}, {"model", "animated"}, {"animation", 0}};
      const json played = write_object(parse_ok(json{{"scene", {{"objects", {animated}}}}}.dump()).scene.objects.at(0));
      for (const char* key : {"speed", "loop"}) defaults[shape.schema + ".animation." + key] = played["animation"][key];
    }
    for (const ObjectField& row : shape.rows) {
      if (row.default_value.is_null() || !written.contains(row.key())) continue;
      json value = written[row.key()];
      // "A number, or [sx, sy, sz]": the document gives the number.
      if (row.type == FieldType::NumberOrVec3 && value[0] == value[1] && value[1] == value[2]) value = value[0];
      defaults[shape.schema + "." + row.key()] = value;
    }
  }
  return defaults;
}

TEST(ApiDocument, EveryDefaultInTheDocumentIsTheParsers) {
  const std::map<std::string, json> parser = parser_defaults();
  const std::map<std::string, json> document = document_defaults();
  ASSERT_FALSE(document.empty());
  for (const auto& [field, value] : document) {
    const auto it = parser.find(field);
    if (it == parser.end()) {
      ADD_FAILURE() << "docs/openapi.json gives " << field << " the default " << value.dump()
                    << ", which this test does not read from the parser: add it to parser_defaults()";
      continue;
    }
    // nlohmann compares numbers by value: 1 == 1.0.
    EXPECT_EQ(value, it->second) << field << ": docs/openapi.json says " << value.dump() << ", the parser gives "
                                 << it->second.dump();
  }
}

TEST(ApiDocument, EveryParserDefaultIsInTheDocument) {
  const std::map<std::string, json> document = document_defaults();
  for (const auto& [field, value] : parser_defaults())
    EXPECT_TRUE(document.count(field)) << field << " defaults to " << value.dump()
                                       << " in the parser but has no \"default\" in docs/openapi.json";
}

// The body that sets `property` of `component` to `value`.
json body_setting(const std::string& component, const std::string& property, const json& value) {
  if (component == "RenderRequest") return {{property, value}};
  if (component == "Camera") return {{"camera", {{property, value}}}};
  if (component == "Light") return {{"light", {{property, value}}}};
  if (component == "Shadow") return {{"shadow", {{property, value}}}};
  return nullptr;
}

TEST(ApiDocument, EveryEnumIsWhatTheParserTakes) {
  const json document = load_document();
  int checked = 0;
  for (const auto& [component, schema] : document["components"]["schemas"].items()) {
    if (!schema.contains("properties")) continue;
    for (const auto& [property, p] : schema["properties"].items()) {
      if (!p.contains("enum") || body_setting(component, property, 0).is_null()) continue;
      const std::string field = component == "RenderRequest" ? property
                                : std::string(component == "Camera" ? "camera" : component == "Light" ? "light" : "shadow") +
                                      "." + property;
      for (const json& value : p["enum"]) {
        const std::string body = body_setting(component, property, value).dump();
        const ParsedRequest ok = parse_render_request(body);
        EXPECT_TRUE(ok.ok()) << body << ": " << ok.error.message;
        ++checked;
      }
      // A value the document does not list is refused, naming the field.
      const json other = p["enum"][0].is_string() ? json("not-listed") : json(12);
      const ParsedRequest refused = parse_render_request(body_setting(component, property, other).dump());
      EXPECT_FALSE(refused.ok()) << field << " takes " << other.dump() << ", which docs/openapi.json does not list";
      if (!refused.ok()) {
        EXPECT_EQ(refused.error.field, field);
      }
    }
  }
  EXPECT_GE(checked, 15);
}

// Where a request-side component's property sits in a body, and what else
// the body needs for a value at the edge of its range to be valid on its
// own (a camera.near of 10^6 needs a farther far). nullopt: not a request
// component.
struct RangeCase {
  json body;           // with the property set to `value`
  std::string field;   // the parser's path for it
  bool sun_hours = false;  // a POST /api/sun-hours body, not a render's
};

std::optional<RangeCase> range_case(const std::string& component, const std::string& property, const json& value) {
  const json sun = {{"latitude", 0}, {"longitude", 0}, {"utc", "2000-01-01T00:00:00Z"}};
  if (component == "RenderRequest") return RangeCase{{{property, value}}, property};
  if (component == "Camera") {
    json camera = {{property, value}};
    if (property == "near") camera["far"] = 1e9;
    if (property == "far") camera["near"] = 1e-9;
    return RangeCase{{{"camera", camera}}, "camera." + property};
  }
  if (component == "Light") {
    json light = {{property, value}};
    // light.size's range in the properties is a perspective light's; an
    // orthographic one's (at most 90 degrees, the schema's `else`) is a
    // case of RequestParserRejects (tests/test_request_parser.cpp).
    if (property == "size" || property == "fov_y_deg") light["projection"] = "perspective";
    json body = {{"light", light}};
    if (property == "fov_y_deg") body["shadow"] = {{"fit", "fixed"}};
    if (property == "size") body["shadow"] = {{"filter", "pcss"}};
    return RangeCase{body, "light." + property};
  }
  if (component == "Sun") {
    json clock = sun;
    clock[property] = value;
    return RangeCase{{{"light", {{"sun", clock}}}}, "light.sun." + property};
  }
  if (component == "Shadow") {
    // near and far have each the whole range; fit "fixed" also wants
    // near < far, which the document states beside them (not a range).
    json shadow = {{property, value}};
    if (property != "near" && property != "far" && property != "cascades") shadow["fit"] = "fixed";
    return RangeCase{{{"shadow", shadow}}, "shadow." + property};
  }
  if (component == "BiasObject") return RangeCase{{{"shadow", {{"bias", {{property, value}}}}}}, "shadow.bias." + property};
  // POST /api/sun-hours: a one-day period (which the steps at the range's
  // bounds divide), and a grid of whole cells whatever the size or spacing.
  if (component.rfind("SunHours", 0) == 0) {
    json body = sun_hours_body();
    if (component == "SunHoursRequest") {
      body[property] = value;
      return RangeCase{body, property, true};
    }
    const std::string part = component == "SunHoursSite" ? "site" : component == "SunHoursPeriod" ? "period" : "grid";
    body[part][property] = value;
    if (component == "SunHoursGrid" && property == "size") {
      const double v = value.is_array() ? value[0].get<double>() : value.get<double>();
      body["grid"]["spacing"] = v > 1e6 ? v / 2 : v > 0 ? v : 1.0;  // spacing itself is at most 1e6
    }
    if (component == "SunHoursGrid" && property == "spacing") {
      const double v = value.get<double>();
      body["grid"]["size"] = {v > 0 ? v : 1.0, v > 0 ? v : 1.0};
    }
    return RangeCase{body, part + "." + property, true};
  }
  for (const ShapeFields& shape : shape_fields()) {
    if (component != shape.schema) continue;
    const std::string& type = shape.type;
    json o = {{"type", type}, {property, value}};
    if (type == "mesh") o["model"] = "teapot";  // built in: found without a store
    if (type == "mesh" && property == "animation") {
      // Its one ranged number: the speed of an animation of a model that has one.
      o["model"] = "animated";
      o["animation"] = {{"index", 0}, {"speed", value}};
      return RangeCase{{{"scene", {{"objects", json::array({o})}}}}, "scene.objects[0].animation.speed"};
    }
    return RangeCase{{{"scene", {{"objects", json::array({o})}}}}, "scene.objects[0]." + property};
  }
  return std::nullopt;
}

// The schemas of answers, not of request bodies: their ranges describe what
// the server sends.
bool is_response_schema(const std::string& component) {
  return component == "Health" || component == "SceneList" || component == "Model" || component == "ModelList" ||
         component == "SunHoursAnswer";
}

// A body through the parser of its route: whether it is taken, and if not
// the field its refusal names and why.
struct Verdict {
  bool ok;
  std::string field, message;
};
Verdict parse_case(const RangeCase& c) {
  if (c.sun_hours) {
    const ParsedSunHours p = parse_sun_hours_request(c.body.dump());
    return {p.ok(), p.error.field, p.error.message};
  }
  const ParsedRequest p = parse_render_request(c.body.dump(), Route::Render, test_models());
  return {p.ok(), p.error.field, p.error.message};
}

// A number with a range somewhere in a property's schema: the property
// itself, its array items (set all alike, so the first names the field),
// or a branch of oneOf / anyOf / allOf.
struct Ranged {
  const json* schema;
  int items;  // 0: the property itself; n: an array of n such numbers
};

void collect_ranged(const json& schema, int items, std::vector<Ranged>& out) {
  if (!schema.is_object()) return;
  const bool number = schema.contains("type") && (schema["type"] == "number" || schema["type"] == "integer");
  if (number && (schema.contains("minimum") || schema.contains("maximum") || schema.contains("exclusiveMinimum") ||
                 schema.contains("exclusiveMaximum")))
    out.push_back({&schema, items});
  if (schema.contains("items")) collect_ranged(schema["items"], schema.value("minItems", 3), out);
  for (const char* branches : {"oneOf", "anyOf", "allOf"})
    if (schema.contains(branches))
      for (const json& branch : schema[branches]) collect_ranged(branch, items, out);
}

// Every numeric range the document states for a request field is the
// parser's: an inclusive bound is taken and a value just beyond it refused
// naming the field; an exclusive bound is refused and a value just inside
// taken. Array items and oneOf branches included. (Ranges that depend on
// another field, such as an orthographic light's size, and rules between
// fields, such as near < far, are in the document's prose and the parser's
// own tests.)
TEST(ApiDocument, EveryNumericRangeIsWhatTheParserTakes) {
  const json document = load_document();
  int checked = 0;
  for (const auto& [component_key, schema] : document["components"]["schemas"].items()) {
    if (!schema.contains("properties")) continue;
    // Named copies: lambdas below use them (C++17 cannot capture a structured binding).
    const std::string component = component_key;
    for (const auto& [property_key, p] : schema["properties"].items()) {
      const std::string property = property_key;
      std::vector<Ranged> ranged;
      collect_ranged(p, 0, ranged);
      if (ranged.empty() || is_response_schema(component)) continue;
      if (!range_case(component, property, 0)) {
        ADD_FAILURE() << component << "." << property
                      << " has a numeric range, but this test does not know where it goes in a body: add it to range_case()";
        continue;
      }
      // A model placed at the edge of the position or scale range reaches
      // past the coordinate limit (a rule on the placed model, in the
      // document's prose): there only "beyond the bound is refused" holds.
      const bool bound_has_no_room = component == "MeshObject" && (property == "position" || property == "scale");
      for (const Ranged& r : ranged) {
        const json& s = *r.schema;
        const bool integer = s["type"] == "integer";
        const auto step = [&](double bound, double direction) {
          return bound + direction * (integer ? 1.0 : std::max(1e-6, 1e-6 * std::abs(bound)));
        };
        const auto expect = [&](double number, bool taken, const char* why) {
          if (taken && bound_has_no_room) return;
          const json value = r.items == 0 ? json(number) : json(std::vector<double>(std::size_t(r.items), number));
          RangeCase c = *range_case(component, property, value);
          if (r.items > 0) c.field += "[0]";
          const Verdict parsed = parse_case(c);
          if (taken) {
            EXPECT_TRUE(parsed.ok) << c.field << " " << why << ": " << c.body.dump() << " -> " << parsed.field << ": "
                                   << parsed.message;
          } else {
            EXPECT_FALSE(parsed.ok) << c.field << " " << why << ": " << c.body.dump() << " was taken";
            if (!parsed.ok) {
              EXPECT_EQ(parsed.field, c.field) << c.body.dump() << ": " << parsed.message;
            }
          }
          ++checked;
        };
        if (s.contains("minimum")) {
          expect(s["minimum"].get<double>(), true, "at its minimum");
          expect(step(s["minimum"].get<double>(), -1.0), false, "below its minimum");
        }
        if (s.contains("exclusiveMinimum")) {
          expect(s["exclusiveMinimum"].get<double>(), false, "at its exclusive minimum");
          expect(step(s["exclusiveMinimum"].get<double>(), 1.0), true, "just over its exclusive minimum");
        }
        if (s.contains("maximum")) {
          expect(s["maximum"].get<double>(), true, "at its maximum");
          expect(step(s["maximum"].get<double>(), 1.0), false, "above its maximum");
        }
        if (s.contains("exclusiveMaximum")) {
          expect(s["exclusiveMaximum"].get<double>(), false, "at its exclusive maximum");
          expect(step(s["exclusiveMaximum"].get<double>(), -1.0), true, "just under its exclusive maximum");
        }
      }
    }
  }
  EXPECT_GE(checked, 120);
}

// ---------------------------------------------------------------------------
// The field table (server/request_fields.hpp) row by row: each row's
// property in the document has the row's type, default, range, enum and
// required-ness, and a description holding the row's doc line; each request
// property of the document has a row.

// The component that describes the object at `parent` ("" for the body).
std::string component_of(const std::string& parent) {
  return parent.empty() ? std::string(kRequestSchema) : request_field(parent).schema;
}

// The number (or integer) schema inside a property: itself, its items, or a
// branch of oneOf; nullptr if none.
const json* numeric_schema(const json& s) {
  if (!s.is_object()) return nullptr;
  if (s.contains("type") && (s["type"] == "number" || s["type"] == "integer")) return &s;
  if (s.contains("items")) return numeric_schema(s["items"]);
  if (s.contains("oneOf"))
    for (const json& branch : s["oneOf"])
      if (const json* found = numeric_schema(branch)) return found;
  return nullptr;
}

// The array schema of a property (itself or a oneOf branch): its item count.
int array_items(const json& s) {
  if (s.value("type", "") == "array") return s.value("minItems", -1) == s.value("maxItems", -2) ? s.value("minItems", 0) : -1;
  if (s.contains("oneOf"))
    for (const json& branch : s["oneOf"])
      if (int n = array_items(branch); n != 0) return n;
  return 0;
}

bool has_const(const json& s, const std::string& word) {
  if (s.value("const", json()) == word) return true;
  if (s.contains("oneOf"))
    for (const json& branch : s["oneOf"])
      if (has_const(branch, word)) return true;
  return false;
}

bool refers_to(const json& s, const std::string& component) {
  const std::string ref = "#/components/schemas/" + component;
  if (s.value("$ref", "") == ref) return true;
  if (s.contains("oneOf"))
    for (const json& branch : s["oneOf"])
      if (refers_to(branch, component)) return true;
  return false;
}

template <class Target>
void expect_row_in_document(const FieldRow<Target>& row, const std::string& component, const json& schemas) {
  const std::string where = component + "." + row.key() + " (row " + row.path + ")";
  const json& owner = schemas[component];
  if (!owner.contains("properties") || !owner["properties"].contains(row.key())) {
    ADD_FAILURE() << where << ": docs/openapi.json has no such property";
    return;
  }
  const json& p = owner["properties"][row.key()];
  EXPECT_EQ(p.value("default", json()), row.default_value) << where << ": default";
  const bool required = owner.contains("required") && std::find(owner["required"].begin(), owner["required"].end(),
                                                                row.key()) != owner["required"].end();
  EXPECT_EQ(required, !row.required.empty()) << where << ": required";
  if (!row.doc.empty()) {
    EXPECT_NE(p.value("description", "").find(row.doc), std::string::npos)
        << where << ": the description does not say \"" << row.doc << "\"";
  }
  if (!row.word.empty()) {
    EXPECT_TRUE(has_const(p, row.word)) << where << ": does not take \"" << row.word << "\"";
  }
  const json* number = numeric_schema(p);
  switch (row.type) {
    case FieldType::Integer:
    case FieldType::Number:
    case FieldType::Vec3:
    case FieldType::Size2:
    case FieldType::Color:
    case FieldType::NumberOrVec3: {
      if (number == nullptr) {
        ADD_FAILURE() << where << ": no numeric schema";
        break;
      }
      const bool integer = row.type == FieldType::Integer;
      EXPECT_EQ((*number)["type"], integer ? "integer" : "number") << where;
      EXPECT_EQ(number->value(row.range.open_min ? "exclusiveMinimum" : "minimum", json()), row.range.min)
          << where << ": minimum";
      EXPECT_EQ(number->value(row.range.open_max ? "exclusiveMaximum" : "maximum", json()), row.range.max)
          << where << ": maximum";
      const int items = row.type == FieldType::Vec3 || row.type == FieldType::Color || row.type == FieldType::NumberOrVec3
                            ? 3
                        : row.type == FieldType::Size2 ? 2
                                                       : 0;
      EXPECT_EQ(array_items(p), items) << where << ": items";
      break;
    }
    case FieldType::IntegerChoice:
      EXPECT_EQ(p.value("type", ""), "integer") << where;
      EXPECT_EQ(p.value("enum", json()), json(row.numbers)) << where << ": enum";
      break;
    case FieldType::Choice:
      EXPECT_EQ(p.value("type", ""), "string") << where;
      EXPECT_EQ(p.value("enum", json()), json(row.choices)) << where << ": enum";
      break;
    case FieldType::Boolean:
      EXPECT_EQ(p.value("type", ""), "boolean") << where;
      break;
    case FieldType::Text:
      EXPECT_EQ(p.value("type", ""), "string") << where;
      break;
    case FieldType::Animation: {
      // A name, an index, or an object naming one of them.
      json types = json::array();
      for (const json& alternative : p.value("oneOf", json::array())) types.push_back(alternative.value("type", ""));
      EXPECT_EQ(types, json({"string", "integer", "object"})) << where;
      break;
    }
    case FieldType::Object:
    case FieldType::Scene:
      EXPECT_TRUE(refers_to(p, row.schema)) << where << ": not a $ref to " << row.schema;
      break;
    case FieldType::ObjectList:
      EXPECT_EQ(p.value("maxItems", json()), row.range.max) << where << ": maxItems";
      break;
  }
}

TEST(ApiDocument, EveryFieldRowIsInTheDocument) {
  const json schemas = load_document()["components"]["schemas"];
  for (const RequestField& row : request_fields()) expect_row_in_document(row, component_of(row.parent()), schemas);
  for (const ShapeFields& shape : shape_fields()) {
    EXPECT_EQ(schemas[shape.schema]["properties"]["type"], json({{"const", shape.type}})) << shape.schema;
    for (const ObjectField& row : shape.rows) expect_row_in_document(row, shape.schema, schemas);
  }
}

TEST(ApiDocument, EveryRequestPropertyInTheDocumentHasARow) {
  const json schemas = load_document()["components"]["schemas"];
  // The request's components, and the key each property's row has.
  std::map<std::string, std::string> parents = {{kRequestSchema, ""}};
  for (const RequestField& row : request_fields())
    if (!row.schema.empty()) parents[row.schema] = row.path;
  int checked = 0;
  for (const auto& [component, parent] : parents) {
    for (const auto& [property, p] : schemas[component]["properties"].items()) {
      const std::string path = parent.empty() ? property : parent + "." + property;
      EXPECT_NO_THROW(request_field(path)) << component << "." << property << " has no row " << path;
      ++checked;
    }
  }
  // A scene object: one group of rows per type, in the document's order.
  json refs = json::array(), mapping = json::object();
  for (const ShapeFields& shape : shape_fields()) {
    refs.push_back({{"$ref", "#/components/schemas/" + shape.schema}});
    mapping[shape.type] = "#/components/schemas/" + shape.schema;
    for (const auto& item : schemas[shape.schema]["properties"].items()) {
      const std::string property = item.key();  // a named copy: C++17 lambdas cannot capture a structured binding
      const bool has_row = property == "type" || std::any_of(shape.rows.begin(), shape.rows.end(),
                                                             [&](const ObjectField& r) { return r.path == property; });
      EXPECT_TRUE(has_row) << shape.schema << "." << property << " has no row in the " << shape.type << " group";
      ++checked;
    }
  }
  EXPECT_EQ(schemas["SceneObject"]["oneOf"], refs);
  EXPECT_EQ(schemas["SceneObject"]["discriminator"]["mapping"], mapping);
  EXPECT_GE(checked, 60);
}

TEST(ApiDocument, TheBuiltInSceneNamesAreTheServers) {
  json names = json::array();
  for (const BuiltinScene& scene : builtin_scenes()) names.push_back(scene.name);
  EXPECT_EQ(load_document()["components"]["schemas"]["BuiltinSceneName"]["enum"], names);
}

}  // namespace
}  // namespace umbra
