// The point light: a position orbiting its target, shadows drawn from it in
// perspective.
#include <glm/geometric.hpp>

#include "core/lights/light_kind.hpp"

namespace umbra {

namespace {

LightState place(const Light& light, double time) {
  LightState state;
  state.position = orbit_light_position(light, time);
  return state;
}

glm::dvec3 direction_to_light(const Light&, const glm::dvec3& light_position, const glm::dvec3& point) {
  return glm::normalize(light_position - point);
}

}  // namespace

extern const LightKind kPointLight;  // listed in lights.cpp
const LightKind kPointLight = {"point", LightProjection::Perspective, place, direction_to_light};

}  // namespace umbra
