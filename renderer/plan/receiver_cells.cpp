#include "plan/receiver_cells.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <glm/mat4x4.hpp>
#include <glm/matrix.hpp>

namespace umbra {

namespace {

// How much wider than the view's depth range the region is taken: the main
// pass decides in float whether a view holds a point.
constexpr double kDepthSlack = 1e-3;

double area_xz(const Aabb& b) { return (b.max.x - b.min.x) * (b.max.z - b.min.z); }

bool overlap_xz(const Aabb& a, const Aabb& b) {
  return a.min.x <= b.max.x && b.min.x <= a.max.x && a.min.z <= b.max.z && b.min.z <= a.max.z;
}

Aabb merged(const Aabb& a, const Aabb& b) {
  Aabb m = a;
  m.extend(b);
  return m;
}

// Merges overlapping boxes until none overlap.
void merge_overlapping(std::vector<Aabb>& boxes) {
  for (bool changed = true; changed;) {
    changed = false;
    for (std::size_t i = 0; i < boxes.size() && !changed; ++i) {
      for (std::size_t j = i + 1; j < boxes.size(); ++j) {
        if (!overlap_xz(boxes[i], boxes[j])) continue;
        boxes[i] = merged(boxes[i], boxes[j]);
        boxes.erase(boxes.begin() + std::ptrdiff_t(j));
        changed = true;
        break;
      }
    }
  }
}

// Whether the convex polygon and the x/z box [low, high] widened by `slack`
// (narrowed, if negative) meet: separated only along the box's axes or one
// of the polygon's edge normals.
bool polygon_meets_box(const PlanePolygon& polygon, glm::dvec2 low, glm::dvec2 high, double slack) {
  if (polygon.empty()) return false;
  low -= slack;
  high += slack;
  glm::dvec2 p_low(1e300), p_high(-1e300);
  for (const glm::dvec2& p : polygon) p_low = glm::min(p_low, p), p_high = glm::max(p_high, p);
  if (p_high.x < low.x || high.x < p_low.x || p_high.y < low.y || high.y < p_low.y) return false;
  if (polygon.size() < 3) return true;  // a segment: its box meets the box (conservative)
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const glm::dvec2 a = polygon[i], b = polygon[(i + 1) % polygon.size()];
    // Counter-clockwise: the outside of edge a -> b is to its right.
    const glm::dvec2 outward(b.y - a.y, a.x - b.x);
    const double edge = glm::dot(outward, a);
    // The box corner furthest inside along this edge's normal.
    const glm::dvec2 inmost(outward.x > 0.0 ? low.x : high.x, outward.y > 0.0 ? low.y : high.y);
    if (glm::dot(outward, inmost) > edge) return false;
  }
  return true;
}

std::vector<double> cuts(double low, double high, const std::vector<Aabb>& boxes, int axis) {
  std::vector<double> c{low, high};
  for (const Aabb& b : boxes) {
    c.push_back(b.min[axis]);
    c.push_back(b.max[axis]);
  }
  std::sort(c.begin(), c.end());
  c.erase(std::unique(c.begin(), c.end()), c.end());
  return c;
}

}  // namespace

double polygon_area(const PlanePolygon& polygon) {
  double twice = 0.0;
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const glm::dvec2 a = polygon[i], b = polygon[(i + 1) % polygon.size()];
    twice += a.x * b.y - b.x * a.y;
  }
  return 0.5 * std::abs(twice);
}

// Andrew's monotone chain.
PlanePolygon convex_hull(std::vector<glm::dvec2> points) {
  std::sort(points.begin(), points.end(), [](const glm::dvec2& a, const glm::dvec2& b) {
    return a.x < b.x || (a.x == b.x && a.y < b.y);
  });
  points.erase(std::unique(points.begin(), points.end()), points.end());
  if (points.size() < 3) return points;
  const auto turn = [](const glm::dvec2& o, const glm::dvec2& a, const glm::dvec2& b) {
    return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
  };
  PlanePolygon hull(2 * points.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {  // lower chain
    while (k >= 2 && turn(hull[k - 2], hull[k - 1], points[i]) <= 0.0) --k;
    hull[k++] = points[i];
  }
  for (std::size_t i = points.size() - 1, lower = k + 1; i-- > 0;) {  // upper chain
    while (k >= lower && turn(hull[k - 2], hull[k - 1], points[i]) <= 0.0) --k;
    hull[k++] = points[i];
  }
  hull.resize(k - 1);  // the last point is the first
  return hull;
}

// Sutherland-Hodgman against the four sides.
PlanePolygon clipped(PlanePolygon polygon, const glm::dvec2& low, const glm::dvec2& high) {
  for (int side = 0; side < 4 && !polygon.empty(); ++side) {
    const int axis = side % 2;
    const double bound = side < 2 ? low[axis] : high[axis];
    const auto inside = [&](const glm::dvec2& p) { return side < 2 ? p[axis] >= bound : p[axis] <= bound; };
    PlanePolygon out;
    for (std::size_t i = 0; i < polygon.size(); ++i) {
      const glm::dvec2 a = polygon[i], b = polygon[(i + 1) % polygon.size()];
      if (inside(a)) out.push_back(a);
      if (inside(a) != inside(b)) out.push_back(a + (b - a) * ((bound - a[axis]) / (b[axis] - a[axis])));
    }
    polygon = std::move(out);
  }
  return polygon;
}

PlanePolygon view_polygon_on_plane(const ShadowView& view, int layer_size, const TexelRect& rect, double y) {
  if (rect.empty()) return {};
  const glm::dmat4 eye_from_clip = glm::inverse(view.projection);
  const glm::dmat4 world_from_eye = glm::inverse(view.view);
  // The eight corners of the part of the view's frustum whose texels lie in
  // `rect`: corner k has x from bit 0, y from bit 1, far from bit 2.
  std::array<glm::dvec3, 8> corner;
  for (int k = 0; k < 4; ++k) {
    const glm::dvec2 texel{k & 1 ? rect.max.x : rect.min.x, k & 2 ? rect.max.y : rect.min.y};
    const glm::dvec2 ndc = texel / double(layer_size) * 2.0 - 1.0;
    glm::dvec4 near_eye = eye_from_clip * glm::dvec4(ndc, -1.0, 1.0);
    glm::dvec4 far_eye = eye_from_clip * glm::dvec4(ndc, 1.0, 1.0);
    const glm::dvec3 n = glm::dvec3(near_eye) / near_eye.w, f = glm::dvec3(far_eye) / far_eye.w;
    // Both lie on one line of sight (a ray from a perspective eye, a line
    // along the axis of an orthographic one): widen along it.
    corner[k] = glm::dvec3(world_from_eye * glm::dvec4(n - kDepthSlack * (f - n), 1.0));
    corner[k + 4] = glm::dvec3(world_from_eye * glm::dvec4(f + kDepthSlack * (f - n), 1.0));
  }
  // The plane meets this convex solid in a convex polygon whose vertices
  // lie on its edges (those between corners one bit apart).
  std::vector<glm::dvec2> points;
  for (int a = 0; a < 8; ++a) {
    const double da = corner[a].y - y;
    if (da == 0.0) points.emplace_back(corner[a].x, corner[a].z);
    for (int bit = 1; bit < 8; bit <<= 1) {
      const int b = a | bit;
      if (b == a) continue;
      const double db = corner[b].y - y;
      if ((da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0)) {
        const glm::dvec3 p = corner[a] + (corner[b] - corner[a]) * (da / (da - db));
        points.emplace_back(p.x, p.z);
      }
    }
  }
  return convex_hull(std::move(points));
}

Aabb bounds_on_plane(const PlanePolygon& polygon, double y) {
  Aabb out;
  for (const glm::dvec2& p : polygon) out.extend({p.x, y, p.y});
  return out;
}

Aabb view_rect_on_plane(const ShadowView& view, int layer_size, const TexelRect& rect, double y) {
  return bounds_on_plane(view_polygon_on_plane(view, layer_size, rect, y), y);
}

namespace {

// Adds to `regions` where on the plane at height y `view` holds a point
// whose texel lies within `rect` widened by `margin` texels.
void add_region(std::vector<PlanePolygon>& regions, const ShadowView& view, int layer_size, TexelRect rect,
                double margin, double y) {
  if (rect.empty()) return;
  rect.min -= margin;
  rect.max += margin;
  PlanePolygon region = view_polygon_on_plane(view, layer_size, rect, y);
  if (!region.empty()) regions.push_back(std::move(region));
}

}  // namespace

std::vector<PlanePolygon> shadowable_regions(double y, const ShadowPlan& light,
                                             const std::vector<std::vector<TexelRect>>& rects, double margin_texels) {
  std::vector<PlanePolygon> regions;
  for (std::size_t i = 0; i < light.views.size() && i < rects.size(); ++i)
    if (!light.views[i].empty)
      for (const TexelRect& rect : rects[i]) add_region(regions, light.views[i], light.layer_size, rect, margin_texels, y);
  return regions;
}

std::vector<PlanePolygon> view_regions(double y, const ShadowPlan& light, const std::vector<TexelRect>& view_rects,
                                       double margin_texels) {
  std::vector<PlanePolygon> regions;
  for (std::size_t i = 0; i < light.views.size() && i < view_rects.size(); ++i)
    if (!light.views[i].empty) add_region(regions, light.views[i], light.layer_size, view_rects[i], margin_texels, y);
  return regions;
}

PlaneCells plane_cells(const Aabb& plane, const std::vector<PlanePolygon>& regions) {
  // The regions that meet the plane, and their boxes clipped to it.
  std::vector<const PlanePolygon*> meeting;
  std::vector<Aabb> kept;
  for (const PlanePolygon& region : regions) {
    Aabb r = bounds_on_plane(region, plane.min.y);
    if (r.empty()) continue;
    r.min.x = std::max(r.min.x, plane.min.x);
    r.min.z = std::max(r.min.z, plane.min.z);
    r.max.x = std::min(r.max.x, plane.max.x);
    r.max.z = std::min(r.max.z, plane.max.z);
    if (r.min.x <= r.max.x && r.min.z <= r.max.z) kept.push_back(r), meeting.push_back(&region);
  }
  // Many casters (a thousand spheres): their bounding box, without the
  // quadratic merge below, and cells judged by the boxes alone.
  constexpr std::size_t kMergedOneByOne = 64;
  const bool by_boxes = kept.size() > kMergedOneByOne;
  if (by_boxes) {
    Aabb all;
    for (const Aabb& r : kept) all.extend(r);
    kept = {all};
  }
  merge_overlapping(kept);
  while (kept.size() > std::size_t(kMaxReceiverRegions)) {
    std::size_t best_i = 0, best_j = 1;
    double best_growth = 1e300;
    for (std::size_t i = 0; i < kept.size(); ++i)
      for (std::size_t j = i + 1; j < kept.size(); ++j) {
        const double growth = area_xz(merged(kept[i], kept[j])) - area_xz(kept[i]) - area_xz(kept[j]);
        if (growth < best_growth) best_growth = growth, best_i = i, best_j = j;
      }
    kept[best_i] = merged(kept[best_i], kept[best_j]);
    kept.erase(kept.begin() + std::ptrdiff_t(best_j));
    merge_overlapping(kept);
  }

  PlaneCells cells;
  cells.x_cuts = cuts(plane.min.x, plane.max.x, kept, 0);
  cells.z_cuts = cuts(plane.min.z, plane.max.z, kept, 2);
  // A box its regions fill less than half of (wedges reaching out from a
  // point light amid the casters, whose boxes merge into most of the
  // floor) is cut into strips, so that its cells can follow the wedges.
  std::vector<const Aabb*> poorly_filled;
  if (!by_boxes) {
    for (const Aabb& box : kept) {
      double filled = 0.0;
      for (const PlanePolygon* region : meeting)
        filled += polygon_area(clipped(*region, {box.min.x, box.min.z}, {box.max.x, box.max.z}));
      if (filled < 0.5 * area_xz(box)) poorly_filled.push_back(&box);
    }
  }
  if (!poorly_filled.empty()) {
    // One lattice over all of them, kRefinedCuts steps across the widest
    // way, so that boxes side by side share their cuts.
    Aabb span;
    for (const Aabb* box : poorly_filled) span.extend(*box);
    const double step = std::max(span.max.x - span.min.x, span.max.z - span.min.z) / kRefinedCuts;
    for (const Aabb* box : poorly_filled) {
      for (int axis : {0, 2}) {
        std::vector<double>& c = axis == 0 ? cells.x_cuts : cells.z_cuts;
        const auto first = long(std::floor((box->min[axis] - span.min[axis]) / step)) + 1;
        const auto last = long(std::ceil((box->max[axis] - span.min[axis]) / step)) - 1;
        for (long k = first; k <= last && k < kRefinedCuts; ++k) c.push_back(span.min[axis] + double(k) * step);
      }
    }
    for (std::vector<double>* c : {&cells.x_cuts, &cells.z_cuts}) {
      std::sort(c->begin(), c->end());
      c->erase(std::unique(c->begin(), c->end()), c->end());
    }
  }
  const std::size_t columns = cells.x_cuts.size() - 1, rows = cells.z_cuts.size() - 1;
  cells.shadowable.assign(columns * rows, false);
  if (by_boxes) {
    // Every box's sides are cuts, so a cell lies wholly inside a box or
    // wholly outside it: its centre tells.
    for (std::size_t j = 0; j < rows; ++j)
      for (std::size_t i = 0; i < columns; ++i) {
        const double x = 0.5 * (cells.x_cuts[i] + cells.x_cuts[i + 1]);
        const double z = 0.5 * (cells.z_cuts[j] + cells.z_cuts[j + 1]);
        for (const Aabb& r : kept)
          if (r.min.x <= x && x <= r.max.x && r.min.z <= z && z <= r.max.z) cells.shadowable[j * columns + i] = true;
      }
    return cells;
  }
  // A cell is shadowable where a region overlaps it: more than touches its
  // side (a region already reaches a texel past the last one a point may
  // read). Each region is tested only against the cells its box spans.
  const double slack = 1e-9 * (plane.max.x - plane.min.x + plane.max.z - plane.min.z);
  const auto first_cell = [](const std::vector<double>& c, double v) {
    const auto at = std::upper_bound(c.begin(), c.end(), v) - c.begin() - 1;
    return std::size_t(std::clamp<std::ptrdiff_t>(at, 0, std::ptrdiff_t(c.size()) - 2));
  };
  for (std::size_t k = 0; k < meeting.size(); ++k) {
    const Aabb box = bounds_on_plane(*meeting[k], plane.min.y);
    const std::size_t i0 = first_cell(cells.x_cuts, box.min.x - slack), i1 = first_cell(cells.x_cuts, box.max.x + slack);
    const std::size_t j0 = first_cell(cells.z_cuts, box.min.z - slack), j1 = first_cell(cells.z_cuts, box.max.z + slack);
    for (std::size_t j = j0; j <= j1; ++j)
      for (std::size_t i = i0; i <= i1; ++i)
        if (!cells.shadowable[j * columns + i] &&
            polygon_meets_box(*meeting[k], {cells.x_cuts[i], cells.z_cuts[j]}, {cells.x_cuts[i + 1], cells.z_cuts[j + 1]},
                              -slack))
          cells.shadowable[j * columns + i] = true;
  }
  return cells;
}

void append_cell_triangles(const PlaneCells& cells, double y, const glm::dvec3& color, const glm::dvec3& origin,
                           CellTriangles& out) {
  const std::size_t columns = cells.x_cuts.size();
  const auto first = std::uint32_t(out.vertices.size());
  for (double z : cells.z_cuts) {
    for (double x : cells.x_cuts) {
      const glm::dvec3 p = glm::dvec3(x, y, z) - origin;
      out.vertices.push_back({{float(p.x), float(p.y), float(p.z)},
                              {0.0f, 1.0f, 0.0f},
                              {float(color.x), float(color.y), float(color.z)}});
    }
  }
  for (std::size_t j = 0; j + 1 < cells.z_cuts.size(); ++j) {
    for (std::size_t i = 0; i + 1 < columns; ++i) {
      // tessellate()'s quad: (-x, +z), (+x, +z), (+x, -z), (-x, -z).
      const auto at = [&](std::size_t ii, std::size_t jj) { return first + std::uint32_t(jj * columns + ii); };
      const std::uint32_t a = at(i, j + 1), b = at(i + 1, j + 1), c = at(i + 1, j), d = at(i, j);
      auto& to = cells.shadowable[j * (columns - 1) + i] ? out.shadowable : out.unshadowable;
      to.insert(to.end(), {a, b, c, a, c, d});
    }
  }
}

void append_polygon_triangles(const std::vector<PlanePolygon>& polygons, double y, const glm::dvec3& color,
                              const glm::dvec3& origin, CellTriangles& out, std::vector<std::uint32_t>& indices) {
  for (const PlanePolygon& polygon : polygons) {
    const auto first = std::uint32_t(out.vertices.size());
    for (const glm::dvec2& q : polygon) {
      const glm::dvec3 p = glm::dvec3(q.x, y, q.y) - origin;
      out.vertices.push_back({{float(p.x), float(p.y), float(p.z)},
                              {0.0f, 1.0f, 0.0f},
                              {float(color.x), float(color.y), float(color.z)}});
    }
    // Counter-clockwise in (x, z) is clockwise seen from above, as a cell's
    // (-x, +z), (+x, +z), (+x, -z) is: the fan runs backwards.
    for (std::uint32_t i = 1; i + 1 < polygon.size(); ++i)
      indices.insert(indices.end(), {first, first + i + 1, first + i});
  }
}

}  // namespace umbra
