// The exact reference: the API's "shadow" quantity computed by casting rays
// on the CPU against the scene as it is: the analytic primitives (plane,
// rotated box, sphere) in double precision, each by its shape's own exact
// test (core/shapes), and mesh objects' triangles through Embree
// (mesh_ray_cast.hpp). No GL and no shadow map, so it is what
// the GL output is judged against.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "core/image.hpp"
#include "core/light_math.hpp"
#include "core/request.hpp"
#include "core/scene.hpp"
#include "core/shapes/shape.hpp"

namespace umbra {

class MeshRays;  // mesh_ray_cast.hpp

/// Where a ray first meets the scene.
struct RayHit {
  double t = 0.0;          ///< distance along the (unit) ray direction
  glm::dvec3 point{0.0};
  /// Unit normal the light is judged by (N.L, facing away from the light).
  /// Analytic surfaces: the exact normal, facing the ray's origin. Meshes:
  /// the model's vertex normals interpolated, flipped on a back face, as
  /// the GL main pass computes the N.L that zeroes its "shadow" output
  /// (shaders/scene.frag), so that the reference and the render agree on
  /// which side of a smooth mesh's terminator is dark. It may lean away
  /// from the ray's origin by up to the angle between facets.
  glm::dvec3 normal{0.0};
  /// Unit normal of the surface's own plane (a mesh's triangle), facing
  /// the ray's origin: what rays leaving the surface must clear. Equal to
  /// `normal` for analytic surfaces.
  glm::dvec3 geometric_normal{0.0};
  /// Where rays that leave the surface start: off it on the
  /// geometric_normal side (front) or the other (back). Analytic surfaces:
  /// the point moved by 1e-9 * (1 + |point|) along the normal, a hair at
  /// every scale in double. Meshes: Wächter and Binder's float offset in the
  /// model's space (offset_off_surface), since Embree tests in float.
  glm::dvec3 leave_front{0.0}, leave_back{0.0};
  int object = -1;         ///< index into scene.objects
};

/// A cast ended early because its caller asked it to (see cast_exact_pixels).
struct CastStopped : std::runtime_error {
  CastStopped() : std::runtime_error("the ray cast was stopped") {}
};

/// The scene's objects in a bounding-volume hierarchy over their bounds, so
/// a ray is tested against the few objects near it instead of all of them;
/// inside a mesh object's bounds, Embree's BVH of its model (one per model,
/// cached across requests: model_bvh). It answers exactly as testing every
/// object in order would: the nearest hit, the lowest object index among
/// equally near ones. A mesh hit's distance is computed in double against
/// the plane of the triangle Embree found, as an analytic one is, so
/// "equally near" means the same for both kinds (a mesh face and an
/// analytic face in one plane tie when their doubles agree).
class RayScene {
 public:
  /// Builds (or takes from the cache) the BVH of each mesh object's model.
  /// `stop_requested`, if given, is asked during those builds: once it
  /// answers true, CastStopped. Throws EmbreeError if Embree fails.
  explicit RayScene(const Scene& scene, const std::function<bool()>& stop_requested = nullptr);
  ~RayScene();
  RayScene(const RayScene&) = delete;
  RayScene& operator=(const RayScene&) = delete;
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
  // Per object: its mesh rays for a mesh object with triangles, else null.
  std::vector<std::unique_ptr<const MeshRays>> meshes_;
  // Per object: its shape's exact intersection (null for a mesh), looked
  // up once here rather than for every ray.
  std::vector<ShapeIntersect> exact_;
};

/// First hit of the ray origin + t * direction (unit) with t in (t_min, t_max).
std::optional<RayHit> cast_ray(const Scene& scene, const glm::dvec3& origin, const glm::dvec3& direction,
                               double t_min, double t_max);

/// The fraction of the light's direct light that reaches `point` on an
/// analytic surface (normal `normal`, facing the viewer): 0 when the
/// surface faces away from the light; for light.size > 0 the fraction of a
/// fixed stratified set of 64 points on the light's disc that the point
/// sees. `light_position` is the light position after orbit.
double exact_visibility(const RenderRequest& request, const glm::dvec3& light_position, const glm::dvec3& point,
                        const glm::dvec3& normal);
/// The same for any surface a ray found (its point, normals and offsets).
double exact_visibility(const RayScene& rays, const RenderRequest& request, const glm::dvec3& light_position,
                        const RayHit& surface);

/// The exact visibility over one pixel's area, sampled finer than its centre
/// (kCoverageSamples^2 points spread over the pixel).
enum class PixelCoverage : std::uint8_t {
  unknown,  ///< not asked for, or no sample saw geometry
  dark,     ///< every sample that saw geometry is exactly in shadow (0)
  lit,      ///< ... exactly lit (1)
  mixed,    ///< anything else: a shadow edge or a penumbra crosses the pixel
};
/// Samples per pixel side of a PixelCoverage (4 x 4 points per pixel).
inline constexpr int kCoverageSamples = 4;
/// Given a width x height mask (row 0 at the top), the PixelCoverage of
/// each pixel marked non-zero; the others may stay unknown.
using PixelCoverageOf = std::function<std::vector<PixelCoverage>(const std::vector<std::uint8_t>& which)>;

/// The exact reference at one point of the image: what one camera ray finds.
struct ExactPixel {
  bool geometry = false;  ///< the ray hit something (between camera near and far)
  int object = -1;
  double n_dot_l = 0.0;   ///< cosine between the surface normal and the light
  double visibility = 1.0;
  /// Unit surface normal (RayHit::normal: a mesh's interpolated one); zero
  /// where no geometry. Float: it only tells smooth surfaces from creases,
  /// never feeds the shadow test.
  glm::vec3 normal{0.0f};
};

/// The request's camera and light over its scene's rays: the exact
/// reference at any point of the image. The mesh BVHs are built (or taken
/// from the cache) once, in the constructor, which asks `stop_requested`
/// during those builds (CastStopped). `request` must outlive the view.
class ExactView {
 public:
  explicit ExactView(const RenderRequest& request, const std::function<bool()>& stop_requested = nullptr);

  /// The reference at image point (px, py), in pixels from the top-left
  /// corner: a pixel's centre is (x + 0.5, y + 0.5). Thread-safe.
  ExactPixel at(double px, double py) const;
  /// What the camera ray through image point (px, py) meets first, between
  /// the camera's near and far planes; nullopt where it meets nothing.
  std::optional<RayHit> surface_at(double px, double py) const;
  /// The scene's rays, as this view casts them.
  const RayScene& rays() const { return rays_; }

  /// One camera ray per pixel centre, as the rasterizer samples them: every
  /// pixel of the view (width x height, row 0 at the top), using all
  /// hardware threads. `stop_requested`, if given, is asked between rows
  /// (from those threads, one at a time): once it answers true the cast
  /// ends and throws CastStopped, so a client that has left does not keep
  /// cores busy for minutes.
  std::vector<ExactPixel> pixels(const std::function<bool()>& stop_requested = nullptr) const;

  /// pixels() for the pixels `indices` (y * width + x, each < width x
  /// height) only, in that order, each exactly as pixels() casts it; on all
  /// threads, asking `stop_requested` as pixels() does. Throws
  /// std::invalid_argument for an index outside the image.
  std::vector<ExactPixel> pixels_at(const std::vector<std::size_t>& indices,
                                    const std::function<bool()>& stop_requested = nullptr) const;
  /// pixels_at without the vector: use(k, pixel) for each indices[k], from
  /// the threads that cast them (several at once, each k once), so that
  /// what is made of a pixel is made there too.
  void each_pixel_at(const std::vector<std::size_t>& indices,
                     const std::function<void(std::size_t, const ExactPixel&)>& use,
                     const std::function<bool()>& stop_requested = nullptr) const;

  /// The PixelCoverage of each pixel marked non-zero in `which` (width x
  /// height): kCoverageSamples^2 points (x + (i + 0.5) / k, y + (j + 0.5) /
  /// k), each judged as pixels() judges a centre; on all threads, asking
  /// `stop_requested` as pixels() does. Throws std::invalid_argument if
  /// `which` is not width x height.
  std::vector<PixelCoverage> coverage(const std::vector<std::uint8_t>& which,
                                      const std::function<bool()>& stop_requested = nullptr) const;
  /// coverage() as measure_shadow_error takes it; it refers to this view.
  PixelCoverageOf coverage_of(const std::function<bool()>& stop_requested = nullptr) const;

 private:
  const RenderRequest& request_;
  const glm::dmat4 inverse_;  // of the camera's projection * view
  const LightState light_;
  const RayScene rays_;
};

/// ExactView(request, stop_requested).pixels(stop_requested).
std::vector<ExactPixel> cast_exact_pixels(const RenderRequest& request,
                                          const std::function<bool()>& stop_requested = nullptr);

/// The "exact" output: round(255 * v) per pixel, 255 where no geometry.
Image exact_image(const std::vector<ExactPixel>& pixels, int width, int height);

/// The "error" output: RGB, red = how much darker the render is than the
/// exact value (false shadow), blue = how much brighter (false light).
Image error_image(const Image& rendered_shadow, const Image& exact);

}  // namespace umbra
