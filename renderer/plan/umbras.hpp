// Where a floor is certainly dark under a light of no size (a direction,
// or a point), and where it is certainly lit.
//
// On llvmpipe a floor's shadow lookups are most of a shadowed frame's cost
// (scattered texel reads that miss the cache), and a lookup costs the same
// whatever it finds. But much of a floor needs none:
// - A point whose segment to the light passes through a box or sphere is
//   dark in the exact reference. Taken far enough inside that every texel
//   the filter reads around it sees the object, the lookup would say 0
//   there too (umbras_on_plane).
// - A point none of whose texels sees any object is lit (shadow_bounds_
//   on_plane: outside the shadows of the objects' grown bounds).
// The main pass draws the first with the program that has no direct light,
// the second with the one that has no shadow term, and runs the lookup
// only in between (run_display_pass). Pixels come out as the lookup would
// have drawn them, but for one kind: at a box's foot the map holds the box's
// back faces (front faces are culled in the shadow pass), which meet the
// floor, so the lookup lets light leak into the umbra there; drawn dark,
// those pixels are as the exact reference has them. No GL here.
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include <glm/vec3.hpp>

#include "core/light_math.hpp"
#include "plan/receiver_cells.hpp"
#include "core/request.hpp"
#include "core/scene.hpp"

namespace umbra {

/// The most umbras umbras_on_plane gives (the others are left to the
/// lookup, which draws them just as dark).
inline constexpr std::size_t kMaxUmbras = 64;
/// The most objects besides the plane whose shadow bounds
/// shadow_bounds_on_plane finds (past that, the plane keeps its cells).
inline constexpr std::size_t kMaxShadowBoundsObjects = 64;

/// Points whose convex hull lies inside `object` shrunk by `margin` world
/// units on every side and between world heights `low` and `high`: a
/// box's corners (boxes turn about y only, so the shrunk box cut to the
/// slab is a box), rings on a sphere's shrunk surface. None for planes and
/// meshes, or where nothing is left.
std::vector<glm::dvec3> points_inside(const SceneObject& object, double margin, double low, double high);

/// The umbras on the plane object whose world bounds are `plane` (a
/// horizontal rectangle at height plane.min.y), seen from above: for each
/// box and sphere of `objects`, a convex polygon (counter-clockwise in x/z)
/// of points that the object hides from `light`, taken so far inside the
/// object's shadow that every texel within `reach_texels` of the point's
/// own, in whichever view the main pass reads it from, sees the object in
/// front of the plane. Cut to the plane's rectangle; at most kMaxUmbras.
/// None when the light is not above the plane.
///
/// - How far inside: the object is shrunk by `reach_texels` texels' world
///   size (times sqrt 2, the texel square's corner) where it meets the
///   light's rays (orthographic: the largest texel of the views that may
///   serve the umbra, up to the first that holds all of it with the reach
///   to spare; perspective: a texel's angle times the object's farthest
///   point from the light), so that any ray that close to one through the
///   shrunk object passes through the object.
/// - None for an object that a view which may serve its umbra cuts with its
///   near plane (that view's layer lacks part of it), nor for one whose
///   shadow a single view (the seeds' fixed light box, or a cone) does not
///   hold all of with the reach to spare: the lookup reads nothing there.
/// - None when the light grazes the plane by less than a microradian.
/// - Under a point light, an object reaching up past 3/4 of the light's
///   height above the plane is cut there: its shadow reaches 4 times the
///   light's height out, not to infinity.
///
/// With `world_margin` > 0 the object is shrunk by at least that many world
/// units; with `reach_texels` 0 by exactly that, and no view is asked
/// anything (filter "exact" proves umbras dark by geometry alone, whatever
/// the maps hold: frame_plan.cpp's proved plane parts).
std::vector<PlanePolygon> umbras_on_plane(const Aabb& plane, const ShadowPlan& light,
                                          const std::vector<SceneObject>& objects, double reach_texels,
                                          double world_margin = 0.0);

/// Where on the plane object `plane_object`, whose world bounds are
/// `plane`, the lookup can find anything: for every other object, the
/// shadow of its bounds (`bounds`, one per object) grown on every side by
/// `reach_texels` texels' world size (times sqrt 2), cast from the light
/// onto the plane: convex polygons, counter-clockwise in x/z, cut to the
/// plane's rectangle. A point outside all of them reads only texels whose
/// rays meet no object: the lookup finds it lit, whatever the light's size.
/// The texel is the largest of the views that may serve the shadow (as
/// umbras_on_plane takes it); for a perspective light, a texel's angle
/// times the object's farthest corner from the light.
/// - What lies at or above a point light's height is on no ray down from
///   it. The shadow of what lies just below it reaches ever further out:
///   the bounds are cut where theirs would fall four times further from
///   the light's foot than any of the plane.
/// - The bounds grow by at least `world_margin` world units (filter
///   "exact": with `reach_texels` 0, by exactly that).
/// - None (leave the plane to plane_cells) when the light is not above the
///   plane (or grazes it by less than a microradian), when a point light's
///   foot is inside an object's grown bounds (its shadow surrounds the
///   foot), or past kMaxShadowBoundsObjects objects. An empty list: nothing
///   can shadow the plane.
std::optional<std::vector<PlanePolygon>> shadow_bounds_on_plane(const Aabb& plane, std::size_t plane_object,
                                                                const ShadowPlan& light, const std::vector<Aabb>& bounds,
                                                                double reach_texels, double world_margin = 0.0);

}  // namespace umbra
