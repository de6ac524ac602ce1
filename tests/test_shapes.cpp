// The shape table (core/shapes): every row's tessellation, bounds, exact
// intersection and cost figures agree with each other, and the names
// round-trip. A new kind's row is checked by adding its objects to
// objects_of() below.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <set>
#include <string>

#include <glm/geometric.hpp>

#include "core/builtin_models.hpp"
#include "core/scene.hpp"
#include "core/shapes/shape.hpp"
#include "model_support.hpp"

namespace umbra {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kPi = 3.14159265358979323846;

// A few objects of `type`, of different sizes, places and turns.
std::vector<SceneObject> objects_of(SceneObject::Type type) {
  std::vector<SceneObject> out;
  const auto add = [&](glm::dvec3 center, glm::dvec3 size, double radius, double turn) {
    SceneObject o;
    o.type = type;
    o.center = center;
    o.size = type == SceneObject::Type::Plane ? glm::dvec3(size.x, 0.0, size.z) : size;
    o.radius = radius;
    o.rotation_y_deg = turn;
    o.color = {0.2, 0.4, 0.6};
    out.push_back(o);
  };
  switch (type) {
    case SceneObject::Type::Plane:
    case SceneObject::Type::Box:
    case SceneObject::Type::Sphere:
    case SceneObject::Type::Cylinder:  // size.y: its height
      add({0, 0, 0}, {1, 1, 1}, 0.5, 0.0);
      add({3, -2, 5}, {4, 0.5, 2}, 2.5, 30.0);
      add({-100, 40, 7}, {0.01, 3, 20}, 0.01, 123.0);
      break;
    case SceneObject::Type::Mesh: {
      SceneObject closed;
      closed.type = type;
      closed.model = test::box_model({0.5f, 1.0f, 1.5f});
      closed.model_id = "box";
      closed.center = {2, 3, 4};
      closed.rotation_deg = {10, 20, 30};
      closed.mesh_scale = {1, 2, 0.5};
      out.push_back(closed);
      SceneObject open = closed;
      open.model = test::quad_model(2.0f);
      open.model_id = "quad";
      out.push_back(open);
      SceneObject knot;
      knot.type = type;
      knot.model = find_builtin_model("torus-knot")->model;
      knot.model_id = find_builtin_model("torus-knot")->id;
      knot.center = {-1, 0.5, 2};
      out.push_back(knot);
      break;
    }
  }
  return out;
}

// One object's tessellation alone, about the world origin (so that float
// positions are world positions).
Mesh tessellation_of(const SceneObject& o) {
  Mesh mesh;
  shape_kind(o.type).tessellate(o, mesh);
  return mesh;
}

glm::dvec3 corner(const Mesh& mesh, std::size_t index) {
  const Vertex& v = mesh.vertices[mesh.indices[index]];
  return glm::dvec3(v.position[0], v.position[1], v.position[2]) + mesh.origin;
}

// The nearest triangle the ray meets in (t_min, t_max) (Möller-Trumbore in
// double), and that triangle's unit normal.
double intersect_triangles(const Mesh& mesh, const glm::dvec3& origin, const glm::dvec3& dir, double t_min,
                           double t_max, glm::dvec3& normal) {
  double best = kInf;
  for (std::size_t i = 0; i + 2 < mesh.indices.size(); i += 3) {
    const glm::dvec3 a = corner(mesh, i), b = corner(mesh, i + 1), c = corner(mesh, i + 2);
    const glm::dvec3 e1 = b - a, e2 = c - a, p = glm::cross(dir, e2);
    const double det = glm::dot(e1, p);
    if (std::abs(det) < 1e-300) continue;
    const glm::dvec3 s = origin - a;
    const double u = glm::dot(s, p) / det;
    if (u < 0.0 || u > 1.0) continue;
    const glm::dvec3 q = glm::cross(s, e1);
    const double v = glm::dot(dir, q) / det;
    if (v < 0.0 || u + v > 1.0) continue;
    const double t = glm::dot(e2, q) / det;
    if (t > t_min && t < t_max && t < best) {
      best = t;
      normal = glm::normalize(glm::cross(e1, e2));
    }
  }
  return best;
}

// How far the tessellation may lie from the exact surface, in world units:
// the row's own claim (ShapeKind::tessellation_error, which filter "exact"
// relies on), and float positions. The tests below hold every row to it.
double tessellation_slack(const SceneObject& o) {
  const Aabb b = shape_kind(o.type).bounds(o);
  const double rounding = 1e-6 * (glm::length(b.max) + glm::length(b.min) + glm::length(b.extent())) + 1e-9;
  return tessellation_error(o).distance + rounding;
}

glm::dvec3 random_direction(std::mt19937& random) {
  std::normal_distribution<double> normal;
  for (;;) {
    const glm::dvec3 d(normal(random), normal(random), normal(random));
    if (glm::length(d) > 1e-3) return glm::normalize(d);
  }
}

TEST(Shapes, TheTableIsInTypeOrderAndItsNamesAreUniqueAndRoundTrip) {
  const std::vector<SceneObject::Type> types = {SceneObject::Type::Plane, SceneObject::Type::Box,
                                                SceneObject::Type::Sphere, SceneObject::Type::Mesh,
                                                SceneObject::Type::Cylinder};
  ASSERT_EQ(shape_kinds().size(), types.size());
  std::set<std::string> names;
  for (std::size_t i = 0; i < types.size(); ++i) {
    const ShapeKind& kind = shape_kind(types[i]);
    EXPECT_EQ(kind.type, types[i]);
    EXPECT_EQ(shape_kinds()[i], &kind);
    ASSERT_NE(kind.name, nullptr);
    EXPECT_TRUE(names.insert(kind.name).second) << "two rows named " << kind.name;
    EXPECT_EQ(find_shape_kind(kind.name), &kind);
  }
  // The API's names, as the parser reads them.
  EXPECT_EQ(find_shape_kind("plane"), &shape_kind(SceneObject::Type::Plane));
  EXPECT_EQ(find_shape_kind("box"), &shape_kind(SceneObject::Type::Box));
  EXPECT_EQ(find_shape_kind("sphere"), &shape_kind(SceneObject::Type::Sphere));
  EXPECT_EQ(find_shape_kind("mesh"), &shape_kind(SceneObject::Type::Mesh));
  EXPECT_EQ(find_shape_kind("cylinder"), &shape_kind(SceneObject::Type::Cylinder));
  EXPECT_EQ(find_shape_kind("Box"), nullptr);
  EXPECT_EQ(find_shape_kind(""), nullptr);
}

TEST(Shapes, EveryRowHasWhatEveryCallerCalls) {
  for (const ShapeKind* kind : shape_kinds()) {
    SCOPED_TRACE(kind->name);
    EXPECT_NE(kind->bounds, nullptr);
    EXPECT_NE(kind->surface_bounds, nullptr);
    EXPECT_NE(kind->closed, nullptr);
    EXPECT_NE(kind->tessellate, nullptr);
    EXPECT_NE(kind->triangles, nullptr);
    EXPECT_NE(kind->vertices, nullptr);
    EXPECT_FALSE(objects_of(kind->type).empty()) << "no test objects for this kind: add them to objects_of";
  }
  // Only meshes go to Embree (RayScene builds a MeshRays for a row without intersect).
  for (const ShapeKind* kind : shape_kinds())
    EXPECT_EQ(kind->intersect == nullptr, kind->type == SceneObject::Type::Mesh) << kind->name;
}

TEST(Shapes, CountsAreWhatTheTessellationMakes) {
  for (const ShapeKind* kind : shape_kinds()) {
    for (const SceneObject& o : objects_of(kind->type)) {
      SCOPED_TRACE(kind->name);
      const Mesh mesh = tessellation_of(o);
      EXPECT_EQ(kind->vertices(o), mesh.vertices.size());
      EXPECT_EQ(kind->triangles(o), mesh.indices.size() / 3);
      EXPECT_EQ(mesh.indices.size() % 3, 0u);
      EXPECT_GT(mesh.indices.size(), 0u);
    }
  }
}

TEST(Shapes, TheTessellationLiesWithinTheBounds) {
  for (const ShapeKind* kind : shape_kinds()) {
    for (const SceneObject& o : objects_of(kind->type)) {
      SCOPED_TRACE(kind->name);
      const Aabb bounds = kind->bounds(o), surface = kind->surface_bounds(o);
      const Mesh mesh = tessellation_of(o);
      const double slack = tessellation_slack(o);
      Aabb made;
      for (std::size_t i = 0; i < mesh.indices.size(); ++i) made.extend(corner(mesh, i));
      for (int a = 0; a < 3; ++a) {
        EXPECT_GE(made.min[a], bounds.min[a] - slack) << "axis " << a;
        EXPECT_LE(made.max[a], bounds.max[a] + slack) << "axis " << a;
        EXPECT_GE(made.min[a], surface.min[a] - slack) << "axis " << a;
        EXPECT_LE(made.max[a], surface.max[a] + slack) << "axis " << a;
        // And the bounds are tight: the tessellation reaches them (a
        // sphere's vertices miss its equator's extremes by at most the sagitta).
        EXPECT_LE(made.min[a], surface.min[a] + slack) << "axis " << a;
        EXPECT_GE(made.max[a], surface.max[a] - slack) << "axis " << a;
      }
    }
  }
}

// Random rays through each analytic object's bounds: the exact test and
// the tessellation agree on hit or miss, but for rays so near the rim that
// moving them by the tessellation's error changes the exact answer; where
// both hit, at the same distance within that error (over the cosine of
// incidence), with nearly the same normal. Rays that pass the bounds at a
// distance miss both.
TEST(Shapes, TheExactIntersectionAgreesWithTheTessellation) {
  std::mt19937 random(30);
  std::uniform_real_distribution<double> centred(-0.5, 0.5);
  for (const ShapeKind* kind : shape_kinds()) {
    if (!kind->intersect) continue;
    for (const SceneObject& o : objects_of(kind->type)) {
      SCOPED_TRACE(std::string(kind->name) + " at x " + std::to_string(o.center.x));
      const Mesh mesh = tessellation_of(o);
      const Aabb bounds = kind->bounds(o);
      const double size = glm::length(bounds.extent());
      const double error = tessellation_slack(o);
      const auto exact = [&](const glm::dvec3& origin, const glm::dvec3& dir, glm::dvec3& normal) {
        return kind->intersect(o, origin, dir, 0.0, kInf, normal);
      };
      int hits = 0;
      for (int n = 0; n < 400; ++n) {
        const glm::dvec3 extent = bounds.extent();
        const glm::dvec3 target =
            bounds.center() + glm::dvec3(centred(random) * extent.x, centred(random) * extent.y, centred(random) * extent.z);
        const glm::dvec3 dir = random_direction(random);
        const glm::dvec3 origin = target - dir * (2.0 * size + 1.0);
        glm::dvec3 normal_a, normal_b;
        const double a = exact(origin, dir, normal_a);
        const double b = intersect_triangles(mesh, origin, dir, 0.0, kInf, normal_b);
        const glm::dvec3 u = glm::normalize(glm::cross(dir, std::abs(dir.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0)));
        const glm::dvec3 v = glm::cross(dir, u);
        bool near_rim = false;
        for (const glm::dvec3& shift : {u, -u, v, -v}) {
          glm::dvec3 unused;
          near_rim |= (exact(origin + shift * (2.0 * error), dir, unused) < kInf) != (a < kInf);
        }
        if (near_rim) continue;
        ASSERT_EQ(a < kInf, b < kInf) << "the exact test " << (a < kInf ? "hits" : "misses")
                                      << " where the tessellation does not";
        if (a == kInf) continue;
        ++hits;
        if (!kind->closed(o)) {
          // An open surface has one normal for both sides: turn both towards the ray.
          if (glm::dot(normal_a, dir) > 0.0) normal_a = -normal_a;
          if (glm::dot(normal_b, dir) > 0.0) normal_b = -normal_b;
        }
        EXPECT_NEAR(glm::length(normal_a), 1.0, 1e-12);
        EXPECT_LT(glm::dot(normal_a, dir), 0.0) << "a ray from outside meets a face that looks towards it";
        EXPECT_GT(glm::dot(normal_a, normal_b), std::cos(kPi / 24.0)) << "the triangle met faces elsewhere";
        const double incidence = -glm::dot(normal_a, dir);
        if (incidence < 0.2) continue;  // grazing: the distance is ill-conditioned
        EXPECT_NEAR(a, b, error / incidence + 1e-9 * (2.0 * size + 1.0));
      }
      EXPECT_GT(hits, 50);
      for (int n = 0; n < 100; ++n) {
        const glm::dvec3 dir = random_direction(random);
        const glm::dvec3 side = glm::normalize(glm::cross(dir, random_direction(random)));
        const glm::dvec3 origin = bounds.center() + side * (size + 2.0 * error + 1e-3) - dir * (3.0 * size + 1.0);
        glm::dvec3 unused;
        EXPECT_EQ(exact(origin, dir, unused), kInf);
        EXPECT_EQ(intersect_triangles(mesh, origin, dir, 0.0, kInf, unused), kInf);
      }
    }
  }
}

// The umbra support's points lie inside the object: inside its bounds, and
// a ray from the centre through each point leaves the object past it.
TEST(Shapes, UmbraPointsLieInsideTheObject) {
  std::size_t found = 0;
  for (const ShapeKind* kind : shape_kinds()) {
    if (!kind->points_inside) continue;
    for (const SceneObject& o : objects_of(kind->type)) {
      SCOPED_TRACE(kind->name);
      const Aabb bounds = kind->bounds(o);
      const double margin = 1e-3 * glm::length(bounds.extent());
      const std::vector<glm::dvec3> points = kind->points_inside(o, margin, -kInf, kInf);
      found += points.size();
      for (const glm::dvec3& p : points) {
        const glm::dvec3 from = bounds.center();
        if (glm::distance(p, from) < 1e-12) continue;
        const glm::dvec3 dir = glm::normalize(p - from);
        glm::dvec3 unused;
        const double leaves = kind->intersect(o, from, dir, 0.0, kInf, unused);
        EXPECT_GT(leaves, glm::distance(p, from) + 0.5 * margin);
      }
    }
  }
  EXPECT_GT(found, 0u);
}

// points_around holds every point within the margin of the object at or
// above `low`, as sun hours uses it: slid along any upward direction onto
// the plane y = low, each such point (a ray's hit on the exact surface,
// pushed out by up to 0.999 margin) lands inside the hull of the slid
// points, the object's footprint.
TEST(Shapes, PointsAroundHoldTheObjectGrownByTheMargin) {
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const auto random_direction = [&] {
    for (;;) {
      const glm::dvec3 d(unit(random), unit(random), unit(random));
      if (glm::length(d) > 0.1 && glm::length(d) <= 1.0) return glm::normalize(d);
    }
  };
  using Point2 = std::pair<double, double>;
  const auto turn = [](const Point2& o2, const Point2& a, const Point2& b) {
    return (a.first - o2.first) * (b.second - o2.second) - (a.second - o2.second) * (b.first - o2.first);
  };
  std::size_t checked = 0;
  std::set<std::string> kinds;
  for (const ShapeKind* kind : shape_kinds()) {
    if (!kind->points_around) continue;
    kinds.insert(kind->name);
    for (const SceneObject& o : objects_of(kind->type)) {
      SCOPED_TRACE(kind->name);
      const Aabb bounds = kind->bounds(o);
      const double margin = 1e-3 * glm::length(bounds.extent());
      EXPECT_TRUE(kind->points_around(o, margin, bounds.max.y + 2 * margin).empty()) << "nothing above";
      for (const double low : {bounds.min.y - 1.0, bounds.center().y, bounds.max.y - 0.1 * bounds.extent().y}) {
        const std::vector<glm::dvec3> points = kind->points_around(o, margin, low);
        ASSERT_GE(points.size(), 4u);
        for (const glm::dvec3& p : points) EXPECT_GE(p.y, low);
        // Points near the object above `low`.
        std::vector<glm::dvec3> near;
        while (near.size() < 1000) {
          const glm::dvec3 from = bounds.center() + 2.0 * glm::length(bounds.extent()) * random_direction();
          const glm::dvec3 dir = glm::normalize(
              bounds.center() + 0.5 * bounds.extent() * glm::dvec3(unit(random), unit(random), unit(random)) - from);
          glm::dvec3 normal;
          const double t = kind->intersect(o, from, dir, 0.0, kInf, normal);
          if (!(t < kInf)) continue;
          const glm::dvec3 q = from + t * dir + 0.999 * margin * std::abs(unit(random)) * random_direction();
          if (q.y >= low) near.push_back(q);
        }
        for (int s = 0; s < 8; ++s) {
          glm::dvec3 sun = random_direction();
          sun.y = std::max(0.05, std::abs(sun.y));
          sun = glm::normalize(sun);
          const auto slide = [&](const glm::dvec3& p) {
            const double t = (p.y - low) / sun.y;
            return Point2{p.x - t * sun.x, p.z - t * sun.z};
          };
          std::vector<Point2> slid;
          for (const glm::dvec3& p : points) slid.push_back(slide(p));
          std::sort(slid.begin(), slid.end());
          std::vector<Point2> hull;  // counter-clockwise (monotone chain)
          for (int pass = 0; pass < 2; ++pass) {
            const std::size_t first = hull.size();
            for (const Point2& q : slid) {
              while (hull.size() >= first + 2 && turn(hull[hull.size() - 2], hull.back(), q) <= 0) hull.pop_back();
              hull.push_back(q);
            }
            hull.pop_back();
            std::reverse(slid.begin(), slid.end());
          }
          for (const glm::dvec3& q : near) {
            const Point2 at = slide(q);
            bool inside = true;
            for (std::size_t i = 0; i < hull.size(); ++i)
              inside = inside && turn(hull[i], hull[(i + 1) % hull.size()], at) >= 0;
            EXPECT_TRUE(inside) << q.x << " " << q.y << " " << q.z;
            ++checked;
          }
        }
      }
    }
  }
  EXPECT_GT(checked, 100000u);
  // The solids (whose footprints were their bounds' before) each have one.
  EXPECT_EQ(kinds, (std::set<std::string>{"box", "cylinder", "sphere"}));
}

}  // namespace
}  // namespace umbra
