// The exact reference: the API's "shadow" quantity computed by casting rays
// against the analytic primitives (plane, rotated box, sphere) on the CPU.
// No GL and no shadow map, so it is what the GL output is judged against.
#pragma once

#include <functional>
#include <optional>
#include <stdexcept>

#include <glm/vec3.hpp>

#include "image.hpp"
#include "request.hpp"
#include "scene.hpp"

namespace umbra {

/// Where a ray first meets the scene.
struct RayHit {
  double t = 0.0;          ///< distance along the (unit) ray direction
  glm::dvec3 point{0.0};
  glm::dvec3 normal{0.0};  ///< unit, facing the ray's origin
  int object = -1;         ///< index into scene.objects
};

/// The index of the first object the ray cast cannot intersect (a mesh:
/// meshes come with Embree in a later phase), or -1 when it covers the
/// whole scene. Requests for "exact" or "error" on such a scene are refused
/// (RenderService::submit) rather than answered without the mesh.
int first_object_not_ray_cast(const Scene& scene);

/// The scene's objects in a bounding-volume hierarchy over their bounds, so
/// a ray is tested against the few objects near it instead of all of them.
/// It answers exactly as testing every object in order would: the nearest
/// hit, the lowest object index among equally near ones.
class RayScene {
 public:
  /// Throws std::invalid_argument if first_object_not_ray_cast(scene) >= 0.
  explicit RayScene(const Scene& scene);
  /// First hit of origin + t * direction (unit) with t in (t_min, t_max).
  std::optional<RayHit> cast(const glm::dvec3& origin, const glm::dvec3& direction, double t_min, double t_max) const;
  /// Whether anything lies on the ray with t in (0, t_max).
  bool occluded(const glm::dvec3& origin, const glm::dvec3& direction, double t_max) const;

 private:
  struct Node {
    Aabb box;
    int first = 0, count = 0;  // leaf: objects order_[first, first + count)
    int left = -1, right = -1; // inner node: children
  };
  int build(int first, int count, const std::vector<Aabb>& bounds, const std::vector<glm::dvec3>& centers);
  // Calls visit(object index) for each object in a leaf whose box the ray
  // meets within (t_min, *t_max); visit may lower *t_max and returns false to stop.
  template <class Visit>
  void traverse(const glm::dvec3& origin, const glm::dvec3& direction, double t_min, const double* t_max,
                Visit&& visit) const;

  const Scene& scene_;
  std::vector<int> order_;
  std::vector<Node> nodes_;
};

/// First hit of the ray origin + t * direction (unit) with t in (t_min, t_max).
std::optional<RayHit> cast_ray(const Scene& scene, const glm::dvec3& origin, const glm::dvec3& direction,
                               double t_min, double t_max);

/// The fraction of the light's direct light that reaches `point` (normal
/// `normal`, facing the viewer): 0 when the surface faces away from the
/// light; for light.size > 0 the fraction of a fixed stratified set of 64
/// points on the light's disc that the point sees. `light_position` is the
/// light position after orbit.
double exact_visibility(const RenderRequest& request, const glm::dvec3& light_position, const glm::dvec3& point,
                        const glm::dvec3& normal);

/// One camera ray per pixel centre, as the rasterizer samples them.
struct ExactPixel {
  bool geometry = false;  ///< the ray hit something (between camera near and far)
  int object = -1;
  double n_dot_l = 0.0;   ///< cosine between the surface normal and the light
  double visibility = 1.0;
  /// Unit surface normal facing the viewer; zero where no geometry. Float:
  /// it only tells smooth surfaces from creases, never feeds the shadow test.
  glm::vec3 normal{0.0f};
};

/// A cast ended early because its caller asked it to (see cast_exact_pixels).
struct CastStopped : std::runtime_error {
  CastStopped() : std::runtime_error("the ray cast was stopped") {}
};

/// Every pixel of the request's camera view (width x height, row 0 at the
/// top), using all hardware threads. `stop_requested`, if given, is asked
/// between rows (from those threads): once it answers true the cast ends
/// and throws CastStopped, so a client that has left does not keep cores
/// busy for minutes.
std::vector<ExactPixel> cast_exact_pixels(const RenderRequest& request,
                                          const std::function<bool()>& stop_requested = nullptr);

/// The "exact" output: round(255 * v) per pixel, 255 where no geometry.
Image exact_image(const std::vector<ExactPixel>& pixels, int width, int height);

/// The "error" output: RGB, red = how much darker the render is than the
/// exact value (false shadow), blue = how much brighter (false light).
Image error_image(const Image& rendered_shadow, const Image& exact);

}  // namespace umbra
