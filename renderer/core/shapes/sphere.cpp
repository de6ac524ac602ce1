// The sphere: `radius` about `center`. Closed; tessellated as a UV sphere.
#include <cmath>
#include <limits>
#include <utility>

#include "core/shapes/mesh_builder.hpp"
#include "core/shapes/shape.hpp"

namespace umbra {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// A UV sphere fine enough that its silhouette departs from the true
// sphere by < 0.1 % of the radius (1 - cos(pi / 96)).
constexpr int kStacks = 48, kSlices = 96;

Aabb bounds(const SceneObject& o) {
  Aabb b;
  b.extend(o.center - glm::dvec3(o.radius));
  b.extend(o.center + glm::dvec3(o.radius));
  return b;
}

bool closed(const SceneObject&) { return true; }

void tessellate(const SceneObject& o, Mesh& mesh) {
  MeshBuilder builder{mesh};
  constexpr double kPi = 3.14159265358979323846;
  const std::uint32_t first = std::uint32_t(mesh.vertices.size());
  for (int i = 0; i <= kStacks; ++i) {
    const double theta = kPi * i / kStacks;
    for (int j = 0; j <= kSlices; ++j) {
      const double phi = 2.0 * kPi * j / kSlices;
      const glm::dvec3 n{std::sin(theta) * std::cos(phi), std::cos(theta), -std::sin(theta) * std::sin(phi)};
      builder.vertex(o.center + n * o.radius, n, o.color);
    }
  }
  const std::uint32_t row = kSlices + 1;
  for (int i = 0; i < kStacks; ++i) {
    for (int j = 0; j < kSlices; ++j) {
      const std::uint32_t a = first + i * row + j, b = a + row, c = b + 1, d = a + 1;
      if (i != 0) mesh.indices.insert(mesh.indices.end(), {a, b, d});
      if (i != kStacks - 1) mesh.indices.insert(mesh.indices.end(), {d, b, c});
    }
  }
}

// Two triangles a cell, but one at each pole's row of cells.
std::uint64_t triangles(const SceneObject&) { return 2 * kStacks * kSlices - 2 * kSlices; }
std::uint64_t vertices(const SceneObject&) { return (kStacks + 1) * (kSlices + 1); }

double intersect(const SceneObject& o, const glm::dvec3& origin, const glm::dvec3& dir, double t_min, double t_max,
                 glm::dvec3& normal) {
  const glm::dvec3 oc = origin - o.center;
  const double b = glm::dot(oc, dir);
  const double c = glm::dot(oc, oc) - o.radius * o.radius;
  const double disc = b * b - c;
  if (disc < 0.0) return kInf;
  const double root = std::sqrt(disc);
  // The numerically stable pair of roots.
  const double q = b > 0.0 ? -b - root : -b + root;
  double ta = q, tb = q != 0.0 ? c / q : -b;
  if (ta > tb) std::swap(ta, tb);
  const double t = ta > t_min ? ta : tb;
  if (!(t > t_min && t < t_max)) return kInf;
  normal = glm::normalize(origin + t * dir - o.center);
  return t;
}

std::vector<glm::dvec3> points_inside(const SceneObject& object, double margin, double low, double high) {
  std::vector<glm::dvec3> points;
  const double radius = object.radius - margin;
  if (!(radius > 0.0)) return points;
  // Rings of 16 points on the sphere at five latitudes, and where the
  // slab's faces cut it: their hull lies inside the sphere and the slab.
  std::vector<double> heights{low, high};
  for (const double degrees : {-60.0, -30.0, 0.0, 30.0, 60.0})
    heights.push_back(object.center.y + radius * std::sin(degrees * 3.14159265358979323846 / 180.0));
  for (const double h : heights) {
    const double dy = h - object.center.y;
    if (!(h >= low && h <= high && std::abs(dy) < radius)) continue;
    const double ring = std::sqrt(radius * radius - dy * dy);
    for (int k = 0; k < 16; ++k) {
      const double angle = k * (2.0 * 3.14159265358979323846 / 16.0);
      points.emplace_back(object.center.x + ring * std::cos(angle), h, object.center.z + ring * std::sin(angle));
    }
  }
  return points;
}

// Each face is a chord of a cell at most pi / kStacks wide each way (the
// slices are as fine: 2 pi / kSlices): a face point lies within R (1 -
// cos(pi / kStacks)) of the sphere. An interpolated normal lies among its
// face's vertex normals, as does the true normal of a point of the face;
// those are at most the cell's diagonal apart, sqrt(2) pi / kStacks (0.093),
// and the exact point along a camera ray leans from the face's point by a
// further sliver: 0.12 bounds both.
TessellationError tessellation_error_of(const SceneObject& o) {
  return {o.radius * (1.0 - std::cos(3.14159265358979323846 / kStacks)), 0.12};
}

// A solid of revolution around the sphere grown by `margin` (radius R):
// its meridian has vertices at R / cos 15 deg every 30 deg from -60 to 60
// and at -+75 deg (where the polar tangents y = -+R meet the next), so
// every edge lies at least R from the centre and the polygon holds the
// circle; each vertex's height is a ring of 16 points at 1 / cos(pi / 16)
// of its radius, whose polygon holds the circle there. Cut at `low`: the
// rings above, and one at `low` as wide as the wider of the two around it.
std::vector<glm::dvec3> points_around(const SceneObject& object, double margin, double low) {
  constexpr double kPi = 3.14159265358979323846;
  constexpr int kSides = 6, kRing = 16;
  std::vector<glm::dvec3> points;
  const double radius = object.radius + margin, step = kPi / kSides;
  const double corner = radius / std::cos(0.5 * step), widen = 1.0 / std::cos(kPi / kRing);
  if (!(object.center.y + radius >= low)) return points;
  std::vector<std::pair<double, double>> rings;  // (height, meridian radius), bottom up
  for (int j = 0; j <= kSides; ++j) {
    const double angle = -0.5 * kPi + j * step;
    // The first and last vertices are where the polar tangents meet the
    // next ones: at y = -+R, radius R tan(step / 2).
    if (j == 0) rings.emplace_back(object.center.y - radius, radius * std::tan(0.5 * step));
    else if (j == kSides) rings.emplace_back(object.center.y + radius, radius * std::tan(0.5 * step));
    else rings.emplace_back(object.center.y + corner * std::sin(angle), corner * std::cos(angle));
  }
  std::vector<std::pair<double, double>> kept;
  for (std::size_t i = 0; i < rings.size(); ++i) {
    if (rings[i].first >= low) {
      if (kept.empty() && i > 0) kept.emplace_back(low, std::max(rings[i - 1].second, rings[i].second));
      kept.push_back(rings[i]);
    }
  }
  for (const auto& [y, meridian] : kept)
    for (int k = 0; k < kRing; ++k) {
      const double angle = k * (2.0 * kPi / kRing);
      points.emplace_back(object.center.x + widen * meridian * std::cos(angle), y,
                          object.center.z + widen * meridian * std::sin(angle));
    }
  return points;
}

// The ray's closest approach to the centre, within the sphere shrunk by
// `margin`, past t = margin: the chord through the shrunk sphere reaches
// beyond margin.
bool surely_meets(const SceneObject& o, const glm::dvec3& origin, const glm::dvec3& dir, double margin) {
  const double r = o.radius - margin;
  if (!(r > 0.0)) return false;
  const glm::dvec3 oc = origin - o.center;
  const double b = glm::dot(oc, dir);
  const double c = glm::dot(oc, oc) - b * b;  // squared distance from the centre to the line
  if (!(c < r * r)) return false;
  const double half_chord = std::sqrt(r * r - c);
  return -b + half_chord > margin;  // the shrunk sphere's exit lies past t = margin
}

bool contains(const SceneObject& o, const glm::dvec3& point, double margin) {
  const double r = o.radius - margin;
  return r > 0.0 && glm::dot(point - o.center, point - o.center) < r * r;
}

}  // namespace

extern const ShapeKind kSphereShape;  // listed in shapes.cpp
const ShapeKind kSphereShape = {
    SceneObject::Type::Sphere, "sphere", bounds, bounds, closed, /*horizontal_plane=*/false, tessellate, triangles,
    vertices, intersect, points_inside, tessellation_error_of, surely_meets, contains, points_around,
};

}  // namespace umbra
