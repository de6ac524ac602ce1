#include "service/request_cost.hpp"

#include "reference/sun_hours_footprints.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>
#include <glm/vec4.hpp>

#include "core/light_math.hpp"
#include "core/mesh_instance.hpp"
#include "core/model.hpp"
#include "plan/conservative_maps.hpp"
#include "plan/draw_cost.hpp"
#include "reference/ray_cast.hpp"
#include "core/scene.hpp"
#include "core/shapes/shape.hpp"
#include "gpu/shader_interface.hpp"

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
// kMsPerDrawnTriangle: plan/draw_cost.hpp, where the renderer sizes its
// chunked draws by it.
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
// A mesh's layers past the first (ViewLayers::mesh_overdraw), measured with
// issue 29's model: 4,000 stacked 40 x 40 quads (8,000 triangles), one
// object, each layer nearer the eye and the light than the one before, so
// every fragment is shaded. Large triangles cost less a fragment than a
// sphere's small ones (kMsPerPixelLayer), but the shadow lookup runs for
// each layer. Camera, 256^2 and 512^2, 8.1e7 and 3.2e8 fragments: pcf_radius
// 0 and 1 1.1..2.4 s at 256^2, 4.9 s at 512^2; pcf_radius 8 10.6 s at 256^2.
constexpr double kMsPerMeshFragment = 2.5e-5;  // plus kMsPerGather for each of its shadow-map reads
// Map 2048^2 and 1024^2, 1.3e10 and 3.3e9 texels: 5.2 s and 1.24 s.
constexpr double kMsPerMeshTexel = 5.0e-7;
// kMsPerTileTest: a triangle tested against a 64 x 64 tile, plan/draw_cost.hpp.
// Filter "exact"'s conservative passes (certify.geom), per triangle and
// pass, 960x540: the 102,400-triangle teapot 0.5 us (small triangles),
// the torus knot (16,386) 1.15 us, `columns` (11,342) 1.3 us: the larger
// end, so that the maps are not chosen where they cost more.
constexpr double kMsPerConservativeTriangle = 1.0e-3;
// The same drawn on the CPU (plan/conservative_maps.cpp, 2 cores,
// bench/results/certified.md, 2026-11-27): per view, each texel of the
// centre map and of the conservative maps (a quarter of the layer's) about
// 2e-6 ms with its upload, each triangle's setup 2e-4 ms; the main pass's
// certificate 4e-4 ms more a triangle than the proofs' program (the
// 102,400-triangle teapot: maps 86 ms, proofs 44, ray cast 68).
constexpr double kMsPerCertifiedMapTexel = 2.0e-6;
constexpr double kMsPerCertifiedViewTriangle = 2.0e-4;
constexpr double kMsPerCertificateTriangle = 4.0e-4;
// The exact output's ray cast measured over ray_cast_ms, in the certified
// bench (bench/results/certified.md, 960x540, 2 cores): 0.29..0.76 over 16
// scenes, median 0.4.
constexpr double kRayCastShare = 0.4;
// On a GPU the shaders draw the maps and the sliver marks, whatever the
// scene's size. Measured on an NVIDIA H100 machine (16 hardware threads,
// 2026-11-28, 960x540, timers around each pass added for the purpose): the
// conservative passes 28-55 ns a triangle and pass (the teapots, the torus
// knot), the sliver pass 8 ns a triangle, a layer's clears and centre map
// and the rest about 0.6 ms (hovering-plate's 3 layers 1.7-1.9 ms, 6 cube
// faces 11 ms); its CPU's full ray cast 0.21-0.54 times ray_cast_ms x
// kRayCastShare over the bench scenes, median 0.45. One machine's numbers:
// another GPU's or CPU's differ, but not the order of the paths for the
// scenes measured (the teapot's maps took 58 ms there, its whole ray cast
// 26).
constexpr double kGpuMsPerConservativeTriangle = 4.0e-5;
constexpr double kGpuMsPerSliverTriangle = 1.0e-5;
constexpr double kGpuMsPerCertifiedLayer = 0.6;
constexpr double kGpuRayCastScale = 0.45;

// Mesh sizes, as tessellate() builds them: each shape's row says (test_shapes
// checks it against its tessellation).
std::uint64_t scene_vertices(const Scene& scene) {
  std::uint64_t n = 0;
  for (const auto& o : scene.objects) n += shape_kind(o.type).vertices(o);
  return n;
}

// The exact reference's rays: camera and shadow rays, each testing the
// objects and meshes it meets.
double ray_cast_ms(const CostFactors& f) {
  return (f.camera_rays + f.shadow_rays) * (f.objects_per_ray * kMsPerRayObjectTest + f.meshes_per_ray * kMsPerRayMeshTest) +
         f.camera_rays * kMsPerCameraRay + f.shadow_rays * kMsPerShadowRay;
}

double gathers_per_pixel(const ShadowSettings& shadow) {
  if (!shadow.enabled) return 0.0;
  switch (shadow.filter) {
    case ShadowFilter::Hard: return 1.0;
    case ShadowFilter::Pcf: return double(shadow.pcf_radius + 1) * double(shadow.pcf_radius + 1);
    case ShadowFilter::Pcss: return double(kPcssBlockerSamples + kPcssFilterSamples);
    // The certificate: up to 4 texels of three maps for light, 9 of two for shadow.
    case ShadowFilter::Exact: return 8.0;
  }
  return 1.0;
}

}  // namespace

std::uint64_t scene_triangles(const Scene& scene) {
  std::uint64_t n = 0;
  for (const auto& o : scene.objects) n += shape_kind(o.type).triangles(o);
  return n;
}

namespace {

// Where an object's bounds fall in a view: the share of the image their
// projected rectangle covers (clipped to it), or around_eye when they reach
// to or behind a perspective eye, where the projection wraps around.
struct Coverage {
  double share = 0.0;
  bool around_eye = false;
};

Coverage bounds_coverage(const Aabb& bounds, const glm::dmat4& view_projection) {
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (const glm::dvec3& corner : bounds.corners()) {
    const glm::dvec4 clip = view_projection * glm::dvec4(corner, 1.0);
    if (!(clip.w > 1e-12)) return {0.0, true};
    x0 = std::min(x0, clip.x / clip.w), x1 = std::max(x1, clip.x / clip.w);
    y0 = std::min(y0, clip.y / clip.w), y1 = std::max(y1, clip.y / clip.w);
  }
  const double w = std::min(x1, 1.0) - std::max(x0, -1.0), h = std::min(y1, 1.0) - std::max(y0, -1.0);
  return {w > 0.0 && h > 0.0 ? w * h / 4.0 : 0.0, false};
}

// The world direction along which a view's clip x and y stay 0: its
// forward axis (either sign), orthographic or perspective.
glm::dvec3 view_forward(const glm::dmat4& view_projection) {
  const glm::dmat4& m = view_projection;  // column-major: m[column][row]
  return glm::cross(glm::dvec3(m[0][0], m[1][0], m[2][0]), glm::dvec3(m[0][1], m[1][1], m[2][1]));
}

// A perspective view's eye, where clip x, y and w are all 0; none for an
// orthographic view (w does not vary).
std::optional<glm::dvec3> view_eye(const glm::dmat4& view_projection) {
  const glm::dmat4& m = view_projection;
  const glm::dvec3 row0(m[0][0], m[1][0], m[2][0]), row1(m[0][1], m[1][1], m[2][1]), row3(m[0][3], m[1][3], m[2][3]);
  if (glm::length(row3) <= 1e-9 * glm::length(row0)) return std::nullopt;
  const glm::dmat3 rows = glm::transpose(glm::dmat3(row0, row1, row3));
  if (std::abs(glm::determinant(rows)) < 1e-300) return std::nullopt;
  return glm::inverse(rows) * -glm::dvec3(m[3][0], m[3][1], m[3][3]);
}

// Whether the main pass will cull closed objects' back faces: the renderer
// does when the eye is outside every closed object's bounds by the near
// plane's reach (closed_meshes_seen_from_outside); here by twice that,
// erring towards drawing every face.
bool camera_culls_closed_faces(const RenderRequest& request) {
  const Camera& camera = request.camera;
  const double aspect = double(request.width) / double(request.height);
  const double tan_half = std::tan(camera.fov_y_deg * 3.14159265358979323846 / 360.0);
  const double reach = camera.near_plane * std::sqrt(1.0 + tan_half * tan_half * (1.0 + aspect * aspect));
  for (const SceneObject& o : request.scene.objects) {
    if (!shape_kind(o.type).closed(o)) continue;
    const Aabb box = object_bounds(o);
    if (box.empty()) continue;
    const glm::dvec3 outside = glm::max(glm::max(box.min - camera.position, camera.position - box.max), 0.0);
    if (glm::length(outside) <= 2.0 * reach) return false;
  }
  return true;
}

// How deep a mesh's triangles lie seen from a view: along its forward axis
// for an orthographic view; for a perspective one, the most along the
// directions from the eye to the bounds' centre and 8 corners. A wide view
// looks through a mesh at many angles: blinds seen edge on at their centre
// are thousands of layers deep towards their ends.
double layers_seen_from(const SceneObject& o, const Aabb& bounds, const std::optional<glm::dvec3>& eye,
                        const glm::dvec3& forward) {
  if (!eye) return mesh_layers_along(o, forward);
  const auto along = [&](const glm::dvec3& point) {
    const glm::dvec3 toward = point - *eye;
    return mesh_layers_along(o, toward == glm::dvec3(0.0) ? forward : toward);
  };
  double layers = along(bounds.center());
  for (const glm::dvec3& corner : bounds.corners()) layers = std::max(layers, along(corner));
  return layers;
}

}  // namespace

double depth_complexity(const Scene& scene, const glm::dmat4& view_projection) {
  double sum = 0.0;
  for (const auto& o : scene.objects) {
    // Bounds around a perspective eye count as the whole view, the most
    // such an object can cover.
    const Coverage c = bounds_coverage(object_bounds(o), view_projection);
    sum += c.around_eye ? 1.0 : c.share;
  }
  return sum;
}

ViewLayers view_layers(const Scene& scene, const glm::dmat4& view_projection, bool closed_faces_culled) {
  ViewLayers v;
  const glm::dvec3 forward = view_forward(view_projection);
  const std::optional<glm::dvec3> eye = view_eye(view_projection);
  for (const SceneObject& o : scene.objects) {
    if (o.type != SceneObject::Type::Mesh || !o.model || o.model->bounds.empty()) continue;
    const Aabb bounds = object_bounds(o);
    const Coverage c = bounds_coverage(bounds, view_projection);
    const double share = c.around_eye ? 1.0 : c.share;
    if (share <= 0.0) continue;
    // Bounds around a perspective eye: its triangles may face it from any side.
    double layers = c.around_eye ? mesh_deepest_layers(o, forward) : layers_seen_from(o, bounds, eye, forward);
    // A closed surface faces each way with half its area: culling draws one half.
    if (closed_faces_culled && o.model->closed) layers *= 0.5;
    v.deepest_mesh = std::max(v.deepest_mesh, layers);
    v.mesh_overdraw += share * std::max(0.0, layers - 1.0);
  }
  return v;
}

namespace {

// mesh_tile_tests of every mesh object in a view, summed; keeps the most a
// triangle in f.tiles_per_triangle.
double count_tile_tests(const Scene& scene, const glm::dmat4& view_projection, double width, double height,
                        CostFactors& f) {
  double sum = 0.0;
  for (const SceneObject& o : scene.objects) {
    const double tiles = mesh_tile_tests(o, view_projection, width, height);
    if (tiles <= 0.0) continue;
    sum += tiles;
    f.tiles_per_triangle = std::max(f.tiles_per_triangle, tiles / double(std::max<std::uint64_t>(1, mesh_triangle_count(o))));
  }
  return sum;
}

}  // namespace

namespace {

// The ray cast's meshes: how many a ray meets at most (no more than its
// objects_per_ray), and the triangles of the distinct models whose BVHs
// are built. The kinds with an exact test of their own are tested in
// closed form; the others (meshes) through a BVH of their model (RayScene).
void count_ray_meshes(const Scene& scene, CostFactors& f) {
  std::vector<const TriangleModel*> models;
  for (const SceneObject& o : scene.objects) {
    if (shape_kind(o.type).intersect) continue;
    f.meshes_per_ray += 1.0;
    if (std::find(models.begin(), models.end(), o.model.get()) != models.end()) continue;
    models.push_back(o.model.get());
    f.bvh_triangles += mesh_triangle_count(o);
  }
  f.meshes_per_ray = std::min(f.meshes_per_ray, f.objects_per_ray);
}

}  // namespace

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
      const bool shadow_culls = request.shadow.cull != CullMode::None;
      for (const ShadowView& view : plan.views) {
        if (view.empty) continue;
        ++f.draws;
        const glm::dmat4 view_projection = view.projection * view.view;
        f.shadow_texel_layers += layer_texels * std::max(1.0, depth_complexity(request.scene, view_projection));
        const ViewLayers meshes = view_layers(request.scene, view_projection, shadow_culls);
        f.mesh_texel_layers += layer_texels * meshes.mesh_overdraw;
        f.deepest_mesh = std::max(f.deepest_mesh, meshes.deepest_mesh);
        const double size = double(plan.layer_size);
        f.mesh_shadow_tile_tests += count_tile_tests(request.scene, view_projection, size, size, f);
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
      const ViewLayers meshes =
          view_layers(request.scene, camera.projection * camera.view, camera_culls_closed_faces(request));
      f.mesh_pixel_layers = image_pixels * meshes.mesh_overdraw;
      f.deepest_mesh = std::max(f.deepest_mesh, meshes.deepest_mesh);
      f.mesh_tile_tests += count_tile_tests(request.scene, camera.projection * camera.view, double(request.width),
                                            double(request.height), f);
    }
    f.mesh_tile_tests += f.mesh_shadow_tile_tests;
  }
  if (casts_rays) {
    f.camera_rays = image_pixels;
    f.shadow_rays = image_pixels * (request.light.size > 0.0 ? 64.0 : 1.0);
    f.objects_per_ray = std::log2(double(request.scene.objects.size()) + 1.0) + camera_layers;
    count_ray_meshes(request.scene, f);
  }
  return f;
}

CertifiedPath ExactFilterPaths::best() const {
  if (maps_ms <= proofs_ms && maps_ms <= ray_cast_ms) return CertifiedPath::Maps;
  return proofs_ms <= ray_cast_ms ? CertifiedPath::Proofs : CertifiedPath::RayCast;
}

namespace {

// exact_filter_paths from the request's factors and those of its exact
// output (`as_exact`), which estimate_cost has already counted.
ExactFilterPaths exact_filter_paths(const RenderRequest& request, const CostFactors& f, const CostFactors& as_exact,
                                    CertifyingGl gl) {
  const bool gpu = gl == CertifyingGl::Gpu;
  const double ray_cast = ray_cast_ms(as_exact) * kRayCastShare * (gpu ? kGpuRayCastScale : 1.0);
  const int views = std::max(0, f.draws - 1);  // the camera's draw aside
  const double quads = double(f.triangles) * kMsPerConservativeTriangle;
  const bool on_cpu = f.triangles <= kMostConservativeTriangles;
  Scene objects;
  for (const SceneObject& o : request.scene.objects)
    if (o.type != SceneObject::Type::Plane) objects.objects.push_back(o);
  const CameraMatrices camera = camera_matrices(request.camera, request.width, request.height);
  const double cover = depth_complexity(objects, camera.projection * camera.view);
  ExactFilterPaths paths;
  const double triangles = double(f.triangles);
  double maps = on_cpu ? f.shadow_texels / 4.0 * kMsPerCertifiedMapTexel +
                             triangles * (double(views) * kMsPerCertifiedViewTriangle + kMsPerCertificateTriangle)
                       : 2.0 * double(views) * quads;
  double slivers = on_cpu ? 0.0 : quads;
  if (gpu) {
    maps = double(views) * (kGpuMsPerCertifiedLayer + 2.0 * triangles * kGpuMsPerConservativeTriangle);
    slivers = triangles * kGpuMsPerSliverTriangle;
  }
  paths.maps_ms = maps + slivers + ray_cast / 20.0;
  paths.proofs_ms = slivers + ray_cast * std::min(1.0, 3.0 * cover);
  paths.ray_cast_ms = ray_cast;
  return paths;
}

RenderRequest as_exact_output(const RenderRequest& request) {
  RenderRequest as_exact = request;
  as_exact.output = Output::Exact;
  return as_exact;
}

}  // namespace

ExactFilterPaths exact_filter_paths(const RenderRequest& request, CertifyingGl gl) {
  return exact_filter_paths(request, cost_factors(request), cost_factors(as_exact_output(request)), gl);
}

const CostPart& RequestCost::dominant() const {
  return *std::max_element(parts.begin(), parts.end(),
                           [](const CostPart& a, const CostPart& b) { return a.ms < b.ms; });
}

RequestCost estimate_cost(const RenderRequest& request, CertifyingGl gl) {
  RequestCost cost;
  const CostFactors& f = cost.factors = cost_factors(request);
  const double triangles = double(f.triangles);
  const bool area_light = request.light.size > 0.0;
  cost.parts = {
      {"scene triangles", triangles * (kMsPerUploadedTriangle + kMsPerDrawnTriangle * f.draws), "scene.objects",
       "use fewer objects (a sphere is " +
           std::to_string(shape_kind(SceneObject::Type::Sphere).triangles(SceneObject{})) +
           " triangles) or smaller models, or fewer shadow.cascades"},
      {"shadow-map fill", f.shadow_texel_layers * kMsPerShadowTexelLayer + f.shadow_texels * kMsPerShadowTexel,
       "shadow.map_size", "lower shadow.map_size or shadow.cascades, or spread overlapping objects apart"},
      {"pixels", f.pixels * kMsPerPixel + f.pixel_layers * kMsPerPixelLayer,
       request.output == Output::Depth ? "shadow.map_size" : "width",
       request.output == Output::Depth ? "lower shadow.map_size" : "lower width and height"},
      {"mesh overdraw",
       f.mesh_pixel_layers * (kMsPerMeshFragment + f.gathers_per_pixel * kMsPerGather) +
           f.mesh_texel_layers * kMsPerMeshTexel,
       "scene.objects",
       "a model's triangles lie up to about " + std::to_string(std::llround(f.deepest_mesh)) +
           " layers deep in a view, each layer drawn in turn: use models whose triangles overlap less, fewer "
           "of them, or lower width and height and shadow.map_size"},
      {"mesh triangle extent", f.mesh_tile_tests * kMsPerTileTest,
       f.mesh_shadow_tile_tests * 2.0 >= f.mesh_tile_tests ? "shadow.map_size" : "width",
       "a model's triangles each span up to about " + std::to_string(std::llround(f.tiles_per_triangle)) +
           " tiles of 64 x 64 pixels in a view, and each is tested against every tile its bounding box covers: " +
           (f.mesh_shadow_tile_tests * 2.0 >= f.mesh_tile_tests ? "lower shadow.map_size, " : "lower width and height, ") +
           "or use models with smaller triangles, or fewer of them"},
      {"shadow filter taps", f.pixels * f.gathers_per_pixel * kMsPerGather,
       request.shadow.filter == ShadowFilter::Pcf ? "shadow.pcf_radius" : "width",
       request.shadow.filter == ShadowFilter::Pcf ? "lower shadow.pcf_radius, or width and height"
                                                   : "lower width and height, or use filter \"pcf\""},
      {"ray cast", ray_cast_ms(f),
       area_light ? "light.size" : "width",
       area_light ? "an area light casts 64 shadow rays a pixel: lower width and height, or use light.size 0"
                  : "lower width and height, or use fewer objects"},
      {"mesh BVH build", double(f.bvh_triangles) * kMsPerBvhTriangle, "scene.objects",
       "the exact reference builds a BVH of each model's triangles: use smaller models"},
  };
  // Filter "exact" (docs/certified-shadows.md): two more passes of the
  // map, conservative (a geometry shader's box per triangle, every
  // fragment's depth written: on llvmpipe about 8 times an ordinary pass's
  // fill was measured), and the ray cast of the pixels they leave
  // uncertain: up to a third of the frame in the bench scenes at 320 x 180.
  const bool certified = request.shadow.filter == ShadowFilter::Exact && request.shadow.enabled &&
                         request.output != Output::Depth && request.output != Output::Exact;
  if (certified) {
    const CostFactors e = cost_factors(as_exact_output(request));
    cost.exact_filter_path = exact_filter_paths(request, f, e, gl).best();
    // The maps and the pixels they leave; without maps (where they would
    // cost more), every pixel but the proved plane parts' may be ray cast.
    const double settle = cost.exact_filter_path == CertifiedPath::Maps
                              ? 8.0 * (f.shadow_texel_layers * kMsPerShadowTexelLayer + f.shadow_texels * kMsPerShadowTexel) +
                                    ray_cast_ms(e) / 3.0
                              : ray_cast_ms(e);
    cost.parts.push_back({"certified maps and uncertain pixels", settle + double(e.bvh_triangles) * kMsPerBvhTriangle,
                          "shadow.filter", "use filter \"pcf\", or lower shadow.map_size, width and height"});
  }
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
  if (certified) {
    // The certified maps (two of depth, two of ids), the certificates and
    // unlit colours read back, the reference's records of the cast pixels.
    bytes += std::uint64_t(f.shadow_texels) * 4 * sizeof(float) + pixels * (8 + 4 + 3);
    bytes += pixels * sizeof(ExactPixel) + f.bvh_triangles * kBvhBytesPerTriangle;
    // On llvmpipe, the passes drawn on the CPU; on a GPU, the list of the
    // pixels to ray cast (ShadowRenderer::dispatch_cast_list: two R8UI
    // images and up to 8 bytes a pixel).
    if (gl == CertifyingGl::Llvmpipe && f.triangles <= kMostConservativeTriangles)
      bytes += f.triangles * kCertifiedCpuBytesPerTriangle;
    if (gl == CertifyingGl::Gpu) bytes += pixels * (2 + 8);
  }
  cost.peak_bytes = bytes;
  return cost;
}

// Sun hours. The rays start at grid points, not at a camera's surfaces,
// and walk the scene's bounding-volume tree: each is priced as an exact
// output's shadow ray (kMsPerShadowRay plus its object tests).
// NREL SPA: 3.15e6 in 10.6 s on one core; priced at one core's speed, since
// the renders on the same cores and a busy machine slow the two-core run.
constexpr double kMsPerSunPosition = 3.5e-3;
// The footprints: a hull and its spans per sample (an object's footprint,
// a model's cluster's, a solid's core), and one pass over the grid per
// stretch of daylight.
constexpr double kMsPerFootprint = 1.0e-3;
// A model's triangle, once per request: its shell, its cluster and its
// shell's core (the open teapot's 102,400: about 6 ms; five closed
// spheres' 995,000, whose cores are looked for: 0.31 s).
constexpr double kMsPerModelTriangle = 4.0e-4;
constexpr double kMsPerStretchPoint = 2.0e-6;
// A grid row per sample (its cores' spans merged and compared with the
// last sample's), and a core's shadow's row (its span, and the points that
// enter or leave it): the city of 144 towers on a 1000 x 1000 grid, 727
// samples of 20,000 such rows in about 0.45 s on two cores.
constexpr double kMsPerFootprintRow = 3.0e-5;
// A pair inside a footprint and outside the cores' shadows, judged for a
// proof of dark (a turned box's slab test, a pole's quadratic): 200 thin
// poles, 21 M of them in about 0.4 s.
constexpr double kMsPerFootprintPoint = 2.5e-5;
// A point met again inside another footprint of the same sample (one
// index test): 1000 identical thin boxes stacked at one spot.
constexpr double kMsPerFootprintVisit = 3.0e-6;
// A unit of a mesh shadow's drawing (GridShadow::work: a triangle judged,
// an edge slid), per sample. The plan draws each fresh; the walk draws
// from a memory that re-judges only what turned where samples are close
// (ten teapots' day at one-minute steps: 450,000 units a sample, 727
// samples in about 1.7 s on two cores when set, 1.2-1.4 s since), fresh
// where they are not (the sun turns about 0.25 degrees a minute; past
// kMeshMemoryMostStepSeconds, six minutes a step, a memory would start
// afresh at every sample: a month at ten minutes). A
// year at ten minutes keeps a memory per time of day instead
// (mesh_memory_day_slots; 490,000 units a sample, 26,736 samples in
// 59-77 s; 114 s fresh).
constexpr double kMsPerMeshShadowUnit = 5.0e-6, kMsPerDayMemoryMeshShadowUnit = 6.0e-6,
                 kMsPerFreshMeshShadowUnit = 8.5e-6;
// Answer text per point: JSON (hours and longest run) or CSV (x, y, z too).
constexpr std::uint64_t kAnswerBytesPerPoint = 96;
// include_samples: a sample's instant, azimuth and elevation as JSON text.
constexpr double kMsPerSampleText = 1.0e-3;
constexpr std::uint64_t kAnswerBytesPerSample = 112;

SunHoursCost estimate_sun_hours_cost(const SunHoursRequest& request, std::size_t samples, double sun_up_share,
                                     const FootprintShares& shares) {
  CostFactors f;
  const Scene& scene = request.view.scene;
  const double points = double(request.grid.points());
  const double samples_up = double(samples) * sun_up_share;
  f.shadow_rays = points * samples_up;
  // The tree's levels, and the objects whose bounds the ray passes through
  // up to its first hit (FootprintShares::tests), each with about as many
  // of the tree's nodes: overlapping bounds share no subtree to skip (1000
  // stacked thin turned boxes: 1.8 s measured for 117 k rays).
  const double tree = std::log2(double(scene.objects.size()) + 1.0);
  constexpr double kTestsPerOverlap = 2.0;
  f.objects_per_ray = tree + 1.0 + kTestsPerOverlap * shares.tests;
  count_ray_meshes(scene, f);
  // A model costs a ray a traversal of its tree only where the ray meets
  // its bounds: the models whose footprints hold the pair (most of a
  // site's rays meet none; ten teapots' pure ray cast was priced 5.7x
  // over with every model on every ray).
  const double models_in_scene = f.meshes_per_ray;
  f.meshes_per_ray = std::min(f.meshes_per_ray, shares.mesh_depth);
  const bool points_dominate = points >= double(samples);
  const std::string rays_field = points_dominate ? "grid.spacing" : "period.step_minutes";
  const std::string rays_advice = "take a larger grid.spacing or a smaller grid.size, a longer period.step_minutes "
                                  "or a shorter period";
  CostFactors in_footprints = f;
  in_footprints.shadow_rays = f.shadow_rays * shares.queried;
  in_footprints.objects_per_ray = tree + 1.0 + kTestsPerOverlap * shares.queried_tests;
  // A ray left to the query lies in some footprint: at most one model's
  // and those of the others whose bounds it passes.
  in_footprints.meshes_per_ray = std::min({models_in_scene, 1.0 + shares.queried_tests, in_footprints.objects_per_ray});
  // Stretches of daylight: about one a day, at least one.
  const double days = std::max(1.0, (request.period.end_unix_s - request.period.start_unix_s) / 86400.0);
  const double mesh_shadow_ms =
      request.period.step_seconds() <= kMeshMemoryMostStepSeconds ? kMsPerMeshShadowUnit
      : mesh_memory_day_slots(request.period.step_seconds(), samples) > 0 ? kMsPerDayMemoryMeshShadowUnit
                                                                          : kMsPerFreshMeshShadowUnit;
  const double footprints_ms = samples_up * std::max(shares.hulls, double(scene.objects.size())) * kMsPerFootprint +
                               shares.model_triangles * kMsPerModelTriangle +
                               std::min(days, samples_up) * points * kMsPerStretchPoint +
                               samples_up * (double(request.grid.rows) + shares.core_rows) * kMsPerFootprintRow +
                               f.shadow_rays * shares.candidates * kMsPerFootprintPoint +
                               f.shadow_rays * shares.depth * kMsPerFootprintVisit +
                               samples_up * shares.mesh_shadow_work * mesh_shadow_ms;
  const double pure_ms = ray_cast_ms(f);
  const double via_footprints_ms = footprints_ms + ray_cast_ms(in_footprints);

  SunHoursCost out;
  out.footprints = via_footprints_ms < pure_ms;
  out.ray_cast_ms = pure_ms;
  RequestCost& cost = out.cost;
  cost.factors = out.footprints ? in_footprints : f;
  cost.parts = {
      {"sun positions", double(samples) * kMsPerSunPosition, "period.step_minutes",
       "take a longer period.step_minutes or a shorter period"},
      {"sun-hours footprints", out.footprints ? footprints_ms : 0.0, rays_field,
       "each object's footprint on the grid is drawn for every sample with the sun up: " + rays_advice},
      {"sun-hours rays", ray_cast_ms(cost.factors), rays_field,
       "one ray per point and sample with the sun up" +
           std::string(out.footprints ? " inside an object's footprint (" : " (") +
           std::to_string(std::llround(cost.factors.shadow_rays)) + "): " + rays_advice},
      {"mesh BVH build", double(f.bvh_triangles) * kMsPerBvhTriangle, "scene.objects",
       "the ray cast builds a BVH of each model's triangles: use smaller models"},
  };
  // The picture: a camera ray per pixel, and from its surface a ray per
  // sample with the sun up (the pure ray cast: its points are not a plane).
  const double pixels = request.picture ? double(request.view.width) * double(request.view.height) : 0.0;
  if (request.picture) {
    CostFactors picture = f;
    picture.camera_rays = pixels;
    picture.shadow_rays = pixels * samples_up;
    cost.parts.push_back({"sun-hours picture", ray_cast_ms(picture), "width",
                          "one ray per pixel and sample with the sun up: lower width and height, or take a longer "
                          "period.step_minutes or a shorter period"});
  }
  if (request.include_samples)
    cost.parts.push_back({"samples listed", double(samples) * kMsPerSampleText, "include_samples",
                          "every sample's instant and sun position is written into the answer: leave out "
                          "include_samples, or take a longer period.step_minutes"});
  for (const CostPart& part : cost.parts) cost.total_ms += part.ms;
  const std::uint64_t per_point = sizeof(PointTally) + kAnswerBytesPerPoint + (out.footprints ? 3 * 8 : 0);
  const std::uint64_t listed = request.include_samples ? std::uint64_t(samples) * kAnswerBytesPerSample : 0;
  cost.peak_bytes = std::uint64_t(points) * per_point + std::uint64_t(samples) * sizeof(SunSample) +
                    f.bvh_triangles * kBvhBytesPerTriangle + std::uint64_t(pixels) * (4 + 3 + 3) + listed;
  // Over the memory budget: what holds most of it.
  const double picture_bytes = pixels * (4 + 3 + 3), grid_bytes = points * double(per_point);
  if (double(listed) > std::max(picture_bytes, grid_bytes)) {
    cost.memory_field = "include_samples";
    cost.memory_advice = "leave out include_samples, or take a longer period.step_minutes";
  } else if (picture_bytes > grid_bytes) {
    cost.memory_field = "width";
    cost.memory_advice = "lower width and height";
  } else {
    cost.memory_field = "grid.spacing";
    cost.memory_advice = "take a larger grid.spacing or a smaller grid.size";
  }
  return out;
}

SunHoursPlan plan_sun_hours(const SunHoursRequest& request) {
  SunHoursPlan plan;
  plan.samples = sample_count(request.period).value_or(0);
  // The path and its cost from a few hundred of the samples: the sun's
  // share of the period, and the footprints' share of the grid at 32 of
  // the probes with the sun up.
  const std::vector<SunSample> probes = probe_samples(request.site, request.period, plan.samples);
  std::vector<glm::dvec3> up;
  for (const SunSample& s : probes)
    if (s.up()) up.push_back(s.direction);
  std::vector<glm::dvec3> directions;
  const std::size_t picked = std::min<std::size_t>(32, up.size());
  for (std::size_t i = 0; i < picked; ++i) directions.push_back(up[i * up.size() / picked]);
  const FootprintShares shares = footprint_shares(request.view.scene, request.grid, directions);
  plan.estimate = estimate_sun_hours_cost(request, plan.samples, sun_up_share(probes), shares);
  return plan;
}

}  // namespace umbra
