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

/// The light as a lit point sees it, what the exact reference's shadow rays
/// aim at: for a finite light (`finite`), a disc centred at `center` of
/// radius `radius` (world units) facing the point, the rays ending on it;
/// otherwise a cone of directions around the unit direction `center`, of
/// angular radius atan(`radius`), the rays going to infinity. An ideal light
/// (size 0) has radius 0.
struct LightDisc {
  glm::dvec3 center{0.0};
  double radius = 0.0;
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
  /// The light seen from a point (the exact reference's shadow rays),
  /// `to_center` being direction_to_light's answer for that point.
  LightDisc (*disc_seen_from)(const Light& light, const glm::dvec3& light_position, const glm::dvec3& to_center);
  /// Its shadow views fitted to the scene (fit "scene", plan_shadow), the
  /// light placed at plan.position and looking along `light_view`: sets
  /// plan.views and plan.layout, and may lower plan.layer_size.
  void (*fit_views)(ShadowPlan& plan, const RenderRequest& request, const glm::dmat4& light_view);
};

/// The place of both orbiting kinds (point, directional): on the orbit
/// (orbit_light_position), its light always direct.
LightState place_on_orbit(const Light& light, double time);

/// Every kind.
const std::vector<const LightKind*>& light_kinds();
/// The kind of `light`: a sun when it has one (a sun is orthographic,
/// Light::sun), else by its projection.
const LightKind& light_kind(const Light& light);
/// The row named `name`, or null.
const LightKind* find_light_kind(std::string_view name);

}  // namespace umbra
