// The request's field table (server/request_fields.hpp): its shape, its
// defaults against the typed request's own, and the facts its "when used"
// rules read. The table against docs/openapi.json: test_api_document.cpp.
#include <gtest/gtest.h>

#include <cstdio>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "core/builtin_models.hpp"
#include "core/light_math.hpp"
#include "core/sun_position.hpp"
#include "request_fields.hpp"
#include "request_parser.hpp"

namespace umbra {
namespace {

using json = nlohmann::json;

RenderRequest parse_ok(const std::string& body) {
  const ParsedRequest p = parse_render_request(body);
  EXPECT_TRUE(p.ok()) << body << " -> " << p.error.field << ": " << p.error.message;
  return p.ok() ? *p.request : RenderRequest{};
}

std::string text(const glm::dvec3& v) {
  char buffer[96];
  std::snprintf(buffer, sizeof buffer, "(%.17g %.17g %.17g)", v.x, v.y, v.z);
  return buffer;
}
std::string text(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.17g", v);
  return buffer;
}

std::string text(const SceneObject& o) {
  return "type " + std::to_string(int(o.type)) + " center " + text(o.center) + " size " + text(o.size) + " radius " +
         text(o.radius) + " rotation_y " + text(o.rotation_y_deg) + " color " + text(o.color) + " rotation " +
         text(o.rotation_deg) + " scale " + text(o.mesh_scale) + " override " + std::to_string(o.mesh_color_override);
}

// Every field of a request that does not depend on the scene, as text (so
// that a difference shows which).
std::string text_without_scene(const RenderRequest& q) {
  const Camera& c = q.camera;
  const Light& l = q.light;
  const ShadowSettings& s = q.shadow;
  std::string t = "width " + std::to_string(q.width) + " height " + std::to_string(q.height) + "\ncamera up " +
                  text(c.up) + " fov " + text(c.fov_y_deg) + " near " + text(c.near_plane) + " far " +
                  text(c.far_plane) + "\nlight target " + text(l.target) + " color " + text(l.color) + " ambient " +
                  text(l.ambient) + " projection " + to_string(l.projection) + " fov " + text(l.fov_y_deg) +
                  " size " + text(l.size) + " orbit " + text(l.orbit_deg_per_s) + "\ntime " + text(q.time) +
                  "\nshadow enabled " + std::to_string(s.enabled) + " map " + std::to_string(s.map_size) +
                  " filter " + std::to_string(int(s.filter)) + " pcf " + std::to_string(s.pcf_radius) +
                  " bias auto " + std::to_string(s.bias.automatic) + " constant " + text(s.bias.constant) +
                  " slope " + text(s.bias.slope) + " normal_offset " + text(s.bias.normal_offset) + " cull " +
                  std::to_string(int(s.cull)) + " fit " + std::to_string(int(s.fit)) + " cascades " +
                  std::to_string(s.cascades) + " ortho " + text(s.ortho_half_size) + " near " +
                  text(s.near_plane) + " far " + text(s.far_plane) + "\noutput " + to_string(q.output) +
                  " depth_bits " + std::to_string(q.depth_bits);
  if (l.sun)
    t += "\nsun " + text(l.sun->latitude_deg) + " " + text(l.sun->longitude_deg) + " " + text(l.sun->utc_unix_s) +
         " north " + text(l.sun->north_deg);
  for (const SceneObject& o : q.scene.objects) t += "\n" + text(o);
  return t;
}

// A body with `value` at the dotted `path`, inside `base`.
json with(json base, const std::string& path, const json& value) {
  json* at = &base;
  std::size_t start = 0;
  for (std::size_t dot = path.find('.'); dot != std::string::npos; dot = path.find('.', start)) {
    at = &(*at)[path.substr(start, dot - start)];
    start = dot + 1;
  }
  (*at)[path.substr(start)] = value;
  return base;
}

const json kSun = {{"latitude", 48}, {"longitude", 2}, {"utc", "2026-06-21T12:00:00Z"}};

TEST(RequestFields, PathsAreUniqueAndEveryParentIsAnObjectRow) {
  std::set<std::string> paths, objects = {""};
  for (const RequestField& row : request_fields()) {
    EXPECT_TRUE(paths.insert(row.path).second) << row.path << " has two rows";
    EXPECT_TRUE(objects.count(row.parent())) << row.path << ": its parent has no Object or Scene row before it";
    if (row.type == FieldType::Object || row.type == FieldType::Scene) objects.insert(row.path);
    if (row.type == FieldType::Choice) {
      EXPECT_FALSE(row.choices.empty()) << row.path;
    }
    if (row.type == FieldType::IntegerChoice) {
      EXPECT_FALSE(row.numbers.empty()) << row.path;
    }
    EXPECT_LE(row.range.min, row.range.max) << row.path;
    EXPECT_TRUE(row.required.empty() || row.default_value.is_null()) << row.path << ": required, yet a default";
    EXPECT_TRUE(row.set != nullptr || row.type == FieldType::Scene || row.type == FieldType::ObjectList ||
                row.type == FieldType::Object)
        << row.path << " fills no member";
  }
  EXPECT_EQ(&request_field("shadow.bias.slope"), request_fields_in("shadow.bias").at(1));
  EXPECT_THROW(request_field("shadow.nope"), std::out_of_range);
}

TEST(RequestFields, EveryObjectTypeIsOneGroupOfRows) {
  std::set<std::string> types;
  std::set<int> kinds;
  for (const ShapeFields& shape : shape_fields()) {
    EXPECT_TRUE(types.insert(shape.type).second) << shape.type;
    EXPECT_TRUE(kinds.insert(int(shape.kind)).second) << shape.type;
    std::set<std::string> keys = {"type"};
    for (const ObjectField& row : shape.rows) {
      EXPECT_TRUE(keys.insert(row.path).second) << shape.type << "." << row.path << " has two rows";
      EXPECT_TRUE(row.set != nullptr || row.type == FieldType::Text || row.type == FieldType::Animation)
          << shape.type << "." << row.path;
    }
  }
}

// The rows' defaults (which the parser applies) are the typed request's own
// (core/request.hpp): one default, whoever builds a RenderRequest.
TEST(RequestFields, TheTypedRequestsDefaultsAreTheRows) {
  RenderRequest typed;
  typed.scene.objects.clear();
  RenderRequest parsed = parse_ok("{}");
  parsed.scene.objects.clear();
  EXPECT_EQ(text_without_scene(parsed), text_without_scene(typed));

  SunClock sun = *parse_ok(json{{"light", {{"sun", kSun}}}}.dump()).light.sun;
  EXPECT_EQ(sun.north_deg, SunClock{}.north_deg);

  for (const ShapeFields& shape : shape_fields()) {
    json object = {{"type", shape.type}};
    if (shape.kind == SceneObject::Type::Mesh) object["model"] = "teapot";
    const RenderRequest q = parse_ok(json{{"scene", {{"objects", {object}}}}}.dump());
    SceneObject expected;
    expected.type = shape.kind;
    // The one default the struct does not hold: a plane is 10 x 10 unless
    // sized (SceneObject::size says 1 for every type).
    if (shape.kind == SceneObject::Type::Plane) expected.size = {10.0, 0.0, 10.0};
    EXPECT_EQ(text(q.scene.objects.at(0)), text(expected)) << shape.type;
  }
}

// Sending a field's default gives the request that leaving it out gives.
TEST(RequestFields, SendingADefaultChangesNothing) {
  int checked = 0;
  for (const RequestField& row : request_fields()) {
    if (row.default_value.is_null()) continue;
    // The object that holds it as given (a sun needs its place and time; a
    // bias object, even empty, is the seeds' bias instead of "auto").
    json base = json::object();
    if (row.path.rfind("light.sun.", 0) == 0) base = {{"light", {{"sun", kSun}}}};
    if (row.path.rfind("shadow.bias.", 0) == 0) base = {{"shadow", {{"bias", json::object()}}}};
    const std::string body = with(base, row.path, row.default_value).dump();
    EXPECT_EQ(text_without_scene(parse_ok(body)), text_without_scene(parse_ok(base.dump()))) << body;
    ++checked;
  }
  for (const ShapeFields& shape : shape_fields()) {
    json object = {{"type", shape.type}};
    if (shape.kind == SceneObject::Type::Mesh) object["model"] = "teapot";
    const std::string plain = json{{"scene", {{"objects", {object}}}}}.dump();
    for (const ObjectField& row : shape.rows) {
      if (row.default_value.is_null()) continue;
      json sent = object;
      sent[row.path] = row.default_value;
      const std::string body = json{{"scene", {{"objects", {sent}}}}}.dump();
      EXPECT_EQ(text_without_scene(parse_ok(body)), text_without_scene(parse_ok(plain))) << body;
      ++checked;
    }
  }
  EXPECT_GE(checked, 45);
}

// The server does not see core/light_math.hpp's kMaxCascades: its row holds the number.
TEST(RequestFields, CascadesGoUpToTheRenderersMost) {
  EXPECT_EQ(request_field("shadow.cascades").range.max, double(kMaxCascades));
}

TEST(RequestFields, FieldUseReadsTheRequest) {
  RenderRequest q;
  FieldUse u = field_use(q, false);
  EXPECT_TRUE(u.shadowed && u.shadow_pass && u.filtering && u.pcf_used && u.camera_fitted);
  EXPECT_FALSE(u.depth || u.sun || u.sun_down || u.fixed || u.perspective);
  // sun_down counts only for a sun.
  EXPECT_FALSE(field_use(q, true).sun_down);
  q.light.sun = SunClock{};
  u = field_use(q, true);
  EXPECT_TRUE(u.sun && u.sun_down);
  EXPECT_FALSE(u.shadowed || u.shadow_pass || u.filtering);
  q.output = Output::Depth;
  u = field_use(q, true);
  EXPECT_TRUE(u.depth && u.shadow_pass);
  EXPECT_FALSE(u.filtering);
  q = RenderRequest{};
  q.shadow.filter = ShadowFilter::Pcss;
  EXPECT_TRUE(field_use(q, false).pcf_used);  // PCSS with an ideal light is PCF
  q.light.size = 1.0;
  EXPECT_FALSE(field_use(q, false).pcf_used);
  q.light.projection = LightProjection::Perspective;
  q.shadow.fit = FrustumFit::Fixed;
  u = field_use(q, false);
  EXPECT_TRUE(u.perspective && u.fixed);
  EXPECT_FALSE(u.camera_fitted);
}

// Umbra-Unused-Fields is the rows' used_when: a row whose rule says unused
// is listed when sent, and only then.
TEST(RequestFields, UnusedFieldsAreTheRowsThatSayUnused) {
  const std::string body =
      R"({"output": "depth", "shadow": {"fit": "fixed", "ortho_half_size": 4, "pcf_radius": 2},
          "light": {"projection": "perspective", "fov_y_deg": 50}, "depth_bits": 16})";
  const ParsedRequest p = parse_render_request(body);
  ASSERT_TRUE(p.ok()) << p.error.message;
  const FieldUse use = field_use(*p.request, false);
  std::vector<std::string> expected;
  for (const char* path : {"output", "shadow", "shadow.fit", "shadow.ortho_half_size", "shadow.pcf_radius", "light",
                           "light.projection", "light.fov_y_deg", "depth_bits"})
    if (!request_field(path).used(use)) expected.push_back(path);
  EXPECT_EQ(p.unused_fields, expected);
  EXPECT_EQ(expected, (std::vector<std::string>{"shadow.ortho_half_size", "shadow.pcf_radius"}));
}

// What the server asks about a sun (sun_position.hpp, which it may see) is
// what the renderer's light_at places the light by.
TEST(RequestFields, TheServersSunIsLightAts) {
  int down = 0, up = 0;
  for (const double latitude : {-70.0, 0.0, 48.8566, 78.2}) {
    for (double time = 0.0; time < 86400.0; time += 3600.0 * 1.7) {
      Light light;
      light.sun = SunClock{latitude, 2.35, 1.8e9, 30.0};
      const LightState state = light_at(light, time);
      const SunAngles sun = sun_at(*light.sun, time);
      ASSERT_TRUE(state.sun);
      EXPECT_EQ(state.sun->azimuth_deg, sun.azimuth_deg);
      EXPECT_EQ(state.sun->elevation_deg, sun.elevation_deg);
      EXPECT_EQ(state.direct, above_horizon(sun)) << latitude << " " << time;
      ++(state.direct ? up : down);
    }
  }
  EXPECT_GT(up, 0);
  EXPECT_GT(down, 0);
}

// The JSON writer (GET /api/scenes) is the rows read back: every object
// field has a getter, and what is written parses to the same object.
TEST(RequestFields, EveryObjectFieldIsWrittenBack) {
  for (const ShapeFields& shape : shape_fields())
    for (const ObjectField& row : shape.rows) EXPECT_NE(row.get, nullptr) << shape.type << "." << row.path;
}

TEST(RequestFields, AWrittenObjectParsesToTheSameObject) {
  std::vector<SceneObject> objects;
  for (const BuiltinScene& scene : builtin_scenes())
    for (const SceneObject& o : scene.objects) objects.push_back(o);
  // One of each type with no field at its default.
  auto object = [](SceneObject::Type type, glm::dvec3 center, glm::dvec3 color) {
    SceneObject o;
    o.type = type;
    o.center = center;
    o.color = color;
    return o;
  };
  SceneObject plane = object(SceneObject::Type::Plane, {1.5, -2, 3.25}, {0.1, 0.2, 0.3});
  plane.size = {4, 0, 7.5};
  SceneObject box = object(SceneObject::Type::Box, {0, 0.5, -1}, {0.9, 0.5, 0.25});
  box.size = {1, 2, 3};
  box.rotation_y_deg = 33.5;
  SceneObject sphere = object(SceneObject::Type::Sphere, {2, 1, 2}, {0.3, 0.6, 0.9});
  sphere.radius = 0.75;
  SceneObject mesh = object(SceneObject::Type::Mesh, {1, 0, -1}, {0.2, 0.4, 0.6});
  const BuiltinModel* teapot = find_builtin_model("teapot");
  ASSERT_NE(teapot, nullptr);
  mesh.model = teapot->model;
  mesh.model_id = teapot->id;
  mesh.rotation_deg = {10, 20, 30};
  mesh.mesh_scale = {0.5, 1.5, 2.5};
  mesh.mesh_color_override = true;
  SceneObject cylinder = object(SceneObject::Type::Cylinder, {-3, 2.5, 4}, {0.7, 0.1, 0.4});
  cylinder.radius = 0.25;
  cylinder.size.y = 5;
  objects.insert(objects.end(), {plane, box, sphere, mesh, cylinder});
  std::set<SceneObject::Type> types;
  for (const SceneObject& o : objects) {
    types.insert(o.type);
    const json written = write_object(o);
    const RenderRequest q = parse_ok(json{{"scene", {{"objects", json::array({written})}}}}.dump());
    ASSERT_EQ(q.scene.objects.size(), 1u) << written.dump();
    EXPECT_EQ(text(q.scene.objects[0]), text(o)) << written.dump();
    EXPECT_EQ(q.scene.objects[0].model_id, o.model_id) << written.dump();
  }
  EXPECT_EQ(types.size(), shape_fields().size()) << "an object type is not covered";
}

}  // namespace
}  // namespace umbra
