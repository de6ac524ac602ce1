#include "plan/umbras.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec4.hpp>

#include "core/shapes/shape.hpp"

namespace umbra {

namespace {

// A texel's neighbour `reach` texels away along both axes is reach * sqrt 2
// texels from it.
constexpr double kDiagonal = 1.4142135623730951;

// Where the light's ray through `p` meets the plane at height y: along the
// direction, or from the point light through p (p below the light).
glm::dvec2 projected(const ShadowPlan& light, const glm::dvec3& p, double y) {
  const glm::dvec3 ray = light.perspective ? p - light.position : light.direction;
  const glm::dvec3 at = p + ray * ((y - p.y) / ray.y);
  return {at.x, at.z};
}

PlanePolygon shadow_of(const ShadowPlan& light, const std::vector<glm::dvec3>& points, double y) {
  std::vector<glm::dvec2> on_plane;
  on_plane.reserve(points.size());
  for (const glm::dvec3& p : points) on_plane.push_back(projected(light, p, y));
  return convex_hull(std::move(on_plane));
}

// Whether `view` holds every corner of `region` (on the plane at height y),
// and so all of it, with `reach` texels to spare.
bool holds_with_reach(const ShadowView& view, int layer_size, const PlanePolygon& region, double y, double reach) {
  const glm::dmat4 view_projection = view.view_projection();
  for (const glm::dvec2& q : region) {
    const glm::dvec4 clip = view_projection * glm::dvec4(q.x, y, q.y, 1.0);
    if (!(clip.w > 0.0)) return false;
    const glm::dvec3 ndc = glm::dvec3(clip) / clip.w;
    const glm::dvec2 texel = (glm::dvec2(ndc) * 0.5 + 0.5) * double(layer_size);
    if (!(std::abs(ndc.z) <= 1.0) || !(texel.x >= reach && texel.y >= reach) ||
        !(texel.x <= layer_size - reach && texel.y <= layer_size - reach))
      return false;
  }
  return !region.empty();
}

// Whether two convex solids, given by their corners and the directions of
// their edges, meet: no axis separates them among the cross products of
// those directions, which include both solids' face normals.
bool convex_solids_meet(const std::vector<glm::dvec3>& a, const std::vector<glm::dvec3>& b,
                        const std::vector<glm::dvec3>& edges) {
  for (std::size_t i = 0; i < edges.size(); ++i)
    for (std::size_t j = i + 1; j < edges.size(); ++j) {
      const glm::dvec3 axis = glm::cross(edges[i], edges[j]);
      if (!(glm::length(axis) > 1e-12 * glm::length(edges[i]) * glm::length(edges[j]))) continue;
      const auto extent = [&](const std::vector<glm::dvec3>& corners) {
        glm::dvec2 range(std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity());
        for (const glm::dvec3& c : corners) range = {std::min(range.x, glm::dot(c, axis)), std::max(range.y, glm::dot(c, axis))};
        return range;
      };
      const glm::dvec2 ea = extent(a), eb = extent(b);
      if (ea.y < eb.x || eb.y < ea.x) return false;
    }
  return true;
}

// Whether `view`'s near plane leaves all of `object` (its world bounds) in
// its layer: the part of the view before its near plane and within its
// sides must not meet the object. A far plane that cuts an object lies
// past every point the view serves, and the part of the object in front
// of those points is kept.
bool near_plane_keeps(const ShadowView& view, const Aabb& object) {
  const bool perspective = view.tan_half > 0.0;
  // Orthographic: in normalized coordinates (affine in world space), the
  // view before its near plane is x and y within +-1 and z below -1.
  // Perspective: in eye space (looking down -z), the pyramid from the eye
  // to the near plane's rectangle.
  const glm::dmat4 to = perspective ? view.view : view.view_projection();
  const auto transformed = [&](const glm::dvec3& p) {
    const glm::dvec4 c = to * glm::dvec4(p, 1.0);
    return glm::dvec3(c) / c.w;
  };
  std::vector<glm::dvec3> corners;
  for (const glm::dvec3& c : object.corners()) corners.push_back(transformed(c));
  std::vector<glm::dvec3> edges;
  for (const glm::dvec3& axis : {glm::dvec3(1, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, 1)})
    edges.push_back(transformed(object.min + axis) - transformed(object.min));
  std::vector<glm::dvec3> before_near;
  if (perspective) {
    const double n = view.near_plane, side = n * view.tan_half;
    before_near = {{0.0, 0.0, 0.0}, {-side, -side, -n}, {side, -side, -n}, {side, side, -n}, {-side, side, -n}};
    for (std::size_t k = 1; k < before_near.size(); ++k) edges.push_back(before_near[k]);
  } else {
    double lowest = -1.0;
    for (const glm::dvec3& c : corners) lowest = std::min(lowest, c.z);
    if (!(lowest < -1.0)) return true;
    for (int k = 0; k < 8; ++k)
      before_near.emplace_back(k & 1 ? 1.0 : -1.0, k & 2 ? 1.0 : -1.0, k & 4 ? -1.0 : lowest);
  }
  edges.insert(edges.end(), {glm::dvec3(1, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, 1)});
  return !convex_solids_meet(corners, before_near, edges);
}

// The world size of the texels the main pass may read for points of
// `region` (the plane at height y), whose shadow comes through `points`
// inside `object`: the largest texel of the views that may serve the
// region, at the distance of the farthest point for a perspective light.
// None where the lookup would not find the object in every texel it reads:
// a view that may serve the region cuts the object with its near plane, or
// the region is not all in the light's view. Cascades are fitted to what
// the camera sees, so a part of the region outside them all is out of
// sight; a single view (the seeds' fixed light box, or a cone) may leave
// out what the camera sees, and must hold the whole region.
std::optional<double> texel_size_for(const ShadowPlan& light, const std::vector<glm::dvec3>& points,
                                     const Aabb& object, const PlanePolygon& region, double y, double reach) {
  if (light.layout == ShadowLayout::Single &&
      !holds_with_reach(light.views.front(), light.layer_size, region, y, reach + 1.0))
    return std::nullopt;
  double texel = 0.0;
  if (light.perspective) {
    // A cube face or cone: a texel's angle is largest at the view's centre,
    // where it is texel_size.x (per unit of distance).
    double farthest = 0.0;
    for (const glm::dvec3& p : points) farthest = std::max(farthest, glm::distance(p, light.position));
    for (const ShadowView& view : light.views) {
      if (!near_plane_keeps(view, object)) return std::nullopt;
      texel = std::max(texel, view.texel_size.x * farthest);
    }
    return texel;
  }
  // The main pass reads a point from the first view that holds it with the
  // filter's reach: no view after one that holds all of the region.
  for (const ShadowView& view : light.views) {
    if (!near_plane_keeps(view, object)) return std::nullopt;
    texel = std::max({texel, view.texel_size.x, view.texel_size.y});
    if (holds_with_reach(view, light.layer_size, region, y, reach + 1.0)) break;
  }
  return texel;
}

// The corners of `plane`'s x/z rectangle moved out by `fraction` of its
// larger side (in, if negative).
constexpr double kEdgeHair = 1e-4;
double plane_reach(const Aabb& plane, double fraction) {
  return fraction * std::max(plane.max.x - plane.min.x, plane.max.z - plane.min.z);
}
glm::dvec2 plane_low(const Aabb& plane, double fraction) {
  return glm::dvec2(plane.min.x, plane.min.z) - plane_reach(plane, fraction);
}
glm::dvec2 plane_high(const Aabb& plane, double fraction) {
  return glm::dvec2(plane.max.x, plane.max.z) + plane_reach(plane, fraction);
}

// Whether the light comes down onto the plane at height y steeply enough
// that shadows cast on it stay within reach of double precision: a sun
// grazing it by less than a microradian casts them millions of widths
// away, where cutting them to the plane loses their edges.
bool lights_plane_from_above(const ShadowPlan& light, double y) {
  if (light.perspective) return light.position.y > y;
  return light.direction.y < -1e-6 * glm::length(light.direction);
}

}  // namespace

std::vector<glm::dvec3> points_inside(const SceneObject& object, double margin, double low, double high) {
  // Each shape's own (core/shapes): a box's corners, rings on a sphere.
  const auto inside = shape_kind(object.type).points_inside;
  return inside ? inside(object, margin, low, high) : std::vector<glm::dvec3>{};
}

std::vector<PlanePolygon> umbras_on_plane(const Aabb& plane, const ShadowPlan& light,
                                          const std::vector<SceneObject>& objects, double reach_texels,
                                          double world_margin) {
  std::vector<PlanePolygon> umbras;
  const double y = plane.min.y;
  if (plane.empty() || light.views.empty() || !lights_plane_from_above(light, y)) return umbras;
  const double high =
      light.perspective ? y + 0.75 * (light.position.y - y) : std::numeric_limits<double>::infinity();
  // Cut a hair inside the plane's edge: drawn with float vertices, an umbra
  // cut exactly to it could darken a pixel just past the plane.
  const glm::dvec2 inner_low = plane_low(plane, -kEdgeHair), inner_high = plane_high(plane, -kEdgeHair);
  for (const SceneObject& object : objects) {
    if (umbras.size() >= kMaxUmbras) break;
    const std::vector<glm::dvec3> whole = points_inside(object, 0.0, y, high);
    if (whole.size() < 2) continue;
    double margin = world_margin;
    if (reach_texels > 0.0) {
      const std::optional<double> texel =
          texel_size_for(light, whole, object_bounds(object), shadow_of(light, whole, y), y, reach_texels);
      if (!texel) continue;
      margin = std::max(margin, reach_texels * kDiagonal * *texel);
    }
    if (!(margin > 0.0)) continue;
    PlanePolygon umbra =
        clipped(shadow_of(light, points_inside(object, margin, y, high), y), inner_low, inner_high);
    if (umbra.size() >= 3 && polygon_area(umbra) > 0.0) umbras.push_back(std::move(umbra));
  }
  return umbras;
}

std::optional<std::vector<PlanePolygon>> shadow_bounds_on_plane(const Aabb& plane, std::size_t plane_object,
                                                                const ShadowPlan& light, const std::vector<Aabb>& bounds,
                                                                double reach_texels, double world_margin) {
  const double y = plane.min.y;
  if (plane.empty() || light.views.empty() || !lights_plane_from_above(light, y) ||
      bounds.size() > kMaxShadowBoundsObjects + 1)
    return std::nullopt;
  // Cut a little past the plane's edge: drawn with float vertices, shadows
  // cut exactly to it could leave unmarked a pixel on the edge that the
  // plane's own cells cover, and draw it lit (a speckle where tiles of a
  // floor overlap). The marks draw nothing, so past the edge they are
  // harmless.
  const glm::dvec2 outer_low = plane_low(plane, kEdgeHair * 10.0), outer_high = plane_high(plane, kEdgeHair * 10.0);
  const auto texel_of = [](const ShadowView& view) { return std::max(view.texel_size.x, view.texel_size.y); };
  double largest_texel = 0.0;  // orthographic: world units; perspective: per unit of distance
  for (const ShadowView& view : light.views) largest_texel = std::max(largest_texel, texel_of(view));
  std::vector<PlanePolygon> shadows;
  for (std::size_t i = 0; i < bounds.size(); ++i) {
    if (i == plane_object || bounds[i].empty()) continue;
    double farthest = 1.0;
    if (light.perspective) {
      farthest = 0.0;
      for (const glm::dvec3& corner : bounds[i].corners())
        farthest = std::max(farthest, glm::distance(corner, light.position));
    }
    bool bounded = true;
    // The object's bounds grown by `texel` texels' reach, cast onto the
    // plane and cut to it; empty if nothing of it is above the plane.
    const auto shadow_with = [&](double texel) {
      const double margin = std::max(world_margin, reach_texels * kDiagonal * texel * farthest);
      Aabb grown = bounds[i];
      grown.min -= margin;
      grown.max += margin;
      // What lies below the plane (the margin aside) is behind every
      // point of it: its texels' depths are past the plane's.
      grown.min.y = std::max(grown.min.y, y - margin);
      // Nothing at or above a point light's height is on a ray down from it.
      if (light.perspective && !(grown.min.y < light.position.y)) return PlanePolygon{};
      if (light.perspective && !(grown.max.y < light.position.y - 1e-9 * (light.position.y - y))) {
        // Rays down from the light meet only what lies below it, but the
        // shadow of what lies just below reaches ever further out: cut the
        // bounds where theirs would fall past `far_out` (four times as far
        // as any of the plane from the light's foot), off the plane
        // anyway. Unless the light's foot is inside them (the shadow would
        // surround it).
        const glm::dvec2 foot(light.position.x, light.position.z);
        const glm::dvec2 nearest = glm::clamp(foot, glm::dvec2(grown.min.x, grown.min.z), glm::dvec2(grown.max.x, grown.max.z));
        const double inner = glm::distance(nearest, foot);
        double far_out = 0.0;
        for (const glm::dvec2 corner : {glm::dvec2(plane.min.x, plane.min.z), glm::dvec2(plane.max.x, plane.max.z),
                                        glm::dvec2(plane.min.x, plane.max.z), glm::dvec2(plane.max.x, plane.min.z)})
          far_out = std::max(far_out, 4.0 * glm::distance(corner, foot));
        // A point at height h and distance `inner` from the foot falls at
        // inner * (light - y) / (light - h) from it.
        grown.max.y = std::min(grown.max.y, light.position.y - (light.position.y - y) * inner / far_out);
        if (!(grown.max.y < light.position.y - 1e-9 * (light.position.y - y))) {  // the foot inside, or a hair away
          bounded = false;
          return PlanePolygon{};
        }
      }
      if (grown.max.y < grown.min.y) return PlanePolygon{};
      return clipped(shadow_of(light, grown.corners(), y), outer_low, outer_high);
    };
    PlanePolygon shadow = shadow_with(largest_texel);
    if (!bounded) return std::nullopt;
    if (!light.perspective && shadow.size() >= 3) {
      // Every point of that shadow is read from the first view that holds
      // all of it with the reach, or an earlier one: only their texels
      // matter, and points outside the shadow they give read no texel of
      // the object in any view.
      double texel = 0.0;
      for (const ShadowView& view : light.views) {
        texel = std::max(texel, texel_of(view));
        if (holds_with_reach(view, light.layer_size, shadow, y, reach_texels + 1.0)) {
          shadow = shadow_with(texel);
          break;
        }
      }
    }
    if (shadow.size() >= 3 && polygon_area(shadow) > 0.0) shadows.push_back(std::move(shadow));
  }
  return shadows;
}

}  // namespace umbra
