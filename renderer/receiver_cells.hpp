// Where on a floor the shadow map can darken anything.
//
// On llvmpipe every pixel of a draw runs every instruction of its shader,
// whichever way its branches go (the lanes an `if` masks off still run it),
// so a floor's pixels far from every caster paid for the whole shadow
// lookup only to find themselves lit: on the default scene, 95 % of the
// frame. The main pass therefore draws each plane that casts nothing as a
// grid of cells, cut along the edges of the regions where a point can read
// a caster's texel: those cells with the shadow program, the others with
// the program that has no shadow term. Their pixels come out as they would
// have (a point that reads no caster's texel is lit), for a fraction of the
// cost. No GL here.
#pragma once

#include <cstdint>
#include <vector>

#include "light_math.hpp"
#include "scene.hpp"

namespace umbra {

/// The most regions plane_cells keeps apart (more are merged): at most
/// (2 * kMaxReceiverRegions + 1)^2 cells, two triangles each.
inline constexpr int kMaxReceiverRegions = 6;

/// The part of the horizontal plane at world height `y` that `view` holds
/// (within its near and far planes, a hair wider for rounding) where the
/// point's texel in the view's layer (layer_size^2) lies within `rect`: its
/// world x/z bounds (min.y = max.y = y); empty if there is none.
Aabb view_rect_on_plane(const ShadowView& view, int layer_size, const TexelRect& rect, double y);

/// Where on the horizontal plane at height `y` a point may read a texel
/// that a caster covers in some view of `light`, reading up to
/// `margin_texels` around its own texel: one x/z box per view and caster
/// that meet. `rects`: each caster's texels in each view
/// (CasterTexels::by_object).
std::vector<Aabb> shadowable_regions(double y, const ShadowPlan& light,
                                     const std::vector<std::vector<TexelRect>>& rects, double margin_texels);

/// The same around `view_rects`, one per view of `light` (CasterTexels::
/// by_view: around all of its casters at once): looser than one region per
/// caster, and as cheap for a thousand casters as for one.
std::vector<Aabb> view_regions(double y, const ShadowPlan& light, const std::vector<TexelRect>& view_rects,
                               double margin_texels);

/// A horizontal plane cut into a grid of cells.
struct PlaneCells {
  /// World x and z of the cells' sides, ascending; the first and last are
  /// the plane's own sides.
  std::vector<double> x_cuts;
  std::vector<double> z_cuts;
  /// Per cell, x fastest (cell (i, j) at j * (x_cuts.size() - 1) + i):
  /// whether a point in it may be shadowed.
  std::vector<bool> shadowable;
};

/// `plane`'s bounds cut along the sides of `regions` (x/z boxes, as
/// shadowable_regions gives): a cell is shadowable where it lies in one.
/// Regions are clipped to the plane, overlapping ones merged, and past
/// kMaxReceiverRegions the two whose merged box grows least are merged, so
/// a cell may be marked shadowable needlessly, never the other way.
PlaneCells plane_cells(const Aabb& plane, std::vector<Aabb> regions);

/// Cells' triangles for the main pass, positions relative to a mesh origin.
struct CellTriangles {
  std::vector<Vertex> vertices;
  std::vector<std::uint32_t> shadowable;    ///< indices of the shadowable cells
  std::vector<std::uint32_t> unshadowable;  ///< and of the others
};

/// Appends `cells` of the plane at height `y` to `out`: each cell two
/// triangles wound as tessellate() winds a plane (facing +y), so that
/// gl_FrontFacing tells the sides apart as before.
void append_cell_triangles(const PlaneCells& cells, double y, const glm::dvec3& color, const glm::dvec3& origin,
                           CellTriangles& out);

}  // namespace umbra
