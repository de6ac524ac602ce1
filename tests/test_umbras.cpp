// Where a floor is certainly dark or certainly lit (umbras.hpp), checked by
// casting the rays of the texels the main pass would read, without a GPU.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/geometric.hpp>
#include <glm/mat4x4.hpp>
#include <glm/matrix.hpp>

#include "core/light_math.hpp"
#include "reference/ray_cast.hpp"
#include "plan/receiver_cells.hpp"
#include "core/scene.hpp"
#include "plan/umbras.hpp"

namespace umbra {
namespace {

// contact-line's floor and turned box, with a ball beside it: under the sun
// at `time`, or under a point light at `point_light` (x, y, z) if given.
RenderRequest floor_box_ball(double time, std::optional<glm::dvec3> point_light = std::nullopt) {
  RenderRequest r;
  SceneObject floor;
  floor.type = SceneObject::Type::Plane;
  floor.size = {20.0, 0.0, 20.0};
  SceneObject box;
  box.center = {0.0, 0.5, 0.0};
  box.rotation_y_deg = 20.0;
  SceneObject ball;
  ball.type = SceneObject::Type::Sphere;
  ball.center = {1.8, 0.4, -0.6};
  ball.radius = 0.4;
  r.scene.objects = {floor, box, ball};
  r.camera.position = {2.6, 2.6, 3.2};
  r.camera.target = {0.0, 0.3, 0.0};
  r.light.position = {-3.0, 2.0, -2.0};
  r.time = time;
  if (point_light) {
    r.light.projection = LightProjection::Perspective;
    r.light.position = *point_light;
  }
  return r;
}

// The main pass's choice of view for point p (shaders/scene.frag's
// choose_view): a cube face by p's major axis from the light; else the
// first view that holds p with the filter's reach, else the first that
// holds it at all. -1 if none does.
int view_for(const ShadowPlan& plan, const glm::dvec3& p, int reach) {
  if (plan.layout == ShadowLayout::Cube) {
    const glm::dvec3 d = p - plan.position;
    const glm::dvec3 a = glm::abs(d);
    const int axis = a.x >= a.y && a.x >= a.z ? 0 : (a.y >= a.z ? 1 : 2);
    return 2 * axis + (d[axis] < 0.0 ? 1 : 0);
  }
  int fallback = -1;
  for (std::size_t i = 0; i < plan.views.size(); ++i) {
    const glm::dvec4 clip = plan.views[i].view_projection() * glm::dvec4(p, 1.0);
    const glm::dvec3 ndc = glm::dvec3(clip) / clip.w;
    if (!(clip.w > 0.0 && std::abs(ndc.x) <= 1.0 && std::abs(ndc.y) <= 1.0 && std::abs(ndc.z) <= 1.0)) continue;
    const glm::dvec2 texel = (glm::dvec2(ndc) * 0.5 + 0.5) * double(plan.layer_size);
    if (glm::all(glm::greaterThanEqual(texel, glm::dvec2(reach))) &&
        glm::all(glm::lessThanEqual(texel, glm::dvec2(plan.layer_size - reach))))
      return int(i);
    if (fallback < 0) fallback = int(i);
  }
  return fallback;
}

// What the texel `offset` texels from point p's own, in view `view`, looks
// at: its ray from the view's near plane, where that ray meets the plane at
// height y, and the first thing it hits before that (if anything).
struct TexelRay {
  double plane_t = 0.0;          // along the ray, to the plane
  std::optional<RayHit> before;  // first hit short of the plane
  double texel_world = 0.0;      // the texel's world size where the ray meets the plane
};
TexelRay texel_ray(const RenderRequest& r, const ShadowPlan& plan, int view, const glm::dvec3& p,
                   const glm::dvec2& offset, double y) {
  const ShadowView& v = plan.views[std::size_t(view)];
  const glm::dmat4 view_projection = v.view_projection();
  const glm::dvec4 clip = view_projection * glm::dvec4(p, 1.0);
  const glm::dvec2 ndc = glm::dvec2(clip) / clip.w + offset * (2.0 / plan.layer_size);
  const glm::dmat4 to_world = glm::inverse(view_projection);
  const glm::dvec4 near = to_world * glm::dvec4(ndc, -1.0, 1.0), far = to_world * glm::dvec4(ndc, 1.0, 1.0);
  const glm::dvec3 origin = glm::dvec3(near) / near.w;
  const glm::dvec3 direction = glm::normalize(glm::dvec3(far) / far.w - origin);
  TexelRay out;
  out.plane_t = (y - origin.y) / direction.y;
  out.texel_world = plan.perspective ? v.texel_size.x * glm::distance(plan.position, origin + direction * out.plane_t)
                                     : std::max(v.texel_size.x, v.texel_size.y);
  out.before = cast_ray(r.scene, origin, direction, 0.0, out.plane_t * (1.0 - 1e-9));
  return out;
}

// Whether q lies inside the convex polygon (counter-clockwise), its edges
// included.
bool inside(const PlanePolygon& polygon, const glm::dvec2& q) {
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const glm::dvec2 a = polygon[i], b = polygon[(i + 1) % polygon.size()];
    if ((b.x - a.x) * (q.y - a.y) - (b.y - a.y) * (q.x - a.x) < 0.0) return false;
  }
  return true;
}

// Points spread over a convex polygon: mixes of two neighbouring corners
// and the centroid, a hair inside.
std::vector<glm::dvec2> points_over(const PlanePolygon& polygon) {
  glm::dvec2 centroid(0.0);
  for (const glm::dvec2& q : polygon) centroid += q / double(polygon.size());
  std::vector<glm::dvec2> points;
  for (std::size_t i = 0; i < polygon.size(); ++i)
    for (int a = 0; a <= 4; ++a)
      for (int b = 0; a + b <= 4; ++b) {
        const glm::dvec2 mix =
            polygon[i] * (a / 4.0) + polygon[(i + 1) % polygon.size()] * (b / 4.0) + centroid * ((4 - a - b) / 4.0);
        points.push_back(centroid + (mix - centroid) * (1.0 - 1e-9));
      }
  return points;
}

// Points `hair` outside each edge of `shadows` (at its ends and at five
// places along it) that lie outside them all and on the plane (not past
// its edge, where the shadows are cut).
std::vector<glm::dvec2> points_just_outside(const std::vector<PlanePolygon>& shadows, const Aabb& plane, double hair) {
  const auto outside_all = [&](const glm::dvec2& q) {
    return std::none_of(shadows.begin(), shadows.end(), [&](const PlanePolygon& s) { return inside(s, q); });
  };
  std::vector<glm::dvec2> points;
  for (const PlanePolygon& s : shadows)
    for (std::size_t i = 0; i < s.size(); ++i) {
      const glm::dvec2 a = s[i], b = s[(i + 1) % s.size()];
      const glm::dvec2 outward = glm::normalize(glm::dvec2(b.y - a.y, a.x - b.x));
      for (double f : {0.0, 0.05, 0.25, 0.5, 0.75, 0.95, 1.0}) {
        const glm::dvec2 q = a + (b - a) * f + outward * hair;
        if (outside_all(q) && q.x > plane.min.x && q.x < plane.max.x && q.y > plane.min.z && q.y < plane.max.z)
          points.push_back(q);
      }
    }
  return points;
}

// The lights every test below is run under: the sun at four points of its
// orbit, and point lights above the objects and lower than the box's top.
std::vector<RenderRequest> lit_scenes() {
  std::vector<RenderRequest> scenes;
  for (double time : {0.0, 4.0, 9.0, 13.5}) scenes.push_back(floor_box_ball(time));
  for (const glm::dvec3& light : {glm::dvec3(0.3, 1.5, 0.2), glm::dvec3(-2.0, 3.0, 1.0), glm::dvec3(1.5, 0.9, 1.5)})
    scenes.push_back(floor_box_ball(0.0, light));
  return scenes;
}

// Every point of an umbra is dark in the exact reference, and the ray of
// every texel that the filter reads around it meets an object in front of
// the floor: the lookup finds it shadowed, wherever the object's surface
// that the map holds lies along the ray. (The shadow pass culls front
// faces, so at a box's foot that is the box's far side, on the floor: the
// lookup lets light leak in there, and the umbra is right where it is
// not.)
TEST(Umbras, EveryTexelTheFilterReadsAroundAnUmbraSeesAnObjectInFrontOfTheFloor) {
  int umbras = 0, texels = 0;
  for (const RenderRequest& r : lit_scenes()) {
    const ShadowPlan plan = plan_shadow(r);
    const Mesh mesh = tessellate(r.scene);
    const PlaneRange& floor = mesh.planes.at(0);
    const int read = filter_read_texels(r.shadow), reach = filter_reach_texels(r.shadow);
    const glm::dvec3 light = light_at(r.light, r.time).position;
    const std::string where = std::string(plan.perspective ? "point light" : "sun") + " t=" + std::to_string(r.time);
    for (const PlanePolygon& umbra : umbras_on_plane(mesh.bounds[floor.object], plan, r.scene.objects, read + 1.0)) {
      ++umbras;
      for (const glm::dvec2& q : points_over(umbra)) {
        const glm::dvec3 p(q.x, floor.height, q.y);
        ASSERT_EQ(exact_visibility(r, light, p, {0.0, 1.0, 0.0}), 0.0) << where << ": " << q.x << ", " << q.y;
        const int view = view_for(plan, p, reach);
        ASSERT_GE(view, 0) << where;
        for (int dy = -read; dy <= read; ++dy)
          for (int dx = -read; dx <= read; ++dx) {
            const TexelRay ray = texel_ray(r, plan, view, p, {dx, dy}, floor.height);
            ++texels;
            ASSERT_TRUE(ray.before.has_value())
                << where << ": the texel (" << dx << ", " << dy << ") from " << q.x << ", " << q.y << " sees the floor";
            EXPECT_GT(ray.plane_t - ray.before->t, 0.1 * ray.texel_world) << where;
          }
      }
    }
  }
  EXPECT_GE(umbras, 12);
  EXPECT_GT(texels, 50000);
}

// Just outside the shadow of each object's grown bounds, no texel the
// filter reads sees anything but the floor: the lookup would have found
// the point lit.
TEST(Umbras, NoTexelReadFromOutsideTheShadowBoundsSeesAnObject) {
  int points = 0;
  for (const RenderRequest& r : lit_scenes()) {
    const ShadowPlan plan = plan_shadow(r);
    const Mesh mesh = tessellate(r.scene);
    const PlaneRange& floor = mesh.planes.at(0);
    const Aabb& plane = mesh.bounds[floor.object];
    const int read = filter_read_texels(r.shadow), reach = filter_reach_texels(r.shadow);
    const std::string where = std::string(plan.perspective ? "point light" : "sun") + " t=" + std::to_string(r.time);
    const std::optional<std::vector<PlanePolygon>> shadows =
        shadow_bounds_on_plane(plane, floor.object, plan, mesh.bounds, read + 1.0);
    ASSERT_TRUE(shadows.has_value()) << where;
    ASSERT_EQ(shadows->size(), 2u) << where;
    for (const glm::dvec2& q : points_just_outside(*shadows, plane, 1e-6)) {
      const glm::dvec3 p(q.x, floor.height, q.y);
      const int view = view_for(plan, p, reach);
      if (view < 0) continue;  // no view holds it: lit without a lookup
      ++points;
      for (int dy = -read; dy <= read; ++dy)
        for (int dx = -read; dx <= read; ++dx) {
          const TexelRay ray = texel_ray(r, plan, view, p, {dx, dy}, floor.height);
          EXPECT_FALSE(ray.before.has_value())
              << where << ": the texel (" << dx << ", " << dy << ") from " << q.x << ", " << q.y << " sees object "
              << ray.before->object;
        }
    }
  }
  EXPECT_GT(points, 100);
}

// A unit box straight under the sun: its umbra is its footprint less the
// margin all round; the shadow of its bounds, its footprint plus the margin.
TEST(Umbras, ABoxStraightUnderTheSunShadowsItsFootprint) {
  RenderRequest r = floor_box_ball(0.0);
  r.scene.objects.pop_back();  // no ball
  r.scene.objects[1].rotation_y_deg = 0.0;
  ShadowPlan plan;
  plan.direction = {0.0, -1.0, 0.0};
  plan.layer_size = 1000;
  ShadowView view;  // straight down from y = 10 over [-10, 10]^2: texels of 0.02
  view.view = glm::lookAt(glm::dvec3(0.0, 10.0, 0.0), glm::dvec3(0.0), glm::dvec3(0.0, 0.0, -1.0));
  view.projection = glm::ortho(-10.0, 10.0, -10.0, 10.0, 0.0, 20.0);
  view.texel_size = {0.02, 0.02};
  plan.views = {view};
  const Aabb plane = object_bounds(r.scene.objects[0]);
  const double margin = 4.0 * std::sqrt(2.0) * 0.02;
  const std::vector<PlanePolygon> umbras = umbras_on_plane(plane, plan, r.scene.objects, 4.0);
  ASSERT_EQ(umbras.size(), 1u);
  const Aabb u = bounds_on_plane(umbras[0], 0.0);
  EXPECT_NEAR(u.min.x, -0.5 + margin, 1e-12);
  EXPECT_NEAR(u.max.z, 0.5 - margin, 1e-12);
  const std::vector<Aabb> bounds{plane, object_bounds(r.scene.objects[1])};
  const std::optional<std::vector<PlanePolygon>> shadows = shadow_bounds_on_plane(plane, 0, plan, bounds, 4.0);
  ASSERT_TRUE(shadows && shadows->size() == 1u);
  const Aabb s = bounds_on_plane((*shadows)[0], 0.0);
  EXPECT_NEAR(s.min.x, -0.5 - margin, 1e-12);
  EXPECT_NEAR(s.max.z, 0.5 + margin, 1e-12);
  // A light from under the floor reaches none of its top.
  plan.direction = {0.0, 1.0, 0.0};
  EXPECT_TRUE(umbras_on_plane(plane, plan, r.scene.objects, 4.0).empty());
  EXPECT_FALSE(shadow_bounds_on_plane(plane, 0, plan, bounds, 4.0).has_value());
}

// Under a point light lower than the box's top, the box is cut at 3/4 of
// the light's height: its umbra is bounded. The shadow of its bounds is
// cut where it would fall four times as far out as the plane reaches, and
// reaches the plane's edge. A light inside the bounds leaves the plane to
// the cells.
TEST(Umbras, APointLightBelowABoxsTopCastsItsShadowPastThePlanesEdge) {
  const RenderRequest r = floor_box_ball(0.0, glm::dvec3(1.5, 0.9, 1.5));
  const ShadowPlan plan = plan_shadow(r);
  const Mesh mesh = tessellate(r.scene);
  const Aabb& plane = mesh.bounds[0];
  const std::vector<PlanePolygon> umbras = umbras_on_plane(plane, plan, r.scene.objects, 4.0);
  ASSERT_FALSE(umbras.empty());
  for (const PlanePolygon& u : umbras)
    for (const glm::dvec2& q : u) EXPECT_TRUE(std::isfinite(q.x) && std::isfinite(q.y));
  const std::optional<std::vector<PlanePolygon>> shadows = shadow_bounds_on_plane(plane, 0, plan, mesh.bounds, 4.0);
  ASSERT_TRUE(shadows && shadows->size() == 2u);
  // The box's, away from the light (at +x +z): out to the plane's -x and -z edges.
  // (cut a hair past the edge: 1e-3 of the plane's side).
  const Aabb box_shadow = bounds_on_plane((*shadows)[0], 0.0);
  EXPECT_DOUBLE_EQ(box_shadow.min.x, plane.min.x - 0.02);
  EXPECT_DOUBLE_EQ(box_shadow.min.z, plane.min.z - 0.02);
  const RenderRequest inside = floor_box_ball(0.0, glm::dvec3(0.0, 0.9, 0.0));
  EXPECT_FALSE(shadow_bounds_on_plane(plane, 0, plan_shadow(inside), mesh.bounds, 4.0).has_value());
}

// A sun grazing the floor by less than a microradian would cast shadows
// millions of floor widths long, beyond what cutting them to the floor
// keeps exact in double: no umbra, and the floor keeps its cells. A point
// light whose foot is a hair from an object's bounds, whose shadow's cut
// would round to the light's own height, the same.
TEST(Umbras, ShadowsTooLongForDoublePrecisionAreLeftToTheLookup) {
  RenderRequest r = floor_box_ball(0.0);
  ShadowPlan plan = plan_shadow(r);
  const Mesh mesh = tessellate(r.scene);
  const Aabb& plane = mesh.bounds[0];
  plan.direction = glm::normalize(glm::dvec3(1.0, -1e-17, 0.3));
  EXPECT_TRUE(umbras_on_plane(plane, plan, r.scene.objects, 4.0).empty());
  EXPECT_FALSE(shadow_bounds_on_plane(plane, 0, plan, mesh.bounds, 4.0).has_value());
  plan.direction = glm::normalize(glm::dvec3(1.0, -1e-3, 0.3));
  EXPECT_TRUE(shadow_bounds_on_plane(plane, 0, plan, mesh.bounds, 4.0).has_value());

  // A tall box beside a point light at height 1 whose foot is 1e-15 from
  // the box's side.
  ShadowPlan point = plan_shadow(floor_box_ball(0.0, glm::dvec3(0.3, 1.5, 0.2)));
  for (ShadowView& view : point.views) view.texel_size = {0.0, 0.0};
  point.position = {0.5 + 1e-15, 1.0, 0.0};
  const Aabb tall{{-0.5, 0.0, -0.5}, {0.5, 1.5, 0.5}};
  EXPECT_FALSE(shadow_bounds_on_plane(plane, 0, point, {plane, tall}, 4.0).has_value());
  point.position.x = 0.5 + 1e-3;
  const std::optional<std::vector<PlanePolygon>> beside = shadow_bounds_on_plane(plane, 0, point, {plane, tall}, 4.0);
  ASSERT_TRUE(beside && beside->size() == 1u);
  EXPECT_LT(bounds_on_plane((*beside)[0], 0.0).min.x, plane.min.x);  // away from the light, out past the edge
}

// A single view that does not hold all of an umbra (the seeds' fixed light
// box, smaller than the shadow) would leave the lookup reading nothing
// there, and one whose near plane cuts the object holds only part of it:
// no umbra is drawn, so the frame shows what the lookup shows.
TEST(Umbras, AFixedLightBoxThatCutsAShadowDrawsNoUmbra) {
  RenderRequest r = floor_box_ball(0.0);
  r.shadow.fit = FrustumFit::Fixed;
  r.shadow.ortho_half_size = 0.8;
  const ShadowPlan small = plan_shadow(r);
  ASSERT_EQ(small.layout, ShadowLayout::Single);
  const Mesh mesh = tessellate(r.scene);
  EXPECT_TRUE(umbras_on_plane(mesh.bounds[0], small, r.scene.objects, 4.0).empty());
  r.shadow.ortho_half_size = 10.0;
  EXPECT_EQ(umbras_on_plane(mesh.bounds[0], plan_shadow(r), r.scene.objects, 4.0).size(), 2u);

  // A fixed cone half a unit above the box's top: with its near plane
  // nearer than the box, an umbra; with it past the box's nearest corner
  // (0.36 along its axis), the layer lacks part of the box, and none.
  RenderRequest cone = floor_box_ball(0.0, glm::dvec3(0.3, 1.5, 0.2));
  cone.scene.objects.pop_back();  // no ball
  cone.shadow.fit = FrustumFit::Fixed;
  cone.light.fov_y_deg = 150.0;
  cone.shadow.near_plane = 0.1;
  cone.shadow.far_plane = 10.0;
  const ShadowPlan near_enough = plan_shadow(cone);
  ASSERT_EQ(near_enough.layout, ShadowLayout::Single);
  EXPECT_EQ(umbras_on_plane(mesh.bounds[0], near_enough, cone.scene.objects, 4.0).size(), 1u);
  cone.shadow.near_plane = 0.45;
  EXPECT_TRUE(umbras_on_plane(mesh.bounds[0], plan_shadow(cone), cone.scene.objects, 4.0).empty());
}

// Only boxes and spheres are known to be solid all through: a plane or a
// mesh object gives no points inside it, and a box or sphere shrunk past
// nothing, or cut to a slab it does not reach, none either.
TEST(Umbras, OnlyBoxesAndSpheresHavePointsInside) {
  SceneObject box;
  box.size = {1.0, 2.0, 1.0};
  EXPECT_EQ(points_inside(box, 0.1, -10.0, 10.0).size(), 8u);
  EXPECT_TRUE(points_inside(box, 0.5, -10.0, 10.0).empty());
  EXPECT_TRUE(points_inside(box, 0.0, 1.5, 10.0).empty());
  SceneObject ball;
  ball.type = SceneObject::Type::Sphere;
  for (const glm::dvec3& p : points_inside(ball, 0.1, -10.0, 10.0)) EXPECT_LE(glm::length(p), 0.4 + 1e-12);
  EXPECT_TRUE(points_inside(ball, 0.5, -10.0, 10.0).empty());
  SceneObject plane;
  plane.type = SceneObject::Type::Plane;
  EXPECT_TRUE(points_inside(plane, 0.0, -10.0, 10.0).empty());
}

// Filter "exact"'s proved plane parts (frame_plan.cpp): with no texel
// reach, umbras shrink and the shadows of the bounds grow by exactly the
// world margin given, and no view is asked anything.
TEST(Umbras, AWorldMarginAloneShrinksAndGrowsByExactlyThat) {
  RenderRequest r = floor_box_ball(0.0);
  r.scene.objects.pop_back();  // no ball
  r.scene.objects[1].rotation_y_deg = 0.0;
  ShadowPlan plan;
  plan.direction = {0.0, -1.0, 0.0};
  plan.layer_size = 1000;
  ShadowView view;  // a view that holds nothing of the box: the texel rules would give no umbra
  view.view = glm::lookAt(glm::dvec3(50.0, 10.0, 0.0), glm::dvec3(50.0, 0.0, 0.0), glm::dvec3(0.0, 0.0, -1.0));
  view.projection = glm::ortho(-1.0, 1.0, -1.0, 1.0, 0.0, 20.0);
  view.texel_size = {0.002, 0.002};
  plan.layout = ShadowLayout::Single;
  plan.views = {view};
  const Aabb plane = object_bounds(r.scene.objects[0]);
  EXPECT_TRUE(umbras_on_plane(plane, plan, r.scene.objects, 4.0).empty());
  const double margin = 0.03;
  const std::vector<PlanePolygon> umbras = umbras_on_plane(plane, plan, r.scene.objects, 0.0, margin);
  ASSERT_EQ(umbras.size(), 1u);
  const Aabb u = bounds_on_plane(umbras[0], 0.0);
  EXPECT_NEAR(u.min.x, -0.5 + margin, 1e-12);
  EXPECT_NEAR(u.max.z, 0.5 - margin, 1e-12);
  const std::vector<Aabb> bounds{plane, object_bounds(r.scene.objects[1])};
  const std::optional<std::vector<PlanePolygon>> shadows = shadow_bounds_on_plane(plane, 0, plan, bounds, 0.0, margin);
  ASSERT_TRUE(shadows && shadows->size() == 1u);
  const Aabb s = bounds_on_plane((*shadows)[0], 0.0);
  EXPECT_NEAR(s.min.x, -0.5 - margin, 1e-12);
  EXPECT_NEAR(s.max.z, 0.5 + margin, 1e-12);
}

// What the proved parts claim, against the exact reference: every point
// within 2 margins of an umbra shrunk by 3 is dark, and every point within
// 2 margins of one outside all the shadows of the bounds grown by 3 is
// lit, under the sun and point lights (the margin as the frame plan takes
// it is a texel or so; here larger, to test points well inside).
TEST(Umbras, ProvedPartsHoldWithinTwoMarginsOfEveryPoint) {
  int dark = 0, lit = 0;
  for (const RenderRequest& r : lit_scenes()) {
    const ShadowPlan plan = plan_shadow(r);
    const Mesh mesh = tessellate(r.scene);
    const PlaneRange& floor = mesh.planes.at(0);
    const Aabb& plane = mesh.bounds[floor.object];
    const glm::dvec3 light = light_at(r.light, r.time).position;
    const std::string where = std::string(plan.perspective ? "point light" : "sun") + " t=" + std::to_string(r.time);
    for (const double margin : {1e-3, 0.02}) {
      // The eight ways out from a point, 2 margins long.
      std::vector<glm::dvec2> offsets{{0.0, 0.0}};
      for (int k = 0; k < 8; ++k)
        offsets.push_back(2.0 * margin * glm::dvec2(std::cos(k * 0.7853981633974483), std::sin(k * 0.7853981633974483)));
      for (const PlanePolygon& umbra : umbras_on_plane(plane, plan, r.scene.objects, 0.0, 3.0 * margin))
        for (const glm::dvec2& q : points_over(umbra))
          for (const glm::dvec2& d : offsets) {
            const glm::dvec3 p(q.x + d.x, floor.height, q.y + d.y);
            ++dark;
            ASSERT_EQ(exact_visibility(r, light, p, {0.0, 1.0, 0.0}), 0.0) << where << ": " << p.x << ", " << p.z;
          }
      const std::optional<std::vector<PlanePolygon>> shadows =
          shadow_bounds_on_plane(plane, floor.object, plan, mesh.bounds, 0.0, 3.0 * margin);
      ASSERT_TRUE(shadows.has_value()) << where;
      // Points a hair outside each edge, moved 2 margins every way.
      for (const glm::dvec2& q : points_just_outside(*shadows, plane, 1e-9))
        for (const glm::dvec2& d : offsets) {
          const glm::dvec2 moved = q + d;
          if (moved.x <= plane.min.x || moved.x >= plane.max.x || moved.y <= plane.min.z || moved.y >= plane.max.z)
            continue;
          const glm::dvec3 p(moved.x, floor.height, moved.y);
          ++lit;
          EXPECT_EQ(exact_visibility(r, light, p, {0.0, 1.0, 0.0}), 1.0) << where << ": " << p.x << ", " << p.z;
        }
    }
  }
  EXPECT_GE(dark, 5000);
  EXPECT_GE(lit, 1000);
}

}  // namespace
}  // namespace umbra
