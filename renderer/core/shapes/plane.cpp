// The plane: a horizontal rectangle facing +Y, `size` (sx, 0, sz) about
// `center`. Open (one face, never culled), and the floor that others
// shadow: tessellated last, each with its PlaneRange.
#include <cmath>
#include <limits>

#include "core/shapes/mesh_builder.hpp"
#include "core/shapes/shape.hpp"

namespace umbra {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

Aabb bounds(const SceneObject& o) {
  Aabb b;
  b.extend(o.center - glm::dvec3(o.size.x, 0.0, o.size.z) * 0.5);
  b.extend(o.center + glm::dvec3(o.size.x, 0.0, o.size.z) * 0.5);
  return b;
}

bool closed(const SceneObject&) { return false; }

void tessellate(const SceneObject& o, Mesh& mesh) {
  MeshBuilder{mesh}.quad(o.center, {0.5 * o.size.x, 0, 0}, {0, 0, -0.5 * o.size.z}, o.color);
}

std::uint64_t triangles(const SceneObject&) { return 2; }
std::uint64_t vertices(const SceneObject&) { return 4; }

double intersect(const SceneObject& o, const glm::dvec3& origin, const glm::dvec3& dir, double t_min, double t_max,
                 glm::dvec3& normal) {
  if (dir.y == 0.0) return kInf;
  const double t = (o.center.y - origin.y) / dir.y;
  if (!(t > t_min && t < t_max)) return kInf;
  const glm::dvec3 p = origin + t * dir;
  if (std::abs(p.x - o.center.x) > 0.5 * o.size.x || std::abs(p.z - o.center.z) > 0.5 * o.size.z) return kInf;
  normal = {0.0, 1.0, 0.0};
  return t;
}

}  // namespace

extern const ShapeKind kPlaneShape;  // listed in shapes.cpp
const ShapeKind kPlaneShape = {
    SceneObject::Type::Plane, "plane", bounds, bounds, closed, /*horizontal_plane=*/true, tessellate, triangles,
    vertices, intersect, /*points_inside=*/nullptr, /*tessellation_error=*/nullptr, /*surely_meets=*/nullptr, /*contains=*/nullptr,
};

}  // namespace umbra
