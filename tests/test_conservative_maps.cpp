// The conservative maps drawn on the CPU (plan/conservative_maps.hpp)
// against a brute force: each texel's square clipped against each triangle
// in window space, in double. What the certificate relies on
// (docs/certified-shadows.md, "The maps"): a texel that any part of a
// triangle touches holds a depth no farther than the nearest the triangle
// reaches in it, in the nearest map, and in the others map unless the
// triangle's owner is the one the nearest map names.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
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

// A point light's cube face looking down -z from the origin, 48 texels a
// side (96 in the layer), near 0.5, far 20.
ConservativeView point_light_view() {
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
  return view;
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
    const ConservativeView view = point_light_view();
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

namespace umbra {
namespace {

// The cover map (docs/certified-shadows.md, "The cover map"): where it
// holds a depth, every light ray through the texel's square meets a
// triangle no farther than that. Checked at 7 x 7 points of each such
// square, its corners and sides included: the nearest triangle holding the
// point (window space, in double), which must exist and lie no farther.
// Returns how many texels it proved.
std::size_t expect_cover_holds(const Triangles& t, const std::vector<ConservativeObject>& objects,
                               const ConservativeView& view, const char* what) {
  std::vector<bool> models;
  for (const ConservativeObject& o : objects) models.push_back(o.model);
  const SliverEdges edges(t.positions, t.indices, t.objects, models);
  const std::vector<DrawRange> draws = {{0, t.indices.size(), CullMode::None}};
  const ConservativeMaps maps(t.positions, t.indices, objects, t.objects, draws, view, {}, &edges);
  ConservativeBand band;
  band.x1 = band.y1 = view.size;
  maps.draw(band);
  const glm::dmat4 to_clip = glm::dmat4(view.projection) * glm::dmat4(view.view);
  std::vector<std::array<glm::dvec3, 3>> windows;
  for (std::size_t tri = 0; tri < t.objects.size(); ++tri) {
    std::array<glm::dvec3, 3> w;
    for (int k = 0; k < 3; ++k) {
      const glm::dvec4 c = to_clip * glm::dvec4(glm::dvec3(t.positions[t.indices[3 * tri + std::size_t(k)]]), 1.0);
      const glm::dvec3 ndc = glm::dvec3(c) / c.w;
      w[std::size_t(k)] = {(ndc.x * 0.5 + 0.5) * view.size, (ndc.y * 0.5 + 0.5) * view.size, ndc.z * 0.5 + 0.5};
    }
    windows.push_back(w);
  }
  // The nearest depth at window point (x, y) of the triangles holding it.
  const auto first_hit = [&](double x, double y) {
    double nearest = 1e300;
    for (const auto& w : windows) {
      const glm::dvec2 a(w[0]), b(w[1]), c(w[2]);
      const double area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
      if (area == 0.0) continue;
      const double l1 = ((b.x - x) * (c.y - y) - (b.y - y) * (c.x - x)) / area;
      const double l2 = ((c.x - x) * (a.y - y) - (c.y - y) * (a.x - x)) / area;
      const double l3 = 1.0 - l1 - l2;
      if (l1 < 0.0 || l2 < 0.0 || l3 < 0.0) continue;
      nearest = std::min(nearest, l1 * w[0].z + l2 * w[1].z + l3 * w[2].z);
    }
    return nearest;
  };
  std::size_t proved = 0, wrong = 0;
  for (int j = 0; j < view.size; ++j)
    for (int i = 0; i < view.size; ++i) {
      const float cover = band.cover_depth[std::size_t(j) * std::size_t(view.size) + std::size_t(i)];
      if (cover >= 1.0f) continue;
      ++proved;
      for (int a = 0; a <= 6; ++a)
        for (int b = 0; b <= 6; ++b) {
          const double x = i + a / 6.0, y = j + b / 6.0, hit = first_hit(x, y);
          if (hit > double(cover) && ++wrong <= 5)
            ADD_FAILURE() << what << ": texel " << i << ", " << j << " covers to " << cover << " but the ray at " << x
                          << ", " << y
                          << (hit > 1e299 ? std::string(" meets nothing") : " first meets depth " + std::to_string(hit));
        }
    }
  EXPECT_EQ(wrong, 0u) << what;
  return proved;
}

// A height field seen from the light (a sheet, tessellated, bumped): its
// inside is covered; where `fold` > 0 its x is pushed back and forth
// (x + fold sin(8x)), so that it folds over itself, seen from the light.
Triangles sheet(std::mt19937& random, std::uint32_t object, float fold, float z, int n = 18) {
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  std::vector<glm::vec3> grid;
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) {
      const float u = -0.8f + 1.6f * float(x) / float(n), v = -0.8f + 1.6f * float(y) / float(n);
      grid.push_back({u + fold * std::sin(8.0f * u), v, z + 0.1f * unit(random)});
    }
  Triangles t;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const auto at = [&](int i, int k) { return grid[std::size_t(k * (n + 1) + i)]; };
      add_triangle(t, at(x, y), at(x + 1, y), at(x + 1, y + 1), object);
      add_triangle(t, at(x, y), at(x + 1, y + 1), at(x, y + 1), object);
    }
  return t;
}

void append(Triangles& to, const Triangles& more) {
  const auto base = std::uint32_t(to.positions.size());
  to.positions.insert(to.positions.end(), more.positions.begin(), more.positions.end());
  for (std::uint32_t i : more.indices) to.indices.push_back(base + i);
  to.objects.insert(to.objects.end(), more.objects.begin(), more.objects.end());
}

TEST(ConservativeMaps, TheCoverMapHoldsOnlyDepthsEveryRayMeets) {
  std::mt19937 random(5);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  // The second sheet is swollen as a curved shape is (its true surface
  // beyond its faces): more texels touched, none more covered.
  const std::vector<ConservativeObject> objects = {{0.0, true, false}, {0.03, false, false}, {0.0, true, false}};
  for (int scene = 0; scene < 12; ++scene) {
    // A sheet that folds over itself in every other scene, a second one
    // across part of it, and needles.
    Triangles t = sheet(random, 0, scene % 2 ? 0.2f : 0.0f, 0.3f);
    for (glm::vec3& p : t.positions) p.x = 0.6f * p.x - 0.3f;
    // Beside it, and across its edge; in front of it or behind it.
    Triangles second = sheet(random, 1, 0.0f, scene % 4 < 2 ? -0.2f : 0.6f, 5);
    for (glm::vec3& p : second.positions) p = glm::vec3(0.5f * p.x + 0.4f, 0.7f * p.y, p.z);
    append(t, second);
    for (int k = 0; k < 6; ++k) {
      const glm::vec3 c(unit(random) * 0.8f, unit(random) * 0.8f, unit(random) * 0.5f);
      add_triangle(t, c, c + glm::vec3(0.4f, 0.01f * unit(random), 0.1f), c + glm::vec3(0.4f, 0.002f, 0.0f), 2);
    }
    const std::size_t proved = expect_cover_holds(t, objects, orthographic_view(32 + 16 * (scene % 3)), "orthographic");
    // Most of the sheets' inside is proved.
    EXPECT_GT(proved, std::size_t(0.15 * 32 * 32)) << "scene " << scene;
  }
}

TEST(ConservativeMaps, TheCoverMapHoldsForAPointLightToo) {
  std::mt19937 random(9);
  const ConservativeView view = point_light_view();
  const std::vector<ConservativeObject> objects = {{0.0, true, false}, {0.0, false, false}};
  for (int scene = 0; scene < 6; ++scene) {
    Triangles t = sheet(random, 0, scene % 2 ? 0.2f : 0.0f, 0.0f);
    // Tilted, in front of the light; some reach behind it (clipped).
    for (glm::vec3& p : t.positions) p = glm::vec3(3.0f * p.x, 3.0f * p.y, -2.5f + 1.0f * p.x + 0.5f * p.z + 0.2f * float(scene));
    const std::size_t proved = expect_cover_holds(t, objects, view, "perspective");
    EXPECT_GT(proved, 0u) << "scene " << scene;
  }
}

// Triangles whose boxes would take more than kMostTexelTouches passes
// over the layer (swollen across it: an object whose rounding spans the
// map) are not drawn: every texel holds depth 0, owned by no point, so the
// maps prove nothing and the work stays one pass.
TEST(ConservativeMaps, TooMuchToDrawProvesNothing) {
  std::mt19937 random(2);
  const Triangles t = sheet(random, 0, 0.0f, 0.3f, 6);  // 72 triangles
  const ConservativeView view = orthographic_view(32);
  const std::vector<DrawRange> draws = {{0, t.indices.size(), CullMode::None}};
  for (const double swell : {0.0, 1.0}) {
    const ConservativeMaps maps(t.positions, t.indices, {{swell, true, false}}, t.objects, draws, view);
    EXPECT_EQ(maps.proves_nothing(), swell > 0.0) << swell;
    ConservativeBand band;
    band.x1 = band.y1 = view.size;
    maps.draw(band);
    if (swell > 0.0) {
      EXPECT_TRUE(std::all_of(band.nearest_depth.begin(), band.nearest_depth.end(), [](float d) { return d == 0.0f; }));
      EXPECT_TRUE(std::all_of(band.nearest_owner.begin(), band.nearest_owner.end(), [](std::uint32_t o) { return o == kEveryOwner; }));
      EXPECT_TRUE(std::all_of(band.others_depth.begin(), band.others_depth.end(), [](float d) { return d == 0.0f; }));
      int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
      maps.touched(x0, y0, x1, y1);
      EXPECT_TRUE(x0 <= 0 && y0 <= 0 && x1 >= view.size && y1 >= view.size);
    }
  }
}

// Without the scene's edges the cover map proves nothing.
TEST(ConservativeMaps, NoEdgesNoCover) {
  std::mt19937 random(1);
  const Triangles t = sheet(random, 0, 0.0f, 0.3f);
  const ConservativeView view = orthographic_view(32);
  ConservativeBand band;
  band.x1 = band.y1 = view.size;
  ConservativeMaps(t.positions, t.indices, {{0.0, true, false}}, t.objects, {{0, t.indices.size(), CullMode::None}}, view)
      .draw(band);
  EXPECT_TRUE(std::all_of(band.cover_depth.begin(), band.cover_depth.end(), [](float d) { return d == 1.0f; }));
}

}  // namespace
}  // namespace umbra
