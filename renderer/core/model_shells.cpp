#include "core/model_shells.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <numeric>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

namespace umbra {

namespace {

struct Triangle {
  glm::dvec3 a, b, c;
  Aabb box;
};

// Whether the triangle comes within the box (centre, half sizes): no
// separating axis among the box's three, the triangle's normal and the
// nine crossings of their edges (Akenine-Moller). Touching counts.
bool overlaps(const Triangle& t, const glm::dvec3& centre, const glm::dvec3& half) {
  for (int k = 0; k < 3; ++k)
    if (t.box.min[k] > centre[k] + half[k] || t.box.max[k] < centre[k] - half[k]) return false;
  const glm::dvec3 v[3] = {t.a - centre, t.b - centre, t.c - centre};
  const glm::dvec3 e[3] = {v[1] - v[0], v[2] - v[1], v[0] - v[2]};
  const auto separates = [&](const glm::dvec3& axis) {
    const double p0 = glm::dot(v[0], axis), p1 = glm::dot(v[1], axis), p2 = glm::dot(v[2], axis);
    const double r = half.x * std::abs(axis.x) + half.y * std::abs(axis.y) + half.z * std::abs(axis.z);
    return std::min({p0, p1, p2}) > r || std::max({p0, p1, p2}) < -r;
  };
  for (const glm::dvec3& edge : e)
    for (int k = 0; k < 3; ++k) {
      glm::dvec3 unit(0.0);
      unit[k] = 1.0;
      const glm::dvec3 axis = glm::cross(unit, edge);
      if (axis != glm::dvec3(0.0) && separates(axis)) return false;
    }
  const glm::dvec3 normal = glm::cross(e[0], e[1]);
  return !(normal != glm::dvec3(0.0) && separates(normal));
}

// Whether `p` is inside the shell: +1 inside, 0 outside, -1 unsure (the
// ray from p passes near an edge or a corner, or along a face). The ray's
// direction is no simple one, so that a grid of vertices is not met
// square on. It rises: a shell open only at its lowest height is closed
// by a floor there that the ray from a point above it never meets.
int parity(const std::vector<Triangle>& triangles, const glm::dvec3& p) {
  const glm::dvec3 d = glm::normalize(glm::dvec3(0.5773502, 0.6178, 0.5340711));
  constexpr double kEpsilon = 2.2e-16;
  int crossings = 0;
  for (const Triangle& t : triangles) {
    const glm::dvec3 e1 = t.b - t.a, e2 = t.c - t.a;
    const glm::dvec3 normal = glm::cross(e1, e2);
    if (normal == glm::dvec3(0.0)) continue;  // no area (two corners equal, or in a line): crossed by no ray
    const double scale = glm::length(e1) * glm::length(e2);
    const glm::dvec3 q = glm::cross(d, e2);
    const double det = glm::dot(e1, q);
    const glm::dvec3 s = p - t.a;
    const double reach = glm::length(s);
    if (std::abs(det) <= 1e-9 * scale) {
      // Along the face's plane: unsure if the ray lies in it.
      if (std::abs(glm::dot(s, normal)) <= 1e-9 * glm::length(normal) * (reach + 1e-300)) return -1;
      continue;
    }
    const double u = glm::dot(s, q) / det;
    const glm::dvec3 r = glm::cross(s, e1);
    const double w = glm::dot(d, r) / det;
    const double t_hit = glm::dot(e2, r) / det;
    // How far rounding can move the barycentrics: the products' errors
    // (a few ulps of |s| |e| and of |e1| |e2|) over |det|, sixteen times.
    const double near = 16.0 * kEpsilon * (reach * (glm::length(e1) + glm::length(e2)) + scale) / std::abs(det) + 1e-9;
    if (u < -near || w < -near || u + w > 1.0 + near) continue;
    if (u < near || w < near || u + w > 1.0 - near) return -1;  // near an edge: unsure
    if (std::abs(t_hit) <= 1e-9 * (1.0 + reach)) return -1;     // p on the face
    if (t_hit > 0.0) ++crossings;
  }
  return crossings % 2;
}

// The shell's triangles' box, and whether `core` is proved inside it.
// `work` counts the triangles looked at.
bool fits(const std::vector<Triangle>& triangles, const Aabb& core, double margin, std::uint64_t& work) {
  if (core.empty()) return false;
  const glm::dvec3 centre = core.center(), half = 0.5 * core.extent() + glm::dvec3(margin);
  for (const Triangle& t : triangles) {
    ++work;
    if (overlaps(t, centre, half)) return false;
  }
  work += triangles.size();
  return parity(triangles, centre) == 1;
}

// A coordinate's bits, -0 as 0: positions equal as numbers weld (as
// is_closed welds them), whatever bits an exporter wrote.
std::uint64_t bits_of(float f) {
  if (f == 0.0f) f = 0.0f;
  std::uint32_t b;
  std::memcpy(&b, &f, sizeof b);
  return b;
}

}  // namespace

std::vector<std::array<std::uint32_t, 3>> welded_corners(const TriangleModel& model, std::uint32_t& ids) {
  std::vector<std::pair<std::array<std::uint64_t, 2>, std::uint32_t>> keys;
  std::vector<std::array<std::uint32_t, 3>> corners;
  for (const ModelPart& part : model.parts) {
    const auto base = std::uint32_t(keys.size());
    for (std::uint32_t v = 0; v < part.positions.size(); ++v) {
      const glm::vec3& p = part.positions[v];
      keys.push_back({{bits_of(p.x) << 32 | bits_of(p.y), bits_of(p.z)}, base + v});
    }
    for (std::size_t t = 0; t < part.triangle_count(); ++t)
      corners.push_back({base + part.indices[3 * t], base + part.indices[3 * t + 1], base + part.indices[3 * t + 2]});
  }
  std::sort(keys.begin(), keys.end());
  std::vector<std::uint32_t> welded(keys.size());
  ids = keys.empty() ? 0 : 1;
  for (std::size_t i = 0; i < keys.size(); ++i) {
    if (i > 0 && keys[i].first != keys[i - 1].first) ++ids;
    welded[keys[i].second] = ids - 1;
  }
  for (auto& c : corners) c = {welded[c[0]], welded[c[1]], welded[c[2]]};
  return corners;
}

namespace {

// The directed edges of the triangles (welded corners) whose reverse is
// not among them: none when they close up. False when there is no edge,
// or a directed edge twice (no shell then). Triangles with two equal
// corners are left out (as is_closed leaves them).
bool open_edges(const std::vector<std::array<std::uint32_t, 3>>& triangles, std::vector<std::uint64_t>& open) {
  std::vector<std::uint64_t> edges;
  for (const auto& c : triangles) {
    if (c[0] == c[1] || c[1] == c[2] || c[2] == c[0]) continue;
    for (int k = 0; k < 3; ++k) edges.push_back(std::uint64_t(c[k]) << 32 | c[(k + 1) % 3]);
  }
  if (edges.empty()) return false;
  std::sort(edges.begin(), edges.end());
  if (std::adjacent_find(edges.begin(), edges.end()) != edges.end()) return false;
  open.clear();
  for (const std::uint64_t e : edges)
    if (!std::binary_search(edges.begin(), edges.end(), (e << 32) | (e >> 32))) open.push_back(e);
  return true;
}

// Whether a shell's open edges (open_edges, not none; `corners` its
// triangles' welded corners and `triangles` their coordinates, in the same
// order) close up once a floor is laid at height `floor`: each lies at that
// height (both corners), and they meet an even number of times at each
// corner, so that they bound a region of that plane (even-odd) which closes
// the shell.
bool closes_over_floor(const std::vector<std::uint64_t>& open, const std::vector<std::array<std::uint32_t, 3>>& corners,
                       const std::vector<Triangle>& triangles, double floor) {
  std::vector<std::pair<std::uint32_t, double>> heights;  // a corner's id, its y
  for (std::size_t t = 0; t < corners.size(); ++t) {
    heights.push_back({corners[t][0], triangles[t].a.y});
    heights.push_back({corners[t][1], triangles[t].b.y});
    heights.push_back({corners[t][2], triangles[t].c.y});
  }
  std::sort(heights.begin(), heights.end());
  const auto y_of = [&](std::uint32_t id) {
    return std::lower_bound(heights.begin(), heights.end(), std::make_pair(id, -std::numeric_limits<double>::infinity()))
        ->second;
  };
  std::vector<std::uint32_t> open_corners;
  for (const std::uint64_t e : open) {
    const auto from = std::uint32_t(e >> 32), to = std::uint32_t(e);
    if (y_of(from) != floor || y_of(to) != floor) return false;
    open_corners.push_back(from);
    open_corners.push_back(to);
  }
  std::sort(open_corners.begin(), open_corners.end());
  for (std::size_t i = 0; i < open_corners.size();) {
    std::size_t j = i;
    while (j < open_corners.size() && open_corners[j] == open_corners[i]) ++j;
    if ((j - i) % 2 != 0) return false;
    i = j;
  }
  return true;
}

// Which shell each triangle (its welded corners, `ids` distinct) is in.
std::vector<std::uint32_t> shells_of(const std::vector<std::array<std::uint32_t, 3>>& corners, std::uint32_t ids,
                                     std::uint32_t& shells) {
  // Triangles joined through a shared corner are one shell (union-find).
  std::vector<std::uint32_t> parent(ids);
  std::iota(parent.begin(), parent.end(), 0u);
  const auto find = [&](std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (const auto& c : corners) {
    const std::uint32_t r = find(c[0]);
    parent[find(c[1])] = r;
    parent[find(c[2])] = r;
  }
  // Roots numbered in order of first use.
  std::vector<std::uint32_t> number(parent.size(), ~0u), out(corners.size());
  shells = 0;
  for (std::size_t t = 0; t < corners.size(); ++t) {
    std::uint32_t& n = number[find(corners[t][0])];
    if (n == ~0u) n = shells++;
    out[t] = n;
  }
  return out;
}

}  // namespace

std::vector<std::uint32_t> triangle_shells(const TriangleModel& model, std::uint32_t& shells) {
  std::uint32_t ids = 0;
  const std::vector<std::array<std::uint32_t, 3>> corners = welded_corners(model, ids);
  return shells_of(corners, ids, shells);
}

std::vector<Aabb> shell_cores(const TriangleModel& model, double margin, bool open_floors) {
  std::vector<Aabb> cores;
  std::vector<Triangle> all;
  for (const ModelPart& part : model.parts)
    for (std::size_t t = 0; t < part.triangle_count(); ++t) {
      Triangle tri;
      tri.a = glm::dvec3(part.positions[part.indices[3 * t]]);
      tri.b = glm::dvec3(part.positions[part.indices[3 * t + 1]]);
      tri.c = glm::dvec3(part.positions[part.indices[3 * t + 2]]);
      tri.box.extend(tri.a), tri.box.extend(tri.b), tri.box.extend(tri.c);
      all.push_back(tri);
    }
  std::uint32_t shells = 0, ids = 0;
  const std::vector<std::array<std::uint32_t, 3>> corners = welded_corners(model, ids);
  const std::vector<std::uint32_t> shell_of = shells_of(corners, ids, shells);
  std::vector<std::array<std::uint32_t, 3>> shell_corners;
  // Candidates that fail late could cost 70 passes over a shell: the
  // looking stops at kShellCoreWork passes over the whole model.
  std::uint64_t work = 0;
  const std::uint64_t budget = std::uint64_t(kShellCoreWork) * all.size() + 65536;
  // Triangles by shell.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> by_shell(all.size());
  for (std::size_t t = 0; t < all.size(); ++t) by_shell[t] = {shell_of[t], std::uint32_t(t)};
  std::sort(by_shell.begin(), by_shell.end());
  std::vector<Triangle> shell;
  for (std::size_t first = 0; first < by_shell.size();) {
    std::size_t last = first;
    while (last < by_shell.size() && by_shell[last].first == by_shell[first].first) ++last;
    shell.clear();
    shell_corners.clear();
    Aabb bounds;
    for (std::size_t i = first; i < last; ++i) {
      shell.push_back(all[by_shell[i].second]);
      shell_corners.push_back(corners[by_shell[i].second]);
      bounds.extend(shell.back().box);
    }
    first = last;
    if (shell.size() > kShellCoreMaxTriangles) continue;
    // The whole model closes up; each shell must on its own, or the
    // parity below would count the crossings of an open piece. With
    // open_floors, a shell open only at its lowest height (a building
    // without its ground face) is closed by a floor there, which a rising
    // ray from above it never meets (parity's, and the callers').
    std::vector<std::uint64_t> open;
    if (!open_edges(shell_corners, open)) continue;
    const bool closed = open.empty();
    if (!closed && !(open_floors && closes_over_floor(open, shell_corners, shell, bounds.min.y))) continue;
    // Above an open floor, a box at least twice the margin up: a rising
    // ray from it passes the open edges far above Embree's rounding there
    // (a red team measured misses up to 1.7e-7 of the coordinates: the
    // margin is 1e-5 of them), not the 1 % of the shell's height the
    // candidates on the floor leave.
    const double lowest = closed ? -std::numeric_limits<double>::infinity() : bounds.min.y + 2.0 * margin;
    // Candidates, largest first: the bounds shrunk about their centre, or
    // about the middle of their floor, by fractions across and up.
    static constexpr double kFractions[] = {0.98, 0.9, 0.75, 0.6, 0.45, 0.3};
    std::vector<Aabb> candidates;
    const glm::dvec3 centre = bounds.center(), half = 0.5 * bounds.extent();
    for (const double across : kFractions)
      for (const double up : kFractions)
        for (const bool on_floor : {false, true}) {
          Aabb box;
          box.min = {centre.x - across * half.x, 0.0, centre.z - across * half.z};
          box.max = {centre.x + across * half.x, 0.0, centre.z + across * half.z};
          const double floor_gap = (1.0 - 0.98) * half.y;
          box.min.y = on_floor ? bounds.min.y + floor_gap : centre.y - up * half.y;
          box.max.y = on_floor ? bounds.min.y + floor_gap + up * 2.0 * half.y * 0.98 : centre.y + up * half.y;
          box.min.y = std::max(box.min.y, lowest);
          if (box.min.x < box.max.x && box.min.y < box.max.y && box.min.z < box.max.z) candidates.push_back(box);
        }
    const auto volume = [](const Aabb& b) {
      const glm::dvec3 e = b.extent();
      return e.x * e.y * e.z;
    };
    // First of all the bounds themselves, shrunk by twice the margin: a
    // shell that is a box (a block of a city) fills them.
    Aabb whole = bounds;
    whole.min += glm::dvec3(2.0 * margin);
    whole.max -= glm::dvec3(2.0 * margin);
    if (whole.min.x < whole.max.x && whole.min.y < whole.max.y && whole.min.z < whole.max.z) candidates.push_back(whole);
    std::stable_sort(candidates.begin(), candidates.end(),
                     [&](const Aabb& a, const Aabb& b) { return volume(a) > volume(b); });
    for (const Aabb& candidate : candidates)
      if (work < budget && fits(shell, candidate, margin, work)) {
        cores.push_back(candidate);
        break;
      }
  }
  return cores;
}

std::vector<Aabb> shell_clusters(const TriangleModel& model, const std::vector<std::uint32_t>& shell_of,
                                 std::uint32_t shell_count, int fewest, int most) {
  std::vector<Aabb> out;
  if (shell_of.empty()) return out;
  struct Triangle {
    glm::dvec3 centre;
    Aabb box;
  };
  // The triangles, in order of shell (a counting sort).
  std::vector<std::size_t> start(std::size_t(shell_count) + 1, 0);
  for (const std::uint32_t s : shell_of) ++start[s + 1];
  for (std::size_t s = 0; s < shell_count; ++s) start[s + 1] += start[s];
  std::vector<std::size_t> next(start.begin(), start.end() - 1);
  std::vector<Triangle> triangles(shell_of.size());
  std::size_t index = 0;
  for (const ModelPart& part : model.parts) {
    for (std::size_t t = 0; t < part.triangle_count(); ++t, ++index) {
      const glm::dvec3 a(part.positions[part.indices[3 * t]]), b(part.positions[part.indices[3 * t + 1]]),
          c(part.positions[part.indices[3 * t + 2]]);
      Triangle& tri = triangles[next[shell_of[index]]++];
      tri.box.min = glm::min(glm::min(a, b), c);
      tri.box.max = glm::max(glm::max(a, b), c);
      tri.centre = 0.5 * (tri.box.min + tri.box.max);
    }
  }
  // A cluster: triangles [first, last) and their box.
  struct Cluster {
    std::size_t first, last;
    Aabb box;
  };
  const auto cluster_of = [&](std::size_t first, std::size_t last) {
    Cluster c{first, last, {}};
    for (std::size_t i = first; i < last; ++i)
      c.box.min = glm::min(c.box.min, triangles[i].box.min), c.box.max = glm::max(c.box.max, triangles[i].box.max);
    return c;
  };
  const auto longest_axis = [](const Aabb& b) {
    const glm::dvec3 e = b.extent();
    return e.x >= e.y && e.x >= e.z ? 0 : (e.y >= e.z ? 1 : 2);
  };
  std::vector<Cluster> clusters;
  // The shells, each a run of the sorted triangles.
  for (std::size_t s = 0; s < shell_count; ++s)
    if (start[s] < start[s + 1]) clusters.push_back(cluster_of(start[s], start[s + 1]));
  if (int(clusters.size()) > most) {
    // More shells than boxes: the shells halved at the median of their
    // boxes' centres along the longest side, and the halves again.
    std::vector<Cluster> shells = std::move(clusters);
    clusters.clear();
    int depth = 0;
    while (depth < 30 && (2 << depth) <= most) ++depth;
    const auto split = [&](auto&& self, std::size_t first, std::size_t last, int levels) -> void {
      if (levels == 0 || last - first < 2) {
        Cluster c{0, 0, {}};
        for (std::size_t i = first; i < last; ++i) c.box.extend(shells[i].box);
        clusters.push_back(c);
        return;
      }
      Aabb centres;
      for (std::size_t i = first; i < last; ++i) centres.extend(shells[i].box.center());
      const int axis = longest_axis(centres);
      const std::size_t middle = first + (last - first) / 2;
      std::nth_element(shells.begin() + std::ptrdiff_t(first), shells.begin() + std::ptrdiff_t(middle),
                       shells.begin() + std::ptrdiff_t(last), [axis](const Cluster& a, const Cluster& b) {
                         return a.box.center()[axis] < b.box.center()[axis];
                       });
      self(self, first, middle, levels - 1);
      self(self, middle, last, levels - 1);
    };
    split(split, 0, shells.size(), depth);
  } else {
    // Fewer: the cluster of most triangles halved at the median of their
    // centres along the longest side of those, until there are `fewest`.
    while (int(clusters.size()) < fewest) {
      const auto biggest = std::max_element(clusters.begin(), clusters.end(), [](const Cluster& a, const Cluster& b) {
        return a.last - a.first < b.last - b.first;
      });
      if (biggest->last - biggest->first < 2) break;
      const std::size_t first = biggest->first, last = biggest->last, middle = first + (last - first) / 2;
      Aabb centres;
      for (std::size_t i = first; i < last; ++i)
        centres.min = glm::min(centres.min, triangles[i].centre), centres.max = glm::max(centres.max, triangles[i].centre);
      const int axis = longest_axis(centres);
      std::nth_element(triangles.begin() + std::ptrdiff_t(first), triangles.begin() + std::ptrdiff_t(middle),
                       triangles.begin() + std::ptrdiff_t(last),
                       [axis](const Triangle& a, const Triangle& b) { return a.centre[axis] < b.centre[axis]; });
      *biggest = cluster_of(first, middle);
      clusters.push_back(cluster_of(middle, last));
    }
  }
  for (const Cluster& c : clusters) out.push_back(c.box);
  return out;
}

}  // namespace umbra
