// The box: `size` (sx, sy, sz) full edge lengths about `center`, turned
// `rotation_y_deg` about its vertical axis. Closed.
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "core/shapes/mesh_builder.hpp"
#include "core/shapes/shape.hpp"

namespace umbra {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

Aabb bounds(const SceneObject& o) {
  Aabb b;
  for (int i = 0; i < 8; ++i) {
    const glm::dvec3 local{(i & 1 ? 0.5 : -0.5) * o.size.x, (i & 2 ? 0.5 : -0.5) * o.size.y,
                           (i & 4 ? 0.5 : -0.5) * o.size.z};
    b.extend(o.center + rotate_y(local, o.rotation_y_deg));
  }
  return b;
}

bool closed(const SceneObject&) { return true; }

// Six quads, each facing out along one of the box's turned axes.
void tessellate(const SceneObject& o, Mesh& mesh) {
  MeshBuilder builder{mesh};
  const glm::dvec3 half = o.size * 0.5;
  const glm::dvec3 axes[3] = {rotate_y({1, 0, 0}, o.rotation_y_deg), {0, 1, 0},
                              rotate_y({0, 0, 1}, o.rotation_y_deg)};
  for (int k = 0; k < 3; ++k) {
    for (double sign : {1.0, -1.0}) {
      const glm::dvec3 n = axes[k] * sign;
      const int iu = (k + 1) % 3, iv = (k + 2) % 3;
      // u x v must equal n: (axes[iu] x axes[iv]) = axes[k] for a right-handed frame.
      const glm::dvec3 u = axes[iu] * half[iu];
      const glm::dvec3 v = axes[iv] * (half[iv] * sign);
      builder.quad(o.center + n * half[k], u, v, o.color);
    }
  }
}

std::uint64_t triangles(const SceneObject&) { return 12; }
std::uint64_t vertices(const SceneObject&) { return 24; }

double intersect(const SceneObject& o, const glm::dvec3& origin, const glm::dvec3& dir, double t_min, double t_max,
                 glm::dvec3& normal) {
  // In the box's own frame it is axis-aligned: the slab test.
  const glm::dvec3 o_local = rotate_y(origin - o.center, -o.rotation_y_deg);
  const glm::dvec3 d_local = rotate_y(dir, -o.rotation_y_deg);
  const glm::dvec3 half = 0.5 * o.size;
  double t0 = -kInf, t1 = kInf;
  int axis0 = 0, axis1 = 0;
  for (int k = 0; k < 3; ++k) {
    if (d_local[k] == 0.0) {
      if (std::abs(o_local[k]) > half[k]) return kInf;
      continue;
    }
    double a = (-half[k] - o_local[k]) / d_local[k];
    double b = (half[k] - o_local[k]) / d_local[k];
    if (a > b) std::swap(a, b);
    if (a > t0) t0 = a, axis0 = k;
    if (b < t1) t1 = b, axis1 = k;
    if (t0 > t1) return kInf;
  }
  double t = t0;
  int axis = axis0;
  if (!(t > t_min)) t = t1, axis = axis1;  // the origin is inside: the exit
  if (!(t > t_min && t < t_max)) return kInf;
  glm::dvec3 n_local(0.0);
  n_local[axis] = (o_local[axis] + t * d_local[axis]) > 0.0 ? 1.0 : -1.0;
  normal = rotate_y(n_local, o.rotation_y_deg);
  return t;
}

// Boxes turn about y only, so the shrunk box cut to the slab is a box: its
// 8 corners.
std::vector<glm::dvec3> points_inside(const SceneObject& object, double margin, double low, double high) {
  std::vector<glm::dvec3> points;
  const glm::dvec3 half = 0.5 * object.size - margin;
  const double bottom = std::max(object.center.y - half.y, low), top = std::min(object.center.y + half.y, high);
  if (!(half.x > 0.0 && half.y > 0.0 && half.z > 0.0 && bottom < top)) return points;
  for (int i = 0; i < 8; ++i) {
    const glm::dvec3 corner = rotate_y({i & 1 ? half.x : -half.x, 0.0, i & 2 ? half.z : -half.z}, object.rotation_y_deg);
    points.emplace_back(object.center.x + corner.x, i & 4 ? top : bottom, object.center.z + corner.z);
  }
  return points;
}

// The box grown by `margin` on every side (points_inside's box shrunk by
// -margin) holds the box's points within `margin`; cut at `low`, it stays
// a box (turned about y only). None where it only touches `low`: the box
// itself then lies below it.
std::vector<glm::dvec3> points_around(const SceneObject& object, double margin, double low) {
  return points_inside(object, -margin, low, kInf);
}

// The slab test against the box shrunk by `margin`: the ray is inside all
// three slabs together over an interval reaching past t = margin.
bool surely_meets(const SceneObject& o, const glm::dvec3& origin, const glm::dvec3& dir, double margin) {
  const glm::dvec3 o_local = rotate_y(origin - o.center, -o.rotation_y_deg);
  const glm::dvec3 d_local = rotate_y(dir, -o.rotation_y_deg);
  const glm::dvec3 half = 0.5 * o.size - margin;
  if (!(half.x > 0.0 && half.y > 0.0 && half.z > 0.0)) return false;
  double t0 = margin, t1 = kInf;
  for (int k = 0; k < 3; ++k) {
    if (d_local[k] == 0.0) {
      if (!(std::abs(o_local[k]) < half[k])) return false;
      continue;
    }
    double a = (-half[k] - o_local[k]) / d_local[k];
    double b = (half[k] - o_local[k]) / d_local[k];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  return t0 < t1;
}

bool contains(const SceneObject& o, const glm::dvec3& point, double margin) {
  const glm::dvec3 local = rotate_y(point - o.center, -o.rotation_y_deg);
  const glm::dvec3 half = 0.5 * o.size - margin;
  return std::abs(local.x) < half.x && std::abs(local.y) < half.y && std::abs(local.z) < half.z;
}

}  // namespace

extern const ShapeKind kBoxShape;  // listed in shapes.cpp
const ShapeKind kBoxShape = {
    SceneObject::Type::Box, "box", bounds, bounds, closed, /*horizontal_plane=*/false, tessellate, triangles,
    vertices, intersect, points_inside, /*tessellation_error=*/nullptr, surely_meets, contains, points_around,
};

}  // namespace umbra
