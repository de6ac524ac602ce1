// The directional light: parallel light along position -> target, the
// position orbiting the target; shadows drawn orthographically, in
// cascades fitted to what the camera sees (shared with the sun).
#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

#include "core/lights/light_kind.hpp"
#include "core/lights/view_fitting.hpp"

namespace umbra {

namespace {

glm::dvec3 direction_to_light(const Light& light, const glm::dvec3& light_position, const glm::dvec3&) {
  return glm::normalize(light_position - light.target);
}

// A disc of angular diameter `size`: directions within half of it.
LightDisc disc_seen_from(const Light& light, const glm::dvec3&, const glm::dvec3& to_center) {
  return {to_center, sun_disc_tan_radius(light), false};
}

// Boxes below named `Extent` hold light view-space points; `Aabb` world ones.
using Extent = Aabb;

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// One orthographic view around every object (used when the camera sees no
// object: there is nothing to focus on).
ShadowView ortho_around(const glm::dmat4& view, const std::vector<Aabb>& boxes, int size) {
  Extent e;
  for (const auto& b : boxes)
    for (const auto& c : b.corners()) e.extend(transform(view, c));
  ShadowView v;
  v.view = view;
  const double width = std::max(e.max.x - e.min.x, e.max.y - e.min.y);
  const double margin = std::max({width, e.max.z - e.min.z, 1e-30}) / size;
  // View space looks down -Z: the nearest point has the largest z.
  v.near_plane = -e.max.z - margin;
  v.far_plane = -e.min.z + margin;
  v.projection = glm::ortho(e.min.x - margin, e.max.x + margin, e.min.y - margin, e.max.y + margin, v.near_plane,
                            v.far_plane);
  set_texel_size(v, false, size);
  return v;
}

// The orthographic view for the receivers `points` (already in light view
// space): x/y hold them with `reach` texels to spare, quantised and snapped
// to whole texels; near is pulled towards the light over every caster above
// that rectangle.
ShadowView ortho_for_receivers(const glm::dmat4& view, const Extent& receivers, const std::vector<Extent>& casters,
                               int size, int reach) {
  // Width: the larger side, grown so `reach` + 1 texels fit on each side,
  // then rounded up to a power of 2^(1/16): it keeps its value (and so the
  // texel grid) under small camera moves.
  const double raw = std::max({receivers.max.x - receivers.min.x, receivers.max.y - receivers.min.y, 1e-30});
  const double spare = spare_fraction(reach + 2, size);  // + 1 for snapping the origin
  const double width = std::exp2(std::ceil(std::log2(raw / (1.0 - spare)) * 16.0) / 16.0);
  const double texel = width / size;
  // Origin snapped to a multiple of the texel, so that as the rectangle
  // slides the texels stay where they were and edges do not shimmer.
  const glm::dvec2 center = 0.5 * (glm::dvec2(receivers.min) + glm::dvec2(receivers.max));
  const double x0 = std::floor((center.x - 0.5 * width) / texel) * texel;
  const double y0 = std::floor((center.y - 0.5 * width) / texel) * texel;

  double nearest = receivers.max.z, farthest = receivers.min.z;
  for (const auto& c : casters) {
    if (c.max.x < x0 || c.min.x > x0 + width || c.max.y < y0 || c.min.y > y0 + width) continue;
    nearest = std::max(nearest, c.max.z);
  }
  const double depth_margin = 1e-3 * std::max(nearest - farthest, width) + 1e-9 * std::abs(nearest);
  ShadowView v;
  v.view = view;
  v.near_plane = -nearest - depth_margin;
  v.far_plane = -farthest + depth_margin;
  v.projection = glm::ortho(x0, x0 + width, y0, y0 + width, v.near_plane, v.far_plane);
  set_texel_size(v, false, size);
  return v;
}

// Camera view depths [near, far] of what the camera sees of the objects,
// or nothing if it sees none.
bool visible_depth_range(const CameraMatrices& camera, const std::vector<Aabb>& boxes, double& near_depth,
                         double& far_depth) {
  near_depth = kInfinity;
  far_depth = -kInfinity;
  const glm::dmat4 view_projection = camera.projection * camera.view;
  for (const auto& b : boxes) {
    for (const auto& p : frustum_box_intersection(view_projection, b)) {
      const double depth = -transform(camera.view, p).z;
      near_depth = std::min(near_depth, depth);
      far_depth = std::max(far_depth, depth);
    }
  }
  return near_depth <= far_depth;
}

// Cascades over the camera's visible depths [d0, d1], split logarithmically:
// each cascade then spans the same ratio of depths and so keeps about the
// same ratio of texels to pixels. (The "practical" blend with a uniform
// split exists for d0 = the camera's near plane; d0 here is the nearest
// visible geometry, so the blend would only waste the first cascade.)
std::vector<ShadowView> cascade_views(const RenderRequest& request, const CameraMatrices& camera,
                                      const glm::dmat4& light_view, const std::vector<Aabb>& boxes,
                                      const std::vector<Extent>& casters, double d0, double d1, int count, int size) {
  const Camera& c = request.camera;
  const double aspect = double(request.width) / request.height;
  const int reach = filter_reach_texels(request.shadow);
  std::vector<ShadowView> views;
  double split_near = d0;
  for (int i = 1; i <= count; ++i) {
    const double f = double(i) / count;
    const double split_far = i == count ? d1 : d0 * std::pow(d1 / d0, f);
    // The slice's own frustum, a hair deeper so that rounding at the split
    // never leaves a receiver between two slices.
    const glm::dmat4 slice = glm::perspective(glm::radians(c.fov_y_deg), aspect, split_near * (1.0 - 1e-6),
                                              split_far * (1.0 + 1e-6)) * camera.view;
    Extent receivers;
    for (const auto& b : boxes)
      for (const auto& p : frustum_box_intersection(slice, b)) receivers.extend(transform(light_view, p));
    if (!receivers.empty()) views.push_back(ortho_for_receivers(light_view, receivers, casters, size, reach));
    split_near = split_far;
  }
  return views;
}

void plan_orthographic(ShadowPlan& plan, const RenderRequest& request, const glm::dmat4& light_view) {
  const std::vector<Aabb> boxes = bounds_of(request.scene);
  std::vector<Extent> casters;
  casters.reserve(boxes.size());
  for (const auto& b : boxes) {
    Extent e;
    for (const auto& corner : b.corners()) e.extend(transform(light_view, corner));
    casters.push_back(e);
  }
  const CameraMatrices camera = camera_matrices(request.camera, request.width, request.height);
  double d0 = 0.0, d1 = 0.0;
  if (!visible_depth_range(camera, boxes, d0, d1)) {
    plan.views = {ortho_around(light_view, boxes, plan.layer_size)};
    return;
  }
  d0 = std::max(d0, request.camera.near_plane);
  d1 = std::max(d1, d0 * (1.0 + 1e-9));

  // Auto: add cascades until the nearest one gives the nearest visible
  // receiver no more than kTexelsPerPixel texels per pixel, or kMaxCascades.
  constexpr double kTexelsPerPixel = 1.5;
  const double pixel_at_d0 = d0 * 2.0 * std::tan(glm::radians(request.camera.fov_y_deg) * 0.5) / request.height;
  const int requested = request.shadow.cascades;
  for (int count = requested > 0 ? requested : 1; count <= (requested > 0 ? requested : kMaxCascades); ++count) {
    const int size = std::min(request.shadow.map_size, int(std::sqrt(kMaxShadowTexels / count)));
    plan.layer_size = size;
    plan.views = cascade_views(request, camera, light_view, boxes, casters, d0, d1, count, size);
    if (plan.views.empty()) break;
    if (plan.views.front().texel_size.x <= kTexelsPerPixel * pixel_at_d0) break;
  }
  if (plan.views.empty()) plan.views = {ortho_around(light_view, boxes, plan.layer_size)};
  plan.layout = plan.views.size() > 1 ? ShadowLayout::Cascades : ShadowLayout::Single;
}

}  // namespace

void fit_orthographic_views(ShadowPlan& plan, const RenderRequest& request, const glm::dmat4& light_view) {
  plan_orthographic(plan, request, light_view);
}

extern const LightKind kDirectionalLight;  // listed in lights.cpp
const LightKind kDirectionalLight = {
    "directional", LightProjection::Orthographic, place_on_orbit, direction_to_light, disc_seen_from,
    fit_orthographic_views,
};

}  // namespace umbra
