#include "core/polygon_triangulation.hpp"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace umbra {

namespace {

struct Point {
  double x, y;
  std::uint32_t index;  // into the rings' points
};

double cross(const Point& o, const Point& a, const Point& b) {
  return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}

double signed_area(const std::vector<Point>& ring) {
  double area = 0.0;
  for (std::size_t i = 0, j = ring.size() - 1; i < ring.size(); j = i++)
    area += (ring[j].x - ring[i].x) * (ring[j].y + ring[i].y);
  return 0.5 * area;
}

// Whether segments ab and cd cross at a point inside both (touching at an
// end does not count: bridges and ears meet the polygon at its vertices).
bool properly_cross(const Point& a, const Point& b, const Point& c, const Point& d, double eps) {
  const double d1 = cross(a, b, c), d2 = cross(a, b, d), d3 = cross(c, d, a), d4 = cross(c, d, b);
  return ((d1 > eps && d2 < -eps) || (d1 < -eps && d2 > eps)) && ((d3 > eps && d4 < -eps) || (d3 < -eps && d4 > eps));
}

bool same_place(const Point& a, const Point& b) { return a.x == b.x && a.y == b.y; }

// Inside or on triangle abc (counter-clockwise).
bool in_triangle(const Point& p, const Point& a, const Point& b, const Point& c, double eps) {
  return cross(a, b, p) >= -eps && cross(b, c, p) >= -eps && cross(c, a, p) >= -eps;
}

// Joins `hole` (clockwise) into `outer` (counter-clockwise) by a bridge
// from the hole's rightmost vertex to the nearest outer vertex it sees:
// outer ... P, M, hole from M round to M, M, P ... (Eberly's rule, with
// "sees" tested against every edge rather than through reflex vertices).
void bridge(std::vector<Point>& outer, const std::vector<Point>& hole, const std::vector<std::vector<Point>>& others,
            double eps) {
  std::size_t m = 0;
  for (std::size_t i = 1; i < hole.size(); ++i)
    if (hole[i].x > hole[m].x) m = i;
  const Point& M = hole[m];
  const auto blocked = [&](const Point& P) {
    const auto crosses = [&](const std::vector<Point>& ring) {
      for (std::size_t i = 0, j = ring.size() - 1; i < ring.size(); j = i++)
        if (properly_cross(M, P, ring[j], ring[i], eps)) return true;
      return false;
    };
    if (crosses(outer) || crosses(hole)) return true;
    for (const auto& other : others)
      if (crosses(other)) return true;
    return false;
  };
  std::size_t best = outer.size();
  double best_distance = 0.0;
  for (std::size_t i = 0; i < outer.size(); ++i) {
    const double dx = outer[i].x - M.x, dy = outer[i].y - M.y, distance = dx * dx + dy * dy;
    if (best < outer.size() && distance >= best_distance) continue;
    // The bridge must leave P into the polygon's inside: between its
    // neighbours' edges, on the inner side.
    const Point& prev = outer[(i + outer.size() - 1) % outer.size()];
    const Point& next = outer[(i + 1) % outer.size()];
    const bool convex = cross(prev, outer[i], next) >= 0.0;
    const bool inside = convex ? cross(prev, outer[i], M) > eps && cross(outer[i], next, M) > eps
                               : !(cross(prev, outer[i], M) <= eps && cross(outer[i], next, M) <= eps);
    if (!inside || blocked(outer[i])) continue;
    best = i;
    best_distance = distance;
  }
  if (best == outer.size()) best = 0;  // nothing seen (rings crossing): the ear clipping falls back
  std::vector<Point> joined(outer.begin(), outer.begin() + std::ptrdiff_t(best) + 1);
  for (std::size_t k = 0; k <= hole.size(); ++k) joined.push_back(hole[(m + k) % hole.size()]);
  joined.insert(joined.end(), outer.begin() + std::ptrdiff_t(best), outer.end());
  outer = std::move(joined);
}

}  // namespace

PolygonTriangles triangulate_polygon(const std::vector<std::vector<glm::dvec3>>& rings) {
  PolygonTriangles out;
  if (rings.empty() || rings[0].size() < 3) return out;
  // The plane: the outer ring's Newell normal, and two axes in it such that
  // (u, v, normal) is right-handed: the outer ring runs counter-clockwise.
  glm::dvec3 normal(0.0), centre(0.0);
  const std::vector<glm::dvec3>& boundary = rings[0];
  for (std::size_t i = 0, j = boundary.size() - 1; i < boundary.size(); j = i++) {
    const glm::dvec3 &a = boundary[j], &b = boundary[i];
    normal += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
    centre += b;
  }
  centre /= double(boundary.size());
  const double length = glm::length(normal);
  if (!(length > 0.0) || !std::isfinite(length)) return out;
  normal /= length;
  const glm::dvec3 helper = std::abs(normal.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
  const glm::dvec3 u = glm::normalize(glm::cross(helper, normal)), v = glm::cross(normal, u);
  double extent = 0.0;
  std::vector<std::vector<Point>> flat;
  std::uint32_t index = 0;
  for (const auto& ring : rings) {
    std::vector<Point> points;
    for (const glm::dvec3& p : ring) {
      const glm::dvec3 d = p - centre;  // about the centre: large site coordinates keep their precision
      points.push_back({glm::dot(d, u), glm::dot(d, v), index++});
      extent = std::max({extent, std::abs(points.back().x), std::abs(points.back().y)});
    }
    flat.push_back(std::move(points));
  }
  const double eps = 1e-12 * extent * extent;
  std::vector<Point> polygon = flat[0];
  if (signed_area(polygon) < 0.0) std::reverse(polygon.begin(), polygon.end());  // non-planar ring: as its normal says
  // Holes, rightmost first, each clockwise, joined in turn.
  std::vector<std::vector<Point>> holes;
  for (std::size_t r = 1; r < flat.size(); ++r)
    if (flat[r].size() >= 3) holes.push_back(flat[r]);
  for (auto& hole : holes)
    if (signed_area(hole) > 0.0) std::reverse(hole.begin(), hole.end());
  const auto rightmost = [](const std::vector<Point>& ring) {
    double x = ring[0].x;
    for (const Point& p : ring) x = std::max(x, p.x);
    return x;
  };
  std::sort(holes.begin(), holes.end(),
            [&](const std::vector<Point>& a, const std::vector<Point>& b) { return rightmost(a) > rightmost(b); });
  for (std::size_t h = 0; h < holes.size(); ++h) {
    const std::vector<std::vector<Point>> later(holes.begin() + std::ptrdiff_t(h) + 1, holes.end());
    bridge(polygon, holes[h], later, eps);
  }

  // Ear clipping: a convex corner whose triangle holds no other vertex of
  // the polygon (but copies of its own corners, which bridges make).
  std::vector<Point> left = polygon;
  std::size_t since_ear = 0, i = 0;
  while (left.size() > 3) {
    const std::size_t n = left.size();
    const Point &a = left[(i + n - 1) % n], &b = left[i % n], &c = left[(i + 1) % n];
    const double turn = cross(a, b, c);
    bool ear = turn > eps;
    for (std::size_t k = 0; ear && k < n; ++k) {
      const Point& p = left[k];
      if (same_place(p, a) || same_place(p, b) || same_place(p, c)) continue;
      if (in_triangle(p, a, b, c, eps)) ear = false;
    }
    const bool flat_corner = std::abs(turn) <= eps;  // collinear or a spike: no area to cover
    if (ear || flat_corner) {
      if (ear) out.indices.insert(out.indices.end(), {a.index, b.index, c.index});
      left.erase(left.begin() + std::ptrdiff_t(i % n));
      since_ear = 0;
      if (i >= left.size()) i = 0;
      continue;
    }
    i = (i + 1) % n;
    if (++since_ear > n) {  // a whole turn without an ear: not a simple polygon
      out.fell_back = true;
      for (std::size_t k = 1; k + 1 < left.size(); ++k)
        if (std::abs(cross(left[0], left[k], left[k + 1])) > eps)
          out.indices.insert(out.indices.end(), {left[0].index, left[k].index, left[k + 1].index});
      return out;
    }
  }
  if (left.size() == 3 && cross(left[0], left[1], left[2]) > eps)
    out.indices.insert(out.indices.end(), {left[0].index, left[1].index, left[2].index});
  return out;
}

}  // namespace umbra
