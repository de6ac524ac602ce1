// The directional light: parallel light along position -> target, the
// position orbiting the target; shadows drawn orthographically.
#include <glm/geometric.hpp>

#include "core/lights/light_kind.hpp"

namespace umbra {

namespace {

LightState place(const Light& light, double time) {
  LightState state;
  state.position = orbit_light_position(light, time);
  return state;
}

glm::dvec3 direction_to_light(const Light& light, const glm::dvec3& light_position, const glm::dvec3&) {
  return glm::normalize(light_position - light.target);
}

}  // namespace

extern const LightKind kDirectionalLight;  // listed in lights.cpp
const LightKind kDirectionalLight = {"directional", LightProjection::Orthographic, place, direction_to_light};

}  // namespace umbra
