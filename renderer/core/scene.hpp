// Scenes: the built-in ones, bounds, and the triangle meshes the GL passes draw.
// Pure CPU code, no GL: unit tested directly.
#pragma once

#include <algorithm>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/common.hpp>
#include <glm/vec3.hpp>

#include "core/request.hpp"

namespace umbra {

/// Axis-aligned box in world units. Empty when min > max.
struct Aabb {
  glm::dvec3 min{1e300};
  glm::dvec3 max{-1e300};

  bool empty() const { return min.x > max.x; }
  void extend(const glm::dvec3& p);
  void extend(const Aabb& other);
  glm::dvec3 center() const { return 0.5 * (min + max); }
  glm::dvec3 extent() const { return max - min; }
  /// The largest |coordinate| of its corners: how far from the origin it
  /// reaches along any axis.
  double reach() const {
    const glm::dvec3 far = glm::max(glm::abs(min), glm::abs(max));
    return std::max({far.x, far.y, far.z});
  }
  /// The 8 corners (for an empty box, unspecified): corner i takes max.x
  /// where bit 0 of i is set, max.y bit 1, max.z bit 2 (so corners i and
  /// i | bit share an edge).
  std::vector<glm::dvec3> corners() const;
};

/// Rotates v about +Y by `degrees`, counter-clockwise seen from above
/// (right-handed): the rotation a box's rotation_y_deg means.
glm::dvec3 rotate_y(const glm::dvec3& v, double degrees);

/// Tight world-space bounds of one object (a rotated box's rotated corners).
Aabb object_bounds(const SceneObject& object);
/// The largest |coordinate| of `box` relative to `origin` (0 if empty): the
/// scale of the float rounding of its corners there.
double largest_coordinate(const Aabb& box, const glm::dvec3& origin);
Aabb scene_bounds(const Scene& scene);

/// A built-in scene: its objects and its own default camera and light.
struct BuiltinScene {
  std::string name;
  std::string description;
  std::vector<SceneObject> objects;
  glm::dvec3 camera_position;
  glm::dvec3 camera_target;
  glm::dvec3 light_position;
};

const std::vector<BuiltinScene>& builtin_scenes();
const BuiltinScene* find_builtin_scene(const std::string& name);

/// Default camera position/target and light position for a custom scene,
/// derived from its bounds so that every object is in view and the light
/// comes from the same direction as in the built-in scenes.
struct SceneViewDefaults {
  glm::dvec3 camera_position;
  glm::dvec3 camera_target;
  glm::dvec3 light_position;
  glm::dvec3 light_target;
};
SceneViewDefaults default_view_for(const Scene& scene);

/// Interleaved vertex as uploaded to GL.
struct Vertex {
  float position[3];  ///< relative to Mesh::origin
  float normal[3];
  float color[3];
};

/// A plane's triangles in Mesh::indices, and where the rest of the scene lies
/// against it: enough to tell, for any light, whether the plane can shadow
/// anything (plane_can_shadow in light_math.hpp).
struct PlaneRange {
  std::size_t object = 0;  ///< its index in Scene::objects (its triangles: Mesh::object_ranges)
  double height = 0.0;  ///< world y of the plane (planes are horizontal)
  glm::dvec3 color{0.0};  ///< its colour (the main pass may draw it in cells)
  /// The lowest and highest world y of every other object: its bounds, or
  /// for a mesh object its surface's (mesh_surface_bounds, tighter than a
  /// turned box); a scene of this plane alone has none (lowest > highest).
  double lowest_other = 1e300;
  double highest_other = -1e300;
};

/// One object's triangles in Mesh::indices.
struct ObjectRange {
  std::size_t object = 0;  ///< its index in Scene::objects
  std::uint32_t first_index = 0;
  std::uint32_t index_count = 0;
};

/// The whole scene as one vertex/index buffer. Closed meshes (boxes, spheres,
/// closed models) come first, then open ones (open models, then planes), so
/// each pass can cull them apart.
/// Positions are stored relative to `origin` (the bounds' centre, in double)
/// so a scene far from the world origin keeps float precision.
struct Mesh {
  glm::dvec3 origin{0.0};
  std::vector<Vertex> vertices;
  std::vector<std::uint32_t> indices;
  std::uint32_t closed_index_count = 0;  ///< indices [0, closed) are closed meshes
  std::uint32_t open_index_count = 0;    ///< then [closed, closed + open) open ones
  /// The planes, last in the open range, in the scene's order.
  std::vector<PlaneRange> planes;
  /// Each object's world bounds (object_bounds), in the scene's order.
  std::vector<Aabb> bounds;
  /// Each object's triangles, in index order (so that a pass can leave
  /// out what it need not draw).
  std::vector<ObjectRange> object_ranges;
  /// The longest edge of a closed mesh's triangle whose vertex normals
  /// differ (a sphere's, a smooth model's); 0 when every closed triangle is
  /// flat. Across such a triangle the interpolated normal turns, so whether
  /// a point of it faces a point light is known from its vertices only to
  /// within this distance (scene.vert's LIGHT_SIDE).
  double smooth_normal_span = 0.0;
};

Mesh tessellate(const Scene& scene);

/// Whether the camera sees every closed mesh from outside: no closed
/// object's bounds come within reach of the eye, the distance to the near
/// plane's corners (aspect = width / height). A closed mesh's faces look out
/// (is_closed), so from outside each face that looks away from the eye lies
/// behind one of its own faces that looks toward it: the main pass may cull
/// back faces, which spares shading pixels that are drawn over anyway. From
/// inside a box, or with the near plane cutting into one, its back faces are
/// what the camera sees.
bool closed_meshes_seen_from_outside(const Mesh& mesh, const Camera& camera, double aspect);

}  // namespace umbra
