#include "reference/shadow_error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

#include <glm/geometric.hpp>

namespace umbra {

namespace {

// Whether two 4-neighbours of the exact image are split by a silhouette, a
// shadow edge or a crease (see ShadowError::interior_pixels).
bool differ(const ExactPixel& a, const ExactPixel& b) {
  if (a.geometry != b.geometry) return true;
  if (!a.geometry) return false;  // background on both sides
  return a.object != b.object || a.visibility != b.visibility || glm::dot(a.normal, b.normal) < kCreaseNDotN;
}

// 1 for the pixels within kArtifactMargin (Chebyshev) of either pixel of a
// differing 4-neighbour pair: the pairs marked, then dilated by a separable
// max, a row pass then a column pass, so the cost is O(pixels).
std::vector<std::uint8_t> near_edges(const std::vector<ExactPixel>& exact, int w, int h) {
  const auto at = [w](int x, int y) { return std::size_t(y) * w + x; };
  std::vector<std::uint8_t> edge(exact.size(), 0);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (x + 1 < w && differ(exact[at(x, y)], exact[at(x + 1, y)])) edge[at(x, y)] = edge[at(x + 1, y)] = 1;
      if (y + 1 < h && differ(exact[at(x, y)], exact[at(x, y + 1)])) edge[at(x, y)] = edge[at(x, y + 1)] = 1;
    }
  }
  const int r = kArtifactMargin;
  std::vector<std::uint8_t> row_max(exact.size(), 0);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int k = std::max(0, x - r); k <= std::min(w - 1, x + r); ++k) row_max[at(x, y)] |= edge[at(k, y)];
    }
  }
  // The column pass writes over the marks: they are in row_max now.
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      edge[at(x, y)] = 0;
      for (int k = std::max(0, y - r); k <= std::min(h - 1, y + r); ++k) edge[at(x, y)] |= row_max[at(x, k)];
    }
  }
  return edge;
}

}  // namespace

ShadowError measure_shadow_error(const Image& rendered, const std::vector<ExactPixel>& exact,
                                 const PixelCoverageOf& finer) {
  ShadowError e;
  const int w = rendered.width, h = rendered.height;
  std::size_t wrong = 0, false_shadow = 0, false_light = 0, artifacts = 0;
  double sum = 0.0;
  const auto same_object = [&](int x, int y, int object) {
    if (x < 0 || y < 0 || x >= w || y >= h) return true;  // the image border is no silhouette
    const ExactPixel& n = exact[std::size_t(y) * w + x];
    return n.geometry && n.object == object;
  };
  const std::vector<std::uint8_t> near_edge = near_edges(exact, w, h);
  // Interior pixels off by more than kArtifactError, judged by the centres
  // alone; with `finer` they are looked at more closely below, unless their
  // neighbourhoods would cover more than kFinerShare of the image (they do
  // once there are that many of them: then they are only counted).
  const std::size_t finer_budget = std::max(exact.size() / kFinerShare, kFinerPixels);
  std::size_t centre_artifacts = 0;
  std::vector<std::size_t> candidates;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const ExactPixel& p = exact[std::size_t(y) * w + x];
      if (!p.geometry || std::abs(p.n_dot_l) < kGrazingNDotL) continue;
      if (!same_object(x - 1, y, p.object) || !same_object(x + 1, y, p.object) || !same_object(x, y - 1, p.object) ||
          !same_object(x, y + 1, p.object))
        continue;
      const double v = rendered.pixels[std::size_t(y) * w + x] / 255.0;
      const double d = v - p.visibility;
      sum += std::abs(d);
      ++e.pixels;
      if (std::abs(d) > 0.5) {
        ++wrong;
        (d < 0.0 ? false_shadow : false_light)++;
      }
      // Interior pixels are a subset of the measured ones: a silhouette
      // pixel skipped above is itself marked near an edge.
      if (!near_edge[std::size_t(y) * w + x] && (p.visibility == 0.0 || p.visibility == 1.0)) {
        ++e.interior_pixels;
        if (std::abs(d) > kArtifactError && ++centre_artifacts <= finer_budget && finer)
          candidates.push_back(std::size_t(y) * w + x);
      }
    }
  }
  const bool look_finer = finer && centre_artifacts > 0 && centre_artifacts <= finer_budget;
  // Calls visit(index) for each pixel within kArtifactMargin (Chebyshev) of
  // pixel i, clipped to the image, until visit answers false.
  const auto for_each_near = [w, h](std::size_t i, auto&& visit) {
    const int r = kArtifactMargin, cx = int(i % w), cy = int(i / w);
    for (int y = std::max(0, cy - r); y <= std::min(h - 1, cy + r); ++y)
      for (int x = std::max(0, cx - r); x <= std::min(w - 1, cx + r); ++x)
        if (!visit(std::size_t(y) * w + x)) return;
  };
  // The neighbourhoods to sample finer.
  std::vector<std::uint8_t> which;
  std::size_t to_sample = 0;
  if (look_finer) {
    which.assign(exact.size(), 0);
    for (const std::size_t i : candidates)
      for_each_near(i, [&](std::size_t n) {
        to_sample += which[n] == 0;
        which[n] = 1;
        return true;
      });
  }
  if (!look_finer || to_sample > finer_budget) {
    artifacts = centre_artifacts;  // the centres' verdict: an upper bound
  } else {
    // A candidate is an artifact only if its whole neighbourhood is
    // covered by its own exact value (or by no geometry at all).
    const std::vector<PixelCoverage> coverage = finer(which);
    if (coverage.size() != exact.size())
      throw std::invalid_argument("measure_shadow_error: the finer coverage has " + std::to_string(coverage.size()) +
                                  " pixels, the image " + std::to_string(exact.size()));
    for (const std::size_t i : candidates) {
      const PixelCoverage own = exact[i].visibility == 0.0 ? PixelCoverage::dark : PixelCoverage::lit;
      bool uniform = true;
      for_each_near(i, [&](std::size_t n) {
        uniform = coverage[n] == own || coverage[n] == PixelCoverage::unknown;
        return uniform;
      });
      if (uniform)
        ++artifacts;
      else
        --e.interior_pixels;  // an edge between pixel centres: not interior after all
    }
  }
  if (e.pixels > 0) {
    const double n = double(e.pixels);
    e.mae = sum / n;
    e.wrong = wrong / n;
    e.false_shadow = false_shadow / n;
    e.false_light = false_light / n;
  }
  if (e.interior_pixels > 0) e.artifacts = artifacts / double(e.interior_pixels);
  return e;
}

}  // namespace umbra
