// Light-space and camera math, without a GPU.
#include <gtest/gtest.h>

#include <cmath>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <glm/trigonometric.hpp>

#include "core/light_math.hpp"
#include "core/scene.hpp"
#include "scene_support.hpp"

namespace umbra {
namespace {

bool finite(const glm::dmat4& m) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(m[c][r])) return false;
  return true;
}

RenderRequest request_with_light(glm::dvec3 position, LightProjection projection, const char* scene = "three-cubes") {
  RenderRequest r;
  const BuiltinScene* s = find_builtin_scene(scene);
  r.scene.name = s->name;
  r.scene.objects = s->objects;
  r.camera.position = s->camera_position;
  r.camera.target = s->camera_target;
  r.light.position = position;
  r.light.projection = projection;
  return r;
}

// Every point the camera sees of every object is held by some view of the
// light (inside its clip volume), as are the objects that can shadow it.
void expect_visible_scene_inside(const RenderRequest& r) {
  const ShadowPlan plan = plan_shadow(r);
  ASSERT_FALSE(plan.views.empty());
  const CameraMatrices camera = camera_matrices(r.camera, r.width, r.height);
  int checked = 0;
  for (const auto& o : r.scene.objects) {
    for (const auto& p : frustum_box_intersection(camera.projection * camera.view, object_bounds(o))) {
      bool held = false;
      for (const ShadowView& v : plan.views) {
        ASSERT_TRUE(finite(v.view_projection()));
        const glm::dvec4 clip = v.view_projection() * glm::dvec4(p, 1.0);
        if (clip.w <= 0.0) continue;
        const glm::dvec3 ndc = glm::dvec3(clip) / clip.w;
        held = held || (std::abs(ndc.x) <= 1.0 && std::abs(ndc.y) <= 1.0 && std::abs(ndc.z) <= 1.0);
      }
      EXPECT_TRUE(held) << "visible point " << p.x << "," << p.y << "," << p.z << " is in no view";
      ++checked;
    }
  }
  EXPECT_GT(checked, 0);
}

class FitsTheScene : public testing::TestWithParam<std::tuple<LightProjection, glm::dvec3>> {};

TEST_P(FitsTheScene, EveryVisiblePointInsideAView) {
  const auto [projection, position] = GetParam();
  expect_visible_scene_inside(request_with_light(position, projection));
}

INSTANTIATE_TEST_SUITE_P(
    Lights, FitsTheScene,
    testing::Combine(testing::Values(LightProjection::Orthographic, LightProjection::Perspective),
                     testing::Values(glm::dvec3(-2, 4, -1), glm::dvec3(0, 5, 0),   // overhead
                                     glm::dvec3(0.0001, 5, 0), glm::dvec3(10, 0.35, 0),  // ~2 degrees high
                                     glm::dvec3(0, -3, 0.5))));                          // from below

TEST(ScreenPixels, ABoxCoversItsProjectedRectangleCutToTheImage) {
  Camera camera;
  camera.position = {0, 0, 10};
  camera.target = {0, 0, 0};
  camera.fov_y_deg = 90.0;  // at distance 10: y in [-10, 10], x in [-20, 20], 5 pixels a unit
  Aabb box;
  box.extend({-1, -1, 0});
  box.extend({1, 1, 0});
  EXPECT_NEAR(screen_pixels_of(box, camera, 200, 100), 10.0 * 10.0, 1e-6);
  box.extend({100, 0, 0});  // past the right edge (x = 20): cut there
  EXPECT_NEAR(screen_pixels_of(box, camera, 200, 100), 105.0 * 10.0, 1e-6);
  box.extend({0, 0, 20});  // behind the eye: the whole image
  EXPECT_EQ(screen_pixels_of(box, camera, 200, 100), 200.0 * 100.0);
  EXPECT_EQ(screen_pixels_of(Aabb{}, camera, 200, 100), 0.0);
}

TEST(LightSplit, OnlyClosedMeshesCoveringFourPixelsPerTriangleAreSplit) {
  Scene scene;
  SceneObject plane;
  plane.type = SceneObject::Type::Plane;
  plane.size = {20, 1, 20};
  SceneObject box;
  box.type = SceneObject::Type::Box;
  box.center = {0, 0.5, 0};
  SceneObject near_sphere;  // 9,024 triangles over ~45,000 pixels (36,096 needed)
  near_sphere.type = SceneObject::Type::Sphere;
  near_sphere.center = {0, 1, 3};
  near_sphere.radius = 1.0;
  SceneObject far_sphere = near_sphere;  // ... over a few hundred
  far_sphere.center = {0, 1, -40};
  scene.objects = {plane, box, near_sphere, far_sphere};
  Camera camera;
  camera.position = {0, 2, 8};
  camera.target = {0, 1, 0};
  EXPECT_EQ(objects_split_by_the_light(tessellate(scene), camera, 640, 360),
            (std::vector<bool>{false, true, true, false}));
}

TEST(FrustumBoxIntersection, UnitCubeInsideAFrustumIsItself) {
  const glm::dmat4 vp = glm::ortho(-5.0, 5.0, -5.0, 5.0, -5.0, 5.0);
  Aabb box;
  box.extend(glm::dvec3(-1.0));
  box.extend(glm::dvec3(1.0));
  const auto points = frustum_box_intersection(vp, box);
  EXPECT_EQ(points.size(), 8u);
  for (const auto& p : points) EXPECT_DOUBLE_EQ(glm::length(p), std::sqrt(3.0));
}

TEST(FrustumBoxIntersection, AFlatPlaneIsCutToTheFrustum) {
  // Camera 2 units above a 100 x 100 plane, looking straight down with a
  // 90 degree field of view: it sees a 4 x 4 square of it.
  const glm::dmat4 vp = glm::perspective(glm::radians(90.0), 1.0, 0.1, 100.0) *
                        stable_look_at({0, 2, 0}, {0, 0, 0}, {0, 1, 0});
  Aabb plane;
  plane.extend(glm::dvec3(-50, 0, -50));
  plane.extend(glm::dvec3(50, 0, 50));
  const auto points = frustum_box_intersection(vp, plane);
  ASSERT_FALSE(points.empty());
  for (const auto& p : points) {
    EXPECT_NEAR(p.y, 0.0, 1e-9);
    EXPECT_LE(std::abs(p.x), 2.0 + 1e-9);
    EXPECT_LE(std::abs(p.z), 2.0 + 1e-9);
  }
  EXPECT_TRUE(frustum_box_intersection(vp, [] {
                Aabb far_away;
                far_away.extend(glm::dvec3(60, 0, 60));
                far_away.extend(glm::dvec3(61, 1, 61));
                return far_away;
              }()).empty());
}

RenderRequest huge_plane_request() {
  RenderRequest r;
  r.scene.objects = find_builtin_scene("cube-on-plane")->objects;
  r.scene.objects[0].size = {1000.0, 0.0, 1000.0};
  r.camera.position = {2.2, 1.6, 3.0};
  r.camera.target = {0.0, 0.4, 0.0};
  r.camera.near_plane = 0.05;
  r.camera.far_plane = 2000.0;
  r.light.position = {-20, 40, -10};
  return r;
}

TEST(Cascades, ACloseCameraOverAHugeFloorGetsFineNearCascades) {
  const RenderRequest r = huge_plane_request();
  const ShadowPlan plan = plan_shadow(r);
  ASSERT_EQ(plan.layout, ShadowLayout::Cascades);
  ASSERT_EQ(plan.views.size(), std::size_t(kMaxCascades));
  // Each cascade is coarser than the one before; the first resolves the
  // nearby cube far better than one map over 1000 units could.
  for (std::size_t i = 1; i < plan.views.size(); ++i)
    EXPECT_GT(plan.views[i].texel_size.x, plan.views[i - 1].texel_size.x);
  EXPECT_LT(plan.views[0].texel_size.x, 0.01);
  expect_visible_scene_inside(r);
}

TEST(Cascades, TheSeedsSceneNeedsFewAndAnExplicitCountIsObeyed) {
  RenderRequest r = request_with_light({-2, 4, -1}, LightProjection::Orthographic, "cube-on-plane");
  r.camera.position = {2.5, 3.0, 5.0};
  r.camera.target = {0.6, -0.3, 0.6};
  EXPECT_LE(plan_shadow(r).views.size(), 3u);
  r.shadow.cascades = 1;
  EXPECT_EQ(plan_shadow(r).views.size(), 1u);
  EXPECT_EQ(plan_shadow(r).layout, ShadowLayout::Single);
  r.shadow.cascades = 3;
  EXPECT_EQ(plan_shadow(r).views.size(), 3u);
}

TEST(Cascades, TexelGridIsSnappedSoShadowsDoNotShimmer) {
  // Sliding the camera a little keeps the width (quantised) and moves the
  // rectangle by whole texels only.
  RenderRequest r = huge_plane_request();
  r.shadow.cascades = 1;
  const ShadowView a = plan_shadow(r).views[0];
  r.camera.position += glm::dvec3(0.0123, 0.0, 0.0071);
  r.camera.target += glm::dvec3(0.0123, 0.0, 0.0071);
  const ShadowView b = plan_shadow(r).views[0];
  ASSERT_DOUBLE_EQ(a.texel_size.x, b.texel_size.x);
  for (const ShadowView* v : {&a, &b}) {
    // ortho: left = -(m[3][0] + 1) / m[0][0]
    const double left = -(v->projection[3][0] + 1.0) / v->projection[0][0];
    const double in_texels = left / v->texel_size.x;
    EXPECT_NEAR(in_texels, std::round(in_texels), 1e-6);
  }
}

TEST(Planes, APlaneShadowsOnlyWhatLiesBeyondItFromTheLight) {
  PlaneRange floor;
  floor.height = 0.0;
  floor.lowest_other = 0.0;  // a box standing on it
  floor.highest_other = 2.0;
  ShadowPlan sun;
  sun.direction = glm::normalize(glm::dvec3(1, -2, 0));  // from above
  EXPECT_FALSE(plane_can_shadow(floor, sun));
  sun.direction.y = -sun.direction.y;  // from below: the box is in its shadow
  EXPECT_TRUE(plane_can_shadow(floor, sun));
  sun.direction = {1, 0, 0};  // edge-on
  EXPECT_FALSE(plane_can_shadow(floor, sun));

  ShadowPlan lamp;
  lamp.perspective = true;
  lamp.position = {0, 3, 0};
  EXPECT_FALSE(plane_can_shadow(floor, lamp));
  floor.lowest_other = -0.01;  // something reaches under the floor
  EXPECT_TRUE(plane_can_shadow(floor, lamp));
  floor.lowest_other = 0.0;
  lamp.position.y = -1.0;  // a lamp under the floor, the box above it
  EXPECT_TRUE(plane_can_shadow(floor, lamp));
  floor.highest_other = 0.0;  // ... or nothing above it
  EXPECT_FALSE(plane_can_shadow(floor, lamp));

  PlaneRange alone;  // a scene of one plane: nothing else to shadow
  EXPECT_FALSE(plane_can_shadow(alone, lamp));
  lamp.position.y = 1.0;
  EXPECT_FALSE(plane_can_shadow(alone, lamp));
}

TEST(CasterTexels, TheRectangleAroundWhatAViewCanDraw) {
  // An orthographic view down -Z over x, y in [-10, 10]: 100 texels of 0.2.
  ShadowView view;
  view.projection = glm::ortho(-10.0, 10.0, -10.0, 10.0, 0.0, 100.0);
  view.view = glm::translate(glm::dmat4(1.0), glm::dvec3(0, 0, -50));
  Aabb box;
  box.extend({1.0, 2.0, -1.0});
  box.extend({2.0, 3.0, 1.0});
  TexelRect r = caster_texels(view, 100, {box});
  // x 1..2 -> texels 55..60, y 2..3 -> 60..65, one texel wider each way.
  EXPECT_EQ(r.min, glm::dvec2(54.0, 59.0));
  EXPECT_EQ(r.max, glm::dvec2(61.0, 66.0));
  EXPECT_TRUE(caster_texels(view, 100, {}).empty());
  Aabb beside;  // wholly outside the view
  beside.extend({30.0, 0.0, 0.0});
  beside.extend({31.0, 1.0, 1.0});
  EXPECT_TRUE(caster_texels(view, 100, {beside}).empty());
  // Half out: clamped to the layer.
  beside.min.x = 5.0;
  r = caster_texels(view, 100, {beside});
  EXPECT_EQ(r.max.x, 100.0);
  EXPECT_EQ(r.min.x, 74.0);

  // A 90-degree cube face looking down -Z from the origin: a box that
  // reaches behind the eye holds only what lies in front, cut to the face.
  ShadowView face;
  face.projection = glm::perspective(glm::radians(90.0), 1.0, 0.1, 100.0);
  Aabb across;
  across.extend({-0.5, -0.5, -10.0});
  across.extend({0.5, 0.5, 10.0});
  r = caster_texels(face, 200, {across});
  EXPECT_FALSE(r.empty());
  // In front, its nearest part (z = -0.1, the near plane) spans the face.
  EXPECT_EQ(r.min, glm::dvec2(0.0));
  EXPECT_EQ(r.max, glm::dvec2(200.0));
  Aabb behind;
  behind.extend({-1.0, -1.0, 1.0});
  behind.extend({1.0, 1.0, 2.0});
  EXPECT_TRUE(caster_texels(face, 200, {behind}).empty());
  Aabb ahead;  // x, y in [-1, 1] at depth 10..20: within +-0.1 of the centre
  ahead.extend({-1.0, -1.0, -20.0});
  ahead.extend({1.0, 1.0, -10.0});
  r = caster_texels(face, 200, {ahead, behind});
  for (int axis = 0; axis < 2; ++axis) {  // texels 90..110, give or take rounding
    EXPECT_GE(r.min[axis], 88.0);
    EXPECT_LE(r.min[axis], 89.0);
    EXPECT_GE(r.max[axis], 111.0);
    EXPECT_LE(r.max[axis], 112.0);
  }
}

// The per-frame table: each object's rectangle is caster_texels of it
// alone, and each view's is exactly caster_texels of all drawn objects at
// once, for cascades and for cube faces (whose empty views stay empty).
TEST(CasterTexels, TheTablePerObjectAndPerViewAgreesWithTheRectanglesItReplaces) {
  for (const LightProjection projection : {LightProjection::Orthographic, LightProjection::Perspective}) {
    RenderRequest r = request_with_light(projection == LightProjection::Perspective ? glm::dvec3(0, 1.2, 0)
                                                                                     : glm::dvec3(-2, 4, -1),
                                         projection);
    const ShadowPlan plan = plan_shadow(r);
    const Mesh mesh = tessellate(r.scene);
    std::vector<bool> drawn(mesh.bounds.size(), true);
    drawn[1] = false;  // one object left out, as a plane under the scene is
    std::vector<Aabb> casters;
    for (std::size_t i = 0; i < drawn.size(); ++i)
      if (drawn[i]) casters.push_back(mesh.bounds[i]);
    const CasterTexels table = caster_texels_by_view(plan, mesh.bounds, drawn);
    ASSERT_EQ(table.by_view.size(), plan.views.size());
    ASSERT_EQ(table.by_object.size(), plan.views.size());
    int non_empty = 0;
    for (std::size_t v = 0; v < plan.views.size(); ++v) {
      const ShadowView& view = plan.views[v];
      const TexelRect all = view.empty ? TexelRect{} : caster_texels(view, plan.layer_size, casters);
      EXPECT_EQ(table.by_view[v].min, all.min) << v;
      EXPECT_EQ(table.by_view[v].max, all.max) << v;
      for (std::size_t i = 0; i < drawn.size(); ++i) {
        const TexelRect one =
            view.empty || !drawn[i] ? TexelRect{} : caster_texels(view, plan.layer_size, {mesh.bounds[i]});
        EXPECT_EQ(table.by_object[v][i].min, one.min) << v << " " << i;
        EXPECT_EQ(table.by_object[v][i].max, one.max) << v << " " << i;
        non_empty += !one.empty();
      }
    }
    EXPECT_GT(non_empty, 1);
  }
}

// What drop_casters_held_by_earlier_cascades rests on, checked by
// sampling rather than by its convex clipping: every sampled scene point
// within the filter's read of an object's rectangle in cascade k and
// farther from the light than the object's nearest point is looked up (as
// scene.frag's choose_view picks) in another cascade than k, wherever the
// object was left out of k.
int view_chosen_for(const ShadowPlan& plan, int reach, const glm::dvec3& p) {
  int fallback = -1;
  for (std::size_t i = 0; i < plan.views.size(); ++i) {
    const glm::dvec3 ndc = glm::dvec3(plan.views[i].view_projection() * glm::dvec4(p, 1.0));
    if (std::abs(ndc.x) > 1.0 || std::abs(ndc.y) > 1.0 || std::abs(ndc.z) > 1.0) continue;
    const glm::dvec2 texel = (glm::dvec2(ndc) * 0.5 + 0.5) * double(plan.layer_size);
    const bool with_reach = texel.x >= reach && texel.y >= reach && texel.x <= plan.layer_size - reach &&
                            texel.y <= plan.layer_size - reach;
    if (with_reach) return int(i);
    if (fallback < 0) fallback = int(i);
  }
  return fallback;
}

// Points on a grid through each box (a flat box, a floor, gets a finer one).
std::vector<glm::dvec3> grid_points(const std::vector<Aabb>& boxes) {
  std::vector<glm::dvec3> points;
  for (const Aabb& b : boxes) {
    const glm::dvec3 e = b.extent();
    const bool flat = e.y < 1e-6 * std::max(e.x, e.z);
    const int n = flat ? 400 : 24, ny = flat ? 0 : 24;
    for (int i = 0; i <= n; ++i)
      for (int j = 0; j <= ny; ++j)
        for (int k = 0; k <= n; ++k)
          points.push_back(b.min + e * glm::dvec3(double(i) / n, ny == 0 ? 0.5 : double(j) / ny, double(k) / n));
  }
  return points;
}

TEST(CascadeCasters, AnObjectIsLeftOutOfACascadeOnlyWhereItShadowsNothingThatLooksItUp) {
  int dropped = 0, kept_though_the_first_holds_it = 0, sampled = 0;
  for (const char* scene : {"teapot", "three-cubes"}) {
    for (double time = 0.0; time < 18.0; time += 1.5) {
      RenderRequest r = request_with_light({-2.0, 4.0, -1.0}, LightProjection::Orthographic, scene);
      r.time = time;
      r.width = 960;
      r.height = 540;
      const ShadowPlan plan = plan_shadow(r);
      if (plan.layout != ShadowLayout::Cascades) continue;
      const Mesh mesh = tessellate(r.scene);
      const std::vector<bool> all(mesh.bounds.size(), true);
      const CasterTexels before = caster_texels_by_view(plan, mesh.bounds, all);
      CasterTexels after = before;
      const int read = filter_read_texels(r.shadow), reach = filter_reach_texels(r.shadow);
      drop_casters_held_by_earlier_cascades(plan, mesh.bounds, all, r.shadow, after);
      const std::vector<glm::dvec3> points = grid_points(mesh.bounds);
      const glm::dmat4& light_view = plan.views[0].view;
      for (std::size_t k = 0; k < plan.views.size(); ++k) {
        // by_view is the bounding rectangle of what is left in its row.
        std::vector<Aabb> left;
        for (std::size_t i = 0; i < mesh.bounds.size(); ++i)
          if (!after.by_object[k][i].empty()) left.push_back(mesh.bounds[i]);
        const TexelRect rect = plan.views[k].empty ? TexelRect{} : caster_texels(plan.views[k], plan.layer_size, left);
        EXPECT_EQ(after.by_view[k].min, rect.min) << scene << " t=" << time << " view " << k;
        EXPECT_EQ(after.by_view[k].max, rect.max) << scene << " t=" << time << " view " << k;
        for (std::size_t i = 0; i < mesh.bounds.size(); ++i) {
          if (k == 0) {
            EXPECT_EQ(after.by_object[0][i].min, before.by_object[0][i].min);  // the first cascade keeps all
            EXPECT_EQ(after.by_object[0][i].max, before.by_object[0][i].max);
            continue;
          }
          if (before.by_object[k][i].empty()) continue;
          Aabb extent;  // the object in light eye space
          for (const glm::dvec3& c : mesh.bounds[i].corners()) extent.extend(glm::dvec3(light_view * glm::dvec4(c, 1.0)));
          if (!after.by_object[k][i].empty()) {
            bool first_holds_it = true;
            for (const glm::dvec3& c : mesh.bounds[i].corners())
              first_holds_it = first_holds_it && view_chosen_for(plan, reach, c) == 0;
            kept_though_the_first_holds_it += first_holds_it;
            continue;
          }
          ++dropped;
          const glm::dvec2 grow = double(read) * plan.views[k].texel_size;
          for (const glm::dvec3& p : points) {
            const glm::dvec3 e = glm::dvec3(light_view * glm::dvec4(p, 1.0));
            if (e.x < extent.min.x - grow.x || e.x > extent.max.x + grow.x || e.y < extent.min.y - grow.y ||
                e.y > extent.max.y + grow.y || e.z > extent.max.z)
              continue;
            ++sampled;
            EXPECT_NE(view_chosen_for(plan, reach, p), int(k))
                << scene << " t=" << time << ": object " << i << " was left out of view " << k << ", which point "
                << p.x << "," << p.y << "," << p.z << " is looked up in";
          }
        }
      }
    }
  }
  // Both answers occur, and the drops were checked at many points.
  EXPECT_GT(dropped, 0);
  EXPECT_GT(kept_though_the_first_holds_it, 0);
  EXPECT_GT(sampled, 1000);
}

// Two cascades made by hand under a light straight above a unit cube on a
// floor: the first `half_width` either way of the cube's axis and
// `far_plane` deep (the floor lies 10 from the light), the second 4 either
// way. Both 256^2 texels.
ShadowPlan two_cascades(double half_width, double far_plane) {
  ShadowPlan plan;
  plan.layout = ShadowLayout::Cascades;
  plan.layer_size = 256;
  const glm::dmat4 view = glm::lookAt(glm::dvec3(0.0, 10.0, 0.0), glm::dvec3(0.0), glm::dvec3(0.0, 0.0, -1.0));
  for (const auto& [half, far] : {std::pair{half_width, far_plane}, std::pair{4.0, 20.0}}) {
    ShadowView v;
    v.view = view;
    v.near_plane = 1.0;
    v.far_plane = far;
    v.projection = glm::ortho(-half, half, -half, half, 1.0, far);
    v.texel_size = glm::dvec2(2.0 * half / plan.layer_size);
    plan.views.push_back(v);
  }
  return plan;
}

// Where the margins lie: with 3x3 PCF (which reads 3 texels around a point)
// the cube's prism in the second cascade reaches 0.5 + 4 x 8/256 = 0.625
// from its axis, and the first cascade holds a point with the read to
// spare within 1 - 2 x 4/256 of its half width: a half width of 0.66
// holds the prism, 0.635 does not. In depth, the floor must lie inside
// the first cascade's far plane by more than 1e-3 of clip depth (0.0045
// of 9 units here).
TEST(CascadeCasters, TheMarginsAreTheFiltersReadAndItsReach) {
  const std::vector<Aabb> bounds = {Aabb{{-0.5, 0.0, -0.5}, {0.5, 1.0, 0.5}}, Aabb{{-20.0, 0.0, -20.0}, {20.0, 0.0, 20.0}}};
  const std::vector<bool> cube_only = {true, false};
  const ShadowSettings pcf;  // the defaults: 3x3 PCF, automatic bias
  ASSERT_EQ(filter_read_texels(pcf), 3);
  const auto cube_left_in_second = [&](const ShadowPlan& plan, const ShadowSettings& shadow) {
    CasterTexels table = caster_texels_by_view(plan, bounds, {true, true});
    EXPECT_FALSE(table.by_object[1][0].empty());
    const bool dropped = drop_casters_held_by_earlier_cascades(plan, bounds, cube_only, shadow, table);
    EXPECT_FALSE(table.by_object[0][0].empty()) << "the first cascade keeps everything";
    EXPECT_FALSE(table.by_object[1][1].empty()) << "only candidates are taken out";
    EXPECT_EQ(dropped, table.by_object[1][0].empty());
    return !table.by_object[1][0].empty();
  };
  EXPECT_FALSE(cube_left_in_second(two_cascades(0.66, 12.0), pcf));
  EXPECT_TRUE(cube_left_in_second(two_cascades(0.635, 12.0), pcf)) << "the prism reaches past what it holds";
  EXPECT_TRUE(cube_left_in_second(two_cascades(0.66, 10.003), pcf)) << "the floor under it is too near the far plane";
  ShadowSettings hard = pcf;
  hard.filter = ShadowFilter::Hard;  // reads 1 texel: 0.5 + 2 x 8/256 = 0.5625 within 1 - 4/256 of 0.6
  EXPECT_FALSE(cube_left_in_second(two_cascades(0.6, 12.0), hard));
  EXPECT_TRUE(cube_left_in_second(two_cascades(0.6, 12.0), pcf));
  ShadowSettings seeds_bias = pcf;
  seeds_bias.bias.automatic = false;  // looks a point up beside itself: nothing is taken out
  EXPECT_TRUE(cube_left_in_second(two_cascades(0.66, 12.0), seeds_bias));
}

TEST(PointLight, NarrowConeWhenEverythingIsBelowIt) {
  // A point light high above: the whole scene is within a narrow cone.
  RenderRequest r = request_with_light({0, 40, 0}, LightProjection::Perspective);
  const ShadowPlan plan = plan_shadow(r);
  ASSERT_EQ(plan.layout, ShadowLayout::Single);
  const ShadowView& v = plan.views[0];
  EXPECT_GT(v.near_plane, 0.0);
  EXPECT_LT(v.near_plane, 40.0 - 1.0);  // the tallest cube's top is below y = 1
  EXPECT_GT(v.far_plane, 40.0);
  EXPECT_LT(std::atan(v.tan_half) * 2.0, glm::radians(kMaxFittedLightFovDeg));
}

TEST(PointLight, AmidObjectsItUsesSixFacesAndSkipsEmptyOnes) {
  // 3 units above a 50 x 50 floor: no cone holds it. Nothing is above the
  // light, so the upward face has nothing to draw.
  RenderRequest r = request_with_light({0, 3, 0}, LightProjection::Perspective, "cube-on-plane");
  const ShadowPlan plan = plan_shadow(r);
  ASSERT_EQ(plan.layout, ShadowLayout::Cube);
  ASSERT_EQ(plan.views.size(), 6u);
  int empty = 0;
  for (const ShadowView& v : plan.views) {
    EXPECT_TRUE(finite(v.view_projection()));
    EXPECT_GT(v.tan_half, 1.0);  // a kernel margin beyond 90 degrees
    EXPECT_LT(v.tan_half, 1.1);
    empty += v.empty;
  }
  EXPECT_EQ(empty, 1);
  EXPECT_TRUE(plan.views[2].empty);  // +Y
  expect_visible_scene_inside(r);
}

TEST(PointLight, EachCubeFaceIsTheSignedPermutationTheShaderBuilds) {
  // scene.frag (LIGHT_CUBE) does not read the faces' matrices: it rebuilds
  // each from its axis and sign. The two must agree, or every point light
  // would read the wrong texels.
  const glm::dvec3 light(1.5, -2.0, 0.25);
  const glm::dvec3 d(0.3, -0.7, 1.9);  // a point's offset from the light
  for (int face = 0; face < 6; ++face) {
    const int a = face / 2;
    const double s = face % 2 == 0 ? 1.0 : -1.0;
    const glm::dvec3 expected = a == 0   ? glm::dvec3(s * d.z, d.y, -s * d.x)
                                : a == 1 ? glm::dvec3(d.x, s * d.z, -s * d.y)
                                         : glm::dvec3(-s * d.x, d.y, -s * d.z);
    const glm::dmat4 view = cube_face_view(light, face);
    const glm::dvec3 eye(view * glm::dvec4(light + d, 1.0));
    EXPECT_NEAR(glm::length(eye - expected), 0.0, 1e-12) << face;
    // A rotation (no mirror), looking down its axis: a point on the axis
    // in front of the light is straight ahead, at -z.
    EXPECT_NEAR(glm::determinant(glm::dmat3(view)), 1.0, 1e-12) << face;
    glm::dvec3 ahead(0.0);
    ahead[a] = 2.0 * s;
    const glm::dvec3 seen(view * glm::dvec4(light + ahead, 1.0));
    EXPECT_NEAR(glm::length(seen - glm::dvec3(0.0, 0.0, -2.0)), 0.0, 1e-12) << face;
  }
}

TEST(PointLight, CubeFacesAtTheLargestMapStayWithinTheMemoryCap) {
  RenderRequest r = request_with_light({0, 3, 0}, LightProjection::Perspective, "cube-on-plane");
  r.shadow.map_size = 8192;
  const ShadowPlan plan = plan_shadow(r);
  EXPECT_LT(plan.layer_size, 8192);
  EXPECT_LE(6.0 * plan.layer_size * plan.layer_size, kMaxShadowTexels);
}

TEST(LightFrustum, FixedFitIsTheSeedsMatrices) {
  RenderRequest r = request_with_light({-2, 4, -1}, LightProjection::Orthographic);
  r.shadow.fit = FrustumFit::Fixed;
  const ShadowPlan plan = plan_shadow(r);
  ASSERT_EQ(plan.views.size(), 1u);
  const ShadowView& f = plan.views[0];
  EXPECT_DOUBLE_EQ(f.near_plane, 1.0);
  EXPECT_DOUBLE_EQ(f.far_plane, 7.5);
  EXPECT_DOUBLE_EQ(f.projection[0][0], 2.0 / 20.0);
  EXPECT_DOUBLE_EQ(f.texel_size.x, 20.0 / 2048.0);
}

TEST(LightFrustum, DirectionIsPositionToTarget) {
  RenderRequest r = request_with_light({0, 10, 0}, LightProjection::Orthographic);
  EXPECT_NEAR(plan_shadow(r).direction.y, -1.0, 1e-12);
}

TEST(StableLookAt, OverheadLightHasAFiniteOrthonormalBasis) {
  const glm::dmat4 v = stable_look_at({0, 5, 0}, {0, 0, 0}, {0, 1, 0});
  ASSERT_TRUE(finite(v));
  // The target is straight ahead (-Z in view space).
  const glm::dvec4 t = v * glm::dvec4(0, 0, 0, 1);
  EXPECT_NEAR(t.x, 0.0, 1e-12);
  EXPECT_NEAR(t.y, 0.0, 1e-12);
  EXPECT_NEAR(t.z, -5.0, 1e-12);
  const glm::dvec3 x(v[0][0], v[1][0], v[2][0]), y(v[0][1], v[1][1], v[2][1]);
  EXPECT_NEAR(glm::length(x), 1.0, 1e-12);
  EXPECT_NEAR(glm::dot(x, y), 0.0, 1e-12);
}

TEST(StableLookAt, CameraWithUpAlongTheViewLooksUpToo) {
  EXPECT_TRUE(finite(stable_look_at({0, -5, 0}, {0, 0, 0}, {0, 1, 0})));
  EXPECT_TRUE(finite(stable_look_at({3, 0, 0}, {0, 0, 0}, {1, 0, 0})));
  // Nearly (not exactly) vertical: still the requested up, when it is usable.
  const glm::dmat4 tilted = stable_look_at({0.1, 5, 0}, {0, 0, 0}, {0, 1, 0});
  EXPECT_TRUE(finite(tilted));
}

TEST(Orbit, RotatesCounterClockwiseAboutTheTargetsVerticalAxis) {
  Light light;
  light.position = {3, 4, 0};
  light.target = {1, 0, 0};
  light.orbit_deg_per_s = 90.0;
  const glm::dvec3 p = orbit_light_position(light, 1.0);  // 90 degrees
  EXPECT_NEAR(p.x, 1.0, 1e-12);
  EXPECT_NEAR(p.y, 4.0, 1e-12);
  EXPECT_NEAR(p.z, -2.0, 1e-12);  // +X rotated +90 about +Y is -Z
  const glm::dvec3 back = orbit_light_position(light, 4.0);  // full turn
  EXPECT_NEAR(glm::length(back - light.position), 0.0, 1e-9);
  EXPECT_EQ(orbit_light_position(light, 0.0), light.position);
}

TEST(CameraMatrices, AspectFollowsTheImage) {
  Camera c;
  const CameraMatrices m = camera_matrices(c, 200, 100);
  EXPECT_NEAR(m.projection[1][1] / m.projection[0][0], 2.0, 1e-12);
}

// --- Shadow-map reuse -------------------------------------------------------

TEST(PlanCovers, AnIdenticalPlanCoversItself) {
  for (LightProjection projection : {LightProjection::Orthographic, LightProjection::Perspective}) {
    const RenderRequest r = request_with_light({-2.0, 4.0, -1.0}, projection);
    EXPECT_TRUE(plan_covers(plan_shadow(r), plan_shadow(r)));
  }
}

TEST(PlanCovers, APointLightIgnoresTheCamera) {
  RenderRequest a = request_with_light({-2.0, 4.0, -1.0}, LightProjection::Perspective);
  RenderRequest b = a;
  b.camera.position = {6.0, 2.0, -5.0};
  EXPECT_TRUE(plan_covers(plan_shadow(a), plan_shadow(b)));
}

TEST(PlanCovers, AFixedFitIgnoresTheCamera) {
  RenderRequest a = request_with_light({-2.0, 4.0, -1.0}, LightProjection::Orthographic);
  a.shadow.fit = FrustumFit::Fixed;
  RenderRequest b = a;
  b.camera.position = {6.0, 2.0, -5.0};
  EXPECT_TRUE(plan_covers(plan_shadow(a), plan_shadow(b)));
}

TEST(PlanCovers, AMovedLightIsNeverCovered) {
  for (LightProjection projection : {LightProjection::Orthographic, LightProjection::Perspective}) {
    RenderRequest a = request_with_light({-2.0, 4.0, -1.0}, projection);
    RenderRequest b = a;
    b.light.position.x += 1e-6;
    EXPECT_FALSE(plan_covers(plan_shadow(a), plan_shadow(b)));
  }
}

TEST(PlanCovers, ACameraFittedMapServesOnlyWhatItHolds) {
  // The camera fit follows the camera: moving in closer wants finer texels,
  // which the old map does not have.
  RenderRequest far = request_with_light({-2.0, 4.0, -1.0}, LightProjection::Orthographic);
  far.shadow.cascades = 1;
  RenderRequest near = far;
  near.camera.position = far.camera.target + 0.3 * (far.camera.position - far.camera.target);
  const ShadowPlan far_plan = plan_shadow(far), near_plan = plan_shadow(near);
  EXPECT_FALSE(plan_covers(far_plan, near_plan));
  // A view whose box holds the wanted one with texels no larger serves it.
  ShadowPlan wider = near_plan;
  ShadowView& v = wider.views[0];
  const double texel = v.texel_size.x;
  const glm::dmat4 inverse = glm::inverse(v.projection);
  const glm::dvec3 lo(inverse * glm::dvec4(-1, -1, -1, 1)), hi(inverse * glm::dvec4(1, 1, 1, 1));
  // Twice the width at the same texel size: a layer of twice the size.
  wider.layer_size *= 2;
  v.projection = glm::ortho(lo.x - 0.5 * (hi.x - lo.x), hi.x + 0.5 * (hi.x - lo.x), lo.y - 0.5 * (hi.y - lo.y),
                            hi.y + 0.5 * (hi.y - lo.y), v.near_plane - 1.0, v.far_plane + 1.0);
  v.texel_size = glm::dvec2(texel);
  ShadowPlan want = near_plan;
  want.layer_size = wider.layer_size;
  EXPECT_TRUE(plan_covers(wider, want));
  EXPECT_FALSE(plan_covers(want, wider)) << "the smaller box cannot serve the larger";
  v.texel_size = glm::dvec2(texel * 1.01);
  EXPECT_FALSE(plan_covers(wider, want)) << "coarser texels do not serve";
}

}  // namespace
}  // namespace umbra

namespace umbra {
namespace {

using test::expect_near;

TEST(SunLight, SceneAxesAreNorthMinusZEastPlusXAndNorthDegTurnsClockwiseFromAbove) {
  const double s30 = std::sin(glm::radians(30.0)), c30 = std::cos(glm::radians(30.0));
  expect_near(sun_direction(0.0, 0.0, 0.0), {0, 0, -1});     // north
  expect_near(sun_direction(90.0, 0.0, 0.0), {1, 0, 0});     // east
  expect_near(sun_direction(180.0, 30.0, 0.0), {0, s30, c30});  // a noon sun in the south
  expect_near(sun_direction(270.0, 0.0, 0.0), {-1, 0, 0});   // west
  expect_near(sun_direction(123.0, 90.0, 45.0), {0, 1, 0});  // the zenith, whatever the azimuth
  // Seen from above (looking down -Y, +X to the right, -Z up the page),
  // clockwise takes -Z towards +X: north_deg 90 puts north at +X.
  expect_near(sun_direction(0.0, 0.0, 90.0), {1, 0, 0});
  expect_near(sun_direction(0.0, 0.0, -90.0), {-1, 0, 0});
  expect_near(sun_direction(90.0, 0.0, 90.0), {0, 0, 1});    // east turns with it
}

// A sun light over Paris at `utc_unix_s`, 10 units from its target.
Light paris_sun(double utc_unix_s) {
  Light light;
  light.position = {0.0, 10.0, 0.0};
  light.target = {1.0, 0.0, 2.0};
  light.sun = SunClock{48.85, 2.35, utc_unix_s, 0.0};
  return light;
}

TEST(SunLight, LightAtPlacesTheLightTowardsTheSunAtItsDistanceFromTheTarget) {
  const double afternoon = 1797861600.0;  // 2026-12-21T14:00:00Z
  const Light light = paris_sun(afternoon);
  const LightState state = light_at(light, 0.0);
  ASSERT_TRUE(state.sun.has_value());
  const SunAngles sun = solar_position(48.85, 2.35, afternoon);
  EXPECT_DOUBLE_EQ(state.sun->azimuth_deg, sun.azimuth_deg);
  EXPECT_DOUBLE_EQ(state.sun->elevation_deg, sun.elevation_deg);
  // Paris, a winter afternoon: low in the south-west, so the light stands
  // towards +Z (south) and -X (west) of its target.
  EXPECT_GT(sun.azimuth_deg, 180.0);
  EXPECT_LT(sun.azimuth_deg, 270.0);
  EXPECT_GT(sun.elevation_deg, 0.0);
  EXPECT_LT(sun.elevation_deg, 20.0);
  EXPECT_TRUE(state.direct);
  const glm::dvec3 offset = state.position - light.target;
  EXPECT_NEAR(glm::length(offset), glm::length(light.position - light.target), 1e-9);
  expect_near(glm::normalize(offset), sun_direction(sun.azimuth_deg, sun.elevation_deg, 0.0), 1e-12);
  EXPECT_GT(offset.z, 0.0);
  EXPECT_LT(offset.x, 0.0);
  // North turned a quarter clockwise (to +X): the south-west sun moves from
  // +Z/-X to -X/-Z of the target; the sun itself stays where it is.
  Light turned = light;
  turned.sun->north_deg = 90.0;
  const LightState quarter = light_at(turned, 0.0);
  EXPECT_DOUBLE_EQ(quarter.sun->azimuth_deg, sun.azimuth_deg);
  const glm::dvec3 turned_offset = glm::normalize(quarter.position - turned.target);
  expect_near(turned_offset, sun_direction(sun.azimuth_deg, sun.elevation_deg, 90.0), 1e-12);
  EXPECT_NEAR(turned_offset.x, -glm::normalize(offset).z, 1e-12);
  EXPECT_NEAR(turned_offset.z, glm::normalize(offset).x, 1e-12);
  EXPECT_LT(turned_offset.x, 0.0);
  EXPECT_LT(turned_offset.z, 0.0);
}

TEST(SunLight, TimeAdvancesTheClockAndOrbitingDoesNotApply) {
  Light light = paris_sun(1797840000.0);  // 2026-12-21T08:00:00Z
  light.orbit_deg_per_s = 1000.0;
  const LightState later = light_at(light, 3 * 3600.0);
  Light moved = light;
  moved.sun->utc_unix_s += 3 * 3600.0;
  const LightState same = light_at(moved, 0.0);
  EXPECT_DOUBLE_EQ(later.sun->azimuth_deg, same.sun->azimuth_deg);
  EXPECT_DOUBLE_EQ(later.sun->elevation_deg, same.sun->elevation_deg);
  expect_near(later.position, same.position, 1e-12);
  // The morning sun climbs towards noon.
  EXPECT_GT(later.sun->elevation_deg, light_at(light, 0.0).sun->elevation_deg);
}

TEST(SunLight, BelowTheHorizonNoDirectLightArrivesAndNoShadowMapIsNeeded) {
  // Paris at 23:00 UTC in December: deep night.
  RenderRequest request = request_with_light({-2, 4, -1}, LightProjection::Orthographic, "cube-on-plane");
  request.light.sun = SunClock{48.85, 2.35, 1797894000.0, 0.0};  // 2026-12-21T23:00:00Z
  const LightState night = light_at(request.light, 0.0);
  ASSERT_TRUE(night.sun.has_value());
  EXPECT_LT(night.sun->elevation_deg, -10.0);
  EXPECT_FALSE(night.direct);
  EXPECT_FALSE(plan_shadow(request).direct_light);
  // Noon the next day: up again.
  EXPECT_TRUE(plan_shadow([&] {
                RenderRequest noon = request;
                noon.time = 13 * 3600.0;
                return noon;
              }())
                  .direct_light);
  // An orbiting light always lights directly.
  request.light.sun.reset();
  EXPECT_TRUE(light_at(request.light, 0.0).direct);
  EXPECT_FALSE(light_at(request.light, 0.0).sun.has_value());
}

}  // namespace
}  // namespace umbra
