// The models every server holds: the Utah teapot and the torus knot are
// generated, so these tests check what a download would have been trusted
// for: size, shape, which way the faces look, and whether it is closed.
#include <gtest/gtest.h>

#include <cmath>

#include <glm/geometric.hpp>

#include "core/builtin_models.hpp"
#include "assets/model_store.hpp"

namespace umbra {
namespace {

// The welded vertex nearest to `target`, and its normal.
std::pair<glm::vec3, glm::vec3> nearest_vertex(const TriangleModel& model, const glm::vec3& target) {
  const ModelPart& part = model.parts.at(0);
  std::size_t best = 0;
  for (std::size_t i = 1; i < part.positions.size(); ++i)
    if (glm::length(part.positions[i] - target) < glm::length(part.positions[best] - target)) best = i;
  return {part.positions[best], part.normals[best]};
}

// Sum over triangles of a . (b x c) / 6: the enclosed volume, positive
// when every face winds counter-clockwise seen from outside.
double signed_volume(const TriangleModel& model) {
  double volume = 0.0;
  for (const ModelPart& part : model.parts)
    for (std::size_t t = 0; t + 2 < part.indices.size(); t += 3) {
      const glm::dvec3 a(part.positions[part.indices[t]]), b(part.positions[part.indices[t + 1]]),
          c(part.positions[part.indices[t + 2]]);
      volume += glm::dot(a, glm::cross(b, c)) / 6.0;
    }
  return volume;
}

TEST(UtahTeapot, HasTwoTrianglesPerQuadOfEveryPatchAndStandsOnTheFloor) {
  const auto teapot = utah_teapot(8);
  EXPECT_EQ(teapot->triangle_count(), 32u * 8 * 8 * 2);
  // Newell's data, Y up: the spout's tip reaches x = 3.525 (its control
  // points; the curve stays inside them), the handle x = -3, the lid's knob
  // y = 3.15, the body's widest point 2 from the axis.
  EXPECT_FLOAT_EQ(float(teapot->bounds.min.y), 0.0f);
  EXPECT_FLOAT_EQ(float(teapot->bounds.max.y), 3.15f);
  EXPECT_FLOAT_EQ(float(teapot->bounds.min.x), -3.0f);
  EXPECT_GT(teapot->bounds.max.x, 3.3);
  EXPECT_LE(teapot->bounds.max.x, 3.525);
  EXPECT_FLOAT_EQ(float(teapot->bounds.max.z), 2.0f);
  EXPECT_FLOAT_EQ(float(teapot->bounds.min.z), -2.0f);
}

TEST(UtahTeapot, PatchesMeetAtSharedVerticesSoTheSurfaceIsSmooth) {
  // Welded across patch seams: fewer vertices than 32 (n + 1)^2 (each
  // seam's points are shared, the collapsed rows of the knob and the
  // bottom are one point each).
  const auto teapot = utah_teapot(8);
  EXPECT_LT(teapot->parts[0].positions.size(), 32u * 9 * 9 * 9 / 10);
  // On the seam between two body patches (x = 0), the normal is the
  // average of both: it has no x component and points out of the side.
  const auto [side, side_normal] = nearest_vertex(*teapot, {0.0f, 1.35f, 2.0f});
  EXPECT_NEAR(side.x, 0.0f, 1e-6);
  EXPECT_NEAR(side_normal.x, 0.0f, 1e-3);
  EXPECT_GT(side_normal.z, 0.95f);
}

TEST(UtahTeapot, FacesLookOutward) {
  const auto teapot = utah_teapot(8);
  // The knob's top looks up, the bottom's centre down, the body's side
  // (away from the spout and the handle) out, and the handle's outermost
  // point away from the pot.
  EXPECT_GT(nearest_vertex(*teapot, {0.0f, 3.15f, 0.0f}).second.y, 0.99f);
  EXPECT_LT(nearest_vertex(*teapot, {0.0f, 0.0f, 0.0f}).second.y, -0.99f);
  EXPECT_LT(nearest_vertex(*teapot, {0.0f, 1.35f, -2.0f}).second.z, -0.95f);
  EXPECT_LT(nearest_vertex(*teapot, {-3.0f, 1.8f, 0.0f}).second.x, -0.9f);
  // Every stored triangle agrees with its vertices' normals (no patch is
  // wound the other way): its face normal and theirs point the same side.
  const ModelPart& part = teapot->parts[0];
  int against = 0, degenerate = 0;
  for (std::size_t t = 0; t + 2 < part.indices.size(); t += 3) {
    const glm::vec3 a = part.positions[part.indices[t]], b = part.positions[part.indices[t + 1]],
                    c = part.positions[part.indices[t + 2]];
    const glm::vec3 face = glm::cross(b - a, c - a);
    if (glm::length(face) == 0.0f) {
      ++degenerate;  // where a patch's row collapses to a point (knob, bottom)
      continue;
    }
    const glm::vec3 vertex_normals =
        part.normals[part.indices[t]] + part.normals[part.indices[t + 1]] + part.normals[part.indices[t + 2]];
    if (glm::dot(face, vertex_normals) < 0.0f) ++against;
  }
  EXPECT_EQ(against, 0);
  EXPECT_GT(degenerate, 0);
}

TEST(UtahTeapot, IsOpenSoTheShadowPassDrawsBothSides) {
  // The spout's tip and the rim under the lid are open edges.
  EXPECT_FALSE(utah_teapot(4)->closed);
  EXPECT_THROW(utah_teapot(0), std::invalid_argument);
  EXPECT_THROW(utah_teapot(201), std::invalid_argument);
}

TEST(TorusKnot, IsClosedWoundOutwardAndAsLargeAsAsked) {
  const auto knot = torus_knot(1.0, 0.2, 64, 12);
  EXPECT_EQ(knot->triangle_count(), 2u * 64 * 12);
  EXPECT_TRUE(knot->closed);
  // A tube of radius 0.2 is pi 0.2^2 per unit of its length (over 10 here),
  // and the polygonal tube holds a little less.
  EXPECT_GT(signed_volume(*knot), 0.8);
  EXPECT_LT(signed_volume(*knot), 3.14159 * 0.04 * 20.0);
  // Radius 1: the curve's centre line reaches 1.5 from the axis, so the
  // surface 1.7; it rises and falls by 0.5 + 0.2.
  EXPECT_NEAR(std::max(knot->bounds.max.x, knot->bounds.max.z), 1.7, 0.02);
  EXPECT_NEAR(knot->bounds.max.y, 0.7, 0.01);
  EXPECT_THROW(torus_knot(1.0, 0.2, 4, 12), std::invalid_argument);
}

TEST(BuiltinModels, AreFoundByNameAndByAnIdOfTheirGeometry) {
  const BuiltinModel* teapot = find_builtin_model("teapot");
  ASSERT_NE(teapot, nullptr);
  EXPECT_GE(teapot->model->triangle_count(), 100000u);
  EXPECT_EQ(teapot->id, model_geometry_id(*teapot->model));
  EXPECT_EQ(teapot->id.rfind("sha256:", 0), 0u);
  EXPECT_EQ(teapot->id.size(), 7u + 64u);
  EXPECT_EQ(find_builtin_model(teapot->id), teapot);
  const BuiltinModel* knot = find_builtin_model("torus-knot");
  ASSERT_NE(knot, nullptr);
  EXPECT_TRUE(knot->model->closed);
  EXPECT_NE(knot->id, teapot->id);
  EXPECT_EQ(find_builtin_model("kettle"), nullptr);
}

TEST(BuiltinModels, TheStoreListsThemUnlessAFolderModelHasTheName) {
  ModelStore store(1ull << 30);
  // The operator's own "teapot" came first (load_model_folder runs before).
  auto own = std::make_shared<TriangleModel>(*utah_teapot(2));
  ASSERT_EQ(store.add(model_id_for("own teapot"), "teapot", own, true).outcome, ModelStore::Outcome::Added);
  std::vector<std::string> not_held;
  hold_builtin_models(store, not_held);
  ASSERT_EQ(not_held.size(), 1u);
  EXPECT_NE(not_held[0].find("teapot"), std::string::npos);
  EXPECT_EQ(store.find("teapot")->model, own);
  EXPECT_EQ(store.find(find_builtin_model("teapot")->id)->model, find_builtin_model("teapot")->model);
  EXPECT_EQ(store.find("torus-knot")->model, find_builtin_model("torus-knot")->model);
  EXPECT_EQ(store.count(), 3u);

  ModelStore tiny(1000);
  not_held.clear();
  hold_builtin_models(tiny, not_held);
  EXPECT_EQ(not_held.size(), 2u);
  EXPECT_EQ(tiny.count(), 0u);
}

}  // namespace
}  // namespace umbra
