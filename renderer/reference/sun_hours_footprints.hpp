// Sun hours by footprints: a shadow map whose texels are the grid's own
// points. For each sun sample, each object's bounds are projected along
// the sun onto the grid's plane; a point outside every such footprint
// cannot see the object in the sun's direction, so it is lit, proved
// without a ray. The points inside a footprint are settled by the same
// query as the pure ray cast (sees_sun), so the hours equal the pure ray
// cast's at every point and sample, by construction (docs/sun-hours.md).
//
// Inside a footprint, a ray that passes well inside the object is dark for
// certain (ShapeKind::surely_meets: boxes, spheres and cylinders), so the
// query is skipped: the pure ray cast's query would meet that object. Where
// it is wide, the shadow of a solid's core (SolidCore) proves a whole
// stretch of each row dark at once. A model's footprints are drawn from
// clusters of its triangles (shell_clusters), and its shells that close
// up have cores too (shell_cores).
//
// Time is tallied by events: only a point's dark samples touch it, plus
// one pass over the grid per stretch of daylight, so that a grid mostly
// in the sun costs little more than its footprints.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <vector>

#include <glm/vec3.hpp>

#include "core/scene.hpp"
#include "core/sun_hours.hpp"

namespace umbra {

class RayScene;  // reference/ray_cast.hpp

/// Where an object's bounds can be met by a ray leaving the grid's plane
/// upwards: the bounds grown by a margin that covers every test's rounding
/// (the analytic shapes' in double, Embree's in float), and cut to the
/// plane's upper side. Empty: the object lies wholly below the plane.
Aabb reachable_bounds(const Aabb& bounds, double plane_y, double grid_reach);

/// The margin the footprints give an object over the grid: 1e-5 of the
/// magnitudes met (its bounds', the grid's points'), and for a model also
/// of its own coordinates times its largest scale (Embree tests the rays
/// in the model's float space): a hundred times every test's rounding.
double footprint_margin(const SceneObject& object, const SunGrid& grid);

/// Calls row_span(row, first_column, last_column) for each grid row that
/// the footprint of `bounds` (reachable_bounds) along the unit sun
/// direction (direction.y > 0) crosses, with the columns it covers (and
/// those within a slack far above the rounding of this computation),
/// clamped to the grid and to rows [first_row, last_row); with `row_step`,
/// only the rows that are multiples of it.
void footprint_spans(const Aabb& bounds, const glm::dvec3& direction, const SunGrid& grid, int first_row,
                     int last_row, const std::function<void(int row, int first_column, int last_column)>& row_span,
                     int row_step = 1);

/// A part of a solid that a ray from the grid's plane surely meets: points
/// whose hull lies inside the solid shrunk by `margin` and above the plane
/// by `margin`. A ray from the plane whose line passes through that hull
/// meets the solid past it: for an analytic solid it passes through the
/// shrunk solid past t = margin (ShapeKind::surely_meets holds); for a
/// model the hull lies inside a shell that closes up (shell_cores), which
/// the ray then crosses on its way out.
struct SolidCore {
  std::vector<glm::dvec3> points;  ///< world space, at most 128
  Aabb model_box;                  ///< a model's: the shell's core in model space; else empty
};
/// The cores of an object: one for a box, sphere or cylinder
/// (ShapeKind::points_inside), one per shell core of a model
/// (shell_cores, with `margin` / its smallest scale in model space, cut
/// to the plane's side), none for anything else or where nothing is left.
std::vector<SolidCore> solid_cores(const SceneObject& object, double plane_y, double margin);

/// Calls row_span(row, first_column, last_column) for each grid row of
/// [first_row, last_row) with the columns whose points lie inside the
/// core's shadow along the unit sun direction by a slack far above the
/// rounding: every such point's ray surely meets the object (the walk
/// settles them dark without a proof each).
void core_spans(const SolidCore& core, const glm::dvec3& direction, const SunGrid& grid, int first_row,
                int last_row, const std::function<void(int row, int first_column, int last_column)>& row_span);

/// What the footprints path would meet, per (point, sample) pair, averaged
/// over `directions` (each with y > 0), judged on a lattice of at most
/// about 128 x 128 of the grid's points: what the cost model prices the
/// path and the rays by.
struct FootprintShares {
  /// Left to the query: inside a footprint and not surely dark.
  double queried = 0.0;
  /// Inside any footprint, not inside a solid and not in a core's shadow
  /// (SolidCore): each judged for a proof of dark.
  double candidates = 0.0;
  /// Footprints holding a pair outside the cores' shadows (those the walk
  /// visits one by one), on average over all pairs.
  double depth = 0.0;
  /// Rows of the grid that the drawn cores' shadows cross, per sample:
  /// each a span merged and compared with the last sample's, and the
  /// points that enter or leave it touched.
  double core_rows = 0.0;
  /// Models whose footprints hold a pair (outside every core's shadow), on
  /// average over all pairs: the models a ray of the pure ray cast meets
  /// the bounds of, each a traversal of its own tree.
  double mesh_depth = 0.0;
  /// Objects a pair's ray is tested against besides the tree's levels and
  /// one more, on average over all pairs: every other object whose bounds
  /// it passes through, or none where some object surely meets it (its
  /// first hit ends a shadow ray).
  double tests = 0.0;
  /// The same, over the pairs left to the query only.
  double queried_tests = 0.0;
  /// Hulls drawn per sample: the objects' footprints (a model's clusters
  /// each, shell_clusters) and the solids' cores.
  double hulls = 0.0;
  /// Triangles of the models whose clusters and shells are found once per
  /// request (triangle_shells, shell_clusters, shell_cores), those of a
  /// model with open surfaces twice (its mesh_shadow_model too).
  double model_triangles = 0.0;
  /// The mesh shadows' drawing per sample (MeshGridShadow, for models with
  /// open surfaces), in GridShadow::work units.
  double mesh_shadow_work = 0.0;
};
/// The shares for `directions`, in turn until about 16 M units of work (a
/// lattice point visited in a footprint, 16 for a proof of dark), so the
/// plan's time stays bounded however many objects overlap; at least the
/// first direction is judged.
FootprintShares footprint_shares(const Scene& scene, const SunGrid& grid, const std::vector<glm::dvec3>& directions);

/// Samples at most this far apart (seconds) draw their mesh shadows from a
/// memory of the last sample (the sun turns about 1.5 degrees in six
/// minutes, half a memory's drift); further apart, from a memory per time
/// of day (mesh_memory_day_slots) or fresh.
inline constexpr double kMeshMemoryMostStepSeconds = 360.0;

/// How many memories per time of day the walk's mesh shadows keep for
/// samples `step_seconds` apart, `samples` of them: where steps are longer
/// than six minutes (the sun turns 1.5 degrees or more, too far for a
/// memory from one sample to the next) and the period more than a day that
/// holds a whole number of at least 32 steps, the steps of a day (the sun
/// at one time of day a day later is within half a degree); else 0 (the
/// memories follow runs of consecutive samples).
std::size_t mesh_memory_day_slots(double step_seconds, std::size_t samples);

/// ray_cast_sun_hours' answer, by footprints: fills result.tally,
/// result.samples_up, pairs, pairs_by_maps (outside every footprint, or
/// surely dark inside one) and pairs_ray_cast (the rest: one sees_sun
/// query each). On all hardware
/// threads, each a band of grid rows walking the samples in order;
/// `stop_requested` is asked between samples and every few thousand points
/// visited or rays cast (StopPoll), and once it answers true the cast
/// throws CastStopped.
void footprint_sun_hours(const RayScene& rays, const Scene& scene, const SunGrid& grid,
                         const std::vector<SunSample>& samples, SunHoursResult& result,
                         const std::function<bool()>& stop_requested = nullptr,
                        std::atomic<std::uint64_t>* pairs_done = nullptr);

}  // namespace umbra
