// Triangles covering a planar polygon with holes, as city models store
// their walls (a facade with its windows cut out) and roofs. Pure.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

namespace umbra {

struct PolygonTriangles {
  /// Three indices per triangle into the rings' points taken in order
  /// (ring 0's, then ring 1's...), wound as the outer ring runs (counter-
  /// clockwise seen from the side its Newell normal points to).
  std::vector<std::uint32_t> indices;
  /// Ear clipping could not finish (a ring crossing itself or another):
  /// the rest was covered by a fan from one of its corners.
  bool fell_back = false;
};

/// `rings[0]` is the outer boundary, the others holes in it; each a loop
/// of points, not closed (its last point is not its first again). Holes
/// are joined to the boundary by bridges to a vertex each can see, then
/// ears are clipped (Eberly, "Triangulation by Ear Clipping", 2002) in the
/// plane of the outer ring's Newell normal. No triangles for a polygon
/// without area.
PolygonTriangles triangulate_polygon(const std::vector<std::vector<glm::dvec3>>& rings);

}  // namespace umbra
