#include "reference/mesh_ray_cast.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <list>
#include <mutex>
#include <string>

#include <embree3/rtcore.h>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>

#include "core/mesh_instance.hpp"
#include "core/model.hpp"

namespace umbra {

namespace {

// Embree's own message for the last error on this thread (its error
// function is called on the thread that made the failing call).
thread_local std::string embree_message;
// What Embree allocated on this thread, bytes (its memory monitor): builds
// run on the calling thread (the device has one thread), so a build's
// count is the change of this across it.
thread_local std::int64_t embree_bytes = 0;

// The process's one Embree device. "threads=1": Embree's BVH builds would
// otherwise start a TBB pool of one thread per core that competes with
// llvmpipe's for the same cores; rays are cast from the ray cast's own
// threads (cast_exact_pixels), which need no pool at all.
class EmbreeDevice {
 public:
  EmbreeDevice() {
    device_ = rtcNewDevice("threads=1");
    if (!device_) {
      const RTCError error = rtcGetDeviceError(nullptr);
      throw EmbreeError("Embree: could not create a device (error " + std::to_string(int(error)) + ")");
    }
    rtcSetDeviceErrorFunction(
        device_, [](void*, RTCError, const char* message) { embree_message = message ? message : ""; }, nullptr);
    rtcSetDeviceMemoryMonitorFunction(
        device_,
        [](void*, ssize_t bytes, bool) {
          embree_bytes += bytes;
          return true;
        },
        nullptr);
  }
  ~EmbreeDevice() { rtcReleaseDevice(device_); }
  EmbreeDevice(const EmbreeDevice&) = delete;
  EmbreeDevice& operator=(const EmbreeDevice&) = delete;

  RTCDevice handle() const { return device_; }

  // Throws EmbreeError naming `what` if the calls since the last check failed.
  void check(const char* what) const {
    const RTCError error = rtcGetDeviceError(device_);
    if (error == RTC_ERROR_NONE) return;
    if (error == RTC_ERROR_CANCELLED) throw BvhBuildStopped();
    throw EmbreeError(std::string("Embree: ") + what + " failed (error " + std::to_string(int(error)) + ": " +
                      embree_message + ")");
  }

 private:
  RTCDevice device_ = nullptr;
};

EmbreeDevice& device() {
  static EmbreeDevice d;
  return d;
}

RTCScene as_scene(void* scene) { return static_cast<RTCScene>(scene); }

// The largest float below or equal to x (x >= 0), so a ray never reaches
// past the double distance it was given.
float float_at_most(double x) {
  float f = float(x);
  if (double(f) > x) f = std::nextafter(f, 0.0f);
  return f;
}

// The smallest float at or above x.
float float_at_least(double x) {
  float f = float(x);
  if (double(f) < x) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

// Sets `ray`; false if it is not one Embree takes (a non-finite origin or
// direction, an empty range), which then misses: Embree asserts on those.
bool set_ray(RTCRay& ray, const glm::dvec3& origin, const glm::dvec3& direction, float t_near, float t_far) {
  ray.org_x = float(origin.x);
  ray.org_y = float(origin.y);
  ray.org_z = float(origin.z);
  ray.dir_x = float(direction.x);
  ray.dir_y = float(direction.y);
  ray.dir_z = float(direction.z);
  ray.tnear = t_near;
  ray.tfar = t_far;
  ray.time = 0.0f;
  ray.mask = 0xFFFFFFFFu;
  ray.id = 0;
  ray.flags = 0;
  for (float x : {ray.org_x, ray.org_y, ray.org_z, ray.dir_x, ray.dir_y, ray.dir_z})
    if (!std::isfinite(x)) return false;
  return t_near >= 0.0f && t_near <= t_far;
}

// Progress callback of a build: false cancels it. Embree may call it from
// several threads at once, and stop_requested need not be thread-safe
// (ray_cast.hpp); the device's one thread ("threads=1" above) makes every
// call come from the building thread (checked: 1,950 calls, one thread).
bool keep_building(void* stop_requested, double) {
  const auto& stop = *static_cast<const std::function<bool()>*>(stop_requested);
  return !stop();
}

// The cache of model_bvh: most recently used first.
struct BvhCache {
  struct Entry {
    const TriangleModel* model;
    std::weak_ptr<const TriangleModel> alive;  // expired: the model is gone, drop the entry
    std::shared_ptr<const ModelBvh> bvh;
  };
  BvhCache() { device(); }  // made first, so the device outlives the cached scenes
  std::mutex mutex;
  std::list<Entry> entries;
  std::uint64_t bytes = 0;

  void drop(std::list<Entry>::iterator it) {
    bytes -= it->bvh->bytes();
    entries.erase(it);
  }
};

BvhCache& bvh_cache() {
  static BvhCache cache;
  return cache;
}

}  // namespace

ModelBvh::ModelBvh(const TriangleModel& model, const std::function<bool()>& stop_requested) {
  const EmbreeDevice& d = device();
  const std::int64_t bytes_before = embree_bytes;
  RTCScene scene = rtcNewScene(d.handle());
  d.check("rtcNewScene");
  scene_ = scene;
  try {
    // Robust: no optimisation that trades accuracy for speed (watertight
    // edges, so a ray cannot slip between two triangles sharing one).
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
    for (std::size_t p = 0; p < model.parts.size(); ++p) {
      const ModelPart& part = model.parts[p];
      if (part.triangle_count() == 0) continue;
      RTCGeometry geometry = rtcNewGeometry(d.handle(), RTC_GEOMETRY_TYPE_TRIANGLE);
      d.check("rtcNewGeometry");
      // Attached, the scene holds the geometry; released here either way.
      struct Release {
        RTCGeometry g;
        ~Release() { rtcReleaseGeometry(g); }
      } release{geometry};
      auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
          geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), part.positions.size()));
      auto* indices = static_cast<std::uint32_t*>(rtcSetNewGeometryBuffer(
          geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(std::uint32_t), part.triangle_count()));
      d.check("rtcSetNewGeometryBuffer");
      if (!vertices || !indices) throw EmbreeError("Embree: rtcSetNewGeometryBuffer gave no buffer");
      for (std::size_t i = 0; i < part.positions.size(); ++i) {
        for (int k = 0; k < 3; ++k) {
          vertices[3 * i + k] = part.positions[i][k];
          extent_ = std::max(extent_, std::abs(part.positions[i][k]));
        }
      }
      std::memcpy(indices, part.indices.data(), 3 * part.triangle_count() * sizeof(std::uint32_t));
      rtcCommitGeometry(geometry);
      rtcAttachGeometryByID(scene, geometry, unsigned(p));
      d.check("attaching a model part");
    }
    if (stop_requested)
      rtcSetSceneProgressMonitorFunction(scene, keep_building, const_cast<std::function<bool()>*>(&stop_requested));
    rtcCommitScene(scene);
    d.check("building the BVH (rtcCommitScene)");
    if (stop_requested) rtcSetSceneProgressMonitorFunction(scene, nullptr, nullptr);
  } catch (...) {
    rtcReleaseScene(scene);
    throw;
  }
  bytes_ = std::uint64_t(std::max<std::int64_t>(embree_bytes - bytes_before, 0));
}

ModelBvh::~ModelBvh() { rtcReleaseScene(as_scene(scene_)); }

std::shared_ptr<const ModelBvh> model_bvh(const std::shared_ptr<const TriangleModel>& model,
                                          const std::function<bool()>& stop_requested) {
  BvhCache& cache = bvh_cache();
  std::lock_guard<std::mutex> lock(cache.mutex);
  // A model that is gone may have left its address to a new one: drop
  // such entries before looking the address up.
  for (auto it = cache.entries.begin(); it != cache.entries.end();) {
    const auto next = std::next(it);
    if (it->alive.expired()) cache.drop(it);
    it = next;
  }
  for (auto it = cache.entries.begin(); it != cache.entries.end(); ++it) {
    if (it->model != model.get()) continue;
    cache.entries.splice(cache.entries.begin(), cache.entries, it);
    return it->bvh;
  }
  auto bvh = std::make_shared<const ModelBvh>(*model, stop_requested);
  if (bvh->bytes() > kBvhCacheBytes) return bvh;  // used for this request only
  cache.entries.push_front({model.get(), model, bvh});
  cache.bytes += bvh->bytes();
  while (cache.bytes > kBvhCacheBytes || cache.entries.size() > kBvhCacheEntries)
    cache.drop(std::prev(cache.entries.end()));
  return bvh;
}

void clear_model_bvh_cache() {
  BvhCache& cache = bvh_cache();
  std::lock_guard<std::mutex> lock(cache.mutex);
  cache.entries.clear();
  cache.bytes = 0;
}

BvhCacheUse model_bvh_cache_use() {
  BvhCache& cache = bvh_cache();
  std::lock_guard<std::mutex> lock(cache.mutex);
  return {cache.entries.size(), cache.bytes};
}

glm::vec3 offset_off_surface(const glm::vec3& p, const glm::vec3& n, float extent) {
  const float scale = extent > 0.0f ? extent : 1.0f;
  const float near_origin = scale / 32.0f, absolute_step = scale / 65536.0f;
  glm::vec3 out;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(p[k]) < near_origin) {
      out[k] = p[k] + absolute_step * n[k];
      continue;
    }
    // Step the float's bit pattern: a whole number of ULPs of p[k], away
    // from zero when n[k] points away from zero.
    const auto ulps = std::int32_t(256.0f * n[k]);
    std::int32_t bits;
    std::memcpy(&bits, &p[k], sizeof bits);
    bits += p[k] < 0.0f ? -ulps : ulps;
    std::memcpy(&out[k], &bits, sizeof bits);
  }
  return out;
}

MeshRays::MeshRays(const SceneObject& mesh, std::shared_ptr<const ModelBvh> bvh)
    : model_(*mesh.model),
      bvh_(std::move(bvh)),
      to_world_(mesh_transform(mesh)),
      to_model_(glm::inverse(to_world_)),
      normal_to_world_(glm::transpose(glm::inverse(glm::dmat3(to_world_)))) {}

std::optional<MeshHit> MeshRays::intersect(const glm::dvec3& origin, const glm::dvec3& direction, double t_min,
                                           double t_max) const {
  // Not normalized in model space: t measures the world ray.
  const glm::dvec3 o = glm::dvec3(to_model_ * glm::dvec4(origin, 1.0));
  const glm::dvec3 d = glm::dmat3(to_model_) * direction;
  RTCRayHit rh;  // RTC_ALIGN(16) by declaration, on the stack
  // Embree's float range holds the double one with room for its float
  // rounding (a hit at t_max - 1e-12 may be a float ULP past it there), so
  // that the double t below decides: otherwise the answer would depend on
  // how near the range's end a hit is, and the tie rule on traversal order.
  const double slack = 1e-5 * (glm::length(o) / glm::length(d) + (std::isfinite(t_max) ? t_max : 0.0));
  const float t_near = std::max(0.0f, float_at_most(t_min - slack)), t_far = float_at_least(t_max + slack);
  if (!set_ray(rh.ray, o, d, t_near, t_far)) return std::nullopt;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  rtcIntersect1(as_scene(bvh_->scene()), &context, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;

  const ModelPart& part = model_.parts[rh.hit.geomID];
  const std::uint32_t* corner = &part.indices[3 * std::size_t(rh.hit.primID)];
  const glm::dvec3 a(part.positions[corner[0]]), b(part.positions[corner[1]]), c(part.positions[corner[2]]);
  // The distance in double against the float triangle's plane.
  const glm::dvec3 plane_normal = glm::cross(b - a, c - a);  // outward: counter-clockwise faces out
  const double facing = glm::dot(d, plane_normal);
  double t = glm::dot(a - o, plane_normal) / facing;
  if (!std::isfinite(t)) t = rh.ray.tfar;  // edge-on: Embree's own distance
  if (!(t > t_min && t < t_max)) return std::nullopt;

  MeshHit hit;
  hit.t = t;
  // Seen from behind (the ray runs along the outward normal): flipped, as
  // GL flips a back face's normal.
  const double side = facing > 0.0 ? -1.0 : 1.0;
  const glm::dvec3 model_normal = side * glm::normalize(plane_normal);
  hit.geometric_normal = glm::normalize(normal_to_world_ * model_normal);
  // As GL interpolates them: each vertex normal to the world and unit
  // (append_mesh_instance), then blended by the barycentrics.
  const auto vertex_normal = [&](int k) { return glm::normalize(normal_to_world_ * glm::dvec3(part.normals[corner[k]])); };
  const double u = rh.hit.u, v = rh.hit.v;
  const glm::dvec3 shading =
      side * ((1.0 - u - v) * vertex_normal(0) + u * vertex_normal(1) + v * vertex_normal(2));
  hit.shading_normal = glm::length(shading) > 0.0 ? glm::normalize(shading) : hit.geometric_normal;
  // Off the float triangle in its own float space, then to the world.
  const glm::vec3 p(o + t * d), n(model_normal);
  hit.leave_front = glm::dvec3(to_world_ * glm::dvec4(glm::dvec3(offset_off_surface(p, n, bvh_->extent())), 1.0));
  hit.leave_back = glm::dvec3(to_world_ * glm::dvec4(glm::dvec3(offset_off_surface(p, -n, bvh_->extent())), 1.0));
  return hit;
}

bool MeshRays::occluded(const glm::dvec3& origin, const glm::dvec3& direction, double t_max) const {
  const glm::dvec3 o = glm::dvec3(to_model_ * glm::dvec4(origin, 1.0));
  const glm::dvec3 d = glm::dmat3(to_model_) * direction;
  RTCRay ray;
  if (!set_ray(ray, o, d, 0.0f, float_at_most(t_max))) return false;
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  rtcOccluded1(as_scene(bvh_->scene()), &context, &ray);
  return ray.tfar < 0.0f;  // -inf when something was hit
}

}  // namespace umbra
