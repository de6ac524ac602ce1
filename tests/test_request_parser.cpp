// The request parser: defaults, and every class of bad input docs/api.md lists.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include <glm/geometric.hpp>

#include "core/builtin_models.hpp"
#include "core/mesh_instance.hpp"
#include "model_support.hpp"
#include "request_parser.hpp"
#include "core/scene.hpp"

namespace umbra {
namespace {

RenderRequest parse_ok(const std::string& body) {
  ParsedRequest p = parse_render_request(body);
  EXPECT_TRUE(p.ok()) << body << " -> " << p.error.field << ": " << p.error.message;
  return p.ok() ? *p.request : RenderRequest{};
}

TEST(RequestParser, EmptyObjectGivesTheApiDefaults) {
  const RenderRequest q = parse_ok("{}");
  EXPECT_EQ(q.width, 960);
  EXPECT_EQ(q.height, 540);
  EXPECT_EQ(q.scene.name, "cube-on-plane");
  EXPECT_EQ(q.scene.objects.size(), find_builtin_scene("cube-on-plane")->objects.size());
  EXPECT_EQ(q.camera.position, find_builtin_scene("cube-on-plane")->camera_position);
  EXPECT_EQ(q.camera.up, glm::dvec3(0, 1, 0));
  EXPECT_DOUBLE_EQ(q.camera.fov_y_deg, 45.0);
  EXPECT_DOUBLE_EQ(q.camera.near_plane, 0.1);
  EXPECT_DOUBLE_EQ(q.camera.far_plane, 100.0);
  EXPECT_EQ(q.light.position, find_builtin_scene("cube-on-plane")->light_position);
  EXPECT_EQ(q.light.target, glm::dvec3(0.0));
  EXPECT_EQ(q.light.color, glm::dvec3(1.0));
  EXPECT_DOUBLE_EQ(q.light.ambient, 0.3);
  EXPECT_EQ(q.light.projection, LightProjection::Orthographic);
  EXPECT_DOUBLE_EQ(q.light.fov_y_deg, 90.0);
  EXPECT_DOUBLE_EQ(q.light.size, 0.0);
  EXPECT_DOUBLE_EQ(q.light.orbit_deg_per_s, 20.0);
  EXPECT_DOUBLE_EQ(q.time, 0.0);
  EXPECT_TRUE(q.shadow.enabled);
  EXPECT_EQ(q.shadow.map_size, 2048);
  EXPECT_EQ(q.shadow.filter, ShadowFilter::Pcf);
  EXPECT_EQ(q.shadow.pcf_radius, 1);
  EXPECT_TRUE(q.shadow.bias.automatic);
  EXPECT_EQ(q.shadow.cull, CullMode::Front);
  EXPECT_EQ(q.shadow.fit, FrustumFit::Scene);
  EXPECT_DOUBLE_EQ(q.shadow.ortho_half_size, 10.0);
  EXPECT_DOUBLE_EQ(q.shadow.near_plane, 1.0);
  EXPECT_DOUBLE_EQ(q.shadow.far_plane, 7.5);
  EXPECT_EQ(q.output, Output::Color);
  EXPECT_EQ(q.depth_bits, 8);
}

TEST(RequestParser, EmptyBodyIsTheSameAsEmptyObject) {
  EXPECT_EQ(parse_ok("").width, 960);
  EXPECT_EQ(parse_ok("  \n").output, Output::Color);
}

TEST(RequestParser, TheDocumentedDefaultBodyIsAcceptedAndUnusedFieldsAreReported) {
  const std::string body = R"({"width":960,"height":540,"scene":"cube-on-plane",
    "camera":{"up":[0,1,0],"fov_y_deg":45,"near":0.1,"far":100},
    "light":{"target":[0,0,0],"color":[1,1,1],"ambient":0.3,"projection":"orthographic","fov_y_deg":90,"size":0,"orbit_deg_per_s":20},
    "time":0.0,
    "shadow":{"enabled":true,"map_size":2048,"filter":"pcf","pcf_radius":1,"bias":"auto","cull":"front","fit":"scene",
              "ortho_half_size":10,"near":1.0,"far":7.5},
    "output":"color"})";
  ParsedRequest p = parse_render_request(body);
  ASSERT_TRUE(p.ok()) << p.error.field << ": " << p.error.message;
  const std::vector<std::string> expected = {"light.fov_y_deg", "shadow.far", "shadow.near", "shadow.ortho_half_size"};
  EXPECT_EQ(p.unused_fields, expected);
}

TEST(RequestParser, ReadsEveryField) {
  const RenderRequest q = parse_ok(R"({
    "width": 320, "height": 200, "scene": "three-cubes",
    "camera": {"position": [1,2,3], "target": [0,1,0], "up": [0,0,1], "fov_y_deg": 60, "near": 0.5, "far": 50},
    "light": {"position": [3,5,1], "target": [0,0,1], "color": "#ff8000", "ambient": 0.1,
              "projection": "perspective", "fov_y_deg": 70, "orbit_deg_per_s": -10},
    "time": 2.5,
    "shadow": {"enabled": true, "map_size": 1024, "filter": "hard", "bias": {"constant": 0.001, "slope": 0.01, "normal_offset": 1.5},
               "cull": "back", "fit": "fixed", "near": 0.5, "far": 20},
    "output": "shadow"})");
  EXPECT_EQ(q.width, 320);
  EXPECT_EQ(q.scene.name, "three-cubes");
  EXPECT_EQ(q.camera.up, glm::dvec3(0, 0, 1));
  EXPECT_DOUBLE_EQ(q.light.color.r, 1.0);
  EXPECT_DOUBLE_EQ(q.light.color.g, 128.0 / 255.0);
  EXPECT_DOUBLE_EQ(q.light.color.b, 0.0);
  EXPECT_EQ(q.light.projection, LightProjection::Perspective);
  EXPECT_DOUBLE_EQ(q.light.orbit_deg_per_s, -10.0);
  EXPECT_DOUBLE_EQ(q.time, 2.5);
  EXPECT_EQ(q.shadow.filter, ShadowFilter::Hard);
  EXPECT_FALSE(q.shadow.bias.automatic);
  EXPECT_DOUBLE_EQ(q.shadow.bias.normal_offset, 1.5);
  EXPECT_EQ(q.shadow.cull, CullMode::Back);
  EXPECT_EQ(q.shadow.fit, FrustumFit::Fixed);
  EXPECT_EQ(q.output, Output::Shadow);
}

TEST(RequestParser, CustomSceneWithEveryObjectType) {
  const RenderRequest q = parse_ok(R"({"scene": {"objects": [
      {"type": "plane", "center": [0,0,0], "size": [20, 10], "color": [0.5,0.5,0.5]},
      {"type": "box", "center": [0,1,0], "size": [1,2,3], "rotation_y_deg": 30, "color": "#102030"},
      {"type": "sphere", "center": [2,1,0], "radius": 0.75}]}})");
  ASSERT_EQ(q.scene.objects.size(), 3u);
  EXPECT_EQ(q.scene.objects[0].type, SceneObject::Type::Plane);
  EXPECT_DOUBLE_EQ(q.scene.objects[0].size.z, 10.0);
  EXPECT_DOUBLE_EQ(q.scene.objects[1].rotation_y_deg, 30.0);
  EXPECT_DOUBLE_EQ(q.scene.objects[2].radius, 0.75);
  EXPECT_TRUE(q.scene.name.empty());
  // The default camera looks at the custom scene's centre.
  EXPECT_NE(q.camera.position, q.camera.target);
}

TEST(RequestParser, ACustomSceneWithoutCameraFarIsSeenWhole) {
  // A 200 x 200 floor: the default camera stands 2.8 radii away, beyond the
  // fixed far of 100, so far must reach the floor's far side.
  const RenderRequest big = parse_ok(R"({"scene": {"objects": [
      {"type": "plane", "center": [0, 0, 0], "size": [200, 200]},
      {"type": "box", "center": [0, 0.5, 0], "size": [1, 1, 1]}]}})");
  double farthest = 0.0;
  for (double x : {-100.0, 100.0})
    for (double z : {-100.0, 100.0}) farthest = std::max(farthest, glm::length(big.camera.position - glm::dvec3(x, 0, z)));
  EXPECT_GT(big.camera.far_plane, farthest);
  // The same from a camera the client placed, as long as it left far out.
  const RenderRequest placed = parse_ok(R"({"scene": {"objects": [{"type": "plane", "size": [200, 200]}]},
      "camera": {"position": [0, 10, 150], "target": [0, 0, 0]}})");
  EXPECT_GT(placed.camera.far_plane, glm::length(glm::dvec3(100, -10, -250)));
  // A far the client gave is kept, and a small scene keeps the default 100.
  EXPECT_DOUBLE_EQ(parse_ok(R"({"scene": {"objects": [{"type": "plane", "size": [200, 200]}]},
      "camera": {"far": 50}})").camera.far_plane, 50.0);
  EXPECT_DOUBLE_EQ(parse_ok(R"({"scene": {"objects": [{"type": "box"}]}})").camera.far_plane, 100.0);
  // Built-in scenes keep their defaults: three-cubes' floor fits in 100
  // from its own camera; its objects posted back as a custom scene (whose
  // default camera stands farther off) are seen whole too.
  EXPECT_DOUBLE_EQ(parse_ok(R"({"scene": "three-cubes"})").camera.far_plane, 100.0);
}

// --- Mesh objects --------------------------------------------------------

const char* const kBoxId = "sha256:0b0x";

ModelLookup box_lookup() {
  return test::lookup_of({{kBoxId, test::box_model({0.5f, 0.5f, 0.5f})}}, {{"crate", kBoxId}});
}

ParsedRequest parse_with_box(const std::string& objects) {
  return parse_render_request(R"({"scene": {"objects": [)" + objects + "]}}", Route::Render, box_lookup());
}

TEST(RequestParser, MeshObjectsNameTheirModelByIdOrNameAndMixWithPrimitives) {
  const ParsedRequest p = parse_with_box(R"(
      {"type": "plane"},
      {"type": "mesh", "model": "sha256:0b0x", "position": [1, 2, 3], "rotation_deg": [90, 30, -10], "scale": 2},
      {"type": "mesh", "model": "crate", "scale": [1, 2, 3], "color": [0.1, 0.2, 0.3]})");
  ASSERT_TRUE(p.ok()) << p.error.field << ": " << p.error.message;
  const Scene& scene = p.request->scene;
  ASSERT_EQ(scene.objects.size(), 3u);
  const SceneObject& a = scene.objects[1];
  const SceneObject& b = scene.objects[2];
  EXPECT_EQ(a.type, SceneObject::Type::Mesh);
  EXPECT_EQ(a.model_id, kBoxId);
  EXPECT_EQ(b.model_id, kBoxId) << "a name resolves to the model's id";
  EXPECT_EQ(a.model, b.model) << "instances share one model";
  EXPECT_EQ(a.center, glm::dvec3(1, 2, 3));
  EXPECT_EQ(a.rotation_deg, glm::dvec3(90, 30, -10));
  EXPECT_EQ(a.mesh_scale, glm::dvec3(2.0));
  EXPECT_FALSE(a.mesh_color_override);
  EXPECT_EQ(b.center, glm::dvec3(0.0));
  EXPECT_EQ(b.rotation_deg, glm::dvec3(0.0));
  EXPECT_EQ(b.mesh_scale, glm::dvec3(1, 2, 3));
  EXPECT_TRUE(b.mesh_color_override);
  EXPECT_EQ(b.color, glm::dvec3(0.1, 0.2, 0.3));
}

TEST(RequestParser, AMeshWithoutAModelLookupOrWithAnUnknownModelSaysHowToUploadOne) {
  for (const ParsedRequest& p :
       {parse_render_request(R"({"scene": {"objects": [{"type": "mesh", "model": "sha256:0b0x"}]}})"),
        parse_with_box(R"({"type": "box"}, {"type": "mesh", "model": "kettle"})")}) {
    ASSERT_FALSE(p.ok());
    EXPECT_NE(p.error.message.find("POST /api/models"), std::string::npos) << p.error.message;
    EXPECT_NE(p.error.message.find("unknown model"), std::string::npos) << p.error.message;
  }
  EXPECT_EQ(parse_render_request(R"({"scene": {"objects": [{"type": "mesh", "model": "sha256:0b0x"}]}})").error.field,
            "scene.objects[0].model");
  EXPECT_EQ(parse_with_box(R"({"type": "box"}, {"type": "mesh", "model": "kettle"})").error.field,
            "scene.objects[1].model");
  // The message lists the built-in models too.
  EXPECT_NE(parse_with_box(R"({"type": "mesh", "model": "kettle"})").error.message.find("\"torus-knot\""),
            std::string::npos);
}

TEST(RequestParser, BuiltInModelsAreFoundWithoutAStoreAndAStoresOwnModelOfTheNameWins) {
  const ParsedRequest p =
      parse_render_request(R"({"scene": {"objects": [{"type": "mesh", "model": "teapot", "scale": 0.5}]}})");
  ASSERT_TRUE(p.ok()) << p.error.field << ": " << p.error.message;
  EXPECT_EQ(p.request->scene.objects[0].model, find_builtin_model("teapot")->model);
  EXPECT_EQ(p.request->scene.objects[0].model_id, find_builtin_model("teapot")->id);
  const ParsedRequest own = parse_render_request(R"({"scene": {"objects": [{"type": "mesh", "model": "teapot"}]}})",
                                                 Route::Render,
                                                 test::lookup_of({{kBoxId, test::box_model({1, 1, 1})}}, {{"teapot", kBoxId}}));
  ASSERT_TRUE(own.ok());
  EXPECT_EQ(own.request->scene.objects[0].model_id, kBoxId);
}

TEST(RequestParser, TheTeapotAndTorusKnotScenesHoldTheirBuiltInModels) {
  for (const char* name : {"teapot", "torus-knot"}) {
    const RenderRequest q = parse_ok(std::string(R"({"scene": ")") + name + R"("})");
    ASSERT_EQ(q.scene.objects.size(), 2u);
    EXPECT_EQ(q.scene.objects[1].type, SceneObject::Type::Mesh);
    EXPECT_EQ(q.scene.objects[1].model, find_builtin_model(name)->model);
  }
}

TEST(RequestParser, BadMeshFieldsAreRejectedByName) {
  const std::pair<const char*, const char*> cases[] = {
      {R"({"type": "mesh"})", "scene.objects[0].model"},
      {R"({"type": "mesh", "model": 7})", "scene.objects[0].model"},
      {R"({"type": "mesh", "model": "crate", "scale": 0})", "scene.objects[0].scale"},
      {R"({"type": "mesh", "model": "crate", "scale": -1})", "scene.objects[0].scale"},
      {R"({"type": "mesh", "model": "crate", "scale": 2e6})", "scene.objects[0].scale"},
      {R"({"type": "mesh", "model": "crate", "scale": [1, 0, 1]})", "scene.objects[0].scale[1]"},
      {R"({"type": "mesh", "model": "crate", "scale": [1, 1]})", "scene.objects[0].scale"},
      {R"({"type": "mesh", "model": "crate", "scale": "big"})", "scene.objects[0].scale"},
      {R"({"type": "mesh", "model": "crate", "position": [0, 2e6, 0]})", "scene.objects[0].position[1]"},
      {R"({"type": "mesh", "model": "crate", "rotation_deg": [0, 40000, 0]})", "scene.objects[0].rotation_deg[1]"},
      {R"({"type": "mesh", "model": "crate", "rotation_deg": 30})", "scene.objects[0].rotation_deg"},
      {R"({"type": "mesh", "model": "crate", "color": [2, 0, 0]})", "scene.objects[0].color[0]"},
      {R"({"type": "mesh", "model": "crate", "center": [0, 0, 0]})", "scene.objects[0].center"},
      // Each number within its range, but the placed model's corner is not:
      // 1e6 - 1 + 0.5 * 4 > 1e6.
      {R"({"type": "mesh", "model": "crate", "position": [999999, 0, 0], "scale": 4})", "scene.objects[0]"},
  };
  for (const auto& [object, field] : cases) {
    const ParsedRequest p = parse_with_box(object);
    ASSERT_FALSE(p.ok()) << object;
    EXPECT_EQ(p.error.field, field) << object << " -> " << p.error.message;
  }
  // At the limit exactly, it is accepted: 1e6 - 2 + 0.5 * 4 = 1e6.
  EXPECT_TRUE(parse_with_box(R"({"type": "mesh", "model": "crate", "position": [999998, 0, 0], "scale": 4})").ok());
}

TEST(RequestParser, AMeshsBoundsShapeTheDefaultView) {
  const ParsedRequest near_origin = parse_with_box(R"({"type": "mesh", "model": "crate"})");
  const ParsedRequest far_away = parse_with_box(R"({"type": "mesh", "model": "crate", "position": [100, 0, 0]})");
  ASSERT_TRUE(near_origin.ok() && far_away.ok());
  EXPECT_EQ(near_origin.request->camera.target, glm::dvec3(0.0));
  EXPECT_EQ(far_away.request->camera.target, glm::dvec3(100, 0, 0));
}

TEST(RequestParser, AreaLightWithoutFilterUsesPcss) {
  EXPECT_EQ(parse_ok(R"({"light": {"size": 2}})").shadow.filter, ShadowFilter::Pcss);
}

TEST(RequestParser, ThousandObjectsAreAccepted) {
  std::string body = R"({"scene":{"objects":[)";
  for (int i = 0; i < 1000; ++i) body += std::string(i ? "," : "") + R"({"type":"sphere","radius":0.1})";
  body += "]}}";
  EXPECT_EQ(parse_ok(body).scene.objects.size(), 1000u);
}

struct BadInput {
  const char* body;
  const char* field;
};

class RequestParserRejects : public testing::TestWithParam<BadInput> {};

TEST_P(RequestParserRejects, NamingTheField) {
  const BadInput& bad = GetParam();
  ParsedRequest p = parse_render_request(bad.body);
  ASSERT_FALSE(p.ok()) << bad.body;
  EXPECT_EQ(p.error.field, bad.field) << bad.body << " -> " << p.error.message;
  EXPECT_FALSE(p.error.message.empty());
}

INSTANTIATE_TEST_SUITE_P(
    BadBodies, RequestParserRejects,
    testing::Values(
        // Malformed JSON: the field where it broke.
        BadInput{"{", ""}, BadInput{"[1,2", "[2]"}, BadInput{R"({"width": })", "width"},
        BadInput{R"({"width": 960,})", ""}, BadInput{"nonsense", ""}, BadInput{R"({"width": 960} trailing)", ""},
        // Non-finite numbers written as numbers are not JSON at all.
        BadInput{R"({"width": NaN})", "width"}, BadInput{R"({"light": {"ambient": Infinity}})", "light.ambient"},
        BadInput{R"({"camera": {"fov_y_deg": -Infinity}})", "camera.fov_y_deg"},
        BadInput{R"({"time": 1e400})", "time"}, BadInput{R"({"light": {"color": [1, 1e999, 1]}})", "light.color[1]"},
        BadInput{"{\"scene\": \"\xff\"}", "scene"},
        BadInput{R"({"width": 960, "width": 961})", "width"},
        // Not an object.
        BadInput{"[]", ""}, BadInput{"42", ""}, BadInput{"null", ""},
        // Wrong types, strings where numbers belong.
        BadInput{R"({"width": "960"})", "width"}, BadInput{R"({"width": true})", "width"},
        BadInput{R"({"width": null})", "width"}, BadInput{R"({"time": "NaN"})", "time"},
        BadInput{R"({"light": {"ambient": "0.3"}})", "light.ambient"},
        BadInput{R"({"light": {"position": [1, "2", 3]}})", "light.position[1]"},
        BadInput{R"({"light": {"position": [1, 2]}})", "light.position"},
        BadInput{R"({"light": "bright"})", "light"}, BadInput{R"({"shadow": {"enabled": 1}})", "shadow.enabled"},
        BadInput{R"({"scene": 7})", "scene"},
        // Unknown fields, at every level.
        BadInput{R"({"colour": "red"})", "colour"}, BadInput{R"({"light": {"colour": [1,1,1]}})", "light.colour"},
        BadInput{R"({"shadow": {"bias": {"constant": 0.1, "scale": 2}}})", "shadow.bias.scale"},
        BadInput{R"({"scene": {"objects": [{"type": "box", "radius": 1}]}})", "scene.objects[0].radius"},
        BadInput{R"({"scene": {"objects": [], "lights": []}})", "scene.lights"},
        // Out of range.
        BadInput{R"({"width": 15})", "width"}, BadInput{R"({"height": 4097})", "height"},
        BadInput{R"({"width": 100.5})", "width"}, BadInput{R"({"camera": {"fov_y_deg": 180}})", "camera.fov_y_deg"},
        BadInput{R"({"camera": {"fov_y_deg": 0}})", "camera.fov_y_deg"},
        // Narrower than RequestLimits::kMinFovDeg the projection leaves
        // float range and the frame would come back empty.
        BadInput{R"({"camera": {"fov_y_deg": 1e-38}})", "camera.fov_y_deg"},
        BadInput{R"({"camera": {"fov_y_deg": 0.0009}})", "camera.fov_y_deg"},
        BadInput{R"({"light": {"fov_y_deg": 1e-20}})", "light.fov_y_deg"},
        BadInput{R"({"light": {"fov_y_deg": 450}})", "light.fov_y_deg"},
        BadInput{R"({"camera": {"near": 0}})", "camera.near"}, BadInput{R"({"camera": {"near": 5, "far": 2}})", "camera.far"},
        BadInput{R"({"light": {"color": [1, 1.5, 1]}})", "light.color[1]"},
        BadInput{R"({"light": {"color": [-0.1, 1, 1]}})", "light.color[0]"},
        BadInput{R"({"light": {"color": "#12345"}})", "light.color"}, BadInput{R"({"light": {"color": "#gg0000"}})", "light.color"},
        BadInput{R"({"light": {"ambient": 1.5}})", "light.ambient"}, BadInput{R"({"light": {"size": -1}})", "light.size"},
        // An orthographic light's size is an angle: at most 90 degrees (a perspective one's is a radius).
        BadInput{R"({"light": {"size": 90.001}})", "light.size"},
        BadInput{R"({"shadow": {"map_size": 63}})", "shadow.map_size"}, BadInput{R"({"shadow": {"map_size": 8193}})", "shadow.map_size"},
        BadInput{R"({"shadow": {"pcf_radius": 9}})", "shadow.pcf_radius"}, BadInput{R"({"shadow": {"pcf_radius": -1}})", "shadow.pcf_radius"},
        BadInput{R"({"shadow": {"ortho_half_size": 0}})", "shadow.ortho_half_size"},
        BadInput{R"({"shadow": {"fit": "fixed", "near": 5, "far": 5}})", "shadow.far"},
        BadInput{R"({"shadow": {"fit": "fixed", "near": 0}, "light": {"projection": "perspective"}})", "shadow.near"},
        BadInput{R"({"scene": {"objects": [{"type": "box", "size": [1, 0, 1]}]}})", "scene.objects[0].size[1]"},
        BadInput{R"({"scene": {"objects": [{"type": "sphere", "radius": -2}]}})", "scene.objects[0].radius"},
        BadInput{R"({"scene": {"objects": [{"type": "plane", "size": [1, 2, 3]}]}})", "scene.objects[0].size"},
        BadInput{R"({"camera": {"position": [1e7, 0, 0]}})", "camera.position[0]"},
        // Bad choices.
        BadInput{R"({"output": "colour"})", "output"}, BadInput{R"({"light": {"projection": "ortho"}})", "light.projection"},
        BadInput{R"({"shadow": {"filter": "vsm"}})", "shadow.filter"}, BadInput{R"({"shadow": {"cull": "both"}})", "shadow.cull"},
        BadInput{R"({"shadow": {"fit": "camera"}})", "shadow.fit"}, BadInput{R"({"shadow": {"bias": "none"}})", "shadow.bias"},
        BadInput{R"({"scene": {"objects": [{"type": "cone"}]}})", "scene.objects[0].type"},
        BadInput{R"({"scene": {"objects": [{"center": [0,0,0]}]}})", "scene.objects[0].type"},
        BadInput{R"({"scene": {}})", "scene.objects"},
        // Unknown scene names.
        BadInput{R"({"scene": "two-cubes"})", "scene"},
        // Degenerate geometry.
        BadInput{R"({"camera": {"position": [1, 2, 3], "target": [1, 2, 3]}})", "camera.position"},
        BadInput{R"({"light": {"position": [0, 0, 0], "target": [0, 0, 0]}})", "light.position"},
        BadInput{R"({"camera": {"up": [0, 0, 0]}})", "camera.up"},
        // Contradictions.
        BadInput{R"({"light": {"size": 1}, "shadow": {"filter": "pcf"}})", "shadow.filter"},
        BadInput{R"({"shadow": {"cascades": 5}})", "shadow.cascades"}, BadInput{R"({"shadow": {"cascades": 0}})", "shadow.cascades"},
        BadInput{R"({"shadow": {"cascades": "many"}})", "shadow.cascades"},
        BadInput{R"({"shadow": {"cascades": 2, "fit": "fixed"}})", "shadow.cascades"},
        BadInput{R"({"shadow": {"cascades": 3}, "light": {"projection": "perspective"}})", "shadow.cascades"},
        // The depth output's bits per sample: 8 or 16, nothing between, no string.
        BadInput{R"({"output": "depth", "depth_bits": 12})", "depth_bits"},
        BadInput{R"({"output": "depth", "depth_bits": "16"})", "depth_bits"},
        BadInput{R"({"output": "depth", "depth_bits": 16.5})", "depth_bits"},
        BadInput{R"({"output": "depth", "depth_bits": -1})", "depth_bits"},
        BadInput{R"({"depth_bits": 32})", "depth_bits"},
        // A sun light: place and instant required and in range, an RFC 3339
        // instant, and never a point light.
        BadInput{R"({"light": {"sun": {"latitude": 91, "longitude": 0, "utc": "2026-12-21T14:00:00Z"}}})", "light.sun.latitude"},
        BadInput{R"({"light": {"sun": {"latitude": 0, "longitude": -180.5, "utc": "2026-12-21T14:00:00Z"}}})", "light.sun.longitude"},
        BadInput{R"({"light": {"sun": {"longitude": 0, "utc": "2026-12-21T14:00:00Z"}}})", "light.sun.latitude"},
        BadInput{R"({"light": {"sun": {"latitude": 0, "utc": "2026-12-21T14:00:00Z"}}})", "light.sun.longitude"},
        BadInput{R"({"light": {"sun": {"latitude": 0, "longitude": 0}}})", "light.sun.utc"},
        BadInput{R"({"light": {"sun": {"latitude": 0, "longitude": 0, "utc": "2026-13-01T00:00:00Z"}}})", "light.sun.utc"},
        BadInput{R"({"light": {"sun": {"latitude": 0, "longitude": 0, "utc": "2026-12-21 14:00"}}})", "light.sun.utc"},
        BadInput{R"({"light": {"sun": {"latitude": 0, "longitude": 0, "utc": 1766325600}}})", "light.sun.utc"},
        BadInput{R"({"light": {"sun": {"latitude": 0, "longitude": 0, "utc": "6000-01-01T00:00:00Z"}}})", "light.sun.utc"},
        BadInput{R"({"light": {"sun": {"latitude": 0, "longitude": 0, "utc": "2026-12-21T14:00:00Z", "north_deg": 400}}})", "light.sun.north_deg"},
        BadInput{R"({"light": {"sun": {"latitude": 0, "longitude": 0, "utc": "2026-12-21T14:00:00Z", "elevation": 3}}})", "light.sun.elevation"},
        BadInput{R"({"light": {"sun": {"latitude": "48.85", "longitude": 0, "utc": "2026-12-21T14:00:00Z"}}})", "light.sun.latitude"},
        BadInput{R"({"light": {"sun": "Paris"}})", "light.sun"},
        BadInput{R"({"light": {"projection": "perspective", "sun": {"latitude": 0, "longitude": 0, "utc": "2026-12-21T14:00:00Z"}}})", "light.projection"}));

TEST(RequestParser, ASunLightReadsItsPlaceAndInstantAndReportsWhatItDoesNotUse) {
  const ParsedRequest p = parse_render_request(
      R"({"light": {"position": [1, 2, 3], "orbit_deg_per_s": 5, "sun": {"latitude": -33.87, "longitude": 151.21,
          "utc": "2026-06-21T03:00:00+01:00", "north_deg": -30}}})");
  ASSERT_TRUE(p.ok()) << p.error.field << ": " << p.error.message;
  const SunClock& sun = p.request->light.sun.value();
  EXPECT_DOUBLE_EQ(sun.latitude_deg, -33.87);
  EXPECT_DOUBLE_EQ(sun.longitude_deg, 151.21);
  EXPECT_DOUBLE_EQ(sun.utc_unix_s, 1782007200.0);  // 2026-06-21T02:00:00Z
  EXPECT_DOUBLE_EQ(sun.north_deg, -30.0);
  // The sun places the light: orbiting is off, and with the default fit only
  // the direction matters, which the sun gives.
  EXPECT_EQ(p.unused_fields, (std::vector<std::string>{"light.orbit_deg_per_s", "light.position"}));
  // Fit "fixed" measures near and far from the light: the position's
  // distance from the target is used.
  const ParsedRequest fixed = parse_render_request(
      R"({"shadow": {"fit": "fixed"}, "light": {"position": [1, 2, 3], "sun": {"latitude": 0, "longitude": 0, "utc": "2000-01-01T12:00:00Z"}}})");
  ASSERT_TRUE(fixed.ok());
  EXPECT_TRUE(fixed.unused_fields.empty()) << fixed.unused_fields.front();
  EXPECT_FALSE(parse_ok("{}").light.sun.has_value());
  EXPECT_TRUE(parse_ok(R"({"light": {"sun": {"latitude": 90, "longitude": -180, "utc": "0001-01-01T00:00:00Z"}}})").light.sun);
  EXPECT_TRUE(parse_ok(R"({"light": {"sun": {"latitude": -90, "longitude": 180, "utc": "5000-12-31T23:59:59Z"}}})").light.sun);
}

TEST(RequestParser, ABadSunInstantSaysWhatIsWrongWithIt) {
  const ParsedRequest month = parse_render_request(
      R"({"light": {"sun": {"latitude": 0, "longitude": 0, "utc": "2026-13-01T00:00:00Z"}}})");
  ASSERT_FALSE(month.ok());
  EXPECT_NE(month.error.message.find("\"2026-13-01T00:00:00Z\" is not an RFC 3339 date-time: "), std::string::npos)
      << month.error.message;
  EXPECT_NE(month.error.message.find("13"), std::string::npos) << month.error.message;
  const ParsedRequest late = parse_render_request(
      R"({"light": {"sun": {"latitude": 0, "longitude": 0, "utc": "5001-01-01T00:00:00Z"}}})");
  ASSERT_FALSE(late.ok());
  EXPECT_EQ(late.error.message, "years 0001 to 5000 (UTC) are supported");
  // The offset counts: 00:00 at +01:00 on the first day of year 1 is still year 0 in UTC.
  const ParsedRequest early = parse_render_request(
      R"({"light": {"sun": {"latitude": 0, "longitude": 0, "utc": "0001-01-01T00:00:00+01:00"}}})");
  ASSERT_FALSE(early.ok());
  EXPECT_EQ(early.error.field, "light.sun.utc");
  EXPECT_TRUE(parse_render_request(R"({"light": {"sun": {"latitude": 0, "longitude": 0, "utc": "0001-01-01T00:00:00-01:00"}}})").ok());
}

// Issue 29, finding 9: utc alone was checked, so 5000-12-31 + 1e9 s (year
// 5032) was rendered.
TEST(RequestParser, TheSunsClockUtcPlusTimeStaysInTheSupportedYears) {
  const std::string last_day = R"("light": {"sun": {"latitude": 0, "longitude": 0, "utc": "5000-12-31T00:00:00Z"}})";
  const ParsedRequest past = parse_render_request("{" + last_day + R"(, "time": 1e9})");
  ASSERT_FALSE(past.ok());
  EXPECT_EQ(past.error.field, "time");
  EXPECT_NE(past.error.message.find("light.sun.utc + time must lie in years 0001 to 5000 (UTC)"), std::string::npos)
      << past.error.message;
  EXPECT_TRUE(parse_render_request("{" + last_day + R"(, "time": 86399})").ok());
  EXPECT_FALSE(parse_render_request("{" + last_day + R"(, "time": 86400})").ok());
  const std::string first_day = R"("light": {"sun": {"latitude": 0, "longitude": 0, "utc": "0001-01-01T12:00:00Z"}})";
  EXPECT_TRUE(parse_render_request("{" + first_day + R"(, "time": -43200})").ok());
  EXPECT_FALSE(parse_render_request("{" + first_day + R"(, "time": -43201})").ok());
  // Without a sun, time keeps its own range only.
  EXPECT_TRUE(parse_render_request(R"({"time": 1e9})").ok());
}

TEST(RequestParser, ASunBelowTheHorizonReportsTheShadowSettingsUnusedAsShadowsOffWould) {
  const std::string night = R"("sun": {"latitude": 48.85, "longitude": 2.35, "utc": "2026-12-21T22:00:00Z"})";
  const std::string settings = R"("shadow": {"enabled": true, "map_size": 512, "filter": "pcss", "cull": "back", "cascades": 2})";
  ParsedRequest p = parse_render_request("{" + settings + R"(, "light": {"size": 2, )" + night + "}}");
  ASSERT_TRUE(p.ok()) << p.error.message;
  EXPECT_EQ(p.unused_fields, (std::vector<std::string>{"light.size", "shadow.cascades", "shadow.cull", "shadow.enabled",
                                                      "shadow.filter", "shadow.map_size"}));
  // By day the same body uses them all.
  const std::string day = R"("sun": {"latitude": 48.85, "longitude": 2.35, "utc": "2026-12-21T12:00:00Z"})";
  p = parse_render_request("{" + settings + R"(, "light": {"size": 2, )" + day + "}}");
  ASSERT_TRUE(p.ok()) << p.error.message;
  EXPECT_TRUE(p.unused_fields.empty()) << p.unused_fields.front();
  // The depth map is drawn whatever the sun's height: its settings count.
  p = parse_render_request("{" + settings + R"(, "output": "depth", "light": {)" + night + "}}");
  ASSERT_TRUE(p.ok()) << p.error.message;
  EXPECT_EQ(p.unused_fields, std::vector<std::string>{"shadow.filter"});
  // With fit "fixed" and no shadow pass, not even the position's distance counts.
  p = parse_render_request(R"({"shadow": {"fit": "fixed", "enabled": false}, "light": {"position": [1, 2, 3], )" + day + "}}");
  ASSERT_TRUE(p.ok()) << p.error.message;
  EXPECT_EQ(p.unused_fields, (std::vector<std::string>{"light.position", "shadow.fit"}));
}

TEST(RequestParser, CascadesAreAutoOrACount) {
  EXPECT_EQ(parse_ok(R"({"shadow": {"cascades": "auto"}})").shadow.cascades, 0);
  EXPECT_EQ(parse_ok(R"({"shadow": {"cascades": 3}})").shadow.cascades, 3);
  EXPECT_EQ(parse_ok("{}").shadow.cascades, 0);
  // One cascade with a fixed fit is just the fixed map: accepted, and named
  // as not changing anything.
  const ParsedRequest p = parse_render_request(R"({"shadow": {"cascades": 1, "fit": "fixed"}})");
  ASSERT_TRUE(p.ok());
  EXPECT_EQ(p.unused_fields, std::vector<std::string>{"shadow.cascades"});
}

TEST(RequestParser, TheCameraShapesTheDepthMapOfAFittedDirectionalLight) {
  const char* body = R"({"output": "depth", "camera": {"fov_y_deg": 30}, "LIGHT"})";
  std::string ortho = body, perspective = body;
  ortho.replace(ortho.find("\"LIGHT\""), 7, R"("light": {"projection": "orthographic"})");
  perspective.replace(perspective.find("\"LIGHT\""), 7, R"("light": {"projection": "perspective"})");
  EXPECT_TRUE(parse_render_request(ortho).unused_fields.empty());
  EXPECT_EQ(parse_render_request(perspective).unused_fields, (std::vector<std::string>{"camera", "camera.fov_y_deg"}));
}

TEST(RequestParser, TheDepthRouteDrawsTheDepthMapAndJudgesUnusedFieldsByIt) {
  // light.ambient shapes the colour frame, not the depth map: on /api/depth it is reported as unused.
  const ParsedRequest p = parse_render_request(R"({"light": {"ambient": 0.5}})", Route::Depth);
  ASSERT_TRUE(p.ok()) << p.error.field << ": " << p.error.message;
  EXPECT_EQ(p.request->output, Output::Depth);
  EXPECT_EQ(p.unused_fields, std::vector<std::string>{"light.ambient"});
  EXPECT_TRUE(parse_render_request(R"({"light": {"ambient": 0.5}})").unused_fields.empty());
}

TEST(RequestParser, TheDepthRouteTakesAnyOutputAndNamesAnOtherThanDepthUnused) {
  // The same body as /api/render (docs/api.md): every output it takes is
  // taken, the depth map is drawn, and an output other than "depth" has had
  // no effect, which Umbra-Unused-Fields says (nothing is silently ignored).
  const ParsedRequest depth = parse_render_request(R"({"output": "depth"})", Route::Depth);
  ASSERT_TRUE(depth.ok());
  EXPECT_EQ(depth.request->output, Output::Depth);
  EXPECT_TRUE(depth.unused_fields.empty());
  for (const char* output : {"color", "shadow", "exact", "error"}) {
    const std::string body = std::string(R"({"output": ")") + output + R"(", "light": {"ambient": 0.5}})";
    const ParsedRequest q = parse_render_request(body, Route::Depth);
    ASSERT_TRUE(q.ok()) << body << ": " << q.error.field << ": " << q.error.message;
    EXPECT_EQ(q.request->output, Output::Depth) << body;
    EXPECT_EQ(q.unused_fields, (std::vector<std::string>{"light.ambient", "output"})) << body;
  }
  // A value /api/render refuses is refused here too, naming the field.
  const ParsedRequest bad = parse_render_request(R"({"output": "normals"})", Route::Depth);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error.field, "output");
}

TEST(RequestParser, DepthBitsIs8Or16AndReportedUnusedWithoutTheDepthOutput) {
  EXPECT_EQ(parse_ok(R"({"output": "depth"})").depth_bits, 8);
  EXPECT_EQ(parse_ok(R"({"output": "depth", "depth_bits": 8})").depth_bits, 8);
  const ParsedRequest depth = parse_render_request(R"({"output": "depth", "depth_bits": 16})");
  ASSERT_TRUE(depth.ok()) << depth.error.field << ": " << depth.error.message;
  EXPECT_EQ(depth.request->depth_bits, 16);
  EXPECT_TRUE(depth.unused_fields.empty());
  // /api/depth draws the depth map though the body names no output.
  EXPECT_TRUE(parse_render_request(R"({"depth_bits": 16})", Route::Depth).unused_fields.empty());
  // Refused for its value, not as an unknown field (BadBodies checks the field named for each bad value).
  for (const char* bad : {"12", "\"16\"", "16.5", "-1"}) {
    const ParsedRequest p = parse_render_request(std::string(R"({"output": "depth", "depth_bits": )") + bad + "}");
    ASSERT_FALSE(p.ok()) << bad;
    EXPECT_EQ(p.error.field, "depth_bits") << bad;
    EXPECT_EQ(p.error.message.find("unknown"), std::string::npos) << bad << " -> " << p.error.message;
  }
  // Accepted with any other output (a client may keep one body for every
  // view), but named as having no effect.
  for (const char* output : {"color", "shadow", "exact", "error"}) {
    const ParsedRequest p =
        parse_render_request(std::string(R"({"depth_bits": 16, "output": ")") + output + "\"}");
    ASSERT_TRUE(p.ok()) << output;
    EXPECT_EQ(p.unused_fields, std::vector<std::string>{"depth_bits"}) << output;
  }
}

TEST(RequestParser, RejectsMoreThanAThousandObjects) {
  std::string body = R"({"scene":{"objects":[)";
  for (int i = 0; i < 1001; ++i) body += std::string(i ? "," : "") + R"({"type":"sphere"})";
  body += "]}}";
  ParsedRequest p = parse_render_request(body);
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(p.error.field, "scene.objects");
}

TEST(RequestParser, RejectsDeepNestingWithoutRecursing) {
  const std::string body = std::string(10000, '[') + std::string(10000, ']');
  ParsedRequest p = parse_render_request(body);
  ASSERT_FALSE(p.ok());
  EXPECT_NE(p.error.message.find("nested"), std::string::npos);
  const std::string in_field = R"({"light": )" + std::string(10000, '[') + std::string(10000, ']') + "}";
  ParsedRequest q = parse_render_request(in_field);
  ASSERT_FALSE(q.ok());
  EXPECT_EQ(q.error.field.rfind("light", 0), 0u) << q.error.field;
}

TEST(RequestParser, InvalidUtf8IsRejectedWithAPrintableMessage) {
  // Regression: the message once quoted the bad byte, and turning it into
  // the JSON error then threw (a 500).
  for (std::string body : {std::string("{\"scene\": \"\xff\xfe\"}"), std::string("{\"w\xff\": 1}"),
                           std::string("{\"scene\": \"\xc0\xaf\"}"), std::string("{\"scene\": \"a\x01\"}")}) {
    const ParsedRequest p = parse_render_request(body);
    ASSERT_FALSE(p.ok()) << body;
    for (unsigned char c : p.error.message) EXPECT_TRUE(c >= 0x20 && c < 0x7f) << p.error.message;
    for (unsigned char c : p.error.field) EXPECT_TRUE(c >= 0x20 && c < 0x7f) << p.error.field;
  }
}

}  // namespace
}  // namespace umbra

namespace umbra {
namespace {

TEST(RequestParser, TheNarrowestFieldOfViewIsAccepted) {
  const ParsedRequest p = parse_render_request(R"({"camera": {"fov_y_deg": 0.001}, "light": {"fov_y_deg": 0.001}})");
  ASSERT_TRUE(p.ok()) << p.error.field << ": " << p.error.message;
  EXPECT_DOUBLE_EQ(p.request->camera.fov_y_deg, RequestLimits::kMinFovDeg);
}

TEST(RequestParser, AHugeStringOrKeyIsQuotedBackCutShort) {
  const std::string huge(1 << 20, 'x');
  for (const std::string& body : {R"({"output": ")" + huge + R"("})", R"({"light": {"color": ")" + huge + R"("}})",
                                  R"({"scene": ")" + huge + R"("})", R"({")" + huge + R"(": 1})"}) {
    const ParsedRequest p = parse_render_request(body);
    ASSERT_FALSE(p.ok());
    EXPECT_LT(p.error.message.size() + p.error.field.size(), 1200u) << p.error.message.substr(0, 200);
    // It says how much was cut, and still quotes the beginning.
    EXPECT_NE((p.error.message + p.error.field).find("1048576 bytes"), std::string::npos)
        << p.error.message.substr(0, 300) << " | " << p.error.field.substr(0, 300);
    EXPECT_NE((p.error.message + p.error.field).find("xxxxxxxx"), std::string::npos);
  }
}

}  // namespace
}  // namespace umbra

namespace umbra {
namespace {

// Filter "exact" (docs/certified-shadows.md): hard shadows only, and a
// point light's views fitted to the scene; it reads no bias, radius or cull.
TEST(RequestParser, FilterExactIsForALightOfNoSizeAndAFittedPointLight) {
  ParsedRequest ok = parse_render_request(R"({"shadow": {"filter": "exact", "pcf_radius": 2, "cull": "back"}})");
  ASSERT_TRUE(ok.ok()) << ok.error.message;
  EXPECT_EQ(ok.request->shadow.filter, ShadowFilter::Exact);
  for (const char* unused : {"shadow.pcf_radius", "shadow.cull"})
    EXPECT_NE(std::find(ok.unused_fields.begin(), ok.unused_fields.end(), unused), ok.unused_fields.end()) << unused;
  ParsedRequest area = parse_render_request(R"({"light": {"size": 2}, "shadow": {"filter": "exact"}})");
  ASSERT_FALSE(area.ok());
  EXPECT_EQ(area.error.field, "shadow.filter");
  EXPECT_NE(area.error.message.find("light.size 0"), std::string::npos) << area.error.message;
  ParsedRequest fixed = parse_render_request(
      R"({"light": {"projection": "perspective"}, "shadow": {"filter": "exact", "fit": "fixed"}})");
  ASSERT_FALSE(fixed.ok());
  EXPECT_EQ(fixed.error.field, "shadow.fit");
  // An orthographic light with a fixed frustum is certified like any other.
  EXPECT_TRUE(parse_render_request(R"({"shadow": {"filter": "exact", "fit": "fixed"}})").ok());
}

}  // namespace
}  // namespace umbra
