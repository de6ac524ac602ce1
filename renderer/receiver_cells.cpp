#include "receiver_cells.hpp"

#include <algorithm>
#include <array>

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

Aabb view_rect_on_plane(const ShadowView& view, int layer_size, const TexelRect& rect, double y) {
  Aabb out;
  if (rect.empty()) return out;
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
  for (int a = 0; a < 8; ++a) {
    const double da = corner[a].y - y;
    if (da == 0.0) out.extend(corner[a]);
    for (int bit = 1; bit < 8; bit <<= 1) {
      const int b = a | bit;
      if (b == a) continue;
      const double db = corner[b].y - y;
      if ((da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0))
        out.extend(corner[a] + (corner[b] - corner[a]) * (da / (da - db)));
    }
  }
  if (!out.empty()) out.min.y = out.max.y = y;
  return out;
}

namespace {

// Adds to `regions` where on the plane at height y `view` holds a point
// whose texel lies within `rect` widened by `margin` texels.
void add_region(std::vector<Aabb>& regions, const ShadowView& view, int layer_size, TexelRect rect, double margin,
                double y) {
  if (rect.empty()) return;
  rect.min -= margin;
  rect.max += margin;
  const Aabb region = view_rect_on_plane(view, layer_size, rect, y);
  if (!region.empty()) regions.push_back(region);
}

}  // namespace

std::vector<Aabb> shadowable_regions(double y, const ShadowPlan& light,
                                     const std::vector<std::vector<TexelRect>>& rects, double margin_texels) {
  std::vector<Aabb> regions;
  for (std::size_t i = 0; i < light.views.size() && i < rects.size(); ++i)
    if (!light.views[i].empty)
      for (const TexelRect& rect : rects[i]) add_region(regions, light.views[i], light.layer_size, rect, margin_texels, y);
  return regions;
}

std::vector<Aabb> view_regions(double y, const ShadowPlan& light, const std::vector<TexelRect>& view_rects,
                               double margin_texels) {
  std::vector<Aabb> regions;
  for (std::size_t i = 0; i < light.views.size() && i < view_rects.size(); ++i)
    if (!light.views[i].empty) add_region(regions, light.views[i], light.layer_size, view_rects[i], margin_texels, y);
  return regions;
}

PlaneCells plane_cells(const Aabb& plane, std::vector<Aabb> regions) {
  std::vector<Aabb> kept;
  for (Aabb r : regions) {
    r.min.x = std::max(r.min.x, plane.min.x);
    r.min.z = std::max(r.min.z, plane.min.z);
    r.max.x = std::min(r.max.x, plane.max.x);
    r.max.z = std::min(r.max.z, plane.max.z);
    if (r.min.x <= r.max.x && r.min.z <= r.max.z) kept.push_back(r);
  }
  // Many casters (a thousand spheres): their bounding box, without the
  // quadratic merge below.
  constexpr std::size_t kMergedOneByOne = 64;
  if (kept.size() > kMergedOneByOne) {
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
  for (std::size_t j = 0; j + 1 < cells.z_cuts.size(); ++j) {
    for (std::size_t i = 0; i + 1 < cells.x_cuts.size(); ++i) {
      // Every region's sides are cuts, so a cell lies wholly inside a
      // region or wholly outside it: its centre tells.
      const double x = 0.5 * (cells.x_cuts[i] + cells.x_cuts[i + 1]);
      const double z = 0.5 * (cells.z_cuts[j] + cells.z_cuts[j + 1]);
      bool inside = false;
      for (const Aabb& r : kept) inside = inside || (r.min.x <= x && x <= r.max.x && r.min.z <= z && z <= r.max.z);
      cells.shadowable.push_back(inside);
    }
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

}  // namespace umbra
