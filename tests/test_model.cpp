// Triangle models: closedness (which decides shadow-pass culling), normals, size.
#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include "gltf_builder.hpp"
#include "core/model.hpp"

namespace umbra {
namespace {

ModelPart cube_part() {
  ModelPart part;
  test::unit_cube(part.positions, part.indices);
  part.normals = area_weighted_normals(part.positions, part.indices);
  return part;
}

TEST(Model, AWeldedCubeIsClosed) { EXPECT_TRUE(is_closed({cube_part()})); }

TEST(Model, ACubeWithSplitVerticesAndTwoColoursIsClosed) {
  // As glTF exporters write it: 24 vertices (one set per face), and the top
  // face in a part of its own colour. Welding by position joins them.
  const ModelPart cube = cube_part();
  ModelPart sides, top;
  for (std::size_t t = 0; t < cube.indices.size(); t += 3) {
    ModelPart& part = t / 6 == 3 ? top : sides;
    for (int k = 0; k < 3; ++k) {
      part.indices.push_back(std::uint32_t(part.positions.size()));
      part.positions.push_back(cube.positions[cube.indices[t + std::size_t(k)]]);
    }
  }
  EXPECT_TRUE(is_closed({sides, top}));
  EXPECT_FALSE(is_closed({sides}));
}

TEST(Model, ACubeWithoutOneFaceIsOpen) {
  ModelPart part = cube_part();
  part.indices.resize(part.indices.size() - 6);
  EXPECT_FALSE(is_closed({part}));
}

TEST(Model, AQuadIsOpen) {
  ModelPart quad;
  quad.positions = {{0, 0, 0}, {1, 0, 0}, {1, 0, -1}, {0, 0, -1}};
  quad.indices = {0, 1, 2, 0, 2, 3};
  EXPECT_FALSE(is_closed({quad}));
}

TEST(Model, ACubeWithOneFlippedFaceIsNotClosed) {
  ModelPart part = cube_part();
  std::swap(part.indices[1], part.indices[2]);
  std::swap(part.indices[4], part.indices[5]);
  EXPECT_FALSE(is_closed({part}));
}

// Every triangle reversed: watertight and consistently wound, but each
// face looks into the solid. Culled as a closed mesh, it would show its
// inside to the camera and keep its lit side out of the shadow map.
TEST(Model, AnInsideOutCubeIsNotClosed) {
  ModelPart part = cube_part();
  for (std::size_t t = 0; t < part.indices.size(); t += 3) std::swap(part.indices[t + 1], part.indices[t + 2]);
  EXPECT_FALSE(is_closed({part}));
}

TEST(Model, TwoCubesAreClosedOnlyIfBothFaceOut) {
  const ModelPart cube = cube_part();
  ModelPart moved = cube;
  for (glm::vec3& p : moved.positions) p += glm::vec3(3.0f, 0.0f, 0.0f);
  EXPECT_TRUE(is_closed({cube, moved}));
  // The second cube inside out: the two shells' volumes would cancel in one
  // sum; each shell is judged on its own.
  for (std::size_t t = 0; t < moved.indices.size(); t += 3) std::swap(moved.indices[t + 1], moved.indices[t + 2]);
  EXPECT_FALSE(is_closed({cube, moved}));
  // A big outward cube around a small inward one (a hollow solid): not
  // closed either; the inner shell faces into the cavity.
  ModelPart big = cube_part();
  for (glm::vec3& p : big.positions) p *= 4.0f;
  ModelPart cavity = cube_part();
  for (std::size_t t = 0; t < cavity.indices.size(); t += 3) std::swap(cavity.indices[t + 1], cavity.indices[t + 2]);
  EXPECT_FALSE(is_closed({big, cavity}));
  EXPECT_TRUE(is_closed({big}));
  // A small inside-out cube touching the unit cube at one corner: shells
  // are joined by edges, so the shared vertex does not make them one shell
  // whose volumes would sum to a positive one.
  ModelPart touching = cube_part();
  for (glm::vec3& p : touching.positions) p = p * 0.5f + glm::vec3(0.75f);  // its lowest corner at (0.5, 0.5, 0.5)
  for (std::size_t t = 0; t < touching.indices.size(); t += 3) std::swap(touching.indices[t + 1], touching.indices[t + 2]);
  EXPECT_FALSE(is_closed({cube, touching}));
}

TEST(Model, AnEdgeSharedByThreeTrianglesIsNotClosed) {
  ModelPart part = cube_part();
  // A fin inside the cube on the edge 0-1 (which two faces already share).
  part.positions.push_back({0, 0, 0});
  part.indices.insert(part.indices.end(), {0, 1, 8});
  EXPECT_FALSE(is_closed({part}));
}

TEST(Model, NoTrianglesIsNotClosed) { EXPECT_FALSE(is_closed({})); }

TEST(Model, NormalsAreAreaWeighted) {
  // Two triangles share vertex 0: a large one facing +Z and a small one
  // facing +X. The shared normal leans toward the larger.
  const std::vector<glm::vec3> positions = {{0, 0, 0}, {4, 0, 0}, {0, 4, 0}, {0, 1, 0}, {0, 0, -1}};
  const std::vector<std::uint32_t> indices = {0, 1, 2, 0, 4, 3};
  const std::vector<glm::vec3> n = area_weighted_normals(positions, indices);
  const glm::vec3 expected = glm::normalize(glm::vec3(1, 0, 16));  // cross products 16 +Z and 1 +X
  EXPECT_NEAR(glm::distance(n[0], expected), 0.0f, 1e-6f);
  EXPECT_NEAR(glm::distance(n[1], glm::vec3(0, 0, 1)), 0.0f, 1e-6f);
  EXPECT_NEAR(glm::distance(n[3], glm::vec3(1, 0, 0)), 0.0f, 1e-6f);
}

TEST(Model, FinishSetsBoundsAndClosedAndBytesCountTheVectors) {
  TriangleModel model;
  model.parts.push_back(cube_part());
  finish_model(model);
  EXPECT_TRUE(model.closed);
  EXPECT_EQ(model.triangle_count(), 12u);
  EXPECT_EQ(model.bounds.min, glm::dvec3(-0.5));
  EXPECT_EQ(model.bounds.max, glm::dvec3(0.5));
  EXPECT_GE(model.bytes(), 8 * 2 * sizeof(glm::vec3) + 36 * sizeof(std::uint32_t));
}

}  // namespace
}  // namespace umbra
