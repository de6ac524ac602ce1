// Animated glTF models (core/model_rig.hpp, the loader's rig): samplers,
// node channels through a hierarchy, skins and morph targets, checked
// against positions worked out by hand, and real files written by others
// (Debian's assimp-testmodels: the glTF tutorial's simple_skin, Khronos'
// AnimatedMorphCube).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

#include "assets/gltf_loader.hpp"
#include "assets/pose_cache.hpp"
#include "core/model.hpp"
#include "core/model_rig.hpp"
#include "gltf_builder.hpp"

namespace umbra {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using test::GltfBuilder;

const fs::path kSamples = "/usr/share/assimp/models/glTF2";

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// A file of Debian's assimp-testmodels, its buffers read from beside it.
LoadResult load_sample(const std::string& name) {
  const fs::path path = kSamples / name;
  EXPECT_TRUE(fs::exists(path)) << "needs Debian's assimp-testmodels: " << path;
  LoadOptions options;
  options.external_folder = path.parent_path().string();
  return load_gltf(read_file(path), options);
}

RigSampler sampler(std::vector<float> times, std::vector<float> values, std::size_t width,
                   RigInterpolation interpolation = RigInterpolation::Linear) {
  RigSampler s;
  s.times = std::move(times);
  s.values = std::move(values);
  s.width = width;
  s.interpolation = interpolation;
  return s;
}

TEST(ModelRig, SamplersInterpolateAsGltfSays) {
  const RigSampler linear = sampler({0, 2}, {0, 0, 0, 4, 2, 0}, 3);
  EXPECT_EQ(sample(linear, 1.0, false), (std::vector<double>{2, 1, 0}));
  EXPECT_EQ(sample(linear, -5.0, false), (std::vector<double>{0, 0, 0}));  // held before the first key
  EXPECT_EQ(sample(linear, 9.0, false), (std::vector<double>{4, 2, 0}));   // and after the last
  const RigSampler step = sampler({0, 1, 2}, {1, 2, 3}, 1, RigInterpolation::Step);
  EXPECT_EQ(sample(step, 0.99, false)[0], 1.0);
  EXPECT_EQ(sample(step, 1.0, false)[0], 2.0);
  // Cubic spline (in-tangent, value, out-tangent a key): with zero tangents
  // the Hermite curve is smoothstep between the values.
  const RigSampler cubic = sampler({0, 1}, {0, 0, 0, 0, 10, 0}, 1, RigInterpolation::CubicSpline);
  EXPECT_NEAR(sample(cubic, 0.5, false)[0], 5.0, 1e-12);
  EXPECT_NEAR(sample(cubic, 0.25, false)[0], 10.0 * (3 * 0.0625 - 2 * 0.015625), 1e-12);
  // With tangents and 2 s between the keys (in-tangent, value, out-tangent
  // each): p(1) = (p0 + p1) / 2 + dt / 8 (out0 - in1) = 2 + (4 + 2) / 4. A
  // tangent not scaled by dt gives 2.75, in and out swapped 1.5.
  const RigSampler tangents = sampler({0, 2}, {7, 1, 4, -2, 3, 9}, 1, RigInterpolation::CubicSpline);
  EXPECT_NEAR(sample(tangents, 1.0, false)[0], 3.5, 1e-12);
  // A rotation: spherical, the shorter way, normalized. From identity to a
  // quarter turn about Y given as -q (the same rotation, the far way round
  // as quaternions): an eighth of a turn, the same way, at 0.5.
  const double h = std::sqrt(0.5);
  const RigSampler rotation = sampler({0, 1}, {0, 0, 0, 1, 0, float(-h), 0, float(-h)}, 4);
  const std::vector<double> q = sample(rotation, 0.5, true);
  EXPECT_NEAR(q[0], 0.0, 1e-7);
  EXPECT_NEAR(q[1], std::sin(glm::radians(22.5)), 1e-7);
  EXPECT_NEAR(q[3], std::cos(glm::radians(22.5)), 1e-7);
}

TEST(ModelRig, AnimationTimeLoopsOrHolds) {
  EXPECT_DOUBLE_EQ(animation_time(2.0, 5.0, 1.0, true), 1.0);
  EXPECT_DOUBLE_EQ(animation_time(2.0, 5.0, 1.0, false), 2.0);
  EXPECT_DOUBLE_EQ(animation_time(2.0, -0.5, 1.0, true), 1.5);
  EXPECT_DOUBLE_EQ(animation_time(2.0, 3.0, 0.5, true), 1.5);
  EXPECT_DOUBLE_EQ(animation_time(2.0, 1.0, -1.0, false), 0.0);
  EXPECT_DOUBLE_EQ(animation_time(0.0, 7.0, 1.0, true), 0.0);
}

TEST(ModelRig, NodeChannelsMoveTheHierarchy) {
  const LoadResult r = load_gltf(test::sliding_cube(), {});
  ASSERT_TRUE(r.ok()) << r.error;
  ASSERT_TRUE(r.model->rig);
  const ModelRig& rig = *r.model->rig;
  ASSERT_EQ(rig.animations.size(), 1u);
  EXPECT_EQ(rig.animations[0].name, "slide");
  EXPECT_DOUBLE_EQ(rig.animations[0].duration_s, 2.0);
  EXPECT_EQ(find_animation(rig, "slide"), std::optional<std::size_t>(0));
  EXPECT_FALSE(find_animation(rig, "walk"));
  // The rest model is where the nodes put it: the child's +1 only.
  EXPECT_NEAR(r.model->bounds.min.x, 0.5, 1e-6);
  EXPECT_NEAR(r.model->bounds.max.x, 1.5, 1e-6);
  // At 1 s the parent has slid 2 and the child turned 45 degrees about its
  // own centre (1 + 2 = 3): the cube's corners reach sqrt(0.5) from it.
  const TriangleModel mid = pose_model(rig, 0, 1.0);
  EXPECT_EQ(mid.triangle_count(), r.model->triangle_count());
  EXPECT_NEAR(mid.bounds.min.x, 3.0 - std::sqrt(0.5), 1e-6);
  EXPECT_NEAR(mid.bounds.max.x, 3.0 + std::sqrt(0.5), 1e-6);
  EXPECT_NEAR(mid.bounds.max.z, std::sqrt(0.5), 1e-6);
  EXPECT_TRUE(mid.closed);
  // Normals turn with the faces: every one still unit length and facing
  // out of the cube's centre.
  for (const ModelPart& part : mid.parts)
    for (std::size_t v = 0; v < part.positions.size(); ++v)
      EXPECT_GT(glm::dot(part.normals[v], part.positions[v] - glm::vec3(3, 0, 0)), 0.0f);
  // At the end: slid 4, a quarter turn (a cube looks the same).
  const TriangleModel end = pose_model(rig, 0, 2.0);
  EXPECT_NEAR(end.bounds.min.x, 4.5, 1e-6);
  EXPECT_NEAR(end.bounds.max.x, 5.5, 1e-6);
  // STEP holds the first key until the second.
  const LoadResult stepped = load_gltf(test::sliding_cube("STEP"), {});
  ASSERT_TRUE(stepped.ok()) << stepped.error;
  EXPECT_NEAR(pose_model(*stepped.model->rig, 0, 1.9).bounds.min.x, 0.5, 1e-6);
  // The rig is counted with the model.
  EXPECT_GT(r.model->bytes(), rig.bytes());
}

// A glb's JSON changed by `change` (its binary chunk kept).
std::string edited(const std::string& glb, const std::function<void(json&)>& change) {
  const std::uint32_t length = *reinterpret_cast<const std::uint32_t*>(glb.data() + 12);
  test::GltfBuilder b;
  b.doc = json::parse(glb.substr(20, length));
  b.doc.erase("buffers");
  b.bin = glb.substr(20 + length + 8);
  change(b.doc);
  return b.glb();
}

TEST(ModelRig, SkinWeightsAreCheckedAndMadeToSumToOne) {
  const double pi = std::acos(-1.0);
  const LoadResult one = load_gltf(test::bending_strip(float(pi / 2)), {});
  const LoadResult two = load_gltf(test::bending_strip(float(pi / 2), 2.0f), {});
  ASSERT_TRUE(one.ok() && two.ok()) << one.error << two.error;
  // Weights summing to 2 would double every vertex; made to sum to 1,
  // the model is the same, at rest and posed.
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(two.model->bounds.max[k], one.model->bounds.max[k], 1e-6);
    EXPECT_NEAR(pose_model(*two.model->rig, 0, 1.0).bounds.min[k], pose_model(*one.model->rig, 0, 1.0).bounds.min[k],
                1e-6);
  }
  const std::string glb = test::bending_strip(float(pi / 2));
  const auto refused = [](const LoadResult& r, const std::string& text) {
    ASSERT_FALSE(r.ok()) << "loaded, expected " << text;
    EXPECT_EQ(r.status, 400) << r.error;
    EXPECT_NE(r.error.find(text), std::string::npos) << r.error;
  };
  const auto attribute = [](json& d, const char* name) -> json& {
    return d["accessors"][std::size_t(d["meshes"][0]["primitives"][0]["attributes"][name])];
  };
  refused(load_gltf(edited(glb, [&](json& d) { attribute(d, "JOINTS_0")["normalized"] = true; }), {}),
          "JOINTS_0: joint indices must not be normalized");
  // The weights read as unsigned shorts (the bytes of floats: whatever
  // they hold, they must say they are normalized).
  refused(load_gltf(edited(glb,
                           [&](json& d) {
                             json& w = attribute(d, "WEIGHTS_0");
                             w["componentType"] = 5123;
                             w["count"] = 6;
                           }),
                    {}),
          "WEIGHTS_0: integer weights must be normalized");
}

TEST(ModelRig, SkinsBendByTheirJoints) {
  const double pi = std::acos(-1.0);
  const LoadResult r = load_gltf(test::bending_strip(float(pi / 2)), {});
  ASSERT_TRUE(r.ok()) << r.error;
  // At rest the strip is where its joints put it, not at its node's x = 100.
  EXPECT_NEAR(r.model->bounds.min.x, -0.5, 1e-6);
  EXPECT_NEAR(r.model->bounds.max.x, 0.5, 1e-6);
  EXPECT_NEAR(r.model->bounds.max.y, 2.0, 1e-6);
  // A quarter turn about Z at the upper joint: the top row, wholly on it,
  // turns about (0, 1, 0) to x = -1, y = 1 +- 0.5; the middle row, half on
  // each joint, lies halfway between its rest place and its turned one.
  const TriangleModel bent = pose_model(*r.model->rig, 0, 1.0);
  std::vector<glm::vec3> all;
  for (const ModelPart& part : bent.parts) all.insert(all.end(), part.positions.begin(), part.positions.end());
  const auto has = [&](glm::vec3 p) {
    for (const glm::vec3& q : all)
      if (glm::length(q - p) < 1e-5f) return true;
    return false;
  };
  EXPECT_TRUE(has({-1.0f, 0.5f, 0.0f}));   // top row, x = -0.5 before
  EXPECT_TRUE(has({-1.0f, 1.5f, 0.0f}));   // top row, x = +0.5 before
  EXPECT_TRUE(has({-0.5f, 0.0f, 0.0f}));   // bottom row: on the root, still
  // Middle (x = -0.5, y = 1): turned it is (0, 0.5); halfway (-0.25, 0.75).
  EXPECT_TRUE(has({-0.25f, 0.75f, 0.0f}));
  EXPECT_NEAR(bent.bounds.max.y, 1.5, 1e-5);
}

// A quad whose target lifts one corner by 2; the weight runs 0 -> 1.
TEST(ModelRig, MorphTargetsAreWeighed) {
  GltfBuilder b;
  const int positions = b.vec3s({{0, 0, 0}, {1, 0, 0}, {1, 0, -1}, {0, 0, -1}});
  const int lift = b.vec3s({{0, 0, 0}, {0, 0, 0}, {0, 2, 0}, {0, 0, 0}});
  b.doc["meshes"] = json::array({{{"primitives", {{{"attributes", {{"POSITION", positions}}},
                                                    {"indices", b.indices_u32({0, 1, 2, 0, 2, 3})},
                                                    {"targets", {{{"POSITION", lift}}}}}}},
                                  {"weights", {0.25}}}});
  const int node = b.node({{"mesh", 0}});
  b.scene({node});
  const int times = b.accessor(b.view(GltfBuilder::bytes_of(std::vector<float>{0, 1})), GltfBuilder::kFloat, 2, "SCALAR");
  const int weights = b.accessor(b.view(GltfBuilder::bytes_of(std::vector<float>{0, 1})), GltfBuilder::kFloat, 2, "SCALAR");
  b.doc["animations"] = json::array({{{"name", "lift"},
                                      {"samplers", {{{"input", times}, {"output", weights}}}},
                                      {"channels", {{{"sampler", 0}, {"target", {{"node", node}, {"path", "weights"}}}}}}}});
  const LoadResult r = load_gltf(b.glb(), {});
  ASSERT_TRUE(r.ok()) << r.error;
  // At rest the mesh's default weight 0.25 applies.
  EXPECT_NEAR(r.model->bounds.max.y, 0.5, 1e-6);
  EXPECT_NEAR(pose_model(*r.model->rig, 0, 0.5).bounds.max.y, 1.0, 1e-6);
  EXPECT_NEAR(pose_model(*r.model->rig, 0, 1.0).bounds.max.y, 2.0, 1e-6);
}

TEST(ModelRig, HostileAnimationsAreRefused) {
  const json base = [] {
    const std::string glb = test::sliding_cube();
    const std::uint32_t length = *reinterpret_cast<const std::uint32_t*>(glb.data() + 12);
    return json::parse(glb.substr(20, length));
  }();
  const std::string glb = test::sliding_cube();
  const std::uint32_t json_length = *reinterpret_cast<const std::uint32_t*>(glb.data() + 12);
  const std::string bin = glb.substr(20 + json_length + 8);
  const auto with = [&](const std::function<void(json&)>& change) {
    GltfBuilder b;
    b.doc = base;
    b.doc.erase("buffers");
    b.bin = bin;
    change(b.doc);
    return load_gltf(b.glb(), {});
  };
  const auto expect = [](const LoadResult& r, int status, const std::string& text) {
    ASSERT_FALSE(r.ok()) << "loaded, expected " << text;
    EXPECT_EQ(r.status, status) << r.error;
    EXPECT_NE(r.error.find(text), std::string::npos) << r.error;
  };
  ASSERT_TRUE(with([](json&) {}).ok());
  expect(with([](json& d) { d["animations"][0]["samplers"][0]["interpolation"] = "BOUNCY"; }), 400,
         "animations[0].samplers[0].interpolation: must be LINEAR, STEP or CUBICSPLINE");
  expect(with([](json& d) { d["animations"][0]["channels"][0]["sampler"] = 7; }), 400, "channels[0].sampler: 7 is out of range");
  expect(with([](json& d) { d["animations"][0]["channels"][0]["target"]["node"] = 99; }), 400, "target.node: 99 is out of range");
  expect(with([](json& d) { d["animations"][0]["channels"][0]["target"]["path"] = "weights"; }), 400, "which has no morph targets");
  expect(with([](json& d) {
           d["nodes"][1]["matrix"] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
         }),
         400, "which has a matrix");
  // Key times that do not increase.
  expect(with([](json& d) {
           d["accessors"].push_back({{"componentType", 5126}, {"count", 2}, {"type", "SCALAR"}});  // zeros
           d["animations"][0]["samplers"][0]["input"] = d["accessors"].size() - 1;
         }),
         400, "key times must increase");
  // A keyframe count over the limit, in an accessor with no data: refused
  // before anything is read.
  expect(with([](json& d) {
           d["accessors"].push_back({{"componentType", 5126}, {"count", 3000000000u}, {"type", "VEC4"}});
           d["animations"][0]["samplers"][1]["output"] = d["accessors"].size() - 1;
         }),
         422, "keyframe numbers");
  // Output of the wrong length for its keys.
  expect(with([](json& d) { d["animations"][0]["samplers"][0]["output"] = d["animations"][0]["samplers"][1]["output"]; }),
         400, "samplers[0].output: type VEC4 where its channel needs VEC3");
  // Key times before 0 (a cube sliding from time -1).
  {
    test::GltfBuilder b;
    std::vector<glm::vec3> positions;
    std::vector<std::uint32_t> indices;
    test::unit_cube(positions, indices);
    const int node = b.node({{"mesh", b.mesh(b.vec3s(positions), b.indices_u32(indices))}});
    b.scene({node});
    const int times = b.accessor(b.view(test::GltfBuilder::bytes_of(std::vector<float>{-1, 1})),
                                 test::GltfBuilder::kFloat, 2, "SCALAR");
    b.doc["animations"] = json::array(
        {{{"samplers", {{{"input", times}, {"output", b.vec3s({{0, 0, 0}, {1, 0, 0}})}}}},
          {"channels", {{{"sampler", 0}, {"target", {{"node", node}, {"path", "translation"}}}}}}}});
    expect(load_gltf(b.glb(), {}), 400, "samplers[0].input: key times must not be negative");
  }
  // A rotation read from VEC3 values.
  expect(with([](json& d) {
           const std::size_t output = d["animations"][0]["samplers"][1]["output"];
           d["accessors"][output]["type"] = "VEC3";
         }),
         400, "samplers[1].output: type VEC3 where its channel needs VEC4");
  // One sampler read as a translation and as a rotation.
  expect(with([](json& d) { d["animations"][0]["channels"][1]["sampler"] = 0; }), 400,
         "its sampler is read by channels of different widths");
}

// The glTF tutorial's skin (assimp-testmodels): its upper joint swings a
// quarter turn either way over 5.5 s.
TEST(ModelRig, TheTutorialsSimpleSkinBends) {
  const LoadResult r = load_sample("simple_skin/simple_skin.gltf");
  ASSERT_TRUE(r.ok()) << r.error;
  ASSERT_TRUE(r.model->rig);
  // Rest: the joints' binds put the strip at x in [-0.5, 0.5] (as three.js
  // and Blender show it), not where its vertices say (x in [0, 1]).
  EXPECT_NEAR(r.model->bounds.min.x, -0.5, 1e-6);
  EXPECT_NEAR(r.model->bounds.max.x, 0.5, 1e-6);
  EXPECT_NEAR(r.model->bounds.max.y, 2.0, 1e-6);
  EXPECT_NEAR(r.model->rig->animations[0].duration_s, 5.5, 1e-6);
  // At 1 s the upper joint has turned +90 degrees about Z (0.707): the top
  // of the strip leans over to -X, lower than it stood.
  const TriangleModel bent = pose_model(*r.model->rig, 0, 1.0);
  EXPECT_LT(bent.bounds.max.y, 1.75);
  EXPECT_LT(bent.bounds.min.x, -0.9);
  // At 4 s, -90 degrees: to +X.
  const TriangleModel other = pose_model(*r.model->rig, 0, 4.0);
  EXPECT_GT(other.bounds.max.x, 0.9);
  // At 2.75 s it stands straight again (its keys are 0 at 2.5 and 3.0 s).
  const TriangleModel straight = pose_model(*r.model->rig, 0, 2.75);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(straight.bounds.min[k], r.model->bounds.min[k], 1e-5);
    EXPECT_NEAR(straight.bounds.max[k], r.model->bounds.max[k], 1e-5);
  }
}

// Khronos' AnimatedMorphCube: two morph targets weighed by its "Square"
// animation; its buffer is a file beside it.
TEST(ModelRig, KhronosAnimatedMorphCubeMorphs) {
  const LoadResult r = load_sample("glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf");
  ASSERT_TRUE(r.ok()) << r.error;
  ASSERT_TRUE(r.model->rig);
  const ModelRig& rig = *r.model->rig;
  ASSERT_EQ(find_animation(rig, "Square"), std::optional<std::size_t>(0));
  const double duration = rig.animations[0].duration_s;
  ASSERT_GT(duration, 0.0);
  // Some instant of the animation moves the cube's bounds away from rest.
  double moved = 0.0;
  for (int k = 0; k <= 20; ++k) {
    const TriangleModel posed = pose_model(rig, 0, duration * k / 20.0);
    EXPECT_EQ(posed.triangle_count(), r.model->triangle_count());
    for (int c = 0; c < 3; ++c)
      moved = std::max({moved, double(std::abs(posed.bounds.max[c] - r.model->bounds.max[c])),
                        double(std::abs(posed.bounds.min[c] - r.model->bounds.min[c]))});
  }
  EXPECT_GT(moved, 0.1 * double(r.model->bounds.max.x - r.model->bounds.min.x));
}

// Poses are shared, and poses kept or drawn stay within the cache's bytes.
TEST(PoseCache, SharesPosesAndStaysWithinItsBytes) {
  const LoadResult r = load_gltf(test::sliding_cube(), {});
  ASSERT_TRUE(r.ok()) << r.error;
  const std::shared_ptr<const TriangleModel> model = r.model;
  // What one pose holds here, its record included.
  std::uint64_t one = 0;
  {
    PoseCache probe;
    const auto pose = probe.posed(model, 0, 1.0);
    one = probe.bytes();
  }
  PoseCache cache(3 * one + one / 2);
  auto a = cache.posed(model, 0, 1.0);
  EXPECT_EQ(cache.posed(model, 0, 1.0), a);  // the same pose, shared
  auto b = cache.posed(model, 0, 1.5);
  auto c = cache.posed(model, 0, 0.5);
  EXPECT_NE(a, b);
  EXPECT_NEAR(b->bounds.min.x, pose_model(*model->rig, 0, 1.5).bounds.min.x, 0.0);
  // A fourth while renders hold all three: refused, retry later.
  try {
    cache.posed(model, 0, 0.25);
    ADD_FAILURE() << "a fourth pose was made past the bound";
  } catch (const PoseRefused& e) {
    EXPECT_EQ(e.status, 503) << e.what();
  }
  // Let go: the least recently used kept pose makes room.
  a.reset(), b.reset(), c.reset();
  EXPECT_NO_THROW(cache.posed(model, 0, 0.25));
  EXPECT_LE(cache.bytes(), 3 * one + one / 2);
  // Many distinct poses none holds: the least recently used go, the
  // entries stay within their count and the bytes within the bound.
  for (int k = 0; k < 5000; ++k) EXPECT_NO_THROW(cache.posed(model, 0, 1e-4 * k));
  EXPECT_LE(cache.bytes(), 3 * one + one / 2);
  // A pose larger than the whole bound: never.
  PoseCache tiny(16);
  try {
    tiny.posed(model, 0, 1.0);
    ADD_FAILURE() << "a pose larger than the bound was made";
  } catch (const PoseRefused& e) {
    EXPECT_EQ(e.status, 422) << e.what();
  }
}

// A scene's animated objects are posed at the request's time, named.
TEST(PoseCache, PosesAScenesAnimatedObjects) {
  const LoadResult r = load_gltf(test::sliding_cube(), {});
  ASSERT_TRUE(r.ok()) << r.error;
  Scene scene;
  SceneObject still;
  still.type = SceneObject::Type::Mesh;
  still.model = r.model;
  SceneObject moving = still;
  moving.animation = SceneObject::Animation{0, "slide", 2.0, true};
  scene.objects = {still, moving};
  PoseCache cache;
  cache.pose_scene(scene, 1.5);  // the animation's 3 s, wrapped to 1 s
  EXPECT_EQ(scene.objects[0].model, r.model);
  EXPECT_EQ(scene.objects[0].pose, "");
  EXPECT_EQ(scene.objects[1].pose, "animation 0 at 1 s");
  EXPECT_NEAR(scene.objects[1].model->bounds.min.x, pose_model(*r.model->rig, 0, 1.0).bounds.min.x, 0.0);
  EXPECT_FALSE(scene.objects[1].model->rig);
}

// A scene whose distinct poses could never fit together is refused before
// any is made; a pose whose client has gone is stopped.
TEST(PoseCache, RefusesWhatCouldNeverFitAndStopsForAGoneClient) {
  const LoadResult r = load_gltf(test::sliding_cube(), {});
  ASSERT_TRUE(r.ok()) << r.error;
  const std::uint64_t one = r.model->bytes() - r.model->rig->bytes();
  Scene scene;
  for (int i = 0; i < 4; ++i) {
    SceneObject o;
    o.type = SceneObject::Type::Mesh;
    o.model = r.model;
    o.animation = SceneObject::Animation{0, "", 1.0 + 0.1 * i, true};  // four distinct times
    scene.objects.push_back(o);
  }
  PoseCache cache(3 * one + one / 2);
  try {
    Scene copy = scene;
    cache.pose_scene(copy, 1.0);
    ADD_FAILURE() << "four poses were made past a bound of three and a half";
  } catch (const PoseRefused& e) {
    EXPECT_EQ(e.status, 422) << e.what();
    EXPECT_EQ(e.field, "scene.objects[3].animation");
    EXPECT_NE(std::string(e.what()).find("4 poses"), std::string::npos) << e.what();
  }
  EXPECT_EQ(cache.bytes(), 0u);  // none was made
  // The same pose four times is one pose: it fits.
  for (SceneObject& o : scene.objects) o.animation->speed = 1.0;
  Scene same = scene;
  EXPECT_NO_THROW(cache.pose_scene(same, 1.0));
  EXPECT_EQ(same.objects[0].model, same.objects[3].model);
  // A client gone: a pose of 160,000 vertices is stopped (499), and the
  // bytes it had reserved are given back.
  test::GltfBuilder b;
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices;
  constexpr std::uint32_t n = 400;
  for (std::uint32_t z = 0; z < n; ++z)
    for (std::uint32_t x = 0; x < n; ++x) positions.push_back({float(x), 0.0f, -float(z)});
  for (std::uint32_t z = 0; z + 1 < n; ++z)
    for (std::uint32_t x = 0; x + 1 < n; ++x) {
      const std::uint32_t a = z * n + x, c = a + n;
      indices.insert(indices.end(), {a, a + 1, c + 1, a, c + 1, c});
    }
  const int node = b.node({{"mesh", b.mesh(b.vec3s(positions), b.indices_u32(indices))}});
  b.scene({node});
  const int times = b.accessor(b.view(test::GltfBuilder::bytes_of(std::vector<float>{0, 1})), test::GltfBuilder::kFloat,
                               2, "SCALAR");
  b.doc["animations"] = json::array(
      {{{"samplers", {{{"input", times}, {"output", b.vec3s({{0, 0, 0}, {0, 1, 0}})}}}},
        {"channels", {{{"sampler", 0}, {"target", {{"node", node}, {"path", "translation"}}}}}}}});
  const LoadResult grid = load_gltf(b.glb(), {});
  ASSERT_TRUE(grid.ok()) << grid.error;
  PoseCache stopping;
  int asked = 0;
  try {
    stopping.posed(grid.model, 0, 0.5, [&asked] { return ++asked >= 1; });
    ADD_FAILURE() << "a pose of 160,000 vertices never asked whether to stop";
  } catch (const PoseRefused& e) {
    EXPECT_EQ(e.status, 499) << e.what();
  }
  EXPECT_EQ(asked, 1);
  EXPECT_EQ(stopping.bytes(), 0u);
  EXPECT_NO_THROW(stopping.posed(grid.model, 0, 0.5, [] { return false; }));
}

}  // namespace
}  // namespace umbra
