// The table of light kinds, each defined in its own file here.
#include "core/lights/light_kind.hpp"

namespace umbra {

extern const LightKind kPointLight, kDirectionalLight, kSunLight;

LightState place_on_orbit(const Light& light, double time) {
  LightState state;
  state.position = orbit_light_position(light, time);
  return state;
}

const std::vector<const LightKind*>& light_kinds() {
  static const std::vector<const LightKind*> kinds = {&kPointLight, &kDirectionalLight, &kSunLight};
  return kinds;
}

const LightKind& light_kind(const Light& light) {
  if (light.sun) return kSunLight;
  return light.projection == LightProjection::Perspective ? kPointLight : kDirectionalLight;
}

const LightKind* find_light_kind(std::string_view name) {
  for (const LightKind* kind : light_kinds())
    if (name == kind->name) return kind;
  return nullptr;
}

}  // namespace umbra
