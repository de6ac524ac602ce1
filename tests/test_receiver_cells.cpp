// Where a floor can be shadowed (receiver_cells.hpp), without a GPU.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/geometric.hpp>

#include "core/light_math.hpp"
#include "plan/receiver_cells.hpp"
#include "core/scene.hpp"
#include "scene_support.hpp"

namespace umbra {
namespace {

Aabb box_xz(double x0, double z0, double x1, double z1, double y = 0.0) {
  Aabb b;
  b.extend({x0, y, z0});
  b.extend({x1, y, z1});
  return b;
}

// The rectangle [x0, x1] x [z0, z1] as a region, counter-clockwise.
PlanePolygon rect_xz(double x0, double z0, double x1, double z1) { return {{x0, z0}, {x1, z0}, {x1, z1}, {x0, z1}}; }

// An orthographic view straight down from y = 10 over x, z in [-10, 10],
// depths 0..20 (world y 10..-10): 100 texels of 0.2. Eye x is world x, eye
// y is -z.
ShadowView view_down() {
  ShadowView v;
  v.view = glm::lookAt(glm::dvec3(0, 10, 0), glm::dvec3(0), glm::dvec3(0, 0, -1));
  v.projection = glm::ortho(-10.0, 10.0, -10.0, 10.0, 0.0, 20.0);
  v.near_plane = 0.0;
  v.far_plane = 20.0;
  return v;
}

TEST(ReceiverCells, ATexelRectangleSeenStraightDownIsItsSquareOnTheFloor) {
  // Texels x 50..60 (world x 0..2), y 40..50 (eye y -2..0: world z 0..2).
  const TexelRect rect{{50.0, 40.0}, {60.0, 50.0}};
  const Aabb on_floor = view_rect_on_plane(view_down(), 100, rect, 0.0);
  ASSERT_FALSE(on_floor.empty());
  EXPECT_NEAR(on_floor.min.x, 0.0, 1e-9);
  EXPECT_NEAR(on_floor.max.x, 2.0, 1e-9);
  EXPECT_NEAR(on_floor.min.z, 0.0, 1e-9);
  EXPECT_NEAR(on_floor.max.z, 2.0, 1e-9);
  EXPECT_EQ(on_floor.min.y, 0.0);
  // Within the depth range anywhere; behind the eye or beyond far, nowhere.
  EXPECT_FALSE(view_rect_on_plane(view_down(), 100, rect, -9.99).empty());
  EXPECT_TRUE(view_rect_on_plane(view_down(), 100, rect, 15.0).empty());
  EXPECT_TRUE(view_rect_on_plane(view_down(), 100, rect, -11.0).empty());
  EXPECT_TRUE(view_rect_on_plane(view_down(), 100, TexelRect{}, 0.0).empty());
}

TEST(ReceiverCells, ATexelRectangleOfAPerspectiveViewWidensWithDistance) {
  // A 90-degree view down from y = 10: at depth d a texel rectangle spans
  // d times its span at depth 1.
  ShadowView v;
  v.view = glm::lookAt(glm::dvec3(0, 10, 0), glm::dvec3(0), glm::dvec3(0, 0, -1));
  v.projection = glm::perspective(glm::radians(90.0), 1.0, 0.5, 30.0);
  const TexelRect centre{{40.0, 40.0}, {60.0, 60.0}};  // ndc -0.2..0.2
  const Aabb at_5 = view_rect_on_plane(v, 100, centre, 5.0);   // depth 5: x -1..1
  const Aabb at_0 = view_rect_on_plane(v, 100, centre, 0.0);   // depth 10: x -2..2
  EXPECT_NEAR(at_5.max.x, 1.0, 1e-9);
  EXPECT_NEAR(at_0.max.x, 2.0, 1e-9);
  EXPECT_NEAR(at_0.min.z, -2.0, 1e-9);
  EXPECT_TRUE(view_rect_on_plane(v, 100, centre, 9.7).empty());   // nearer than near (depth 0.3)
  EXPECT_TRUE(view_rect_on_plane(v, 100, centre, 10.2).empty());  // behind the eye
}

TEST(ReceiverCells, NoRegionIsOneLitCellAndARegionCutsThePlaneInNine) {
  const Aabb plane = box_xz(-10, -10, 10, 10);
  PlaneCells none = plane_cells(plane, {});
  EXPECT_EQ(none.x_cuts, (std::vector<double>{-10, 10}));
  EXPECT_EQ(none.shadowable, std::vector<bool>{false});

  PlaneCells one = plane_cells(plane, {rect_xz(1, 2, 3, 4)});
  EXPECT_EQ(one.x_cuts, (std::vector<double>{-10, 1, 3, 10}));
  EXPECT_EQ(one.z_cuts, (std::vector<double>{-10, 2, 4, 10}));
  ASSERT_EQ(one.shadowable.size(), 9u);
  for (std::size_t i = 0; i < 9; ++i) EXPECT_EQ(one.shadowable[i], i == 4) << i;

  // Clipped to the plane; a region past its side leaves no cell.
  PlaneCells edge = plane_cells(plane, {rect_xz(5, -20, 30, 20), rect_xz(40, 0, 50, 1)});
  EXPECT_EQ(edge.x_cuts, (std::vector<double>{-10, 5, 10}));
  EXPECT_EQ(edge.z_cuts, (std::vector<double>{-10, 10}));
  EXPECT_EQ(edge.shadowable, (std::vector<bool>{false, true}));
}

TEST(ReceiverCells, ManyRegionsAreMergedButEveryOneStaysShadowable) {
  const Aabb plane = box_xz(-100, -100, 100, 100);
  std::vector<Aabb> regions;
  std::vector<PlanePolygon> polygons;
  for (int k = 0; k < 20; ++k) regions.push_back(box_xz(-95 + 9 * k, -95 + 9 * k, -93 + 9 * k, -93 + 9 * k));
  regions.push_back(box_xz(0, 0, 50, 50));  // overlaps several
  for (const Aabb& r : regions) polygons.push_back(rect_xz(r.min.x, r.min.z, r.max.x, r.max.z));
  const PlaneCells cells = plane_cells(plane, polygons);
  // The merged boxes' sides, and strips where the boxes are mostly empty.
  EXPECT_LE(cells.x_cuts.size(), std::size_t(2 * kMaxReceiverRegions + 2 + kRefinedCuts));
  EXPECT_LE(cells.z_cuts.size(), std::size_t(2 * kMaxReceiverRegions + 2 + kRefinedCuts));
  const auto cell_of = [&](double x, double z) {
    const auto i = std::upper_bound(cells.x_cuts.begin(), cells.x_cuts.end(), x) - cells.x_cuts.begin() - 1;
    const auto j = std::upper_bound(cells.z_cuts.begin(), cells.z_cuts.end(), z) - cells.z_cuts.begin() - 1;
    return cells.shadowable[std::size_t(j) * (cells.x_cuts.size() - 1) + std::size_t(i)];
  };
  for (const Aabb& r : regions)
    for (double fx : {0.01, 0.5, 0.99})
      for (double fz : {0.01, 0.5, 0.99})
        EXPECT_TRUE(cell_of(r.min.x + fx * (r.max.x - r.min.x), r.min.z + fz * (r.max.z - r.min.z)));
  EXPECT_FALSE(cell_of(99, -99));  // far from all of them
}

TEST(ReceiverCells, OneRegionPerViewAroundAllItsCastersHoldsThePerCasterOnes) {
  const RenderRequest r = test::builtin_request("three-cubes");
  const ShadowPlan plan = plan_shadow(r);
  const Mesh mesh = tessellate(r.scene);
  std::vector<bool> drawn(mesh.bounds.size(), true);
  drawn[0] = false;  // all but the floor
  const CasterTexels table = caster_texels_by_view(plan, mesh.bounds, drawn);
  std::vector<Aabb> per_caster, per_view;
  for (const PlanePolygon& p : shadowable_regions(-0.5, plan, table.by_object, 4.0))
    per_caster.push_back(bounds_on_plane(p, -0.5));
  for (const PlanePolygon& p : view_regions(-0.5, plan, table.by_view, 4.0)) per_view.push_back(bounds_on_plane(p, -0.5));
  ASSERT_FALSE(per_caster.empty());
  ASSERT_FALSE(per_view.empty());
  for (const Aabb& c : per_caster) {
    bool held = false;
    for (const Aabb& v : per_view)
      held = held || (v.min.x <= c.min.x + 1e-9 && v.min.z <= c.min.z + 1e-9 && c.max.x <= v.max.x + 1e-9 &&
                      c.max.z <= v.max.z + 1e-9);
    EXPECT_TRUE(held);
  }
}

// The property the main pass relies on: a floor point whose texel in some
// view that holds it lies within a caster's rectangle (and the filter's
// reach) is in a shadowable cell. Checked on a grid of floor points for a
// directional light's cascades, a spot-like cone and a point light's faces.
void expect_every_readable_point_shadowable(RenderRequest r) {
  const ShadowPlan plan = plan_shadow(r);
  const Mesh mesh = tessellate(r.scene);
  ASSERT_EQ(mesh.planes.size(), 1u);
  const PlaneRange& floor = mesh.planes[0];
  ASSERT_FALSE(plane_can_shadow(floor, plan));
  std::vector<Aabb> casters;
  std::vector<bool> drawn(mesh.bounds.size(), true);
  drawn[floor.object] = false;
  for (std::size_t i = 0; i < mesh.bounds.size(); ++i)
    if (drawn[i]) casters.push_back(mesh.bounds[i]);
  const double margin = filter_read_texels(r.shadow) + 1.0;
  const Aabb bounds = mesh.bounds[floor.object];
  const PlaneCells cells =
      plane_cells(bounds, shadowable_regions(floor.height, plan, caster_texels_by_view(plan, mesh.bounds, drawn).by_object, margin));
  const std::size_t columns = cells.x_cuts.size() - 1;
  int readable = 0, unshadowable_cells = 0;
  for (bool s : cells.shadowable) unshadowable_cells += !s;
  // A grid over the floor, and a finer one over the middle, where the
  // casters' rectangles end (0.02 units: about a texel of the finest view).
  std::vector<glm::dvec3> points;
  constexpr int kSteps = 400;
  for (int a = 0; a <= kSteps; ++a)
    for (int b = 0; b <= kSteps; ++b)
      points.push_back({bounds.min.x + (bounds.max.x - bounds.min.x) * a / kSteps, floor.height,
                        bounds.min.z + (bounds.max.z - bounds.min.z) * b / kSteps});
  for (int a = -200; a <= 200; ++a)
    for (int b = -200; b <= 200; ++b) points.push_back({0.02 * a + 0.007, floor.height, 0.02 * b + 0.003});
  for (const glm::dvec3& p : points) {
    {
      bool reads_a_caster = false;
      for (const ShadowView& view : plan.views) {
        if (view.empty) continue;
        const glm::dvec4 clip = view.view_projection() * glm::dvec4(p, 1.0);
        const glm::dvec3 ndc = glm::dvec3(clip) / clip.w;
        if (clip.w <= 0.0 || std::abs(ndc.x) > 1.0 || std::abs(ndc.y) > 1.0 || std::abs(ndc.z) > 1.0) continue;
        const glm::dvec2 texel = (glm::dvec2(ndc) * 0.5 + 0.5) * double(plan.layer_size);
        for (const Aabb& caster : casters) {
          const TexelRect rect = caster_texels(view, plan.layer_size, {caster});
          if (rect.empty()) continue;
          reads_a_caster = reads_a_caster || (texel.x > rect.min.x - (margin - 1.0) && texel.y > rect.min.y - (margin - 1.0) &&
                                              texel.x < rect.max.x + (margin - 1.0) && texel.y < rect.max.y + (margin - 1.0));
        }
      }
      if (!reads_a_caster) continue;
      ++readable;
      const auto i = std::min<std::ptrdiff_t>(
          std::upper_bound(cells.x_cuts.begin(), cells.x_cuts.end(), p.x) - cells.x_cuts.begin() - 1, std::ptrdiff_t(columns) - 1);
      const auto j = std::min<std::ptrdiff_t>(
          std::upper_bound(cells.z_cuts.begin(), cells.z_cuts.end(), p.z) - cells.z_cuts.begin() - 1,
          std::ptrdiff_t(cells.z_cuts.size()) - 2);
      ASSERT_TRUE(cells.shadowable[std::size_t(j) * columns + std::size_t(i)]) << "at " << p.x << ", " << p.z;
    }
  }
  // Not vacuous: some of the floor reads a caster, and some cells need not.
  EXPECT_GT(readable, 0);
  EXPECT_GT(unshadowable_cells, 0);
}

TEST(ReceiverCells, EveryFloorPointThatCanReadACasterIsInAShadowableCell) {
  RenderRequest sun = test::builtin_request("three-cubes");  // cascades
  expect_every_readable_point_shadowable(sun);
  sun.shadow.filter = ShadowFilter::Pcss;  // reads 65 texels out
  sun.light.size = 2.0;
  expect_every_readable_point_shadowable(sun);
  RenderRequest cone = test::builtin_request("three-cubes");  // one cone from high above
  cone.light.projection = LightProjection::Perspective;
  cone.light.position = {0.5, 40.0, 0.5};
  ASSERT_EQ(plan_shadow(cone).layout, ShadowLayout::Single);
  expect_every_readable_point_shadowable(cone);
  RenderRequest faces = test::builtin_request("three-cubes");  // six faces, amid the cubes
  faces.light.projection = LightProjection::Perspective;
  faces.light.position = {0.2, 1.5, 0.3};
  ASSERT_EQ(plan_shadow(faces).layout, ShadowLayout::Cube);
  expect_every_readable_point_shadowable(faces);
}

// Six posts in a ring around a point light lower than their tops: each
// shadow is a wedge from its post to the floor's edge (bench scene
// `point-wide`). The wedges' boxes merge into most of the floor; the cells
// follow the wedges instead, and still hold every point that can read a
// post's texel.
TEST(ReceiverCells, WedgesAcrossTheFloorAreFollowedByTheCells) {
  RenderRequest r;
  SceneObject floor;
  floor.type = SceneObject::Type::Plane;
  floor.size = {30, 1, 30};
  r.scene.objects.push_back(floor);
  for (int k = 0; k < 6; ++k) {
    SceneObject post;
    post.type = SceneObject::Type::Box;
    post.center = {3.0 * std::cos(k * M_PI / 3.0), 0.75, 3.0 * std::sin(k * M_PI / 3.0)};
    post.size = {0.6, 1.5, 0.6};
    post.rotation_y_deg = -60.0 * k;
    r.scene.objects.push_back(post);
  }
  r.camera.position = {7, 6, 9};
  r.camera.target = {0, 0.5, 0};
  r.light.projection = LightProjection::Perspective;
  r.light.position = {0, 1, 0};
  r.light.target = {0, 0, 0};
  const ShadowPlan plan = plan_shadow(r);
  ASSERT_EQ(plan.layout, ShadowLayout::Cube);
  expect_every_readable_point_shadowable(r);

  const Mesh mesh = tessellate(r.scene);
  std::vector<bool> drawn(mesh.bounds.size(), true);
  drawn[0] = false;
  const double margin = filter_read_texels(r.shadow) + 1.0;
  const PlaneCells cells =
      plane_cells(mesh.bounds[0], shadowable_regions(0.0, plan, caster_texels_by_view(plan, mesh.bounds, drawn).by_object, margin));
  double shadowable = 0.0;
  const std::size_t columns = cells.x_cuts.size() - 1;
  for (std::size_t j = 0; j + 1 < cells.z_cuts.size(); ++j)
    for (std::size_t i = 0; i < columns; ++i)
      if (cells.shadowable[j * columns + i])
        shadowable += (cells.x_cuts[i + 1] - cells.x_cuts[i]) * (cells.z_cuts[j + 1] - cells.z_cuts[j]);
  // The wedges cover about a quarter of the floor and their boxes 82 % of
  // it; the cells about 45 %.
  EXPECT_LT(shadowable, 0.5 * 30.0 * 30.0);
  RecordProperty("shadowable_area", std::to_string(shadowable));
}

TEST(ReceiverCells, CellTrianglesFaceUpAsTheWholePlanesDoAndShareTheirCorners) {
  PlaneCells cells = plane_cells(box_xz(-10, -10, 10, 10, -0.5), {rect_xz(1, 2, 3, 4)});
  CellTriangles out;
  append_cell_triangles(cells, -0.5, {0.5, 0.6, 0.7}, {1.0, 0.0, 0.0}, out);
  EXPECT_EQ(out.vertices.size(), 16u);  // a 4 x 4 grid of corners
  EXPECT_EQ(out.shadowable.size(), 6u);
  EXPECT_EQ(out.unshadowable.size(), 48u);
  std::vector<std::uint32_t> all = out.shadowable;
  all.insert(all.end(), out.unshadowable.begin(), out.unshadowable.end());
  double area = 0.0;
  for (std::size_t t = 0; t < all.size(); t += 3) {
    const auto at = [&](std::size_t k) {
      const Vertex& v = out.vertices[all[t + k]];
      return glm::dvec3(v.position[0], v.position[1], v.position[2]);
    };
    const glm::dvec3 n = glm::cross(at(1) - at(0), at(2) - at(0));
    EXPECT_GT(n.y, 0.0);
    area += 0.5 * n.y;
  }
  EXPECT_NEAR(area, 400.0, 1e-3);  // they tile the plane
  // Relative to the origin, with the plane's colour and normal.
  EXPECT_EQ(out.vertices[0].position[0], -11.0f);
  EXPECT_EQ(out.vertices[0].normal[1], 1.0f);
  EXPECT_EQ(out.vertices[0].color[2], 0.7f);
  // tessellate's plane faces the same way.
  Scene scene;
  SceneObject plane;
  plane.type = SceneObject::Type::Plane;
  plane.size = {2.0, 0.0, 2.0};
  scene.objects.push_back(plane);
  const Mesh mesh = tessellate(scene);
  const auto p = [&](std::size_t k) {
    const Vertex& v = mesh.vertices[mesh.indices[k]];
    return glm::dvec3(v.position[0], v.position[1], v.position[2]);
  };
  EXPECT_GT(glm::cross(p(1) - p(0), p(2) - p(0)).y, 0.0);
}

}  // namespace
}  // namespace umbra
