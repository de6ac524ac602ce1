#include "core/convex_patches.hpp"

#include <algorithm>
#include <array>
#include <numeric>
#include <utility>

#include <glm/glm.hpp>

#include "core/model_shells.hpp"

namespace umbra {

namespace {

constexpr std::uint32_t kNone = 0xFFFFFFFFu;
// An edge shared by more triangles than this (a fan of fins along one line)
// joins none of them: the pairs would grow with its square.
constexpr std::size_t kMostTrianglesOnAnEdge = 8;

// A triangle in double: its corners and its counter-clockwise normal
// (not unit: cross(b - a, c - a), exact up to one rounding per component).
struct Face {
  glm::dvec3 corner[3];
  glm::dvec3 normal{0.0};
  double normal_length2 = 0.0;
};

// Every corner of `other` lies on or behind `face`'s plane, within
// kPatchPlaneTolerance of the corner's distance from face's first corner.
bool lies_behind(const Face& other, const Face& face) {
  constexpr double tolerance2 = kPatchPlaneTolerance * kPatchPlaneTolerance;
  for (const glm::dvec3& v : other.corner) {
    const glm::dvec3 d = v - face.corner[0];
    const double s = glm::dot(face.normal, d);
    if (s > 0.0 && s * s > tolerance2 * face.normal_length2 * glm::dot(d, d)) return false;
  }
  return true;
}

}  // namespace

std::vector<std::uint32_t> convex_patches(const TriangleModel& model) {
  const std::size_t n = model.triangle_count();
  std::vector<std::uint32_t> first(n);
  std::iota(first.begin(), first.end(), 0u);
  if (n > kMostPatchedModelTriangles) return first;

  // Each triangle's corners, by pointer into the model (no copy of them).
  std::vector<std::array<const glm::vec3*, 3>> corner_of;
  corner_of.reserve(n);
  for (const ModelPart& part : model.parts)
    for (std::size_t t = 0; t < part.triangle_count(); ++t)
      corner_of.push_back({&part.positions[part.indices[3 * t]], &part.positions[part.indices[3 * t + 1]],
                           &part.positions[part.indices[3 * t + 2]]});
  const auto face_of = [&](std::uint32_t t) {
    Face f;
    for (int k = 0; k < 3; ++k) f.corner[k] = glm::dvec3(*corner_of[t][std::size_t(k)]);
    f.normal = glm::cross(f.corner[1] - f.corner[0], f.corner[2] - f.corner[0]);
    f.normal_length2 = glm::dot(f.normal, f.normal);
    return f;
  };

  // Neighbours through shared edges (welded corners), as lists in one array.
  std::uint32_t ids = 0;
  const std::vector<std::array<std::uint32_t, 3>> welded = welded_corners(model, ids);
  std::vector<std::pair<std::uint64_t, std::uint32_t>> edges;
  edges.reserve(3 * n);
  for (std::uint32_t t = 0; t < n; ++t)
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint32_t a = welded[t][k], b = welded[t][(k + 1) % 3];
      if (a != b) edges.push_back({std::uint64_t(std::min(a, b)) << 32 | std::max(a, b), t});
    }
  std::sort(edges.begin(), edges.end());
  std::vector<std::uint32_t> start(n + 1, 0), neighbours;
  const auto for_each_pair = [&](const auto& f) {
    for (std::size_t i = 0; i < edges.size();) {
      std::size_t j = i;
      while (j < edges.size() && edges[j].first == edges[i].first) ++j;
      if (j - i <= kMostTrianglesOnAnEdge)
        for (std::size_t x = i; x < j; ++x)
          for (std::size_t y = i; y < j; ++y)
            if (x != y && edges[x].second != edges[y].second) f(edges[x].second, edges[y].second);
      i = j;
    }
  };
  for_each_pair([&](std::uint32_t a, std::uint32_t) { ++start[a + 1]; });
  for (std::size_t t = 0; t < n; ++t) start[t + 1] += start[t];
  neighbours.resize(start[n]);
  {
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    for_each_pair([&](std::uint32_t a, std::uint32_t b) { neighbours[fill[a]++] = b; });
  }

  std::vector<bool> assigned(n, false);
  std::vector<std::uint32_t> last_tried_by(n, kNone);
  std::vector<Face> members;
  std::vector<std::uint32_t> grown;
  members.reserve(kMostPatchTriangles);
  for (std::uint32_t seed = 0; seed < n; ++seed) {
    if (assigned[seed]) continue;
    assigned[seed] = true;
    members.assign(1, face_of(seed));
    if (!(members[0].normal_length2 > 0.0)) continue;  // no area: alone
    grown.assign(1, seed);
    last_tried_by[seed] = seed;
    for (std::size_t next = 0; next < grown.size() && members.size() < kMostPatchTriangles; ++next) {
      const std::uint32_t t = grown[next];
      for (std::uint32_t i = start[t]; i < start[t + 1] && members.size() < kMostPatchTriangles; ++i) {
        const std::uint32_t c = neighbours[i];
        // A triangle the patch turned down stays turned down: members only
        // add conditions.
        if (assigned[c] || last_tried_by[c] == seed) continue;
        last_tried_by[c] = seed;
        const Face candidate = face_of(c);
        if (!(candidate.normal_length2 > 0.0)) continue;
        const bool convex = std::all_of(members.begin(), members.end(), [&](const Face& m) {
          return lies_behind(candidate, m) && lies_behind(m, candidate);
        });
        if (!convex) continue;
        assigned[c] = true;
        first[c] = seed;
        members.push_back(candidate);
        grown.push_back(c);
      }
    }
  }
  return first;
}

}  // namespace umbra
