// What a request will cost before it runs: estimated time on the GL thread
// and the ray-cast cores, and peak memory, from the request alone.
//
// Pure CPU code, no GL: unit tested directly (tests/test_request_cost.cpp).
// RenderService::submit refuses a request whose estimate exceeds
// ServiceLimits' budget, since a GL frame cannot be stopped mid-draw: the
// estimate is what bounds how long one frame holds the GL thread.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/mat4x4.hpp>

#include "core/request.hpp"
#include "core/sun_hours.hpp"
#include "plan/frame_plan.hpp"
#include "reference/sun_hours_footprints.hpp"

namespace umbra {

/// The counts the estimate is made of. Each is what one kind of work
/// scales with; the time model multiplies them by measured constants.
struct CostFactors {
  /// Triangles of the scene's mesh (tessellate's), and how many times they
  /// are drawn: once per non-empty shadow view, once for the camera.
  std::uint64_t triangles = 0;
  int draws = 0;
  /// Shadow-map texels rasterised, summed over the non-empty views, each
  /// view's texels times its depth complexity (how many object bounds
  /// overlap a texel on average, at least 1): overlapping objects are each
  /// filled in turn.
  double shadow_texel_layers = 0.0;
  /// Texels of all the map's layers (cleared and held), whether drawn or not.
  double shadow_texels = 0.0;
  /// Output pixels shaded by the main pass (or the depth preview), and the
  /// shadow-map reads per pixel: textureGathers for PCF ((r+1)^2), 1 for
  /// hard, the blocker search and filter samples for PCSS.
  double pixels = 0.0;
  double gathers_per_pixel = 0.0;
  /// Camera pixels times the camera's depth complexity: fragments
  /// rasterised and depth tested.
  double pixel_layers = 0.0;
  /// Fragments of mesh objects beyond what their bounds count (ViewLayers::
  /// mesh_overdraw): camera pixels, and shadow-map texels summed over the
  /// non-empty views, times those extra layers. A model of 4,000 stacked
  /// quads is 4,000 layers deep where its bounds count one.
  double mesh_pixel_layers = 0.0;
  double mesh_texel_layers = 0.0;
  /// The deepest mesh in any of those views (ViewLayers::deepest_mesh), for
  /// the advice.
  double deepest_mesh = 0.0;
  /// 64 x 64 tiles llvmpipe tests mesh triangles against (mesh_tile_tests,
  /// plan/draw_cost.hpp),
  /// summed over the non-empty shadow views and the camera's, and the part
  /// of them in the shadow views. A long thin triangle is tested against
  /// every tile its bounding box covers: 200,000 slivers across a 4096^2
  /// map are 8e8 tests, seconds, where their area is almost nothing.
  double mesh_tile_tests = 0.0;
  double mesh_shadow_tile_tests = 0.0;
  /// The most tiles a mesh's triangles cover on average in any one view,
  /// for the advice.
  double tiles_per_triangle = 0.0;
  /// Ray cast ("exact", "error"): camera rays (one per pixel) and shadow
  /// rays (one per pixel; 64 for an area light), and the objects a ray is
  /// tested against: the bounding-volume tree's depth plus the camera's
  /// depth complexity (overlapping objects cannot be skipped).
  double camera_rays = 0.0;
  double shadow_rays = 0.0;
  double objects_per_ray = 0.0;
  /// Of those objects, the mesh objects a ray is tested against (each an
  /// Embree query, dearer than an analytic test): at most their count,
  /// at most objects_per_ray.
  double meshes_per_ray = 0.0;
  /// Triangles of the distinct models the ray cast builds a BVH for (once
  /// per model, however many placements; counted even when the BVH is
  /// cached from an earlier request, so the estimate never depends on what
  /// ran before).
  std::uint64_t bvh_triangles = 0;
};

/// One part of the estimate, the JSON field that lowers it most, and how.
struct CostPart {
  std::string name;    ///< e.g. "shadow-map fill"
  double ms = 0.0;     ///< estimated milliseconds on the reference machine
  std::string field;   ///< e.g. "shadow.map_size"
  std::string advice;  ///< e.g. "lower shadow.map_size or shadow.cascades"
};

struct RequestCost {
  CostFactors factors;
  /// Filter "exact" (not the exact or depth output): the path priced, the
  /// cheapest for the GL estimate_cost was asked about
  /// (exact_filter_paths(..., gl).best()), which the service takes.
  CertifiedPath exact_filter_path = CertifiedPath::Maps;
  /// Every part, in a fixed order; parts that do not apply are 0 ms.
  std::vector<CostPart> parts;
  /// Sum of the parts: the GL thread's and the ray cast's time together
  /// (they share the same cores).
  double total_ms = 0.0;
  /// Peak memory the request needs at once, bytes: output and read-back
  /// images, framebuffers, the shadow-map layers, the scene's mesh while it
  /// is uploaded, and the ray cast's per-pixel records and mesh BVHs.
  std::uint64_t peak_bytes = 0;

  /// The part with the most milliseconds.
  const CostPart& dominant() const;
  /// Over the memory budget: the field to lower, and how; empty: the
  /// renderer's rule (the shadow map's layers or the image, whichever is
  /// the larger share).
  std::string memory_field, memory_advice;
};

/// Counts the work `request` implies (it must be valid, as the request
/// parser guarantees). Plans the light's views as the renderer will.
CostFactors cost_factors(const RenderRequest& request);

/// Where the GL certifying filter "exact"'s frames runs: on llvmpipe, whose
/// maps and sliver marks the CPU draws, or a GPU, whose shaders draw them:
/// a quad per triangle and pass there costs about 1/25 of llvmpipe's, a
/// layer about 0.6 ms, and the machine's CPU casts its rays in about 0.45
/// of the time priced (one H100 machine's measurements, request_cost.cpp).
enum class CertifyingGl { Llvmpipe, Gpu };

/// The estimate: cost_factors priced by the calibration in request_cost.cpp;
/// filter "exact"'s part on the path `gl` takes.
RequestCost estimate_cost(const RenderRequest& request, CertifyingGl gl = CertifyingGl::Llvmpipe);

/// Filter "exact" on the reference machine (llvmpipe): what each way of
/// certifying a frame (CertifiedPath, plan/frame_plan.hpp) costs beyond
/// the main pass they share (docs/certified-shadows.md, "Choosing the
/// path"). There the conservative maps and the sliver marks are drawn on
/// the CPU (ShadowRenderer::set_certified_passes_on_cpu) for scenes of up
/// to kMostConservativeTriangles: the maps cost each view's centre pass and
/// CPU fill (a quarter of the layer's texels) and a setup per triangle, and
/// the main pass's certificate a little per triangle (a model's many small
/// ones cost most); the sliver marks next to nothing. A heavier scene's
/// passes are a geometry shader's quad per triangle
/// (kMsPerConservativeTriangle), twice per view for the maps and once for
/// the sliver pass. The ray cast is priced as the exact output's
/// (ray_cast_ms, whose calibration leans high) times kRayCastShare, what
/// the bench scenes measured of it.
/// - maps: the maps, the sliver marks, and the ray cast of the pixels the
///   maps leave (a twentieth of the frame's, about the bench scenes'
///   median);
/// - proofs: the sliver marks, and the ray cast of the pixels that are not
///   proved plane parts: the objects' share of the camera's image (their
///   bounds' depth complexity, planes aside) and twice as much again for
///   the bands about their shadows, at most all;
/// - ray cast: every pixel's.
struct ExactFilterPaths {
  double maps_ms = 0.0;
  double proofs_ms = 0.0;
  double ray_cast_ms = 0.0;
  /// The cheapest; Maps on a tie.
  CertifiedPath best() const;
};
ExactFilterPaths exact_filter_paths(const RenderRequest& request, CertifyingGl gl = CertifyingGl::Llvmpipe);

/// A sun-hours analysis (POST /api/sun-hours), by the faster of its two
/// paths: the pure ray cast (one shadow ray per point and sample with the
/// sun up: `sun_up_share` of the samples, core/sun_hours.hpp) or the
/// footprints (each object's footprint per sample, and a ray only for the
/// pairs `shares` says are left to the query, after a proof of dark for
/// those inside a footprint; reference/sun_hours_footprints.hpp). A ray is
/// priced by the objects its traversal tests: the tree's depth plus the
/// footprints holding it (FootprintShares::depth: a thousand objects
/// stacked at one spot are a thousand tests). Both add the sun's positions
/// and the models' BVHs; with include_samples, the samples' text. Peak
/// memory: the tallies (and the footprints' per-point records), the
/// samples, the BVHs and the answer's text.
struct SunHoursCost {
  RequestCost cost;        ///< of the path chosen
  bool footprints = true;  ///< the path chosen
  double ray_cast_ms = 0;  ///< the pure ray cast's estimate, for comparison
};
SunHoursCost estimate_sun_hours_cost(const SunHoursRequest& request, std::size_t samples, double sun_up_share,
                                     const FootprintShares& shares);

/// A sun-hours request's plan: the path the service will run and its cost.
struct SunHoursPlan {
  SunHoursCost estimate;
  std::size_t samples = 0;
};
/// The plan from a few hundred of the period's samples (probe_samples:
/// the sun's share of the period) and, at 32 of them with the sun up, the
/// footprints path simulated on a lattice of the grid (footprint_shares).
/// Cheap: what submit_sun_hours runs before it queues anything.
SunHoursPlan plan_sun_hours(const SunHoursRequest& request);

/// Triangles tessellate() makes for `scene` (without building the mesh).
std::uint64_t scene_triangles(const Scene& scene);

/// Fraction of a view's image the object's bounds cover, summed over the
/// objects: the view's mean depth complexity. `view_projection` maps world
/// to clip space; bounds reaching behind a perspective eye count as
/// covering the whole view.
double depth_complexity(const Scene& scene, const glm::dmat4& view_projection);

/// What a view rasterises beyond depth_complexity: a mesh object's bounds
/// cover its share of the view once, but its triangles may lie many layers
/// deep within them.
struct ViewLayers {
  /// Summed over mesh objects: the share of the view their bounds cover
  /// times the layers of their triangles past the first. A mesh's layers
  /// are its triangles' projected area (projected_area, model.hpp) over its
  /// bounds' (a parallelepiped's), both along the direction from the eye
  /// to it (an orthographic view's direction); for bounds around a
  /// perspective eye, the most over 13 directions and the view's. Half
  /// the area for a closed model whose faces the view culls.
  double mesh_overdraw = 0.0;
  /// The most layers of any one mesh object that the view reaches.
  double deepest_mesh = 0.0;
};
ViewLayers view_layers(const Scene& scene, const glm::dmat4& view_projection, bool closed_faces_culled);

}  // namespace umbra
