// A model's convex patches: groups of its triangles that lie on the surface
// of one convex body, each triangle wholly on or behind the plane of every
// other (behind: against its counter-clockwise normal, the outward side).
// Filter "exact" gives a patch one owner in its maps (docs/certified-
// shadows.md, "Owners"): a ray that leaves a point of one of the patch's
// triangles towards a light on that triangle's outward side enters the
// open half-space in front of it, and every other triangle of the patch
// lies in the closed half-space behind, so the patch cannot shadow its own
// points that face the light. Per-triangle owners leave every pixel near a
// triangle's edge to the ray cast (its neighbour is another owner there);
// a patch leaves only its own border. Model space, pure CPU code, no GL.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/model.hpp"

namespace umbra {

/// The most triangles in one patch: each candidate is tested against every
/// member, so this bounds the work (at most about 6 x this many plane tests
/// per triangle) and how far one patch spreads.
inline constexpr std::size_t kMostPatchTriangles = 48;

/// How far a corner may lie in front of another triangle's plane and still
/// count as behind it: this fraction of its distance from that triangle's
/// corner (the double rounding of the test itself is about 1e-15 of it),
/// so at most about 2e-9 of the model's extent. Sound with room to spare,
/// in model space, where the reference casts: it starts a shadow ray off
/// the surface by 256 float steps of each coordinate (offset_off_surface:
/// at least about 1e-7 of the extent), and a ray towards a light on the
/// triangle's outward side only climbs from there. Heights above a plane
/// compare the same after any affine map, so a placement's scale, even a
/// different one per axis, changes nothing.
inline constexpr double kPatchPlaneTolerance = 1e-9;

/// A model of more triangles than this gets patches of one triangle each
/// (per-triangle owners): finding patches holds about 100 bytes per
/// triangle while it runs, and a layer this heavy is drawn by the shaders
/// anyway (kMostConservativeTriangles).
inline constexpr std::size_t kMostPatchedModelTriangles = 262144;

/// Per triangle of the model (parts in order, each's triangles in order):
/// the first triangle of its convex patch, in the same numbering. Patches
/// grow breadth first from their first triangle through edges shared with
/// it (corners welded by exact position, welded_corners), taking a
/// neighbour only if it and every member lie behind each other's planes
/// (within kPatchPlaneTolerance), up to kMostPatchTriangles. A triangle
/// without area is a patch of its own, as is every triangle of a model
/// above kMostPatchedModelTriangles. Deterministic: the same model gives
/// the same patches.
std::vector<std::uint32_t> convex_patches(const TriangleModel& model);

}  // namespace umbra
