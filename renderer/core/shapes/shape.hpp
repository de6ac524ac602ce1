// A shape kind is one file: its bounds, its tessellation, its exact ray
// intersection, what it costs and its name, in one row (ShapeKind) that
// the rest of the renderer calls through instead of switching on
// SceneObject::Type. Pure CPU code, no GL, no JSON.
//
// To add a kind: a value in SceneObject::Type, a file here defining its
// row, and the row in shapes.cpp's table.
#pragma once

#include <cstdint>
#include <string_view>
#include <vector>

#include <glm/vec3.hpp>

#include "core/request.hpp"
#include "core/scene.hpp"

namespace umbra {

/// ShapeKind::tessellation_error.
struct TessellationError {
  double distance = 0.0;  ///< world units
  double normal_angle = 0.0;  ///< radians
};

/// An exact ray intersection (ShapeKind::intersect).
using ShapeIntersect = double (*)(const SceneObject& object, const glm::dvec3& origin, const glm::dvec3& direction,
                                  double t_min, double t_max, glm::dvec3& normal);

/// What the renderer knows of one kind of SceneObject. Every function takes
/// an object of this kind (its `type` is the row's).
struct ShapeKind {
  SceneObject::Type type;
  /// The API's "type" value ("box"): unique among the rows.
  const char* name;
  /// Tight world-space bounds (object_bounds).
  Aabb (*bounds)(const SceneObject& object);
  /// Bounds of the surface itself: `bounds` for an analytic shape; for a
  /// turned model, tighter than its turned box (mesh_surface_bounds). What
  /// a plane's PlaneRange measures the other objects by.
  Aabb (*surface_bounds)(const SceneObject& object);
  /// Whether its tessellation is a closed surface whose faces look out:
  /// drawn in the closed range (Mesh::closed_index_count), its back faces
  /// culled where the pass allows.
  bool (*closed)(const SceneObject& object);
  /// A horizontal rectangle that others shadow (the plane): tessellated
  /// last, each with its PlaneRange, for the receiver cells and umbras.
  bool horizontal_plane;
  /// Appends its triangles to `mesh` (positions relative to mesh.origin).
  void (*tessellate)(const SceneObject& object, Mesh& mesh);
  /// How many triangles and vertices `tessellate` appends: the cost model's
  /// figures (request_cost).
  std::uint64_t (*triangles)(const SceneObject& object);
  std::uint64_t (*vertices)(const SceneObject& object);
  /// The exact intersection, in double: the nearest hit distance of
  /// origin + t * direction (unit) with t in (t_min, t_max), setting
  /// `normal` to the unit outward normal there; +infinity on a miss (normal
  /// untouched). Null for a triangle model: the reference layer casts those
  /// through Embree (reference/mesh_ray_cast.hpp), which core cannot call.
  ShapeIntersect intersect;
  /// Umbra support (plan/umbras.hpp points_inside): points whose convex
  /// hull lies inside the object shrunk by `margin` world units on every
  /// side and between world heights `low` and `high`; none where nothing is
  /// left. Null for a kind with no umbras (its shadow is left to the lookup).
  std::vector<glm::dvec3> (*points_inside)(const SceneObject& object, double margin, double low, double high);
  /// How far its tessellation departs from the exact surface the reference
  /// casts against: the farthest distance (world units) of a tessellated
  /// point from the true surface, and the largest angle (radians) between
  /// an interpolated normal and the true one. Null: none (flat faces, and a
  /// model, whose triangles are the surface). Filter "exact" allows for it
  /// (docs/certified-shadows.md).
  TessellationError (*tessellation_error)(const SceneObject& object);
  /// Whether origin + t * direction (unit), t > 0, certainly meets the
  /// object: it passes through the object shrunk by `margin` world units on
  /// every side, somewhere past t = margin. Then `intersect` (in double,
  /// whose rounding is far below any margin the callers give) finds a hit
  /// in (0, infinity) however its arithmetic falls, and the bounds around
  /// the object are met. False proves nothing. Null for a kind without one
  /// (a model, a plane). What sun hours settles dark pairs by without the
  /// full query (reference/sun_hours_footprints.hpp).
  bool (*surely_meets)(const SceneObject& object, const glm::dvec3& origin, const glm::dvec3& direction,
                       double margin);
  /// Whether `point` lies inside the object shrunk by `margin` world units
  /// on every side. Then every ray from it, in any direction, passes
  /// inside the object shrunk by margin / 2 past t = margin / 2
  /// (surely_meets with margin / 2 holds for all directions): a point of a
  /// closed convex solid's inside sees no sun. Null with surely_meets.
  bool (*contains)(const SceneObject& object, const glm::dvec3& point, double margin);
  /// Points whose convex hull holds every point within `margin` world
  /// units of the object at or above world height `low` (what a ray leaving
  /// the plane y = low upwards can meet); none where nothing is above. What
  /// sun hours draws an object's footprint from, tighter than its bounds
  /// for a turned box, a round pole or a ball. Null: the bounds stand for
  /// it.
  std::vector<glm::dvec3> (*points_around)(const SceneObject& object, double margin, double low) = nullptr;
};

/// Every kind, in SceneObject::Type order.
const std::vector<const ShapeKind*>& shape_kinds();
/// The row of `type`.
const ShapeKind& shape_kind(SceneObject::Type type);
/// The row's tessellation_error, or none.
TessellationError tessellation_error(const SceneObject& object);
/// The row named `name`, or null.
const ShapeKind* find_shape_kind(std::string_view name);

}  // namespace umbra
