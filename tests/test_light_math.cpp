// Light-space and camera math, without a GPU.
#include <gtest/gtest.h>

#include <cmath>

#include <glm/geometric.hpp>

#include "light_math.hpp"
#include "scene.hpp"

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
  r.light.position = position;
  r.light.projection = projection;
  return r;
}

// Every corner of every object lands inside the light's clip volume.
void expect_scene_inside(const RenderRequest& r) {
  const LightFrustum f = light_frustum(r);
  ASSERT_TRUE(finite(f.view_projection()));
  for (const auto& o : r.scene.objects) {
    for (const auto& corner : object_bounds(o).corners()) {
      const glm::dvec4 clip = f.view_projection() * glm::dvec4(corner, 1.0);
      ASSERT_GT(clip.w, 0.0);
      const glm::dvec3 ndc = glm::dvec3(clip) / clip.w;
      for (int k = 0; k < 3; ++k) {
        EXPECT_LE(std::abs(ndc[k]), 1.0) << "axis " << k << " corner " << corner.x << "," << corner.y << "," << corner.z;
      }
    }
  }
}

class FitsTheScene : public testing::TestWithParam<std::tuple<LightProjection, glm::dvec3>> {};

TEST_P(FitsTheScene, EveryObjectInsideTheUnitCube) {
  const auto [projection, position] = GetParam();
  expect_scene_inside(request_with_light(position, projection));
}

INSTANTIATE_TEST_SUITE_P(
    Lights, FitsTheScene,
    testing::Combine(testing::Values(LightProjection::Orthographic),
                     testing::Values(glm::dvec3(-2, 4, -1), glm::dvec3(0, 5, 0),   // overhead
                                     glm::dvec3(0.0001, 5, 0), glm::dvec3(10, 0.35, 0),  // ~2 degrees high
                                     glm::dvec3(0, -3, 0.5))));                          // from below

TEST(LightFrustum, PerspectiveFitCoversObjectsInFrontOfTheLight) {
  // A point light high above: the whole floor is within a < 150 degree cone.
  RenderRequest r = request_with_light({0, 40, 0}, LightProjection::Perspective);
  expect_scene_inside(r);
  const LightFrustum f = light_frustum(r);
  EXPECT_GT(f.near_plane, 0.0);
  EXPECT_LT(f.near_plane, 40.0 - 0.75);  // the tallest cube's top is below y = 1
  EXPECT_GT(f.far_plane, 40.0);
}

TEST(LightFrustum, PerspectiveOverheadLightIsFinite) {
  RenderRequest r = request_with_light({0, 3, 0}, LightProjection::Perspective, "cube-on-plane");
  const LightFrustum f = light_frustum(r);
  EXPECT_TRUE(finite(f.view_projection()));
  EXPECT_GT(f.near_plane, 0.0);
  // The 50 x 50 floor seen from 3 units up cannot fit in a cone: widest allowed.
  EXPECT_NEAR(std::atan(1.0 / f.projection[1][1]) * 2.0 * 180.0 / 3.14159265358979323846, kMaxFittedLightFovDeg, 1e-6);
}

TEST(LightFrustum, FixedFitIsTheSeedsMatrices) {
  RenderRequest r = request_with_light({-2, 4, -1}, LightProjection::Orthographic);
  r.shadow.fit = FrustumFit::Fixed;
  const LightFrustum f = light_frustum(r);
  EXPECT_DOUBLE_EQ(f.near_plane, 1.0);
  EXPECT_DOUBLE_EQ(f.far_plane, 7.5);
  EXPECT_DOUBLE_EQ(f.projection[0][0], 2.0 / 20.0);
  EXPECT_DOUBLE_EQ(f.texel_size, 20.0 / 2048.0);
}

TEST(LightFrustum, DirectionIsPositionToTarget) {
  RenderRequest r = request_with_light({0, 10, 0}, LightProjection::Orthographic);
  const LightFrustum f = light_frustum(r);
  EXPECT_NEAR(f.direction.y, -1.0, 1e-12);
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

}  // namespace
}  // namespace umbra
