#include "core/raster_outline.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <glm/geometric.hpp>

#include "core/light_math.hpp"
#include "core/scene.hpp"
#include "core/shapes/shape.hpp"

namespace umbra {

namespace {

// How far (world units) the raster may draw an object's corners from where
// they are: its positions are floats relative to the scene's centre
// (tessellate's Mesh::origin), moved through float matrices, so off by up
// to about 1e-6 of the coordinates involved (seen_here's rounding term).
double raster_rounding(const Aabb& b, const glm::dvec3& origin, const glm::dvec3& eye) {
  const glm::dvec3 far_corner = glm::max(glm::abs(b.min - origin), glm::abs(b.max - origin));
  return 1e-6 * (glm::length(far_corner) + glm::length(eye - origin));
}

// World size of a pixel at unit distance, along the image's height.
double pixel_per_distance(const Camera& camera, int height) {
  return 2.0 * std::tan(camera.fov_y_deg * 3.14159265358979323846 / 360.0) / height;
}

glm::dvec3 scene_origin(const Scene& scene) {
  const Aabb all = scene_bounds(scene);
  return all.empty() ? glm::dvec3(0.0) : all.center();
}

// The camera's distance (at least its near plane) to where the object's
// outline can be: anywhere in its bounds, but for a plane (a rectangle
// that fills its flat bounds) only on the rectangle's border.
double outline_distance(const SceneObject& o, const Aabb& b, const Camera& camera) {
  const glm::dvec3 e = camera.position;
  double d = glm::length(glm::clamp(e, b.min, b.max) - e);
  if (shape_kind(o.type).horizontal_plane) {
    // Within the rectangle seen from above or below: the nearest side.
    const double inside_x = std::min(e.x - b.min.x, b.max.x - e.x), inside_z = std::min(e.z - b.min.z, b.max.z - e.z);
    if (inside_x > 0.0 && inside_z > 0.0) d = std::hypot(std::min(inside_x, inside_z), e.y - b.min.y);
  }
  return std::max(d, camera.near_plane);
}

}  // namespace

int silhouette_ring(const RenderRequest& request) {
  const Camera& camera = request.camera;
  const double pixel = pixel_per_distance(camera, request.height);
  const glm::dvec3 origin = scene_origin(request.scene);
  double most = 0.0;
  for (const SceneObject& o : request.scene.objects) {
    const Aabb b = object_bounds(o);
    if (b.empty()) continue;
    // The tessellation of a curved shape, and the raster's rounding where
    // it is more than the sliver marks' band allows for.
    double distance = tessellation_error(o).distance;
    const double d = outline_distance(o, b, camera);
    const double rounding = raster_rounding(b, origin, camera.position);
    if (rounding / (d * pixel) > kMisplacedPixels) distance += rounding;
    if (distance <= 0.0) continue;
    most = std::max(most, distance / (d * pixel));
  }
  // The rasterised outline and the exact one are at most `most` pixels
  // apart; a pixel between them is at most that far from a pixel whose
  // rasterised object differs from its neighbour's.
  return 1 + int(std::ceil(std::min(most, 1e6)));
}

std::vector<PixelRect> misplaced_rectangles(const RenderRequest& request, int width, int height) {
  std::vector<PixelRect> rectangles;
  const Camera& camera = request.camera;
  const glm::dvec3 origin = scene_origin(request.scene);
  const double pixel = pixel_per_distance(camera, height);
  const CameraMatrices m = camera_matrices(camera, width, height);
  const glm::dmat4 to_clip = m.projection * m.view;
  for (const SceneObject& o : request.scene.objects) {
    const Aabb b = object_bounds(o);
    if (b.empty()) continue;
    const double rounding = raster_rounding(b, origin, camera.position);
    const double pixels = rounding / (outline_distance(o, b, camera) * pixel);
    // Only an object within kMisplacedSizes roundings across can lose its
    // outline to the rounding (vanish, or a part of it): the ring widened
    // by silhouette_ring finds the rest.
    if (pixels <= kMisplacedPixels || glm::length(b.max - b.min) > kMisplacedSizes * rounding) continue;
    // The bounds' rectangle on screen, grown by the rounding and 2 pixels
    // (row 0 at the top); the whole image if the bounds reach behind half
    // the near plane.
    const std::optional<ScreenBounds> on_screen = screen_bounds_of(b, to_clip, 0.5 * camera.near_plane);
    const double grow = pixels + 2.0;
    int i0 = 0, i1 = width, j0 = 0, j1 = height;
    if (on_screen) {
      const double x0 = (on_screen->low.x * 0.5 + 0.5) * width, x1 = (on_screen->high.x * 0.5 + 0.5) * width;
      const double y0 = (0.5 - on_screen->high.y * 0.5) * height, y1 = (0.5 - on_screen->low.y * 0.5) * height;
      i0 = int(std::clamp(std::floor(x0 - grow), 0.0, double(width)));
      i1 = int(std::clamp(std::ceil(x1 + grow), 0.0, double(width)));
      j0 = int(std::clamp(std::floor(y0 - grow), 0.0, double(height)));
      j1 = int(std::clamp(std::ceil(y1 + grow), 0.0, double(height)));
    }
    rectangles.push_back({i0, j0, i1, j1});
  }
  return rectangles;
}

void mark_misplaced_objects(const RenderRequest& request, int width, int height, std::vector<std::uint8_t>& marks) {
  for (const auto [i0, j0, i1, j1] : misplaced_rectangles(request, width, height))
    for (int j = j0; j < j1; ++j)
      std::fill_n(marks.begin() + std::ptrdiff_t(std::size_t(j) * std::size_t(width) + std::size_t(i0)), i1 - i0, 1);
}

}  // namespace umbra
