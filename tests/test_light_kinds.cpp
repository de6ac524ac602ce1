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
#include "scene_support.hpp"

namespace umbra {
namespace {

using test::expect_near;

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

// A point light is seen as a disc of its radius at its position; a
// directional light or the sun as a cone of directions around the one
// towards it, as wide as half its angular diameter.
TEST(LightKinds, APointSeesAPointLightAsADiscAndADirectionalOneAsACone) {
  Light light;
  light.size = 0.5;
  const glm::dvec3 position(1, 4, 2), to_center = glm::normalize(glm::dvec3(1, 2, 3));
  light.projection = LightProjection::Perspective;
  const LightDisc disc = light_kind(light).disc_seen_from(light, position, to_center);
  EXPECT_TRUE(disc.finite);
  expect_near(disc.center, position);
  EXPECT_EQ(disc.radius, 0.5);
  light.size = 4.0;  // degrees
  for (const bool sun : {false, true}) {
    light.projection = LightProjection::Orthographic;
    if (sun) light.sun = SunClock{};
    const LightKind& kind = light_kind(light);
    SCOPED_TRACE(kind.name);
    const LightDisc cone = kind.disc_seen_from(light, position, to_center);
    EXPECT_FALSE(cone.finite);
    expect_near(cone.center, to_center);
    EXPECT_NEAR(cone.radius, std::tan(glm::radians(2.0)), 1e-15);
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
