#include "reference/ray_cast.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <mutex>
#include <string>

#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <glm/trigonometric.hpp>

#include "core/light_math.hpp"
#include "core/lights/light_kind.hpp"
#include "reference/mesh_ray_cast.hpp"
#include "reference/worker_pool.hpp"
#include "core/scene.hpp"
#include "core/shapes/shape.hpp"

namespace umbra {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Whether the ray meets `box` (grown by a relative hair, so that rounding
// never makes it miss what the exact primitive test would hit) within
// (t_min, t_max).
bool meets(const Aabb& box, const glm::dvec3& origin, const glm::dvec3& dir, double t_min, double t_max) {
  const glm::dvec3 grow = 1e-9 * (glm::abs(box.min) + glm::abs(box.max) + box.extent()) + 1e-300;
  double t0 = t_min, t1 = t_max;
  for (int a = 0; a < 3; ++a) {
    const double lo = box.min[a] - grow[a], hi = box.max[a] + grow[a];
    if (dir[a] == 0.0) {
      if (origin[a] < lo || origin[a] > hi) return false;
      continue;
    }
    double near_t = (lo - origin[a]) / dir[a], far_t = (hi - origin[a]) / dir[a];
    if (near_t > far_t) std::swap(near_t, far_t);
    t0 = std::max(t0, near_t);
    t1 = std::min(t1, far_t);
    if (t0 > t1) return false;
  }
  return true;
}

// 64 points on the unit disc, one per cell of an 8 x 8 grid mapped
// concentrically (Shirley-Chiu), so they cover the disc evenly.
const std::vector<glm::dvec2>& disc_samples() {
  static const std::vector<glm::dvec2> samples = [] {
    constexpr double kPi = 3.14159265358979323846;
    std::vector<glm::dvec2> s;
    for (int i = 0; i < 8; ++i) {
      for (int j = 0; j < 8; ++j) {
        const double a = 2.0 * (i + 0.5) / 8.0 - 1.0, b = 2.0 * (j + 0.5) / 8.0 - 1.0;
        double r, phi;
        if (std::abs(a) > std::abs(b)) {
          r = a;
          phi = (kPi / 4.0) * (b / a);
        } else {
          r = b;
          phi = (kPi / 2.0) - (kPi / 4.0) * (a / b);
        }
        s.emplace_back(r * std::cos(phi), r * std::sin(phi));
      }
    }
    return s;
  }();
  return samples;
}

// Two unit vectors perpendicular to `axis` and to each other.
void basis(const glm::dvec3& axis, glm::dvec3& u, glm::dvec3& v) {
  const glm::dvec3 helper = std::abs(axis.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
  u = glm::normalize(glm::cross(helper, axis));
  v = glm::cross(axis, u);
}

// Unit direction from `point` towards the light's centre: towards its
// position for a point light, against its direction of travel otherwise.
glm::dvec3 direction_to_light(const Light& light, const glm::dvec3& light_position, const glm::dvec3& point) {
  return light_kind(light).direction_to_light(light, light_position, point);
}

// An analytic surface at `point`: its normal is its plane's, and rays leave
// it a hair off along the normal (1e-9 relative, so at every scale in double).
RayHit analytic_surface(const glm::dvec3& point, const glm::dvec3& normal) {
  RayHit s;
  s.point = point;
  s.normal = s.geometric_normal = normal;
  const double lift = 1e-9 * (1.0 + glm::length(point));
  s.leave_front = point + normal * lift;
  s.leave_back = point - normal * lift;
  return s;
}

// Where a ray from the surface towards `target` starts: off the surface on
// the side the target is. (For an analytic surface, a target on the back
// side is never counted: its direction fails N.L > 0.)
const glm::dvec3& leaving_towards(const RayHit& s, const glm::dvec3& direction) {
  return glm::dot(s.geometric_normal, direction) >= 0.0 ? s.leave_front : s.leave_back;
}

// A shadow ray from a surface to the light: where it starts (off the
// surface on the side it leaves by), its unit direction and how far it goes.
struct ShadowRay {
  const glm::dvec3* origin;
  glm::dvec3 direction;
  double length;
};

// The ray from `surface` to a point of the light (`finite`) or along a
// unit direction.
ShadowRay shadow_ray(const RayHit& surface, const glm::dvec3& at, bool finite) {
  if (finite) {
    const glm::dvec3& origin = leaving_towards(surface, at - surface.point);
    const double length = glm::length(at - origin);
    return {&origin, (at - origin) / length, length};
  }
  return {&leaving_towards(surface, at), at, kInf};
}

}  // namespace

// See ray_cast.hpp; `rays` indexes request.scene.
double exact_visibility(const RayScene& rays, const RenderRequest& request, const glm::dvec3& light_position,
                        const RayHit& surface) {
  const Light& light = request.light;
  const glm::dvec3& point = surface.point;
  const glm::dvec3& normal = surface.normal;
  const glm::dvec3 to_light_center = direction_to_light(light, light_position, point);
  if (glm::dot(normal, to_light_center) <= 0.0) return 0.0;
  const LightDisc disc = light_kind(light).disc_seen_from(light, light_position, to_light_center);
  if (light.size <= 0.0) {
    const ShadowRay ray = shadow_ray(surface, disc.center, disc.finite);
    return rays.occluded(*ray.origin, ray.direction, ray.length) ? 0.0 : 1.0;
  }
  glm::dvec3 u, v;
  basis(to_light_center, u, v);
  int seen = 0;
  const auto& samples = disc_samples();
  for (const glm::dvec2& s : samples) {
    // A point of the disc, or a direction of the cone.
    const glm::dvec3 at = disc.finite ? disc.center + disc.radius * (s.x * u + s.y * v)
                                      : glm::normalize(disc.center + disc.radius * (s.x * u + s.y * v));
    const ShadowRay ray = shadow_ray(surface, at, disc.finite);
    if (glm::dot(normal, ray.direction) > 0.0 && !rays.occluded(*ray.origin, ray.direction, ray.length)) ++seen;
  }
  return double(seen) / double(samples.size());
}

RayScene::RayScene(const Scene& scene, const std::function<bool()>& stop_requested) : scene_(scene) {
  const std::size_t n = scene.objects.size();
  meshes_.resize(n);
  exact_.resize(n);
  std::vector<Aabb> bounds(n);
  std::vector<glm::dvec3> centers(n);
  for (std::size_t i = 0; i < n; ++i) {
    const SceneObject& o = scene.objects[i];
    bounds[i] = object_bounds(o);
    centers[i] = bounds[i].center();
    // A mesh whose model has no triangles has empty bounds: nothing to hit.
    if (bounds[i].empty()) continue;
    // A kind with no exact test of its own (a mesh) is a triangle model: Embree's.
    exact_[i] = shape_kind(o.type).intersect;
    if (!exact_[i]) {
      try {
        meshes_[i] = std::make_unique<const MeshRays>(o, model_bvh(o.model, stop_requested));
      } catch (const BvhBuildStopped&) {
        throw CastStopped();
      }
    }
    order_.push_back(int(i));
  }
  nodes_.reserve(2 * order_.size() + 1);
  if (!order_.empty()) build(0, int(order_.size()), bounds, centers);
}

RayScene::~RayScene() = default;

// Median split along the widest axis of the objects' centres; leaves of up
// to four objects.
int RayScene::build(int first, int count, const std::vector<Aabb>& bounds, const std::vector<glm::dvec3>& centers) {
  const int index = int(nodes_.size());
  nodes_.emplace_back();
  Aabb box, spread;
  for (int i = first; i < first + count; ++i) {
    box.extend(bounds[order_[i]]);
    spread.extend(centers[order_[i]]);
  }
  nodes_[index].box = box;
  if (count <= 4) {
    nodes_[index].first = first;
    nodes_[index].count = count;
    return index;
  }
  const glm::dvec3 e = spread.extent();
  const int axis = e.x >= e.y && e.x >= e.z ? 0 : e.y >= e.z ? 1 : 2;
  const int half = count / 2;
  std::nth_element(order_.begin() + first, order_.begin() + first + half, order_.begin() + first + count,
                   [&](int a, int b) { return centers[a][axis] < centers[b][axis]; });
  const int left = build(first, half, bounds, centers);
  const int right = build(first + half, count - half, bounds, centers);
  nodes_[index].left = left;
  nodes_[index].right = right;
  return index;
}

template <class Visit>
void RayScene::traverse(const glm::dvec3& origin, const glm::dvec3& direction, double t_min, const double* t_max,
                        Visit&& visit) const {
  if (nodes_.empty()) return;
  int stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (!meets(node.box, origin, direction, t_min, *t_max)) continue;
    if (node.left < 0) {
      for (int i = node.first; i < node.first + node.count; ++i)
        if (!visit(order_[i])) return;
    } else {
      stack[top++] = node.right;
      stack[top++] = node.left;
    }
  }
}

std::optional<RayHit> RayScene::cast(const glm::dvec3& origin, const glm::dvec3& direction, double t_min,
                                     double t_max) const {
  RayHit best;
  best.t = t_max;
  std::optional<MeshHit> best_mesh;  // when the nearest so far is a mesh's
  // Objects come in tree order, not index order: an equally near hit wins
  // when its index is lower, as it would testing every object in order.
  double reach = t_max;
  traverse(origin, direction, t_min, &reach, [&](int i) {
    const double limit = best.object < 0 ? t_max : std::nextafter(best.t, kInf);
    glm::dvec3 normal;
    std::optional<MeshHit> mesh_hit;
    double t = kInf;
    if (const MeshRays* mesh = meshes_[i].get()) {
      mesh_hit = mesh->intersect(origin, direction, t_min, limit);
      if (mesh_hit) t = mesh_hit->t;
    } else {
      t = exact_[i](scene_.objects[i], origin, direction, t_min, limit, normal);
    }
    if (t < best.t || (t == best.t && best.object >= 0 && i < best.object)) {
      best.t = t;
      best.normal = normal;
      best.object = i;
      best_mesh = std::move(mesh_hit);
      reach = std::nextafter(best.t, kInf);
    }
    return true;
  });
  if (best.object < 0) return std::nullopt;
  const glm::dvec3 point = origin + best.t * direction;
  if (best_mesh) {
    best.point = point;
    best.normal = best_mesh->shading_normal;
    best.geometric_normal = best_mesh->geometric_normal;
    best.leave_front = best_mesh->leave_front;
    best.leave_back = best_mesh->leave_back;
    return best;
  }
  const glm::dvec3 normal = glm::dot(best.normal, direction) > 0.0 ? -best.normal : best.normal;
  RayHit hit = analytic_surface(point, normal);
  hit.t = best.t;
  hit.object = best.object;
  return hit;
}

bool RayScene::occluded(const glm::dvec3& origin, const glm::dvec3& direction, double t_max) const {
  bool hit = false;
  traverse(origin, direction, 0.0, &t_max, [&](int i) {
    if (const MeshRays* mesh = meshes_[i].get()) {
      hit = mesh->occluded(origin, direction, t_max);
    } else {
      glm::dvec3 unused;
      hit = exact_[i](scene_.objects[i], origin, direction, 0.0, t_max, unused) < kInf;
    }
    return !hit;
  });
  return hit;
}

std::optional<RayHit> cast_ray(const Scene& scene, const glm::dvec3& origin, const glm::dvec3& direction,
                               double t_min, double t_max) {
  return RayScene(scene).cast(origin, direction, t_min, t_max);
}

double exact_visibility(const RenderRequest& request, const glm::dvec3& light_position, const glm::dvec3& point,
                        const glm::dvec3& normal) {
  return exact_visibility(RayScene(request.scene), request, light_position, analytic_surface(point, normal));
}

namespace {

glm::dmat4 inverse_view_projection(const RenderRequest& request) {
  const CameraMatrices camera = camera_matrices(request.camera, request.width, request.height);
  return glm::inverse(camera.projection * camera.view);
}

// Calls row(y) for every y in [0, height) on the workers (worker_pool.hpp),
// each taking the next row left: rows cost what their pixels hold (sky, a
// floor, a model's edge), so a fixed share per thread would leave threads
// idle. Asks stop_requested (if given) before each row; throws CastStopped
// once it answered true.
void for_each_row(int height, const std::function<bool()>& stop_requested, const std::function<void(int)>& row) {
  std::atomic<bool> stopped{false};
  std::mutex asking;  // stop_requested need not be thread-safe
  run_on_workers(height, [&](int y) {
    if (stop_requested) {
      std::lock_guard<std::mutex> lock(asking);
      if (stopped || stop_requested()) stopped = true;
    }
    if (!stopped) row(y);
  });
  if (stopped) throw CastStopped();
}

// How kCoverageSamples^2 samples over pixel (x, y) see the light; stops
// sampling once both a lit and an unlit sample were seen.
PixelCoverage coverage_of_pixel(const ExactView& view, int x, int y) {
  bool dark = false, lit = false;
  for (int j = 0; j < kCoverageSamples; ++j) {
    for (int i = 0; i < kCoverageSamples; ++i) {
      const ExactPixel p = view.at(x + (i + 0.5) / kCoverageSamples, y + (j + 0.5) / kCoverageSamples);
      if (!p.geometry) continue;
      const bool partial = p.visibility != 0.0 && p.visibility != 1.0;
      dark |= p.visibility == 0.0;
      lit |= p.visibility == 1.0;
      if (partial || (dark && lit)) return PixelCoverage::mixed;
    }
  }
  return dark ? PixelCoverage::dark : lit ? PixelCoverage::lit : PixelCoverage::unknown;
}

}  // namespace

ExactView::ExactView(const RenderRequest& request, const std::function<bool()>& stop_requested)
    : request_(request),
      inverse_(inverse_view_projection(request)),
      light_(light_at(request.light, request.time)),
      rays_(request.scene, stop_requested) {}

std::optional<RayHit> ExactView::surface_at(double px, double py) const {
  const double nx = px / request_.width * 2.0 - 1.0;
  const double ny = 1.0 - py / request_.height * 2.0;
  const glm::dvec4 near_h = inverse_ * glm::dvec4(nx, ny, -1.0, 1.0);
  const glm::dvec4 far_h = inverse_ * glm::dvec4(nx, ny, 1.0, 1.0);
  const glm::dvec3 near_p = glm::dvec3(near_h) / near_h.w;
  const glm::dvec3 far_p = glm::dvec3(far_h) / far_h.w;
  const glm::dvec3 dir = glm::normalize(far_p - near_p);
  // The camera sees between its near and far planes, as GL clips.
  const double t_far = glm::length(far_p - near_p);
  return rays_.cast(near_p, dir, 0.0, t_far);
}

ExactPixel ExactView::at(double px, double py) const {
  ExactPixel pixel;
  const auto hit = surface_at(px, py);
  if (!hit) return pixel;
  pixel.geometry = true;
  pixel.object = hit->object;
  pixel.normal = glm::vec3(hit->normal);
  pixel.n_dot_l = glm::dot(hit->normal, direction_to_light(request_.light, light_.position, hit->point));
  // A sun below the horizon lights nothing directly (LightState::direct).
  pixel.visibility = light_.direct ? exact_visibility(rays_, request_, light_.position, *hit) : 0.0;
  return pixel;
}

std::vector<ExactPixel> ExactView::pixels(const std::function<bool()>& stop_requested) const {
  const int width = request_.width;
  std::vector<ExactPixel> pixels(std::size_t(width) * request_.height);
  for_each_row(request_.height, stop_requested, [&](int y) {
    for (int x = 0; x < width; ++x) pixels[std::size_t(y) * width + x] = at(x + 0.5, y + 0.5);
  });
  return pixels;
}

std::vector<ExactPixel> ExactView::pixels_at(const std::vector<std::size_t>& indices,
                                             const std::function<bool()>& stop_requested) const {
  std::vector<ExactPixel> pixels(indices.size());
  each_pixel_at(indices, [&](std::size_t k, const ExactPixel& pixel) { pixels[k] = pixel; }, stop_requested);
  return pixels;
}

void ExactView::each_pixel_at(const std::vector<std::size_t>& indices,
                              const std::function<void(std::size_t, const ExactPixel&)>& use,
                              const std::function<bool()>& stop_requested) const {
  const std::size_t width = std::size_t(request_.width), size = width * std::size_t(request_.height);
  for (const std::size_t i : indices)
    if (i >= size)
      throw std::invalid_argument("ExactView::pixels_at: pixel " + std::to_string(i) + " of " + std::to_string(size));
  // Chunks of consecutive indices, so that threads share no cache line
  // (64 pixels: 2.5 KB) and the stop is asked about often; small, because
  // a certified frame's few thousand uncertain pixels are spread over all
  // the threads.
  constexpr std::size_t kChunk = 64;
  const int chunks = int((indices.size() + kChunk - 1) / kChunk);
  for_each_row(chunks, stop_requested, [&](int chunk) {
    const std::size_t end = std::min(indices.size(), std::size_t(chunk + 1) * kChunk);
    for (std::size_t k = std::size_t(chunk) * kChunk; k < end; ++k)
      use(k, at(double(indices[k] % width) + 0.5, double(indices[k] / width) + 0.5));
  });
}

std::vector<PixelCoverage> ExactView::coverage(const std::vector<std::uint8_t>& which,
                                               const std::function<bool()>& stop_requested) const {
  const int width = request_.width;
  const std::size_t size = std::size_t(width) * request_.height;
  if (which.size() != size)
    throw std::invalid_argument("ExactView::coverage: the mask has " + std::to_string(which.size()) +
                                " pixels, the view " + std::to_string(size));
  std::vector<PixelCoverage> coverage(size, PixelCoverage::unknown);
  for_each_row(request_.height, stop_requested, [&](int y) {
    for (int x = 0; x < width; ++x) {
      const std::size_t i = std::size_t(y) * width + x;
      if (which[i]) coverage[i] = coverage_of_pixel(*this, x, y);
    }
  });
  return coverage;
}

PixelCoverageOf ExactView::coverage_of(const std::function<bool()>& stop_requested) const {
  return [this, stop_requested](const std::vector<std::uint8_t>& which) { return coverage(which, stop_requested); };
}

std::vector<ExactPixel> cast_exact_pixels(const RenderRequest& request, const std::function<bool()>& stop_requested) {
  return ExactView(request, stop_requested).pixels(stop_requested);
}

Image exact_image(const std::vector<ExactPixel>& pixels, int width, int height) {
  Image image{width, height, 1, std::vector<std::uint8_t>(std::size_t(width) * height)};
  for (std::size_t i = 0; i < pixels.size(); ++i)
    image.pixels[i] = std::uint8_t(std::lround(255.0 * (pixels[i].geometry ? pixels[i].visibility : 1.0)));
  return image;
}

Image error_image(const Image& rendered, const Image& exact) {
  Image image{exact.width, exact.height, 3, std::vector<std::uint8_t>(std::size_t(exact.width) * exact.height * 3, 0)};
  for (std::size_t i = 0; i < exact.pixels.size(); ++i) {
    const int difference = int(rendered.pixels[i]) - int(exact.pixels[i]);
    if (difference < 0) image.pixels[3 * i + 0] = std::uint8_t(-difference);  // red: rendered too dark
    if (difference > 0) image.pixels[3 * i + 2] = std::uint8_t(difference);   // blue: rendered too bright
  }
  return image;
}

}  // namespace umbra
