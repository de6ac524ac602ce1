// Cores of a closed model's shells: boxes that lie inside the volume a
// shell encloses, clear of its every triangle by a margin. A line through
// such a box crosses the shell on both sides of it, so a ray that passes
// through the box meets the surface past it, whatever else is there: sun
// hours' proof of dark for models (reference/sun_hours_footprints.hpp), as
// ShapeKind::points_inside is for the analytic solids. Pure CPU code, no GL.
#pragma once

#include <cstdint>
#include <vector>

#include "core/model.hpp"
#include "core/scene.hpp"

namespace umbra {

/// Which shell each triangle of the model is in (parts in order, each's
/// triangles in order): triangles that share a corner (welded by exact
/// position) are in one; numbered from 0 in order of first triangle, and
/// `shells` is set to how many.
std::vector<std::uint32_t> triangle_shells(const TriangleModel& model, std::uint32_t& shells);

/// Per shell of a closed model (TriangleModel::closed; triangles joined
/// through shared corners, welded by exact position), at most one box of
/// model space that lies inside the volume the shell encloses with every
/// point at least `margin` from each of the shell's triangles. A box is
/// proved, not guessed: no triangle of the shell comes within `margin` of
/// it (separating axes, in double) and its centre is inside (an odd number
/// of crossings along a ray, none of them near an edge or grazing).
/// Candidates are the shell's bounds shrunk by twice the margin (a box
/// fills them), then shrunk about their centre and about the middle of
/// their floor (a pitched roof over walls), largest first;
/// a shell none of them fits has none. None for an open model.
/// Time O(triangles x candidates) at worst; shells above
/// kShellCoreMaxTriangles are left out (their cost, not their shape).
std::vector<Aabb> shell_cores(const TriangleModel& model, double margin);

/// The largest shell shell_cores looks into.
inline constexpr std::size_t kShellCoreMaxTriangles = 200000;

}  // namespace umbra
