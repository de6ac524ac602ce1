// The cylinder: a vertical axis whose middle is `center`, `radius` about it
// and `size.y` high, capped at both ends (poles, columns, tree trunks).
// Closed; its side tessellated as a prism of kSlices faces with the true
// normals at its vertices, its caps as fans.
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/shapes/mesh_builder.hpp"
#include "core/shapes/shape.hpp"

namespace umbra {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kPi = 3.14159265358979323846;

// As fine as the sphere's slices: the prism's faces depart from the true
// side by 1 - cos(pi / 96) < 0.06 % of the radius.
constexpr int kSlices = 96;

double half_height(const SceneObject& o) { return 0.5 * o.size.y; }

// The unit vector from the axis at angle `phi` (the sphere's convention:
// phi = 0 along +X, turning towards -Z).
glm::dvec3 radial(int slice) {
  const double phi = 2.0 * kPi * slice / kSlices;
  return {std::cos(phi), 0.0, -std::sin(phi)};
}

Aabb bounds(const SceneObject& o) {
  const glm::dvec3 half{o.radius, half_height(o), o.radius};
  Aabb b;
  b.extend(o.center - half);
  b.extend(o.center + half);
  return b;
}

bool closed(const SceneObject&) { return true; }

void tessellate(const SceneObject& o, Mesh& mesh) {
  MeshBuilder builder{mesh};
  const glm::dvec3 up{0.0, half_height(o), 0.0};
  // The side: a top and a bottom vertex per slice edge, normals radial.
  const std::uint32_t side = std::uint32_t(mesh.vertices.size());
  for (int j = 0; j <= kSlices; ++j) {
    const glm::dvec3 n = radial(j);
    builder.vertex(o.center + up + o.radius * n, n, o.color);
    builder.vertex(o.center - up + o.radius * n, n, o.color);
  }
  for (std::uint32_t j = 0; j < std::uint32_t(kSlices); ++j) {
    const std::uint32_t a = side + 2 * j, b = a + 1, d = a + 2, c = a + 3;  // a, d on top
    mesh.indices.insert(mesh.indices.end(), {a, b, d, d, b, c});
  }
  // The caps: a fan about each end's centre, facing up and down.
  for (const double sign : {1.0, -1.0}) {
    const glm::dvec3 n{0.0, sign, 0.0};
    const std::uint32_t middle = builder.vertex(o.center + sign * up, n, o.color);
    for (int j = 0; j <= kSlices; ++j) builder.vertex(o.center + sign * up + o.radius * radial(j), n, o.color);
    for (std::uint32_t j = 0; j < std::uint32_t(kSlices); ++j) {
      const std::uint32_t p = middle + 1 + j, q = p + 1;
      if (sign > 0.0)
        mesh.indices.insert(mesh.indices.end(), {middle, p, q});
      else
        mesh.indices.insert(mesh.indices.end(), {middle, q, p});
    }
  }
}

std::uint64_t triangles(const SceneObject&) { return 4 * kSlices; }
std::uint64_t vertices(const SceneObject&) { return 2 * (kSlices + 1) + 2 * (kSlices + 2); }

double intersect(const SceneObject& o, const glm::dvec3& origin, const glm::dvec3& dir, double t_min, double t_max,
                 glm::dvec3& normal) {
  const glm::dvec3 p = origin - o.center;
  const double h = half_height(o), r2 = o.radius * o.radius;
  double best = kInf;
  glm::dvec3 best_normal{0.0};
  auto take = [&](double t, const glm::dvec3& n) {
    if (t > t_min && t < t_max && t < best) {
      best = t;
      best_normal = n;
    }
  };
  // The side: |(p + t dir).xz| = radius, between the caps' heights.
  const double a = dir.x * dir.x + dir.z * dir.z;
  if (a > 0.0) {
    const double b = p.x * dir.x + p.z * dir.z;
    const double c = p.x * p.x + p.z * p.z - r2;
    const double disc = b * b - a * c;
    if (disc >= 0.0) {
      const double root = std::sqrt(disc);
      // The numerically stable pair of roots (as the sphere's).
      const double q = b > 0.0 ? -b - root : -b + root;
      for (const double t : {q / a, q != 0.0 ? c / q : -b / a}) {
        const glm::dvec3 hit = p + t * dir;
        if (std::abs(hit.y) <= h) take(t, glm::normalize(glm::dvec3(hit.x, 0.0, hit.z)));
      }
    }
  }
  // The caps: the planes y = +-h, inside the circle.
  if (dir.y != 0.0) {
    for (const double sign : {1.0, -1.0}) {
      const double t = (sign * h - p.y) / dir.y;
      const glm::dvec3 hit = p + t * dir;
      if (hit.x * hit.x + hit.z * hit.z <= r2) take(t, {0.0, sign, 0.0});
    }
  }
  if (best == kInf) return kInf;
  normal = best_normal;
  return best;
}

std::vector<glm::dvec3> points_inside(const SceneObject& o, double margin, double low, double high) {
  std::vector<glm::dvec3> points;
  const double radius = o.radius - margin, h = half_height(o) - margin;
  const double bottom = std::max(o.center.y - h, low), top = std::min(o.center.y + h, high);
  if (!(radius > 0.0 && h > 0.0 && bottom < top)) return points;
  // Rings of 16 points on the shrunk side at the slab's two heights: their
  // hull lies inside the cylinder and the slab.
  for (const double y : {bottom, top})
    for (int k = 0; k < 16; ++k) {
      const double angle = k * (2.0 * kPi / 16.0);
      points.emplace_back(o.center.x + radius * std::cos(angle), y, o.center.z + radius * std::sin(angle));
    }
  return points;
}

// The side's faces are chords of 2 pi / kSlices of arc: within R (1 -
// cos(pi / kSlices)) of the true side; a side normal is interpolated
// between radial ones 2 pi / kSlices (0.065) apart, and the exact point
// leans a little further: 0.08. The caps are exact.
TessellationError tessellation_error_of(const SceneObject& o) {
  return {o.radius * (1.0 - std::cos(kPi / kSlices)), 0.08};
}

}  // namespace

// The ray's stretch inside the cylinder shrunk by `margin` (radius and
// half height), intersected with t > margin: the side's quadratic gives
// the stretch within the radius, the caps' planes the stretch within the
// height.
bool surely_meets(const SceneObject& o, const glm::dvec3& origin, const glm::dvec3& dir, double margin) {
  const double r = o.radius - margin, h = half_height(o) - margin;
  if (!(r > 0.0 && h > 0.0)) return false;
  const glm::dvec3 p = origin - o.center;
  double t0 = margin, t1 = kInf;
  const double a = dir.x * dir.x + dir.z * dir.z;
  const double c = p.x * p.x + p.z * p.z - r * r;
  if (a > 0.0) {
    const double b = p.x * dir.x + p.z * dir.z, disc = b * b - a * c;
    if (!(disc > 0.0)) return false;
    const double root = std::sqrt(disc);
    t0 = std::max(t0, (-b - root) / a);
    t1 = std::min(t1, (-b + root) / a);
  } else if (!(c < 0.0)) {
    return false;  // vertical, outside the radius
  }
  if (dir.y != 0.0) {
    double a_y = (-h - p.y) / dir.y, b_y = (h - p.y) / dir.y;
    if (a_y > b_y) std::swap(a_y, b_y);
    t0 = std::max(t0, a_y);
    t1 = std::min(t1, b_y);
  } else if (!(std::abs(p.y) < h)) {
    return false;
  }
  return t0 < t1;
}

// A prism of 16 sides around the cylinder grown by `margin` (the sides
// touch the circle of radius r + margin), cut at `low`.
std::vector<glm::dvec3> points_around(const SceneObject& o, double margin, double low) {
  std::vector<glm::dvec3> points;
  constexpr int kSides = 16;
  const double corner_radius = (o.radius + margin) / std::cos(kPi / kSides), h = half_height(o) + margin;
  const double bottom = std::max(o.center.y - h, low), top = o.center.y + h;
  if (!(bottom <= top)) return points;
  for (const double y : {bottom, top})
    for (int k = 0; k < kSides; ++k) {
      const double angle = k * (2.0 * kPi / kSides);
      points.emplace_back(o.center.x + corner_radius * std::cos(angle), y, o.center.z + corner_radius * std::sin(angle));
    }
  return points;
}

bool contains(const SceneObject& o, const glm::dvec3& point, double margin) {
  const double r = o.radius - margin, h = half_height(o) - margin;
  const glm::dvec3 p = point - o.center;
  return r > 0.0 && h > 0.0 && p.x * p.x + p.z * p.z < r * r && std::abs(p.y) < h;
}

extern const ShapeKind kCylinderShape;  // listed in shapes.cpp
const ShapeKind kCylinderShape = {
    SceneObject::Type::Cylinder, "cylinder", bounds, bounds, closed, /*horizontal_plane=*/false, tessellate, triangles,
    vertices, intersect, points_inside, tessellation_error_of, surely_meets, contains, points_around,
};

}  // namespace umbra
