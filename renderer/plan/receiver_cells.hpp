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

#include <glm/vec2.hpp>

#include "core/light_math.hpp"
#include "core/scene.hpp"

namespace umbra {

/// The most regions plane_cells keeps apart (more are merged): their sides
/// cut the plane into at most (2 * kMaxReceiverRegions + 1)^2 cells, two
/// triangles each, before the lattice (kRefinedCuts) cuts it further: at
/// most 36^2 cells in all.
inline constexpr int kMaxReceiverRegions = 6;

/// A convex part of a horizontal plane: its corners' world (x, z), in
/// counter-clockwise order in those coordinates; a point or a segment if
/// it has no area.
using PlanePolygon = std::vector<glm::dvec2>;

/// The convex hull of `points`, counter-clockwise in (x, z), without
/// repeated or collinear points (fewer than three points come back as
/// they are, duplicates removed).
PlanePolygon convex_hull(std::vector<glm::dvec2> points);

/// The part of convex `polygon` with low <= (x, z) <= high.
PlanePolygon clipped(PlanePolygon polygon, const glm::dvec2& low, const glm::dvec2& high);

/// The area of a simple polygon (either winding).
double polygon_area(const PlanePolygon& polygon);

/// The world x/z bounds of `polygon` on the plane at height y (min.y =
/// max.y = y); empty for an empty polygon.
Aabb bounds_on_plane(const PlanePolygon& polygon, double y);

/// The part of the horizontal plane at world height `y` that `view` holds
/// (within its near and far planes, a hair wider for rounding) where the
/// point's texel in the view's layer (layer_size^2) lies within `rect`:
/// a convex polygon, empty if there is none. A rectangle of a cube face
/// beside a point light reaches across a floor as a wedge, whose bounding
/// box can be most of the floor.
PlanePolygon view_polygon_on_plane(const ShadowView& view, int layer_size, const TexelRect& rect, double y);

/// view_polygon_on_plane's bounds.
Aabb view_rect_on_plane(const ShadowView& view, int layer_size, const TexelRect& rect, double y);

/// Where on the horizontal plane at height `y` a point may read a texel
/// that a caster covers in some view of `light`, reading up to
/// `margin_texels` around its own texel: one polygon per view and caster
/// that meet. `rects`: each caster's texels in each view
/// (CasterTexels::by_object).
std::vector<PlanePolygon> shadowable_regions(double y, const ShadowPlan& light,
                                             const std::vector<std::vector<TexelRect>>& rects, double margin_texels);

/// The same around `view_rects`, one per view of `light` (CasterTexels::
/// by_view: around all of its casters at once): looser than one region per
/// caster, and as cheap for a thousand casters as for one.
std::vector<PlanePolygon> view_regions(double y, const ShadowPlan& light, const std::vector<TexelRect>& view_rects,
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

/// `plane`'s bounds cut into cells: a cell is shadowable where it meets one
/// of `regions` (as shadowable_regions gives).
/// - The regions' bounding boxes are clipped to the plane, overlapping ones
///   merged, and past kMaxReceiverRegions the two whose merged box grows
///   least are merged; the plane is cut along their sides.
/// - Merged boxes that their regions fill less than half of (wedges across
///   a floor) are cut further, along a lattice of kRefinedCuts steps across
///   them all, so that cells follow the regions more closely.
/// So a cell may be marked shadowable needlessly, never the other way.
PlaneCells plane_cells(const Aabb& plane, const std::vector<PlanePolygon>& regions);

/// The steps of plane_cells' lattice across the boxes that their regions
/// fill poorly: at most this many cuts more along each axis.
inline constexpr int kRefinedCuts = 24;

/// Cells' triangles for the main pass, positions relative to a mesh origin.
struct CellTriangles {
  std::vector<Vertex> vertices;
  std::vector<std::uint32_t> shadowable;    ///< indices of the shadowable cells
  std::vector<std::uint32_t> unshadowable;  ///< and of the others
  std::vector<std::uint32_t> dark;          ///< of the umbras (append_dark_triangles)
  std::vector<std::uint32_t> bounds;        ///< of the shadows of objects' bounds (shadow_bounds_on_plane)
};

/// Appends `cells` of the plane at height `y` to `out`: each cell two
/// triangles wound as tessellate() winds a plane (facing +y), so that
/// gl_FrontFacing tells the sides apart as before.
void append_cell_triangles(const PlaneCells& cells, double y, const glm::dvec3& color, const glm::dvec3& origin,
                           CellTriangles& out);

/// Appends `polygons` (convex, counter-clockwise in x/z) of the plane at
/// height `y` to out.vertices, and their triangles' indices to `indices`
/// (one of out's lists): fans wound as the cells are.
void append_polygon_triangles(const std::vector<PlanePolygon>& polygons, double y, const glm::dvec3& color,
                              const glm::dvec3& origin, CellTriangles& out, std::vector<std::uint32_t>& indices);

/// The same into out.dark (umbras_on_plane's polygons).
inline void append_dark_triangles(const std::vector<PlanePolygon>& polygons, double y, const glm::dvec3& color,
                                  const glm::dvec3& origin, CellTriangles& out) {
  append_polygon_triangles(polygons, y, color, origin, out, out.dark);
}

}  // namespace umbra
