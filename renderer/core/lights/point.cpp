// The point light: a position orbiting its target, shadows drawn from it in
// perspective: one cone around every object when one narrow enough holds
// them, else the six faces of a cube.
#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

#include "core/lights/light_kind.hpp"
#include "core/lights/view_fitting.hpp"
#include "core/shader_facts.hpp"

namespace umbra {

namespace {

glm::dvec3 direction_to_light(const Light&, const glm::dvec3& light_position, const glm::dvec3& point) {
  return glm::normalize(light_position - point);
}

// A spherical light of radius `size` seen from the point is a disc facing it.
LightDisc disc_seen_from(const Light& light, const glm::dvec3& light_position, const glm::dvec3&) {
  return {light_position, light.size, true};
}

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// Near and far of a perspective view from what of the objects lies inside
// it; `empty` if nothing does.
void fit_depth_range(ShadowView& v, const std::vector<Aabb>& boxes, double reach_far) {
  const glm::dmat4 probe = glm::perspective(2.0 * std::atan(v.tan_half), 1.0, reach_far * 1e-9, reach_far) * v.view;
  double nearest = kInfinity, farthest = 0.0;
  for (const auto& b : boxes) {
    for (const auto& p : frustum_box_intersection(probe, b)) {
      const double depth = -transform(v.view, p).z;
      nearest = std::min(nearest, depth);
      farthest = std::max(farthest, depth);
    }
  }
  v.empty = !(nearest <= farthest);
  if (v.empty) nearest = farthest = reach_far * 0.5;
  v.far_plane = farthest * 1.01;
  // 32-bit float depth keeps enough precision for far/near up to ~10^5.
  v.near_plane = std::max(nearest * 0.99, v.far_plane * 1e-5);
  v.projection = glm::perspective(2.0 * std::atan(v.tan_half), 1.0, v.near_plane, v.far_plane);
}

void plan_perspective(ShadowPlan& plan, const RenderRequest& request, const glm::dmat4& light_view) {
  const std::vector<Aabb> boxes = bounds_of(request.scene);
  const int reach = filter_reach_texels(request.shadow);
  double reach_far = 0.0;  // beyond every object
  for (const auto& b : boxes)
    for (const auto& c : b.corners()) reach_far = std::max(reach_far, glm::length(c - plan.position));
  reach_far = std::max(reach_far * 2.0, 1e-30);

  // The narrowest square cone around every corner in front of the light.
  double tan_half = 0.0;
  for (const auto& b : boxes) {
    for (const auto& corner : b.corners()) {
      const glm::dvec3 p = transform(light_view, corner);
      const double depth = -p.z;
      // Beside or behind the light: no cone of less than 180 degrees holds it.
      tan_half = depth <= 1e-9 * reach_far ? kInfinity : std::max(tan_half, std::max(std::abs(p.x), std::abs(p.y)) / depth);
    }
    if (tan_half == kInfinity) break;
  }
  const double spare = spare_fraction(reach + 1, plan.layer_size);
  if (tan_half / (1.0 - spare) <= std::tan(glm::radians(kMaxFittedLightFovDeg * 0.5))) {
    ShadowView v;
    v.view = light_view;
    v.tan_half = std::max(tan_half / (1.0 - spare), 1e-6);
    fit_depth_range(v, boxes, reach_far);
    set_texel_size(v, true, plan.layer_size);
    plan.views = {v};
    plan.layout = ShadowLayout::Single;
    return;
  }

  // Six faces, each a little wider than 90 degrees so that the filter
  // kernel of a point on a face's edge still falls inside that face.
  plan.layout = ShadowLayout::Cube;
  plan.layer_size = std::min(request.shadow.map_size, int(std::sqrt(kMaxShadowTexels / kCubeFaceCount)));
  const double face_spare = spare_fraction(reach + 1, plan.layer_size);
  plan.views.clear();
  for (int face = 0; face < kCubeFaceCount; ++face) {
    ShadowView v;
    v.view = cube_face_view(plan.position, face);
    v.tan_half = 1.0 / (1.0 - face_spare);
    fit_depth_range(v, boxes, reach_far);
    set_texel_size(v, true, plan.layer_size);
    plan.views.push_back(v);
  }
}

}  // namespace

extern const LightKind kPointLight;  // listed in lights.cpp
const LightKind kPointLight = {
    "point", LightProjection::Perspective, place_on_orbit, direction_to_light, disc_seen_from, plan_perspective,
};

}  // namespace umbra
