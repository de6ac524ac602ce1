// The exact shadow of a mesh on a horizontal grid, one sun direction at a
// time: for each grid row, the columns whose rays surely meet the mesh
// (dark), those too near the shadow's edge to say (unsure: left to the
// ray cast) and, by omission, those whose rays surely miss it (lit as far
// as this mesh goes). Sun hours' footprints use it for models with open
// surfaces (a teapot: no closed shell, so no core proves a ray dark), whose
// every footprint pair was a ray through Embree before.
//
// How: each triangle, slid down the sun onto the grid's plane, covers the
// points whose rays meet it. The triangles turned one way count +1 inside
// their outlines, the others -1 after each is walked in the same turning
// sense on the plane, so that the winding number of the triangles' edges
// summed, where the edges shared by two triangles that cover opposite
// sides of them cancel, counts how many cover a point (Σ over triangles,
// every term the same sign). What remains to walk per row is the shadow's
// outline: the edges between a triangle facing the sun and one facing
// away (the silhouette), the open edges, and the cut where triangles cross
// the plane. Triangles are grouped into leaves of nearby ones with the
// cone of their normals, so a leaf wholly facing one way is one test and
// its inner edges none.
//
// Why the answers are proofs (docs/sun-hours.md): a point more than the
// margin (slid onto the plane) from every outline edge, where the count is
// not zero, lies inside the union of triangles that lie above the plane by
// the margin, so the ray that the ray cast casts in float from it passes
// through a triangle or an edge shared by two of them, and Embree's edge
// tests, watertight (RTC_SCENE_FLAG_ROBUST), pass one; where the count is
// zero, its line passes every counted triangle by more than its rounding.
// Embree's depth test (t from a float dot product) is not watertight: near
// the ray's origin, on a face nearly along the ray, a hit's side is noise,
// so each triangle's slice within its own slab of the plane (the margin
// over its cosine with the sun, and more for a sliver) is unsure, above
// the plane and below it. Triangles seen edge on or without area are left
// out of the count and their whole shadows are unsure, wherever they are.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "core/model.hpp"
#include "core/sun_hours.hpp"
#include "reference/column_spans.hpp"

namespace umbra {

/// A model's triangles as its grid shadows need them, found once per model
/// (O(triangles x log)): corners welded by exact position, each triangle's
/// unit normal, the edges with the triangles that run them, and leaves of
/// at most kMeshShadowLeaf nearby triangles with the cone of their normals.
struct MeshShadowModel;
inline constexpr int kMeshShadowLeaf = 64;
std::shared_ptr<const MeshShadowModel> mesh_shadow_model(const TriangleModel& model);
/// Bytes it holds.
std::size_t mesh_shadow_model_bytes(const MeshShadowModel& model);
/// Triangles it holds (degenerate ones too).
std::size_t mesh_shadow_model_triangles(const MeshShadowModel& model);

/// One sample's shadow of a mesh on the grid: for each row drawn, its dark
/// spans and its unsure spans (each sorted and merged; none in common).
struct GridShadow {
  int first_row = 0, last_row = -1;  ///< rows with spans: [first_row, last_row]
  /// Per row r of [first_row, last_row] (r - first_row), where its spans
  /// start in `dark` / `unsure`; one entry more at the end.
  std::vector<std::uint32_t> dark_start, unsure_start;
  std::vector<ColumnSpan> dark, unsure;
  /// What drawing it cost, in units of about one triangle judged or one
  /// edge slid: what the cost model prices the drawing by.
  double work = 0.0;
  bool empty() const { return last_row < first_row; }
  const ColumnSpan* dark_of(int r, std::size_t& count) const {
    const std::size_t i = std::size_t(r - first_row);
    count = dark_start[i + 1] - dark_start[i];
    return dark.data() + dark_start[i];
  }
  const ColumnSpan* unsure_of(int r, std::size_t& count) const {
    const std::size_t i = std::size_t(r - first_row);
    count = unsure_start[i + 1] - unsure_start[i];
    return unsure.data() + unsure_start[i];
  }
};

/// A placement of a model over the grid's plane (y = plane_y): its
/// corners' heights in the world, and each node's lowest and highest.
/// `margin` (world units) covers the ray cast's rounding:
/// the pure query tests its rays in float in the model's space
/// (sun_hours_footprints' caster margin).
class MeshGridShadow {
 public:
  /// With `slots` memories (see draw).
  MeshGridShadow(std::shared_ptr<const MeshShadowModel> model, const glm::dmat4& to_world, double plane_y,
                 double margin, int slots = 0);
  /// The memories hold about `bytes` at most between them (0, as at
  /// first: no bound); past it, slots not started yet draw fresh.
  void set_memory_budget(std::size_t bytes) { memory_budget_ = bytes; }
  /// Bytes the memories hold now.
  std::size_t memory_bytes() const { return memory_held_->load(); }
  ~MeshGridShadow();
  MeshGridShadow(MeshGridShadow&&) noexcept;
  /// The shadow along the unit sun direction d (d.y > 0) on the rows of
  /// `grid` that are multiples of row_step (the others get no spans).
  /// With a slot in [0, slots), the draw keeps what it judged in that
  /// slot's memory, and the next draws there while the sun stays within a
  /// few degrees re-judge only the triangles that may have turned since
  /// (a day's samples a minute apart: a tenth of them); the spans are the
  /// same either way. A slot is one thread's at a time; without one,
  /// draw is safe from any number of threads. A draw far from the slot's
  /// last (more than half the drift) draws fresh, unless `start_when_far`
  /// (the caller's next draws there will be near this one): then it
  /// starts the slot's memory afresh at d. A draw that would gather
  /// more than `most_gathered` row crossings and unsure entries (0: about
  /// a million, 16 bytes each), besides twice the grid's rows, takes the
  /// whole slid box of the model as unsure instead: bounded memory.
  void draw(const glm::dvec3& d, const SunGrid& grid, int row_step, GridShadow& out, int slot = -1,
            std::size_t most_gathered = 0, bool start_when_far = false) const;
  /// The world box of the model's corners: a shadow whose slide of it
  /// misses the grid holds no point of it.
  const Aabb& reach() const { return reach_; }

 private:
  // Corner i of the model in the world.
  glm::dvec3 corner(std::uint32_t i) const;

  std::shared_ptr<const MeshShadowModel> model_;
  glm::dmat4 to_world_;
  glm::dmat3 to_model_;  // the linear part: sun directions into model space
  double plane_y_, margin_;
  std::vector<std::uint8_t> height_; // per corner: 0 below the plane less the margin, 1 near, 2 above plus the margin
  // Per corner, its height in the world; per node, its triangles' lowest
  // and highest; how unevenly the placement stretches (largest over
  // smallest scale), which the depth test's rounding grows with.
  std::vector<double> corner_y_, node_low_, node_high_;
  double stretch_ = 1.0;
  double scale_ = 1.0;  // its three scales summed: a bound on the largest
  Aabb reach_;
  struct Memory;  // what a slot keeps between draws (mesh_grid_shadow.cpp)
  mutable std::vector<std::unique_ptr<Memory>> memory_;
  std::size_t memory_budget_ = 0;
  std::unique_ptr<std::atomic<std::size_t>> memory_held_;  // bytes the memories hold
};

}  // namespace umbra
