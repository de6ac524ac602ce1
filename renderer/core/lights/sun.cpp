// The sun: a directional light placed by the sun's position at
// sun.utc_unix_s + time seconds (solar_position, NREL SPA), at the
// light's distance from its target; no direct light while it is below the
// horizon.
#include <glm/geometric.hpp>

#include "core/lights/light_kind.hpp"
#include "core/lights/view_fitting.hpp"
#include "core/sun_position.hpp"

namespace umbra {

namespace {

LightState place(const Light& light, double time) {
  LightState state;
  const SunClock& clock = *light.sun;
  const SunAngles sun = solar_position(clock.latitude_deg, clock.longitude_deg, clock.utc_unix_s + time);
  state.sun = sun;
  state.direct = sun.elevation_deg > 0.0;
  state.position = light.target + sun_direction(sun.azimuth_deg, sun.elevation_deg, clock.north_deg) *
                                       glm::length(light.position - light.target);
  return state;
}

glm::dvec3 direction_to_light(const Light& light, const glm::dvec3& light_position, const glm::dvec3&) {
  return glm::normalize(light_position - light.target);
}

// A disc of angular diameter `size`: directions within half of it.
LightDisc disc_seen_from(const Light& light, const glm::dvec3&, const glm::dvec3& to_center) {
  return {to_center, sun_disc_tan_radius(light), false};
}

}  // namespace

extern const LightKind kSunLight;  // listed in lights.cpp
// Its views are a directional light's.
const LightKind kSunLight = {
    "sun", LightProjection::Orthographic, place, direction_to_light, disc_seen_from,
    fit_orthographic_views,
};

}  // namespace umbra
