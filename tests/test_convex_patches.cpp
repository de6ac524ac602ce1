// convex_patches (core/convex_patches.hpp): every patch is convex (each of
// its triangles on or behind every other's plane), joined through shared
// edges and no larger than kMostPatchTriangles; a convex solid is one patch,
// a concave crease splits two.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <set>

#include <glm/glm.hpp>

#include "core/builtin_models.hpp"
#include "core/convex_patches.hpp"
#include "core/model.hpp"

namespace umbra {
namespace {

TriangleModel model_of(const std::vector<glm::vec3>& positions, const std::vector<std::uint32_t>& indices) {
  TriangleModel model;
  model.parts.emplace_back();
  model.parts[0].append(positions, std::vector<glm::vec3>(positions.size(), glm::vec3(0.0f, 1.0f, 0.0f)), indices);
  return model;
}

// A unit cube's twelve triangles, counter-clockwise seen from outside.
TriangleModel cube() {
  std::vector<glm::vec3> p;
  for (int i = 0; i < 8; ++i) p.push_back(glm::vec3(float(i & 1), float((i >> 1) & 1), float((i >> 2) & 1)));
  const std::vector<std::uint32_t> quads = {0, 2, 3, 1, 4, 5, 7, 6, 0, 1, 5, 4, 2, 6, 7, 3, 0, 4, 6, 2, 1, 3, 7, 5};
  std::vector<std::uint32_t> indices;
  for (std::size_t q = 0; q < quads.size(); q += 4)
    indices.insert(indices.end(), {quads[q], quads[q + 1], quads[q + 2], quads[q], quads[q + 2], quads[q + 3]});
  return model_of(p, indices);
}

std::vector<std::array<glm::dvec3, 3>> triangles_of(const TriangleModel& model) {
  std::vector<std::array<glm::dvec3, 3>> out;
  for (const ModelPart& part : model.parts)
    for (std::size_t t = 0; t < part.triangle_count(); ++t)
      out.push_back({glm::dvec3(part.positions[part.indices[3 * t]]), glm::dvec3(part.positions[part.indices[3 * t + 1]]),
                     glm::dvec3(part.positions[part.indices[3 * t + 2]])});
  return out;
}

// How far (world units) `v` stands in front of the plane of `t`.
double in_front(const std::array<glm::dvec3, 3>& t, const glm::dvec3& v) {
  const glm::dvec3 n = glm::normalize(glm::cross(t[1] - t[0], t[2] - t[0]));
  return glm::dot(n, v - t[0]);
}

// Each patch: its first triangle is the least, it has at most
// kMostPatchTriangles, and no corner of one member stands in front of
// another's plane by more than the tolerance allows (`slack` of the model's size).
void expect_patches_convex(const TriangleModel& model, const std::vector<std::uint32_t>& first, double slack) {
  const auto triangles = triangles_of(model);
  ASSERT_EQ(first.size(), triangles.size());
  std::map<std::uint32_t, std::vector<std::uint32_t>> patches;
  for (std::uint32_t t = 0; t < first.size(); ++t) {
    ASSERT_LE(first[t], t);
    ASSERT_EQ(first[first[t]], first[t]) << "a patch's first triangle is its own";
    patches[first[t]].push_back(t);
  }
  std::size_t worst_pairs = 0;
  for (const auto& [head, members] : patches) {
    EXPECT_LE(members.size(), kMostPatchTriangles);
    for (std::uint32_t a : members)
      for (std::uint32_t b : members)
        for (const glm::dvec3& v : triangles[b])
          if (a != b && in_front(triangles[a], v) > slack && ++worst_pairs <= 3)
            ADD_FAILURE() << "patch " << head << ": a corner of triangle " << b << " stands "
                          << in_front(triangles[a], v) << " in front of triangle " << a;
  }
  EXPECT_EQ(worst_pairs, 0u);
}

TEST(ConvexPatches, ACubeIsOnePatch) {
  const TriangleModel model = cube();
  const std::vector<std::uint32_t> first = convex_patches(model);
  EXPECT_EQ(first, std::vector<std::uint32_t>(12, 0u));
  expect_patches_convex(model, first, 0.0);
}

TEST(ConvexPatches, AConcaveCreaseSplitsTwoFaces) {
  // Two squares meeting along x = 0, y = 0, rising to either side: a
  // valley whose outward sides face up, into it.
  const std::vector<glm::vec3> p = {{0, 0, 0}, {0, 0, 1}, {-1, 1, 0}, {-1, 1, 1}, {1, 1, 0}, {1, 1, 1}};
  const TriangleModel valley = model_of(p, {0, 3, 1, 0, 2, 3, 0, 5, 4, 0, 1, 5});
  const std::vector<std::uint32_t> first = convex_patches(valley);
  EXPECT_EQ(first, (std::vector<std::uint32_t>{0, 0, 2, 2}));
  expect_patches_convex(valley, first, 0.0);
  // Turned inside out (the outward sides face down: a ridge seen from
  // below): one patch.
  const TriangleModel ridge = model_of(p, {0, 1, 3, 0, 3, 2, 0, 4, 5, 0, 5, 1});
  EXPECT_EQ(convex_patches(ridge), std::vector<std::uint32_t>(4, 0u));
}

TEST(ConvexPatches, AFlatGridIsCutAtTheLargestPatch) {
  std::vector<glm::vec3> p;
  std::vector<std::uint32_t> indices;
  const int n = 12;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) p.push_back(glm::vec3(float(i), 0.0f, float(-j)));
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const auto at = [&](int x, int y) { return std::uint32_t(y * (n + 1) + x); };
      indices.insert(indices.end(), {at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  const TriangleModel grid = model_of(p, indices);
  const std::vector<std::uint32_t> first = convex_patches(grid);
  std::map<std::uint32_t, std::size_t> sizes;
  for (std::uint32_t f : first) ++sizes[f];
  // 288 triangles, all coplanar: the first patch stops at
  // kMostPatchTriangles; breadth-first growth leaves the later ones
  // smaller where earlier patches hem them in.
  EXPECT_EQ(sizes.at(0), kMostPatchTriangles);
  EXPECT_LE(sizes.size(), 2 * 288 / kMostPatchTriangles);
  expect_patches_convex(grid, first, 0.0);
}

TEST(ConvexPatches, ATriangleWithoutAreaIsAlone) {
  // Two triangles of a square, and a third with two equal corners on their
  // shared edge.
  const std::vector<glm::vec3> p = {{0, 0, 0}, {1, 0, 0}, {1, 0, -1}, {0, 0, -1}};
  const TriangleModel model = model_of(p, {0, 2, 2, 0, 1, 2, 0, 2, 3});
  EXPECT_EQ(convex_patches(model), (std::vector<std::uint32_t>{0, 1, 1}));
}

TEST(ConvexPatches, TheTorusKnotsPatchesAreConvexAndFewerThanItsTriangles) {
  const std::shared_ptr<const TriangleModel> knot = find_builtin_model("torus-knot")->model;
  const std::vector<std::uint32_t> first = convex_patches(*knot);
  // The tolerance lets a corner stand 1e-9 of its distance in front; the
  // knot is about 6 across.
  expect_patches_convex(*knot, first, 1e-8);
  std::set<std::uint32_t> heads(first.begin(), first.end());
  // The tube is convex around and gently curved along: patches of many
  // triangles (a fifth of the count would be patches of five on average).
  EXPECT_LT(heads.size(), first.size() / 5);
  // Deterministic.
  EXPECT_EQ(convex_patches(*knot), first);
}

TEST(ConvexPatches, AModelAboveTheLimitKeepsOneTrianglePerPatch) {
  std::vector<glm::vec3> p;
  std::vector<std::uint32_t> indices;
  const std::size_t quads = kMostPatchedModelTriangles / 2 + 1;
  for (std::size_t i = 0; i <= quads; ++i) {
    p.push_back(glm::vec3(float(i), 0.0f, 0.0f));
    p.push_back(glm::vec3(float(i), 0.0f, -1.0f));
  }
  for (std::uint32_t i = 0; i < quads; ++i)
    indices.insert(indices.end(), {2 * i, 2 * i + 2, 2 * i + 3, 2 * i, 2 * i + 3, 2 * i + 1});
  const TriangleModel strip = model_of(p, indices);
  const std::vector<std::uint32_t> first = convex_patches(strip);
  ASSERT_EQ(first.size(), 2 * quads);
  for (std::uint32_t t = 0; t < first.size(); ++t) ASSERT_EQ(first[t], t);
}

}  // namespace
}  // namespace umbra
