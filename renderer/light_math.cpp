#include "light_math.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

namespace umbra {

glm::dvec3 orbit_light_position(const Light& light, double time) {
  return light.target + rotate_y(light.position - light.target, std::fmod(time * light.orbit_deg_per_s, 360.0));
}

glm::dmat4 stable_look_at(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up) {
  const glm::dvec3 forward = glm::normalize(target - eye);
  glm::dvec3 chosen_up = glm::normalize(up);
  // Within ~0.06 degrees of parallel the basis would spin wildly with tiny
  // changes of direction (and at exactly parallel be NaN): substitute.
  if (glm::length(glm::cross(forward, chosen_up)) < 1e-3) {
    if (std::abs(forward.y) > 0.5)
      chosen_up = glm::dvec3(0.0, 0.0, forward.y < 0.0 ? -1.0 : 1.0);
    else
      chosen_up = glm::dvec3(0.0, 1.0, 0.0);
  }
  return glm::lookAt(eye, target, chosen_up);
}

namespace {

struct LightSpaceExtent {
  glm::dvec3 min{std::numeric_limits<double>::max()};
  glm::dvec3 max{std::numeric_limits<double>::lowest()};
};

// Extent of every object's bounding-box corners in the light's view space.
LightSpaceExtent view_space_extent(const glm::dmat4& view, const Scene& scene) {
  LightSpaceExtent e;
  for (const auto& object : scene.objects) {
    for (const auto& corner : object_bounds(object).corners()) {
      const glm::dvec3 p = glm::dvec3(view * glm::dvec4(corner, 1.0));
      e.min = glm::min(e.min, p);
      e.max = glm::max(e.max, p);
    }
  }
  return e;
}

void fit_orthographic(LightFrustum& f, const Scene& scene, int map_size) {
  const LightSpaceExtent e = view_space_extent(f.view, scene);
  // One texel of margin keeps the outermost geometry inside the map; the
  // depth margin keeps the nearest and farthest surfaces off the clip planes.
  const double width = std::max(e.max.x - e.min.x, e.max.y - e.min.y);
  const double scale = std::max({width, e.max.z - e.min.z, 1e-30});
  const double margin = scale / map_size;
  const double x0 = e.min.x - margin, x1 = e.max.x + margin;
  const double y0 = e.min.y - margin, y1 = e.max.y + margin;
  // View space looks down -Z: the nearest point has the largest z.
  f.near_plane = -e.max.z - margin;
  f.far_plane = -e.min.z + margin;
  f.projection = glm::ortho(x0, x1, y0, y1, f.near_plane, f.far_plane);
  f.texel_size = std::max(x1 - x0, y1 - y0) / map_size;
}

// Euclidean distance from p to the box (0 inside).
double distance_to(const Aabb& box, const glm::dvec3& p) {
  const glm::dvec3 outside = glm::max(glm::max(box.min - p, p - box.max), glm::dvec3(0.0));
  return glm::length(outside);
}

void fit_perspective(LightFrustum& f, const Scene& scene, int map_size) {
  const LightSpaceExtent e = view_space_extent(f.view, scene);
  // Depth along the axis is linear in position, so its extremes over a box
  // are at corners; so is the largest |x|/depth over the part in front.
  const double farthest = std::max(-e.min.z, 1e-30);
  const double far_plane = farthest * 1.01;

  const double max_tan = std::tan(glm::radians(kMaxFittedLightFovDeg * 0.5));
  double tan_half = 0.0;
  double nearest_distance = std::numeric_limits<double>::max();
  for (const auto& object : scene.objects) {
    const Aabb bounds = object_bounds(object);
    nearest_distance = std::min(nearest_distance, distance_to(bounds, f.position));
    for (const auto& corner : bounds.corners()) {
      const glm::dvec3 p = glm::dvec3(f.view * glm::dvec4(corner, 1.0));
      const double depth = -p.z;
      if (depth <= 1e-9 * far_plane) {
        // Part of the object lies beside or behind the light: no cone of
        // less than 180 degrees holds it. Take the widest allowed.
        tan_half = max_tan;
        continue;
      }
      tan_half = std::max(tan_half, std::max(std::abs(p.x), std::abs(p.y)) / depth);
    }
  }
  tan_half = std::clamp(tan_half * (1.0 + 2.0 / map_size), 1e-6, max_tan);

  // Near: as far out as nothing inside the cone is cut. A point at distance r
  // inside a cone of half-angle a lies at least r cos(a) along the axis, and
  // no point lies nearer than the nearest corner depth either. (Taking the
  // corner depth alone collapses near towards 0 as soon as a floor reaches
  // behind the light, and with it the depth precision.)
  const double cos_half = 1.0 / std::sqrt(1.0 + tan_half * tan_half);
  const double nearest = std::max(-e.max.z, nearest_distance * cos_half);
  // 32-bit float depth keeps enough precision for far/near up to ~10^5.
  const double near_plane = std::max(nearest * 0.99, far_plane * 1e-5);
  f.near_plane = near_plane;
  f.far_plane = far_plane;
  f.projection = glm::perspective(2.0 * std::atan(tan_half), 1.0, near_plane, far_plane);
  f.texel_size = 2.0 * tan_half / map_size;
}

}  // namespace

LightFrustum light_frustum(const RenderRequest& request) {
  const Light& light = request.light;
  const ShadowSettings& shadow = request.shadow;
  LightFrustum f;
  f.perspective = light.projection == LightProjection::Perspective;
  f.position = orbit_light_position(light, request.time);
  f.direction = glm::normalize(light.target - f.position);
  f.view = stable_look_at(f.position, light.target, glm::dvec3(0.0, 1.0, 0.0));

  if (shadow.fit == FrustumFit::Fixed) {
    f.near_plane = shadow.near_plane;
    f.far_plane = shadow.far_plane;
    if (f.perspective) {
      f.projection = glm::perspective(glm::radians(light.fov_y_deg), 1.0, f.near_plane, f.far_plane);
      f.texel_size = 2.0 * std::tan(glm::radians(light.fov_y_deg) * 0.5) / shadow.map_size;
    } else {
      const double h = shadow.ortho_half_size;
      f.projection = glm::ortho(-h, h, -h, h, f.near_plane, f.far_plane);
      f.texel_size = 2.0 * h / shadow.map_size;
    }
    return f;
  }
  if (request.scene.objects.empty()) {
    // Nothing casts or receives: any valid frustum will do.
    f.projection = f.perspective ? glm::perspective(glm::radians(90.0), 1.0, 0.1, 1.0)
                                 : glm::ortho(-1.0, 1.0, -1.0, 1.0, -1.0, 1.0);
    f.texel_size = 2.0 / shadow.map_size;
    return f;
  }
  if (f.perspective)
    fit_perspective(f, request.scene, shadow.map_size);
  else
    fit_orthographic(f, request.scene, shadow.map_size);
  return f;
}

CameraMatrices camera_matrices(const Camera& camera, int width, int height) {
  CameraMatrices m;
  m.view = stable_look_at(camera.position, camera.target, camera.up);
  m.projection = glm::perspective(glm::radians(camera.fov_y_deg), double(width) / double(height),
                                  camera.near_plane, camera.far_plane);
  return m;
}

}  // namespace umbra
