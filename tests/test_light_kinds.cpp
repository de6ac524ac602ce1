// The light kinds (core/lights): each light picks its row, each row places
// its light and points towards it as its kind does.
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <string>

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

#include "core/light_math.hpp"
#include "core/lights/light_kind.hpp"
#include "core/scene.hpp"

namespace umbra {
namespace {

void expect_near(const glm::dvec3& a, const glm::dvec3& b, double tolerance = 1e-12) {
  EXPECT_NEAR(a.x, b.x, tolerance);
  EXPECT_NEAR(a.y, b.y, tolerance);
  EXPECT_NEAR(a.z, b.z, tolerance);
}

TEST(LightKinds, NamesAreUniqueAndRoundTrip) {
  std::set<std::string> names;
  for (const LightKind* kind : light_kinds()) {
    ASSERT_NE(kind->name, nullptr);
    EXPECT_TRUE(names.insert(kind->name).second) << "two rows named " << kind->name;
    EXPECT_EQ(find_light_kind(kind->name), kind);
    EXPECT_NE(kind->place, nullptr);
    EXPECT_NE(kind->direction_to_light, nullptr);
  }
  EXPECT_EQ(light_kinds().size(), 3u);
  EXPECT_EQ(find_light_kind("spot"), nullptr);
}

TEST(LightKinds, ALightPicksItsKindBySunThenProjection) {
  Light light;
  light.projection = LightProjection::Perspective;
  EXPECT_STREQ(light_kind(light).name, "point");
  light.projection = LightProjection::Orthographic;
  EXPECT_STREQ(light_kind(light).name, "directional");
  light.sun = SunClock{48.85, 2.35, 1718892000.0, 0.0};
  EXPECT_STREQ(light_kind(light).name, "sun");
  for (const LightKind* kind : light_kinds()) {
    SCOPED_TRACE(kind->name);
    // A kind's projection is the one its lights have.
    Light l;
    l.projection = kind->projection;
    if (std::string(kind->name) == "sun") l.sun = SunClock{};
    EXPECT_EQ(&light_kind(l), kind);
  }
}

TEST(LightKinds, OrbitingKindsTurnAboutTheTargetAndPointTowardsTheLight) {
  Light light;
  light.position = {3, 5, 0};
  light.target = {1, 0, 0};
  light.orbit_deg_per_s = 90.0;
  for (const LightProjection projection : {LightProjection::Perspective, LightProjection::Orthographic}) {
    light.projection = projection;
    const LightKind& kind = light_kind(light);
    SCOPED_TRACE(kind.name);
    const LightState state = kind.place(light, 1.0);  // a quarter turn, counter-clockwise seen from above
    expect_near(state.position, {1, 5, -2});
    EXPECT_TRUE(state.direct);
    EXPECT_FALSE(state.sun);
    const glm::dvec3 point(4, 0, 4);
    const glm::dvec3 towards = kind.direction_to_light(light, state.position, point);
    // A point light is seen from the point; a directional one along its direction, wherever the point is.
    expect_near(towards, glm::normalize(projection == LightProjection::Perspective ? state.position - point
                                                                                   : state.position - light.target));
  }
}

TEST(LightKinds, TheSunIsPlacedByTheSunAndGivesNoDirectLightBelowTheHorizon) {
  Light light;
  light.position = {0, 10, 0};
  light.target = {0, 0, 0};
  light.sun = SunClock{48.85, 2.35, 1718892000.0, 0.0};  // Paris, 2024-06-20 14:00 UTC: the sun is up
  const LightKind& kind = light_kind(light);
  const LightState day = kind.place(light, 0.0);
  ASSERT_TRUE(day.sun);
  EXPECT_TRUE(day.direct);
  EXPECT_NEAR(glm::length(day.position - light.target), 10.0, 1e-9);
  expect_near(glm::normalize(day.position - light.target),
              sun_direction(day.sun->azimuth_deg, day.sun->elevation_deg, 0.0), 1e-12);
  expect_near(kind.direction_to_light(light, day.position, {5, 0, 5}), glm::normalize(day.position - light.target));
  const LightState night = kind.place(light, 10.0 * 3600.0);  // midnight
  EXPECT_FALSE(night.direct);
  EXPECT_LT(night.sun->elevation_deg, 0.0);
}

// A point light's shadow rays end at it (its centre, or a point of its
// sphere seen as a disc); a directional light's and the sun's go to
// infinity, within half the disc's angular diameter of its centre.
TEST(LightKinds, ShadowRaysAimAtThePointLightOrAlongTheDirection) {
  Light light;
  light.size = 0.5;
  const glm::dvec3 position(1, 4, 2), to_center = glm::normalize(glm::dvec3(1, 2, 3));
  const glm::dvec3 disc = 0.8 * glm::normalize(glm::cross(to_center, glm::dvec3(0, 1, 0)));
  light.projection = LightProjection::Perspective;
  const LightKind& point = light_kind(light);
  EXPECT_TRUE(point.aim_at_center(light, position, to_center).finite);
  expect_near(point.aim_at_center(light, position, to_center).at, position);
  EXPECT_TRUE(point.aim_at_disc(light, position, to_center, disc).finite);
  expect_near(point.aim_at_disc(light, position, to_center, disc).at, position + 0.5 * disc);
  light.size = 4.0;  // degrees
  for (const bool sun : {false, true}) {
    light.projection = LightProjection::Orthographic;
    if (sun) light.sun = SunClock{};
    const LightKind& kind = light_kind(light);
    SCOPED_TRACE(kind.name);
    EXPECT_FALSE(kind.aim_at_center(light, position, to_center).finite);
    expect_near(kind.aim_at_center(light, position, to_center).at, to_center);
    const LightAim edge = kind.aim_at_disc(light, position, to_center, disc);
    EXPECT_FALSE(edge.finite);
    EXPECT_NEAR(glm::length(edge.at), 1.0, 1e-12);
    // 0.8 of the way to the rim of a disc 4 degrees across.
    EXPECT_NEAR(std::atan(glm::length(glm::cross(edge.at, to_center)) / glm::dot(edge.at, to_center)),
                std::atan(0.8 * std::tan(glm::radians(2.0))), 1e-12);
  }
}

// Each kind fits its own views: a point light's are perspective (a cone or
// a cube), a directional light's and the sun's orthographic (cascades).
TEST(LightKinds, EachKindFitsViewsOfItsProjection) {
  RenderRequest request;
  request.scene.objects = find_builtin_scene("three-cubes")->objects;
  for (const LightKind* kind : light_kinds()) {
    SCOPED_TRACE(kind->name);
    request.light = Light{};
    request.light.projection = kind->projection;
    if (std::string(kind->name) == "sun") request.light.sun = SunClock{48.85, 2.35, 1718892000.0, 0.0};
    ASSERT_EQ(&light_kind(request.light), kind);
    const ShadowPlan plan = plan_shadow(request);
    ASSERT_FALSE(plan.views.empty());
    for (const ShadowView& view : plan.views) {
      if (kind->projection == LightProjection::Perspective)
        EXPECT_GT(view.tan_half, 0.0);
      else
        EXPECT_EQ(view.tan_half, 0.0);
    }
    if (kind->projection == LightProjection::Perspective)
      EXPECT_NE(plan.layout, ShadowLayout::Cascades);
    else
      EXPECT_NE(plan.layout, ShadowLayout::Cube);
  }
}

}  // namespace
}  // namespace umbra
