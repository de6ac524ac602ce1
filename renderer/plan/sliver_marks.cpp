#include "plan/sliver_marks.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

namespace umbra {

namespace {

std::array<std::uint32_t, 3> bits_of(const glm::vec3& p) {
  std::array<std::uint32_t, 3> b;
  std::memcpy(b.data(), &p, sizeof b);
  return b;
}

struct HalfEdge {
  std::array<std::uint32_t, 7> key;  // object, then the corners' bits, lesser first
  std::uint32_t a, b, third, triangle;
};

// Marks the centres within kSliverPixels of the segment pa pb (window
// pixels, y up), its ends included, where another object than `object`
// was drawn (drawn_objects[i] >> drawn_shift: object + 1, 0 none), or
// wherever with `over_itself` (a model's edge).
void mark_band(glm::dvec2 pa, glm::dvec2 pb, std::uint32_t object, bool over_itself, int width, int height,
               const std::vector<std::uint32_t>& drawn_objects, unsigned drawn_shift, std::vector<std::uint8_t>& marks) {
  const double r = kSliverPixels * (1.0 + 1e-9) + 1e-9;  // a hair more, for this arithmetic
  const glm::dvec2 along = pb - pa;
  const double length = glm::length(along);
  const glm::dvec2 d = length > 1e-6 ? along / length : glm::dvec2(1.0, 0.0);
  const glm::dvec2 n(-d.y, d.x);
  // Iterate along the segment's major axis: each column (or row) holds the
  // centres within r of the line over an interval 2 r / |n| long.
  const bool major_x = std::abs(d.x) >= std::abs(d.y);
  const int axis = major_x ? 0 : 1, other = 1 - axis;
  const int extent = major_x ? width : height, other_extent = major_x ? height : width;
  const double lo = std::min(pa[axis], pb[axis]) - r, hi = std::max(pa[axis], pb[axis]) + r;
  if (!(hi >= 0.0 && lo <= double(extent))) return;
  // Clamped in double before the conversion: an end clipped at half the
  // near plane can lie 1e10 pixels away, past int's range.
  const int first = int(std::max(0.0, std::ceil(lo - 0.5)));
  const int last = int(std::min(double(extent - 1), std::floor(hi - 0.5)));
  for (int k = first; k <= last; ++k) {
    const double c = double(k) + 0.5;
    // |(X - pa) . n| <= r over the column: X[other] in [m - h, m + h].
    const double m = pa[other] - (c - pa[axis]) * n[axis] / n[other];
    const double h = r / std::abs(n[other]);
    const double lo_j = std::ceil(m - h - 0.5), hi_j = std::floor(m + h - 0.5);
    if (!(hi_j >= 0.0 && lo_j <= double(other_extent - 1))) continue;
    const int j0 = int(std::max(0.0, lo_j)), j1 = int(std::min(double(other_extent - 1), hi_j));
    for (int j = j0; j <= j1; ++j) {
      glm::dvec2 x(0.0);
      x[axis] = c;
      x[other] = double(j) + 0.5;
      const double s = glm::dot(x - pa, d);
      if (s < -r || s > length + r || std::abs(glm::dot(x - pa, n)) > r) continue;
      const int px = int(x.x), py = int(x.y);
      const std::size_t at = std::size_t(height - 1 - py) * std::size_t(width) + std::size_t(px);
      if (over_itself || (drawn_objects[at] >> drawn_shift) != object + 1) marks[at] = 1;
    }
  }
}

}  // namespace

SliverEdges::SliverEdges(const std::vector<glm::vec3>& positions, const std::vector<std::uint32_t>& indices,
                         const std::vector<std::uint32_t>& triangle_objects, const std::vector<bool>& model_objects,
                         const std::vector<glm::vec3>* normals) {
  std::vector<HalfEdge> halves;
  halves.reserve(indices.size());
  for (std::size_t t = 0; t < triangle_objects.size() && 3 * t + 2 < indices.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      std::uint32_t a = indices[3 * t + std::size_t(k)], b = indices[3 * t + std::size_t((k + 1) % 3)];
      const std::uint32_t third = indices[3 * t + std::size_t((k + 2) % 3)];
      std::array<std::uint32_t, 3> pa = bits_of(positions.at(a)), pb = bits_of(positions.at(b));
      if (pb < pa) {
        std::swap(pa, pb);
        std::swap(a, b);
      }
      HalfEdge h;
      h.key = {triangle_objects[t], pa[0], pa[1], pa[2], pb[0], pb[1], pb[2]};
      h.a = a;
      h.b = b;
      h.third = third;
      h.triangle = std::uint32_t(t);
      halves.push_back(h);
    }
  }
  std::sort(halves.begin(), halves.end(), [](const HalfEdge& x, const HalfEdge& y) { return x.key < y.key; });
  for (std::size_t i = 0; i < halves.size();) {
    std::size_t j = i + 1;
    while (j < halves.size() && halves[j].key == halves[i].key) ++j;
    if (j - i == 2) {
      edges_.push_back({halves[i].a, halves[i].b, halves[i].key[0], halves[i].third, halves[i + 1].third,
                        halves[i].triangle, halves[i + 1].triangle});
      // The halves' corners are in the same order (lesser position first).
      if (normals)
        edges_.back().crease = normals->at(halves[i].a) != normals->at(halves[i + 1].a) ||
                               normals->at(halves[i].b) != normals->at(halves[i + 1].b);
    } else {
      for (std::size_t k = i; k < j; ++k)
        edges_.push_back({halves[k].a, halves[k].b, halves[k].key[0], halves[k].third, kOpen, halves[k].triangle, kOpen});
    }
    i = j;
  }
  for (Edge& e : edges_) e.model = e.object < model_objects.size() && model_objects[e.object];
}

void SliverEdges::mark(const std::vector<glm::vec3>& positions, const glm::dmat4& view_projection, double near_plane,
                       int width, int height, const std::vector<std::uint32_t>& drawn_objects,
                       std::vector<std::uint8_t>& marks, unsigned drawn_shift) const {
  marks.assign(std::size_t(width) * std::size_t(height), 0);
  if (drawn_objects.size() != marks.size()) return;
  const glm::dvec2 size(width, height);
  const auto window = [&](const glm::dvec4& c) { return (glm::dvec2(c) / c.w * 0.5 + 0.5) * size; };
  const double w_min = 0.5 * near_plane;
  // Each corner once: its clip position, and its window position where it
  // lies in front of half the near plane (most edges need only those).
  std::vector<glm::dvec4> clip(positions.size());
  std::vector<glm::dvec2> seen(positions.size());
  for (std::size_t i = 0; i < positions.size(); ++i) {
    clip[i] = view_projection * glm::dvec4(glm::dvec3(positions[i]), 1.0);
    if (clip[i].w > w_min) seen[i] = window(clip[i]);
  }
  for (const Edge& e : edges_) {
    glm::dvec4 a = clip[e.a], b = clip[e.b];
    if (e.second_third != kOpen && a.w > w_min && b.w > w_min && clip[e.first_third].w > w_min &&
        clip[e.second_third].w > w_min) {
      const glm::dvec2 pa = seen[e.a], pb = seen[e.b];
      // Each third corner's side of the edge, kept by the snapped corners:
      // moving a, b and c by up to d changes the cross product (b - a) x
      // (c - a) by at most 2 d (|b - a| + |c - a| + |c - b|) + 4 d^2.
      // The lengths' sum is at most their L1 norms' (no square roots):
      // a cross product past that bound settles the side; only one
      // between the two needs the Euclidean lengths.
      const auto side = [&](const glm::dvec2& c) {
        const glm::dvec2 ab = pb - pa, ac = c - pa, bc = c - pb;
        const double cross = ab.x * ac.y - ab.y * ac.x;
        const double d = kSnapPixelsBound;
        const auto l1 = [](const glm::dvec2& v) { return std::abs(v.x) + std::abs(v.y); };
        if (std::abs(cross) > 2.0 * d * (l1(ab) + l1(ac) + l1(bc)) + 4.0 * d * d) return cross > 0.0 ? 1 : -1;
        const double moved = 2.0 * d * (glm::length(ab) + glm::length(ac) + glm::length(bc)) + 4.0 * d * d;
        return cross > moved ? 1 : cross < -moved ? -1 : 0;
      };
      const int s1 = side(seen[e.first_third]), s2 = side(seen[e.second_third]);
      // Inside the surface on the screen: the snapped pair covers both
      // sides, and (no crease) either shows the surface as the other would.
      if (s1 != 0 && s1 == -s2 && !e.crease) continue;
    }
    // The part in front of half the near plane (sliver.geom's cut).
    if (a.w < w_min && b.w < w_min) continue;
    glm::dvec2 pa = seen[e.a], pb = seen[e.b];
    if (!(a.w > w_min && b.w > w_min)) {
      if (a.w < w_min) a = a + (b - a) * ((w_min - a.w) / (b.w - a.w));
      if (b.w < w_min) b = b + (a - b) * ((w_min - b.w) / (a.w - b.w));
      pa = window(a);
      pb = window(b);
    }
    mark_band(pa, pb, e.object, e.model || e.crease, width, height, drawn_objects, drawn_shift, marks);
  }
}

}  // namespace umbra
