// Mesh objects in the exact reference (ray_cast.hpp): each TriangleModel's
// triangles in an Embree 3 BVH, built once in the model's own space and
// shared by every placement of it, and the rays of one placement carried
// into that space in double.
//
// Why model space: Embree is single precision. The model's triangles are
// floats in model space already (ModelPart::positions), so Embree sees them
// exactly as stored, and a ray carried there in double loses nothing to a
// scene far from the world origin or to a scale of 0.001 or 1000. The
// distance along the ray is then recomputed in double against the plane of
// the triangle Embree names, so a mesh hit is as precise as an analytic one
// and the two compare (RayScene's tie rule) on equal terms.
//
// Everything Embree owns is held by the RAII classes here; every Embree
// failure becomes an exception (EmbreeError), never a crash.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>

#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "core/scene.hpp"

namespace umbra {

struct TriangleModel;  // model.hpp

/// Embree reported an error (device, buffer, build), with its message.
struct EmbreeError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// The BVH build was cancelled because its caller asked (see model_bvh).
struct BvhBuildStopped : std::runtime_error {
  BvhBuildStopped() : std::runtime_error("the BVH build was stopped") {}
};

/// One model's triangles in an Embree scene (RTC_SCENE_FLAG_ROBUST), model
/// space: geometry id = index of the part in model.parts, primitive id =
/// triangle of that part. Holds copies of the positions and indices (Embree
/// wants padded buffers), never the model itself, so a cached BVH does not
/// keep a model alive that the ModelStore has let go.
class ModelBvh {
 public:
  /// Builds on the calling thread; `stop_requested`, if given, is asked
  /// while building and cancels it (BvhBuildStopped) once it answers true.
  /// Throws EmbreeError if Embree fails (out of memory, among others).
  explicit ModelBvh(const TriangleModel& model, const std::function<bool()>& stop_requested = nullptr);
  ~ModelBvh();
  ModelBvh(const ModelBvh&) = delete;
  ModelBvh& operator=(const ModelBvh&) = delete;

  /// The committed Embree scene (an RTCScene): for rtcIntersect1/rtcOccluded1.
  void* scene() const { return scene_; }
  /// Bytes Embree allocated for it (its memory monitor's count), buffers included.
  std::uint64_t bytes() const { return bytes_; }
  /// The largest |coordinate| of the model's positions: the scale of the
  /// float offset that lets rays leave its surface (offset_off_surface).
  float extent() const { return extent_; }

 private:
  void* scene_ = nullptr;
  std::uint64_t bytes_ = 0;
  float extent_ = 0.0f;
};

/// The model's BVH from a process-wide cache, built now if absent. An entry
/// lives no longer than the model's last shared_ptr (entries of models that
/// are gone are dropped on the next call) and the cache holds at most
/// kBvhCacheBytes and kBvhCacheEntries, least recently used dropped first,
/// so a client alternating "exact" frames of a 1M-triangle model does not
/// pay a one-second build each time. Builds hold the cache's lock (a second
/// request for the same model waits for the first build rather than making
/// its own). Thread-safe.
inline constexpr std::uint64_t kBvhCacheBytes = std::uint64_t(256) << 20;
inline constexpr std::size_t kBvhCacheEntries = 8;
std::shared_ptr<const ModelBvh> model_bvh(const std::shared_ptr<const TriangleModel>& model,
                                          const std::function<bool()>& stop_requested = nullptr);

/// Drops every cached BVH (tests, and a server that wants its memory back).
void clear_model_bvh_cache();
/// What the cache holds now: entries and bytes.
struct BvhCacheUse {
  std::size_t entries = 0;
  std::uint64_t bytes = 0;
};
BvhCacheUse model_bvh_cache_use();

/// A point moved off a float surface through `p` along the unit normal `n`
/// (the side a ray leaves towards), far enough that a single-precision
/// intersection test cannot find that surface again: Wächter and Binder's
/// offset ("A Fast and Robust Method for Avoiding Self-Intersection", Ray
/// Tracing Gems, ch. 6), 256 * n ULPs per coordinate, and near the origin,
/// where ULPs vanish, an absolute n * extent / 65536. Their constants
/// assume a scene of size 1; here they are scaled by `extent`, the largest
/// |coordinate| of the model, so a 0.001-unit model is treated as a 1-unit one.
glm::vec3 offset_off_surface(const glm::vec3& p, const glm::vec3& n, float extent);

/// Where a ray meets a mesh object, in world space.
struct MeshHit {
  double t = 0.0;  ///< along the world ray, in double against the triangle's plane
  /// Unit normal of the triangle's own plane, and the model's vertex
  /// normals interpolated at the hit, both oriented as the GL main pass
  /// orients them: the triangle's outward side (counter-clockwise, mirrored
  /// placements taken into account) when it faces the ray's origin, else
  /// flipped (gl_FrontFacing).
  glm::dvec3 geometric_normal{0.0};
  glm::dvec3 shading_normal{0.0};
  /// The hit moved off the triangle (offset_off_surface, in model space) to
  /// the side geometric_normal points to, and to the other side: where rays
  /// that leave the surface towards either side start.
  glm::dvec3 leave_front{0.0}, leave_back{0.0};
};

/// One mesh object's rays: its transform and its model's BVH.
class MeshRays {
 public:
  /// `mesh` (type Mesh, with a model) must outlive this.
  MeshRays(const SceneObject& mesh, std::shared_ptr<const ModelBvh> bvh);
  /// First hit of origin + t * direction with t in (t_min, t_max).
  std::optional<MeshHit> intersect(const glm::dvec3& origin, const glm::dvec3& direction, double t_min,
                                   double t_max) const;
  /// Whether a triangle lies on the ray with t in (0, t_max) (Embree's
  /// single-precision answer: t_max is rounded down to a float).
  bool occluded(const glm::dvec3& origin, const glm::dvec3& direction, double t_max) const;

 private:
  const TriangleModel& model_;
  std::shared_ptr<const ModelBvh> bvh_;
  glm::dmat4 to_world_, to_model_;
  glm::dmat3 normal_to_world_;  // the inverse transpose of the linear part
};

}  // namespace umbra
