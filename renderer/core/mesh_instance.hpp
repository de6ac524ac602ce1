// Mesh objects: instances of a TriangleModel placed in a scene (position,
// rotation, scale, optional colour). Everything the renderer needs to know
// about that kind of object lives here: its transform, its bounds, its
// triangle counts and its triangles in tessellate()'s Mesh. Pure CPU code,
// no GL: unit tested in tests/test_scene.cpp.
#pragma once

#include <cstdint>

#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>

#include "core/request.hpp"
#include "core/scene.hpp"

namespace umbra {

/// Model space -> world space of a mesh object: translate(center) * Rz * Ry
/// * Rx * scale(mesh_scale), each rotation right-handed in degrees (the X
/// rotation applies first, as the API documents).
glm::dmat4 mesh_transform(const SceneObject& mesh);

/// The world bounds of a mesh object: the 8 transformed corners of its
/// model's bounds (not tight under rotation, but never too small, which is
/// what frustum fitting needs). Empty for a model without triangles.
Aabb mesh_bounds(const SceneObject& mesh);

/// The exact world bounds of a mesh object's transformed positions: under
/// rotation, mesh_bounds' turned box can reach well beyond the surface
/// (the torus-knot scene's reached below its floor). What tessellate()
/// tells planes about the objects around them (PlaneRange), where a box
/// too large would make a floor a caster for nothing. O(positions).
Aabb mesh_surface_bounds(const SceneObject& mesh);

/// Whether the model's surface is closed (TriangleModel::closed): only then
/// may the shadow pass cull its faces.
bool mesh_is_closed(const SceneObject& mesh);

/// How many layers deep the mesh's triangles lie within its bounds, seen
/// along world direction `direction` (any length, either sign): their
/// projected area (projected_area, model.hpp) over that of the model's box
/// as transformed (a parallelepiped). Stacked quads seen face on are as
/// many layers as quads; a closed convex model is 2 (1 with culling). 0
/// for a model without area. O(the model's area_vectors).
double mesh_layers_along(const SceneObject& mesh, const glm::dvec3& direction);

/// The most of mesh_layers_along over 13 directions (the cube's faces,
/// edges and corners) and `also` (unless zero): how deep the mesh may be
/// where no one direction stands for the view (an eye inside its bounds),
/// and what the renderer splits its draws by.
double mesh_deepest_layers(const SceneObject& mesh, const glm::dvec3& also = glm::dvec3(0.0));

std::uint64_t mesh_triangle_count(const SceneObject& mesh);
std::uint64_t mesh_vertex_count(const SceneObject& mesh);

/// Appends the instance's triangles to `out` (positions relative to
/// out.origin): normals by the inverse transpose, and the winding reversed
/// under a mirroring transform (negative determinant) so that
/// counter-clockwise still faces out. Indices only: the caller accounts for
/// them in closed_index_count / open_index_count.
void append_mesh_instance(const SceneObject& mesh, Mesh& out);

}  // namespace umbra
