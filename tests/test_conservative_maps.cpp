// The conservative maps drawn on the CPU (plan/conservative_maps.hpp)
// against a brute force: each texel's square clipped against each triangle
// in window space, in double. What the certificate relies on
// (docs/certified-shadows.md, "The maps"): a texel that any part of a
// triangle touches holds a depth no farther than the nearest the triangle
// reaches in it, in the nearest map, and in the others map unless the
// triangle's owner is the one the nearest map names.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "plan/conservative_maps.hpp"

namespace umbra {
namespace {

struct Triangles {
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices;
  std::vector<std::uint32_t> objects;  // per triangle
};

// The least window depth of the window-space triangle `w` over the texel
// square at (i, j), or none: Sutherland-Hodgman against the square's four
// sides, the depth interpolated along the cuts (it is affine in window x, y).
std::optional<double> least_depth_in_texel(const glm::dvec3 w[3], int i, int j) {
  std::vector<glm::dvec3> poly(w, w + 3);
  const double bounds[4] = {double(i), double(i + 1), double(j), double(j + 1)};
  for (int side = 0; side < 4 && !poly.empty(); ++side) {
    const int axis = side / 2;
    const bool keep_above = side % 2 == 0;
    const auto inside = [&](const glm::dvec3& p) { return keep_above ? p[axis] >= bounds[side] : p[axis] <= bounds[side]; };
    std::vector<glm::dvec3> out;
    for (std::size_t k = 0; k < poly.size(); ++k) {
      const glm::dvec3 a = poly[k], b = poly[(k + 1) % poly.size()];
      if (inside(a)) out.push_back(a);
      if (inside(a) != inside(b)) out.push_back(a + (b - a) * ((bounds[side] - a[axis]) / (b[axis] - a[axis])));
    }
    poly = out;
  }
  if (poly.empty()) return std::nullopt;
  double least = 1e300;
  for (const glm::dvec3& p : poly) least = std::min(least, p.z);
  return least;
}

ConservativeView orthographic_view(int size) {
  ConservativeView v;
  v.layer_size = 2 * size;
  v.size = size;
  v.near_plane = -1.0;
  v.far_plane = 1.0;
  v.texel_size = glm::dvec2(2.0 / v.layer_size);
  return v;  // identity matrices: clip space is the positions' own
}

void expect_maps_hold_every_touch(const Triangles& t, const std::vector<ConservativeObject>& objects,
                                  const ConservativeView& view, const char* what) {
  const std::vector<DrawRange> draws = {{0, t.indices.size(), CullMode::None}};
  const ConservativeMaps maps(t.positions, t.indices, objects, t.objects, draws, view);
  ConservativeBand band;
  band.x1 = band.y1 = view.size;
  maps.draw(band);
  const glm::dmat4 to_clip = glm::dmat4(view.projection) * glm::dmat4(view.view);
  std::size_t touched = 0, wrong = 0;
  for (std::size_t tri = 0; tri < t.objects.size(); ++tri) {
    glm::dvec3 w[3];
    for (int k = 0; k < 3; ++k) {
      const glm::dvec4 c = to_clip * glm::dvec4(glm::dvec3(t.positions[t.indices[3 * tri + std::size_t(k)]]), 1.0);
      const glm::dvec3 ndc = glm::dvec3(c) / c.w;
      w[k] = {(ndc.x * 0.5 + 0.5) * view.size, (ndc.y * 0.5 + 0.5) * view.size, ndc.z * 0.5 + 0.5};
    }
    const std::uint32_t object = t.objects[tri];
    const std::uint32_t owner = objects[object].model ? (std::uint32_t(tri) | kModelTriangleOwner) : object;
    for (int j = 0; j < view.size; ++j)
      for (int i = 0; i < view.size; ++i) {
        const std::optional<double> least = least_depth_in_texel(w, i, j);
        if (!least) continue;
        const double depth = std::clamp(*least, 0.0, 1.0);
        ++touched;
        const std::size_t at = std::size_t(j) * std::size_t(view.size) + std::size_t(i);
        bool ok = band.nearest_depth[at] <= depth;
        if (band.nearest_owner[at] != owner) ok = ok && band.others_depth[at] <= depth;
        // A texel the triangle reaches has an owner, and the others map is
        // never nearer than the nearest.
        ok = ok && band.nearest_owner[at] != kNoOwner && band.nearest_depth[at] <= band.others_depth[at];
        if (!ok && ++wrong <= 5)
          ADD_FAILURE() << what << ": triangle " << tri << " at texel " << i << ", " << j << " reaches depth " << depth
                        << "; nearest " << band.nearest_depth[at] << " (owner " << band.nearest_owner[at] << "), others "
                        << band.others_depth[at];
      }
  }
  EXPECT_EQ(wrong, 0u) << what;
  EXPECT_GT(touched, 0u) << what;
}

void add_triangle(Triangles& t, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c, std::uint32_t object) {
  for (const glm::vec3& p : {a, b, c}) {
    t.indices.push_back(std::uint32_t(t.positions.size()));
    t.positions.push_back(p);
  }
  t.objects.push_back(object);
}

TEST(ConservativeMaps, EveryTexelATriangleTouchesHoldsItsNearestDepth) {
  std::mt19937 random(7);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  const std::vector<ConservativeObject> objects = {{0.0, false, true}, {0.0, false, false}, {0.0, true, false}};
  for (int scene = 0; scene < 40; ++scene) {
    Triangles t;
    const int count = 1 + int(random() % 12);
    for (int k = 0; k < count; ++k) {
      const glm::vec3 centre(unit(random), unit(random), unit(random) * 0.8f);
      const float reach = scene % 3 == 0 ? 0.02f : 0.5f;
      glm::vec3 p[3];
      for (glm::vec3& q : p) q = centre + reach * glm::vec3(unit(random), unit(random), unit(random) * 0.2f);
      if (scene % 4 == 1) p[2] = p[1] + 1e-4f * (p[1] - p[0]);  // a needle: next to no area
      add_triangle(t, p[0], p[1], p[2], std::uint32_t(random() % objects.size()));
    }
    expect_maps_hold_every_touch(t, objects, orthographic_view(32 + int(random() % 3) * 16), "orthographic");
  }
}

TEST(ConservativeMaps, APointLightsViewHoldsEveryTouchToo) {
  std::mt19937 random(11);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  const std::vector<ConservativeObject> objects = {{0.0, false, true}, {0.0, true, false}};
  for (int scene = 0; scene < 30; ++scene) {
    ConservativeView view;
    view.perspective = true;
    view.size = 48;
    view.layer_size = 96;
    view.near_plane = 0.5;
    view.far_plane = 20.0;
    view.tan_half = std::tan(glm::radians(45.0));
    view.texel_size = glm::dvec2(2.0 * view.tan_half / view.layer_size);
    view.projection = glm::perspective(glm::radians(90.0f), 1.0f, 0.5f, 20.0f);
    view.view = glm::lookAt(glm::vec3(0, 0, 0), glm::vec3(0, 0, -1), glm::vec3(0, 1, 0));
    Triangles t;
    for (int k = 0; k < 6; ++k) {
      const glm::vec3 centre(unit(random) * 3.0f, unit(random) * 3.0f, -4.0f + unit(random) * 2.5f);
      glm::vec3 p[3];
      for (glm::vec3& q : p) q = centre + glm::vec3(unit(random), unit(random), unit(random));
      add_triangle(t, p[0], p[1], p[2], std::uint32_t(random() % objects.size()));
    }
    expect_maps_hold_every_touch(t, objects, view, "perspective");
  }
}

// The faces of a closed shape turned from the light are left out (the
// nearer face turned to it covers them), a model's never.
TEST(ConservativeMaps, OnlyAClosedShapesFacesTurnedFromTheLightAreLeftOut) {
  Triangles t;
  // Clockwise seen from +z (the light looks down -z): turned away.
  add_triangle(t, {-0.5f, -0.5f, 0.0f}, {-0.5f, 0.5f, 0.0f}, {0.5f, -0.5f, 0.0f}, 0);
  add_triangle(t, {-0.5f, -0.5f, 0.0f}, {-0.5f, 0.5f, 0.0f}, {0.5f, -0.5f, 0.0f}, 1);
  ConservativeView view = orthographic_view(16);
  view.cull_closed_back = true;
  const std::vector<DrawRange> draws = {{0, 6, CullMode::None}};
  EXPECT_EQ(ConservativeMaps(t.positions, t.indices, {{0.0, false, true}, {0.0, true, true}}, t.objects, draws, view)
                .triangles(),
            1u);
  view.cull_closed_back = false;
  EXPECT_EQ(ConservativeMaps(t.positions, t.indices, {{0.0, false, true}, {0.0, true, true}}, t.objects, draws, view)
                .triangles(),
            2u);
}

// One object's triangles, overlapping, leave the others map far (the
// renderer clears it rather than copying it); a second object's make it
// hold something.
TEST(ConservativeMaps, OneOwnerLeavesTheOthersMapFar) {
  Triangles t;
  add_triangle(t, {-0.5f, -0.5f, 0.2f}, {0.5f, -0.5f, 0.2f}, {0.0f, 0.5f, 0.2f}, 0);
  add_triangle(t, {-0.6f, -0.4f, 0.1f}, {0.4f, -0.6f, 0.3f}, {0.1f, 0.6f, 0.0f}, 0);
  const ConservativeView view = orthographic_view(32);
  const std::vector<ConservativeObject> objects = {{0.0, false, true}, {0.0, false, true}};
  ConservativeBand one;
  one.x1 = one.y1 = view.size;
  ConservativeMaps(t.positions, t.indices, objects, t.objects, {{0, 6, CullMode::None}}, view).draw(one);
  EXPECT_TRUE(one.others_all_far());
  EXPECT_TRUE(std::any_of(one.nearest_depth.begin(), one.nearest_depth.end(), [](float d) { return d < 1.0f; }));
  t.objects[1] = 1;
  ConservativeBand two;
  two.x1 = two.y1 = view.size;
  ConservativeMaps(t.positions, t.indices, objects, t.objects, {{0, 6, CullMode::None}}, view).draw(two);
  EXPECT_FALSE(two.others_all_far());
}

// Bands drawn apart, as many at once as there are cores, make the map
// drawn whole.
TEST(ConservativeMaps, BandsMakeTheWholeMap) {
  std::mt19937 random(3);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  Triangles t;
  // Most of the map, but not its left and bottom edges.
  const auto at = [&] { return 0.6f + 0.4f * unit(random); };
  for (int k = 0; k < 30; ++k)
    add_triangle(t, {at(), at(), unit(random)}, {at(), at(), unit(random)}, {at(), at(), unit(random)}, std::uint32_t(k % 3));
  const ConservativeView view = orthographic_view(64);
  const ConservativeMaps maps(t.positions, t.indices, {{0, false, true}, {0, false, true}, {0, true, false}}, t.objects,
                              {{0, t.indices.size(), CullMode::None}}, view);
  ConservativeBand whole;
  whole.x0 = 5;
  whole.y0 = 3;
  whole.x1 = 60;
  whole.y1 = 61;
  maps.draw(whole);
  // Nothing outside touched() is marked.
  int tx0 = 0, ty0 = 0, tx1 = 0, ty1 = 0;
  maps.touched(tx0, ty0, tx1, ty1);
  std::size_t outside = 0;
  for (int j = 3; j < 61; ++j)
    for (int i = 5; i < 60; ++i) {
      if (i >= tx0 && i < tx1 && j >= ty0 && j < ty1) continue;
      ++outside;
      ASSERT_EQ(whole.nearest_owner[std::size_t(j - 3) * 55 + std::size_t(i - 5)], kNoOwner) << i << ", " << j;
    }
  EXPECT_GT(outside, 0u);
  std::size_t rows = 0;
  draw_conservative_bands(maps, 5, 3, 60, 61, 55 * 12 * 7, [&](const ConservativeBand& band) {
    EXPECT_EQ(band.y0, 3 + int(rows));
    EXPECT_LE(band.height(), 7);
    for (int j = band.y0; j < band.y1; ++j)
      for (int i = band.x0; i < band.x1; ++i) {
        const std::size_t a = std::size_t(j - band.y0) * 55 + std::size_t(i - 5);
        const std::size_t b = std::size_t(j - 3) * 55 + std::size_t(i - 5);
        ASSERT_EQ(band.nearest_depth[a], whole.nearest_depth[b]);
        ASSERT_EQ(band.nearest_owner[a], whole.nearest_owner[b]);
        ASSERT_EQ(band.others_depth[a], whole.others_depth[b]);
      }
    rows += std::size_t(band.height());
  });
  EXPECT_EQ(rows, 58u);
}

}  // namespace
}  // namespace umbra
