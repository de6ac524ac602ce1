// A model's shells (triangles joined through shared corners), boxes
// around groups of them, and the cores of a closed model's shells: boxes
// that lie inside the volume a shell encloses, clear of its every triangle
// by a margin. A line through such a box crosses the shell on both sides
// of it, so a ray that passes through the box meets the surface past it,
// whatever else is there: sun hours' footprints and proofs of dark for
// models (reference/sun_hours_footprints.hpp), as an object's bounds and
// ShapeKind::points_inside are for the analytic solids. Model space, pure
// CPU code, no GL.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/model.hpp"
#include "core/scene.hpp"

namespace umbra {

/// Per triangle (parts in order, each's triangles in order) its corners'
/// welded ids: one per distinct position (equal as numbers: -0 is 0, as
/// Embree sees them), numbered in order of position. `ids` is set to how
/// many.
std::vector<std::array<std::uint32_t, 3>> welded_corners(const TriangleModel& model, std::uint32_t& ids);

/// Which shell each triangle of the model is in (parts in order, each's
/// triangles in order): triangles that share a corner (welded by exact
/// position) are in one; numbered from 0 in order of first triangle, and
/// `shells` is set to how many.
std::vector<std::uint32_t> triangle_shells(const TriangleModel& model, std::uint32_t& shells);

/// Boxes of model space around groups of the model's triangles, what sun
/// hours' footprints are drawn from: far tighter than the one box around
/// a model that is many things (a city's buildings in one file) or round
/// (a teapot). A group is a shell (`shell_of`, triangle_shells: a
/// building); with more than `most` shells, the shells are halved at the
/// median of their boxes' centres along the longest side, and the halves
/// again (at most `most` groups, a power of 2); with fewer than `fewest`,
/// the group of most triangles is halved at the median of its triangles'
/// centres, until there are `fewest` (or single triangles). Every triangle
/// lies in exactly one group, so the boxes together hold the whole
/// surface. Empty for a model without triangles. O(triangles x log).
std::vector<Aabb> shell_clusters(const TriangleModel& model, const std::vector<std::uint32_t>& shell_of,
                                 std::uint32_t shells, int fewest, int most);

/// Per shell of the model that closes up (triangles joined through shared
/// corners, welded by value; every edge of the shell run both ways by its
/// triangles, once each, those with two equal corners left out), at most
/// one box of model space that lies inside the volume the shell encloses
/// with every point at least `margin` from each of the shell's triangles.
/// The rest of the model may be open (a city file with one building not
/// watertight): a line through the box crosses this shell whatever else
/// is there. A box is proved, not guessed: no triangle of the shell comes
/// within `margin` of it (separating axes, in double) and its centre is
/// inside (an odd number of crossings along a ray, none of them near an
/// edge or grazing, by a band that follows the crossing's own rounding).
/// Candidates are the shell's bounds shrunk by twice the margin (a box
/// fills them), then shrunk about their centre and about the middle of
/// their floor (a pitched roof over walls), largest first; a shell none of
/// them fits has none. Time at most about kShellCoreWork passes over the
/// triangles (the candidates not yet tried then are left out, as are
/// shells above kShellCoreMaxTriangles: their cost, not their shape).
///
/// With `open_floors`, a shell also has one when it is open only along
/// edges at its lowest height (a building without its ground face, as city
/// files and exports often write them), closed by a floor there: then the
/// box is proved only for rays that rise (model space), which leave it
/// through the shell, never through the floor below.
std::vector<Aabb> shell_cores(const TriangleModel& model, double margin, bool open_floors = false);

/// The largest shell shell_cores looks into, and how many passes over the
/// model's triangles it spends at most.
inline constexpr std::size_t kShellCoreMaxTriangles = 200000;
inline constexpr int kShellCoreWork = 16;

}  // namespace umbra
