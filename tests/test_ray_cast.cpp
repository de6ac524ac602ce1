// The exact reference against cases solved by hand.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <glm/geometric.hpp>

#include "model_support.hpp"
#include "ray_cast.hpp"
#include "scene.hpp"

namespace umbra {
namespace {

RenderRequest cube_on_plane() {
  RenderRequest r;
  r.scene.objects = find_builtin_scene("cube-on-plane")->objects;
  r.light.position = {0, 10, 0};  // straight overhead
  return r;
}

TEST(RayCast, HitsTheNearestSurfaceWithANormalFacingTheRay) {
  const RenderRequest r = cube_on_plane();
  const auto hit = cast_ray(r.scene, {0, 5, 0}, {0, -1, 0}, 0.0, 1e9);
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->object, 1);  // the cube's top, not the floor
  EXPECT_NEAR(hit->point.y, 0.5, 1e-12);
  EXPECT_NEAR(hit->normal.y, 1.0, 1e-12);
  const auto below = cast_ray(r.scene, {3, -5, 0}, {0, 1, 0}, 0.0, 1e9);
  ASSERT_TRUE(below);
  EXPECT_NEAR(below->normal.y, -1.0, 1e-12);  // the floor seen from below
}

TEST(RayCast, RotatedBoxIsHitWhereItReallyIs) {
  Scene scene;
  SceneObject box;
  box.size = {2, 1, 0.2};
  box.rotation_y_deg = 90;  // now long along z
  scene.objects = {box};
  EXPECT_TRUE(cast_ray(scene, {0, 5, 0.9}, {0, -1, 0}, 0, 1e9));
  EXPECT_FALSE(cast_ray(scene, {0.9, 5, 0}, {0, -1, 0}, 0, 1e9));
}

TEST(RayCast, SphereHitFromOutsideAndInside) {
  Scene scene;
  SceneObject s;
  s.type = SceneObject::Type::Sphere;
  s.center = {0, 0, 0};
  s.radius = 2;
  scene.objects = {s};
  const auto outside = cast_ray(scene, {0, 0, 10}, {0, 0, -1}, 0, 1e9);
  ASSERT_TRUE(outside);
  EXPECT_NEAR(outside->t, 8.0, 1e-12);
  const auto inside = cast_ray(scene, {0, 0, 0}, {0, 0, -1}, 0, 1e9);
  ASSERT_TRUE(inside);
  EXPECT_NEAR(inside->t, 2.0, 1e-12);
}

TEST(ExactVisibility, UnderTheCubeIsDarkAndFarAwayIsLit) {
  const RenderRequest r = cube_on_plane();
  const glm::dvec3 up{0, 1, 0};
  // Directional light straight down: the floor right next to the cube is lit.
  EXPECT_EQ(exact_visibility(r, r.light.position, {0.4, -0.5, 0.4}, up), 0.0);
  EXPECT_EQ(exact_visibility(r, r.light.position, {0.6, -0.5, 0.0}, up), 1.0);
  // Facing away from the light: 0.
  EXPECT_EQ(exact_visibility(r, r.light.position, {0.6, -0.5, 0.0}, -up), 0.0);
}

TEST(ExactVisibility, PointLightShadowSpreads) {
  RenderRequest r = cube_on_plane();
  r.light.projection = LightProjection::Perspective;
  r.light.position = {0, 1.5, 0};  // 1 above the cube's top
  // The cube's top edge at x = 0.5 projects from y=1.5 down to y=-0.5 at x = 1.0.
  EXPECT_EQ(exact_visibility(r, r.light.position, {0.9, -0.5, 0.0}, {0, 1, 0}), 0.0);
  EXPECT_EQ(exact_visibility(r, r.light.position, {1.1, -0.5, 0.0}, {0, 1, 0}), 1.0);
}

TEST(ExactVisibility, AreaLightGivesAPenumbra) {
  RenderRequest r = cube_on_plane();
  r.light.size = 20.0;  // degrees: a wide sun
  // Right at the edge of the hard shadow, part of the disc is hidden.
  const double v = exact_visibility(r, r.light.position, {0.52, -0.5, 0.0}, {0, 1, 0});
  EXPECT_GT(v, 0.0);
  EXPECT_LT(v, 1.0);
}

// The default camera looks down at the cube from (0, 3, 6): it sees the floor
// from above and the cube's top and front. A visible face of a convex box lies
// between its centre and the camera, so its normal points from the centre
// towards the camera by more than the half size.
TEST(ExactPixels, NormalsAreUnitAndFaceTheCamera) {
  RenderRequest r = cube_on_plane();
  r.width = 64;
  r.height = 36;
  int floor_pixels = 0, cube_pixels = 0;
  for (const ExactPixel& p : cast_exact_pixels(r)) {
    if (!p.geometry) continue;
    EXPECT_NEAR(glm::length(p.normal), 1.0f, 1e-6f);
    if (p.object == 0) {
      ++floor_pixels;
      EXPECT_TRUE(p.normal == glm::vec3(0.0f, 1.0f, 0.0f));
    } else {
      ++cube_pixels;
      EXPECT_GT(glm::dot(glm::dvec3(p.normal), r.camera.position - glm::dvec3(0.0)), 0.5);
    }
  }
  EXPECT_GT(floor_pixels, 0);
  EXPECT_GT(cube_pixels, 0);
}

TEST(ExactImages, ErrorIsRedForFalseShadowAndBlueForFalseLight) {
  Image rendered{2, 1, 1, {0, 255}};
  Image exact{2, 1, 1, {255, 0}};
  const Image e = error_image(rendered, exact);
  EXPECT_EQ(e.pixels[0], 255);  // pixel 0 red
  EXPECT_EQ(e.pixels[2], 0);
  EXPECT_EQ(e.pixels[3], 0);
  EXPECT_EQ(e.pixels[5], 255);  // pixel 1 blue
}

// The hierarchy must answer exactly as testing every object in order:
// random scenes of boxes, spheres and planes (touching and overlapping
// ones included), random rays, compared with a brute-force cast.
TEST(RayScene, AnswersExactlyAsTestingEveryObject) {
  std::mt19937 random(12345);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    Scene scene;
    const int n = 1 + trial * 25;
    for (int i = 0; i < n; ++i) {
      SceneObject o;
      o.type = SceneObject::Type(i % 3);
      // On a coarse grid, so that objects touch and share faces often.
      o.center = glm::dvec3(std::round(5 * u(random)), std::round(2 * u(random)), std::round(5 * u(random)));
      o.size = glm::dvec3(1.0 + std::round(u(random)), 1.0, 1.0 + std::round(u(random)));
      o.radius = 0.5 + 0.25 * std::round(u(random));
      o.rotation_y_deg = i % 4 == 0 ? 30.0 * std::round(3 * u(random)) : 0.0;
      scene.objects.push_back(o);
    }
    const RayScene rays(scene);
    for (int k = 0; k < 2000; ++k) {
      const glm::dvec3 origin(8 * u(random), 4 * u(random), 8 * u(random));
      glm::dvec3 dir(u(random), u(random), u(random));
      if (k % 5 == 0) dir[k % 3] = 0.0;  // axis-parallel rays too
      if (glm::length(dir) < 1e-3) continue;
      dir = glm::normalize(dir);
      // Brute force: every object in index order.
      RayHit best;
      best.t = 1e9;
      for (std::size_t i = 0; i < scene.objects.size(); ++i) {
        Scene one;
        one.objects.push_back(scene.objects[i]);
        const auto hit = RayScene(one).cast(origin, dir, 0.0, best.t);
        if (hit && hit->t < best.t) best = *hit, best.object = int(i);
      }
      const auto hit = rays.cast(origin, dir, 0.0, 1e9);
      ASSERT_EQ(hit.has_value(), best.object >= 0) << "trial " << trial << " ray " << k;
      if (hit) {
        EXPECT_EQ(hit->object, best.object) << "trial " << trial << " ray " << k;
        EXPECT_EQ(hit->t, best.t);
        EXPECT_EQ(hit->normal, best.normal);
      }
      const double reach = 3.0 * (1.0 + u(random));
      EXPECT_EQ(rays.occluded(origin, dir, reach), best.object >= 0 && best.t < reach) << "trial " << trial;
    }
  }
}

TEST(RayCast, AScenesMeshesAreRefusedNotMissed) {
  Scene scene;
  scene.objects.resize(3);
  scene.objects[0].type = SceneObject::Type::Plane;
  EXPECT_EQ(first_object_not_ray_cast(scene), -1);
  scene.objects[2].type = SceneObject::Type::Mesh;
  scene.objects[2].model = test::box_model({0.5f, 0.5f, 0.5f});
  scene.objects[2].model_id = "box";
  EXPECT_EQ(first_object_not_ray_cast(scene), 2);
  EXPECT_THROW(RayScene{scene}, std::invalid_argument);
}

}  // namespace
}  // namespace umbra
