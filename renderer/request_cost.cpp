#include "request_cost.hpp"

#include <algorithm>
#include <cmath>

#include <glm/vec4.hpp>

#include "light_math.hpp"
#include "mesh_instance.hpp"
#include "ray_cast.hpp"
#include "scene.hpp"
#include "shader_interface.hpp"

namespace umbra {

namespace {

// Calibration: milliseconds per unit of each factor on the reference machine
// (2 cores shared, llvmpipe LLVM 15, Release build). Measured by posting
// requests that each stress one factor to umbra-server and reading
// Server-Timing (shadow, main, readback; the scene upload shows as queue
// time on a scene's first request), two runs each with a new light time so
// that no shadow map is reused, then fitting these constants by
// least squares to cost_factors() of the same requests and rounding up (the
// larger of the two runs where they disagreed). The requests: the default
// frame; "shadow" at 1024^2, 2048^2, 4096^2 with pcf_radius 8; "color" at
// 2048^2 with hard and PCSS filters; map 4096 and 8192 with 4 cascades at
// 64^2; 300 and 999 spread spheres at 64^2 with map 64; 200 and 999
// overlapping spheres (map 512..8192, 1..4 cascades, 256^2..1024^2);
// "exact" for 1000 spread objects at 480x270, 999 overlapping spheres at
// 256^2, the default scene at 1024^2, and an area light at 512^2.
// bench/cost_report prints the factors of a request body to repeat this.
constexpr double kMsPerUploadedTriangle = 9.0e-5;  // tessellate + upload: 772 ms for 9.0 M triangles
constexpr double kMsPerDrawnTriangle = 1.0e-4;     // per view: 895 ms main, 417..594 ms shadow, 9.0 M
constexpr double kMsPerShadowTexelLayer = 1.0e-6;  // 999 overlapping spheres: 22..45 s for 3.9e10
constexpr double kMsPerShadowTexel = 1.5e-6;       // 4 x 8192^2, one object: 375..853 ms for 2.7e8
constexpr double kMsPerPixel = 1.0e-5;             // shading set-up and read-back
constexpr double kMsPerPixelLayer = 5.0e-5;        // 999 overlapping spheres, 1024^2: 2.0..3.4 s for 6e7
constexpr double kMsPerGather = 1.5e-6;            // pcf_radius 8 (81 gathers) at 4096^2: 2.6..3.0 s
constexpr double kMsPerCameraRay = 1.4e-4;         // default scene, 1024^2: 151..160 ms
constexpr double kMsPerShadowRay = 2.0e-6;         // area light, 512^2, 64 rays a pixel: 452..490 ms
constexpr double kMsPerRayObjectTest = 1.2e-5;     // 999 overlapping spheres, 256^2: 108..113 ms
// Meshes in the ray cast (Embree, renderer/mesh_ray_cast), measured with a
// throwaway program: a UV sphere of 99 k and 998 k triangles over a floor,
// the BVH built on one thread, "exact" at 640x360 on two, rounded up.
constexpr double kMsPerBvhTriangle = 6.0e-4;  // build: 99 k in 44..61 ms, 998 k in 473..489 ms
// A mesh query and its transforms, per ray (two threads): 640x360 "exact"
// 56..71 ms, with an area light (64 shadow rays a pixel) 835..920 ms.
constexpr double kMsPerRayMeshTest = 7.0e-5;
constexpr std::uint64_t kBvhBytesPerTriangle = 90;  // Embree's memory monitor, buffers included: 83..85

// Mesh sizes, as tessellate() builds them (tests check the two agree).
constexpr std::uint64_t kSphereStacks = 48, kSphereSlices = 96;
constexpr std::uint64_t kSphereTriangles = 2 * kSphereStacks * kSphereSlices - 2 * kSphereSlices;
constexpr std::uint64_t kSphereVertices = (kSphereStacks + 1) * (kSphereSlices + 1);
constexpr std::uint64_t kBoxTriangles = 12, kBoxVertices = 24;
constexpr std::uint64_t kPlaneTriangles = 2, kPlaneVertices = 4;

std::uint64_t scene_vertices(const Scene& scene) {
  std::uint64_t n = 0;
  for (const auto& o : scene.objects)
    n += o.type == SceneObject::Type::Sphere ? kSphereVertices
         : o.type == SceneObject::Type::Box  ? kBoxVertices
         : o.type == SceneObject::Type::Mesh ? mesh_vertex_count(o)
                                             : kPlaneVertices;
  return n;
}

double gathers_per_pixel(const ShadowSettings& shadow) {
  if (!shadow.enabled) return 0.0;
  switch (shadow.filter) {
    case ShadowFilter::Hard: return 1.0;
    case ShadowFilter::Pcf: return double(shadow.pcf_radius + 1) * double(shadow.pcf_radius + 1);
    case ShadowFilter::Pcss: return double(kPcssBlockerSamples + kPcssFilterSamples);
  }
  return 1.0;
}

}  // namespace

std::uint64_t scene_triangles(const Scene& scene) {
  std::uint64_t n = 0;
  for (const auto& o : scene.objects)
    n += o.type == SceneObject::Type::Sphere ? kSphereTriangles
         : o.type == SceneObject::Type::Box  ? kBoxTriangles
         : o.type == SceneObject::Type::Mesh ? mesh_triangle_count(o)
                                             : kPlaneTriangles;
  return n;
}

double depth_complexity(const Scene& scene, const glm::dmat4& view_projection) {
  double sum = 0.0;
  for (const auto& o : scene.objects) {
    const Aabb bounds = object_bounds(o);
    double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
    bool behind = false;
    for (const glm::dvec3& corner : bounds.corners()) {
      const glm::dvec4 clip = view_projection * glm::dvec4(corner, 1.0);
      // At or behind a perspective eye the projection wraps around: count
      // the whole view, the most such an object can cover.
      if (!(clip.w > 1e-12)) {
        behind = true;
        break;
      }
      x0 = std::min(x0, clip.x / clip.w), x1 = std::max(x1, clip.x / clip.w);
      y0 = std::min(y0, clip.y / clip.w), y1 = std::max(y1, clip.y / clip.w);
    }
    if (behind) {
      sum += 1.0;
      continue;
    }
    const double w = std::min(x1, 1.0) - std::max(x0, -1.0), h = std::min(y1, 1.0) - std::max(y0, -1.0);
    if (w > 0.0 && h > 0.0) sum += w * h / 4.0;
  }
  return sum;
}

CostFactors cost_factors(const RenderRequest& request) {
  CostFactors f;
  const bool exact = request.output == Output::Exact;
  const bool depth = request.output == Output::Depth;
  const bool casts_rays = exact || request.output == Output::Error;
  const double image_pixels = double(request.width) * double(request.height);
  const CameraMatrices camera = camera_matrices(request.camera, request.width, request.height);
  const double camera_layers = depth_complexity(request.scene, camera.projection * camera.view);

  if (!exact) {
    f.triangles = scene_triangles(request.scene);
    if (request.shadow.enabled || depth) {
      const ShadowPlan plan = plan_shadow(request);
      const double layer_texels = double(plan.layer_size) * double(plan.layer_size);
      f.shadow_texels = layer_texels * double(plan.views.size());
      for (const ShadowView& view : plan.views) {
        if (view.empty) continue;
        ++f.draws;
        f.shadow_texel_layers +=
            layer_texels * std::max(1.0, depth_complexity(request.scene, view.projection * view.view));
      }
    }
    if (depth) {
      // The preview reads one texel per output pixel; nothing is drawn from the camera.
      f.pixels = double(request.shadow.map_size) * double(request.shadow.map_size);
      f.gathers_per_pixel = 1.0;
    } else {
      ++f.draws;
      f.pixels = image_pixels;
      f.gathers_per_pixel = gathers_per_pixel(request.shadow);
      f.pixel_layers = image_pixels * std::max(1.0, camera_layers);
    }
  }
  if (casts_rays) {
    f.camera_rays = image_pixels;
    f.shadow_rays = image_pixels * (request.light.size > 0.0 ? 64.0 : 1.0);
    f.objects_per_ray = std::log2(double(request.scene.objects.size()) + 1.0) + camera_layers;
    std::vector<const TriangleModel*> models;
    for (const SceneObject& o : request.scene.objects) {
      if (o.type != SceneObject::Type::Mesh) continue;
      f.meshes_per_ray += 1.0;
      if (std::find(models.begin(), models.end(), o.model.get()) != models.end()) continue;
      models.push_back(o.model.get());
      f.bvh_triangles += mesh_triangle_count(o);
    }
    f.meshes_per_ray = std::min(f.meshes_per_ray, f.objects_per_ray);
  }
  return f;
}

const CostPart& RequestCost::dominant() const {
  return *std::max_element(parts.begin(), parts.end(),
                           [](const CostPart& a, const CostPart& b) { return a.ms < b.ms; });
}

RequestCost estimate_cost(const RenderRequest& request) {
  RequestCost cost;
  const CostFactors& f = cost.factors = cost_factors(request);
  const double triangles = double(f.triangles);
  const bool area_light = request.light.size > 0.0;
  cost.parts = {
      {"scene triangles", triangles * (kMsPerUploadedTriangle + kMsPerDrawnTriangle * f.draws), "scene.objects",
       "use fewer objects (a sphere is " + std::to_string(kSphereTriangles) +
           " triangles) or smaller models, or fewer shadow.cascades"},
      {"shadow-map fill", f.shadow_texel_layers * kMsPerShadowTexelLayer + f.shadow_texels * kMsPerShadowTexel,
       "shadow.map_size", "lower shadow.map_size or shadow.cascades, or spread overlapping objects apart"},
      {"pixels", f.pixels * kMsPerPixel + f.pixel_layers * kMsPerPixelLayer,
       request.output == Output::Depth ? "shadow.map_size" : "width",
       request.output == Output::Depth ? "lower shadow.map_size" : "lower width and height"},
      {"shadow filter taps", f.pixels * f.gathers_per_pixel * kMsPerGather,
       request.shadow.filter == ShadowFilter::Pcf ? "shadow.pcf_radius" : "width",
       request.shadow.filter == ShadowFilter::Pcf ? "lower shadow.pcf_radius, or width and height"
                                                   : "lower width and height, or use filter \"pcf\""},
      {"ray cast", (f.camera_rays + f.shadow_rays) *
                       (f.objects_per_ray * kMsPerRayObjectTest + f.meshes_per_ray * kMsPerRayMeshTest) +
                       f.camera_rays * kMsPerCameraRay + f.shadow_rays * kMsPerShadowRay,
       area_light ? "light.size" : "width",
       area_light ? "an area light casts 64 shadow rays a pixel: lower width and height, or use light.size 0"
                  : "lower width and height, or use fewer objects"},
      {"mesh BVH build", double(f.bvh_triangles) * kMsPerBvhTriangle, "scene.objects",
       "the exact reference builds a BVH of each model's triangles: use smaller models"},
  };
  for (const CostPart& part : cost.parts) cost.total_ms += part.ms;

  // Peak memory: what is alive at once in the worst phase.
  const std::uint64_t pixels = std::uint64_t(request.width) * std::uint64_t(request.height);
  std::uint64_t bytes = 0;
  if (request.output != Output::Exact) {
    // The mesh on the CPU while it is uploaded, and GL's copy of it.
    const std::uint64_t mesh = scene_vertices(request.scene) * sizeof(Vertex) + f.triangles * 3 * sizeof(std::uint32_t);
    bytes += 2 * mesh;
    bytes += std::uint64_t(f.shadow_texels) * sizeof(float);  // DEPTH_COMPONENT32F layers
    if (request.output == Output::Depth) {
      const std::uint64_t map = std::uint64_t(request.shadow.map_size) * std::uint64_t(request.shadow.map_size);
      const std::uint64_t sample = request.depth_bits == 16 ? 2 : 1;
      bytes += 3 * map * sample;  // preview texture, read-back image, PNG
    } else {
      bytes += pixels * 12;     // RGBA8 colour + 32F depth / 8-bit stencil (8 bytes in llvmpipe) renderbuffers
      bytes += 2 * pixels * 3;  // read-back image and its PNG
    }
  }
  if (request.output == Output::Exact || request.output == Output::Error) {
    bytes += pixels * (sizeof(ExactPixel) + 1 + 3 + 3);  // per-pixel records, exact, error image and PNG
    bytes += f.bvh_triangles * kBvhBytesPerTriangle;     // the models' BVHs, as if none were cached
  }
  cost.peak_bytes = bytes;
  return cost;
}

}  // namespace umbra
