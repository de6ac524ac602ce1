// A light kind is one file (as Filament has one update per light type):
// what places it at a moment of the animation, which way a point sees it,
// and the views its shadow map is drawn from. One row per kind (LightKind), picked by light_kind(); light_at and
// the exact reference call through it. Pure CPU code, no GL.
//
// The kinds: "point" (perspective, orbiting), "directional" (orthographic,
// orbiting), "sun" (orthographic, placed by the sun's position).
#pragma once

#include <string_view>
#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "core/light_math.hpp"
#include "core/request.hpp"

namespace umbra {

/// Where a ray from a lit point goes to reach the light: to a point (`finite`:
/// the ray ends there) or along a unit direction (to infinity).
struct LightAim {
  glm::dvec3 at{0.0};
  bool finite = false;
};

struct LightKind {
  /// Unique among the rows.
  const char* name;
  /// How its shadow map looks from it: from a point (perspective: a cone or
  /// a cube), or along a direction (orthographic: cascades).
  LightProjection projection;
  /// Where it stands `time` seconds into the animation (light_at).
  LightState (*place)(const Light& light, double time);
  /// The unit direction from `point` towards the light's centre, the light
  /// standing at `light_position` (placed): towards that position for a
  /// point light, against its direction of travel otherwise.
  glm::dvec3 (*direction_to_light)(const Light& light, const glm::dvec3& light_position, const glm::dvec3& point);
  /// The exact reference's shadow rays, `to_center` being direction_to_light's
  /// answer: to the light's centre (a light of no size), and to a point of an
  /// area light (light.size > 0), `disc` being the point's offset on the
  /// unit disc that faces the lit point (perpendicular to to_center).
  LightAim (*aim_at_center)(const Light& light, const glm::dvec3& light_position, const glm::dvec3& to_center);
  LightAim (*aim_at_disc)(const Light& light, const glm::dvec3& light_position, const glm::dvec3& to_center,
                          const glm::dvec3& disc);
  /// Its shadow views fitted to the scene (fit "scene", plan_shadow), the
  /// light placed at plan.position and looking along `light_view`: sets
  /// plan.views and plan.layout, and may lower plan.layer_size.
  void (*fit_views)(ShadowPlan& plan, const RenderRequest& request, const glm::dmat4& light_view);
};

/// Every kind.
const std::vector<const LightKind*>& light_kinds();
/// The kind of `light`: a sun when it has one (a sun is orthographic,
/// Light::sun), else by its projection.
const LightKind& light_kind(const Light& light);
/// The row named `name`, or null.
const LightKind* find_light_kind(std::string_view name);

}  // namespace umbra
