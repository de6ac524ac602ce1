#include "reference/certified_frame.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include <glm/geometric.hpp>

#include "core/scene.hpp"
#include "core/shapes/shape.hpp"
#include "reference/ray_cast.hpp"

namespace umbra {

namespace {

// The object and the side of the light its surface turns to.
std::uint32_t surface_code(std::uint32_t code) { return code >> 2; }
std::uint32_t verdict(std::uint32_t code) { return code & 3u; }

}  // namespace

int silhouette_ring(const RenderRequest& request) {
  const Camera& camera = request.camera;
  // World size of a pixel at unit distance, along the image's height.
  const double pixel_per_distance = 2.0 * std::tan(camera.fov_y_deg * 3.14159265358979323846 / 360.0) / request.height;
  double most = 0.0;
  for (const SceneObject& o : request.scene.objects) {
    const double distance = tessellation_error(o).distance;
    if (distance <= 0.0) continue;
    const Aabb b = object_bounds(o);
    const glm::dvec3 nearest = glm::clamp(camera.position, b.min, b.max);
    const double d = std::max(glm::length(nearest - camera.position), camera.near_plane);
    most = std::max(most, distance / (d * pixel_per_distance));
  }
  // The rasterised outline and the exact one are at most `most` pixels
  // apart; a pixel between them is at most that far from a pixel whose
  // rasterised object differs from its neighbour's.
  return 1 + int(std::ceil(std::min(most, 1e6)));
}

namespace {

// dst[x] = the OR of src over [x - r, x + r] (0 outside [0, n)), by
// doubling: after k steps a[i] is the OR of 2^k padded values from i. Each
// step is a plain loop over two buffers, which the compiler vectorises.
void dilate_row(const std::uint8_t* src, std::uint8_t* dst, int n, int r, std::vector<std::uint8_t>& a,
                std::vector<std::uint8_t>& b) {
  const std::size_t length = std::size_t(2 * r + 1);  // the window
  const std::size_t padded = std::size_t(n) + 2 * std::size_t(r);
  a.assign(padded, 0);
  std::copy(src, src + n, a.begin() + r);
  b.resize(padded);
  std::size_t span = 1;  // a[i] = OR of padded[i, i + span)
  while (2 * span <= length) {
    std::uint8_t* next = b.data();
    const std::uint8_t* cur = a.data();
    const std::size_t end = padded - span;
    for (std::size_t i = 0; i < end; ++i) next[i] = cur[i] | cur[i + span];
    for (std::size_t i = end; i < padded; ++i) next[i] = cur[i];
    a.swap(b);
    span *= 2;
  }
  const std::size_t tail = length - span;  // the window is [x, x + span) and [x + tail, x + tail + span)
  const std::uint8_t* cur = a.data();
  for (int x = 0; x < n; ++x) dst[x] = cur[x] | cur[std::size_t(x) + tail];
}

}  // namespace

std::vector<std::uint8_t> pixels_to_ray_cast(const PixelCertificates& certificates, int width, int height,
                                             int ring) {
  const std::vector<std::uint32_t>& codes = certificates.codes;
  const std::vector<std::uint8_t>& slivers = certificates.slivers;
  if (codes.size() != std::size_t(width) * std::size_t(height) || (!slivers.empty() && slivers.size() != codes.size()))
    throw std::invalid_argument("pixels_to_ray_cast: " + std::to_string(codes.size()) + " codes and " +
                                std::to_string(slivers.size()) + " sliver marks for " + std::to_string(width) +
                                " x " + std::to_string(height) + " pixels");
  std::vector<std::uint8_t> edge(codes.size(), 0);
  if (codes.empty()) return edge;
  const std::size_t w = std::size_t(width);
  // Pixels beside a change of object, or of the side of the light the
  // surface turns to (a crease: the reference's camera ray may meet the
  // other face), then grown by ring - 1 each way (a separable max: a row
  // pass, then a column pass). The loops are branch-free, a row at a time,
  // so that they vectorise: this runs on every certified frame.
  std::vector<std::uint8_t> right(w, 0);  // right[x]: x and x + 1 differ
  for (std::size_t y = 0; y < std::size_t(height); ++y) {
    const std::uint32_t* c = codes.data() + y * w;
    std::uint8_t* e = edge.data() + y * w;
    for (std::size_t x = 0; x + 1 < w; ++x) right[x] = std::uint8_t(surface_code(c[x] ^ c[x + 1]) != 0);
    e[0] |= right[0] & std::uint8_t(w > 1);
    for (std::size_t x = 1; x + 1 < w; ++x) e[x] |= std::uint8_t(right[x] | right[x - 1]);
    if (w > 1) e[w - 1] |= right[w - 2];
    if (y + 1 < std::size_t(height)) {
      const std::uint32_t* below = c + w;
      std::uint8_t* e_below = e + w;
      for (std::size_t x = 0; x < w; ++x) {
        const std::uint8_t differs = std::uint8_t(surface_code(c[x] ^ below[x]) != 0);
        e[x] |= differs;
        e_below[x] |= differs;
      }
    }
  }
  // Outside the image is another surface: nothing past the border shows
  // whether the raster and the reference part there (an outline on the
  // border row that the snapped triangle covers and the true one misses; a
  // curved shape whose true surface bulges onto the image from faces just
  // off it), so the border pixels count as beside a change.
  std::fill(edge.begin(), edge.begin() + std::ptrdiff_t(w), std::uint8_t(1));
  std::fill(edge.end() - std::ptrdiff_t(w), edge.end(), std::uint8_t(1));
  for (std::size_t y = 0; y < std::size_t(height); ++y) edge[y * w] = edge[y * w + w - 1] = 1;
  // A ring wider than the image covers it: every pixel is within it.
  const int r = std::min(std::max(0, ring - 1), std::max(width, height));
  if (r > 0) {
    std::vector<std::uint8_t> rows(codes.size());
    std::vector<std::uint8_t> a, b;
    for (std::size_t y = 0; y < std::size_t(height); ++y)
      dilate_row(edge.data() + y * w, rows.data() + y * w, width, r, a, b);
    // The columns, a row at a time: count[x] is how many rows of the
    // window [t - r, t + r] have rows[x] set.
    std::vector<std::uint32_t> count(w, 0);
    for (int y = 0; y < height + r; ++y) {
      if (y < height) {
        const std::uint8_t* add = rows.data() + std::size_t(y) * w;
        for (std::size_t x = 0; x < w; ++x) count[x] += add[x];
      }
      const int leaving = y - 2 * r - 1;
      if (leaving >= 0) {
        const std::uint8_t* sub = rows.data() + std::size_t(leaving) * w;
        for (std::size_t x = 0; x < w; ++x) count[x] -= sub[x];
      }
      const int target = y - r;
      if (target >= 0 && target < height) {
        std::uint8_t* e = edge.data() + std::size_t(target) * w;
        for (std::size_t x = 0; x < w; ++x) e[x] = std::uint8_t(count[x] != 0);
      }
    }
  }
  std::uint8_t* __restrict e = edge.data();
  const std::uint32_t* __restrict c = codes.data();
  for (std::size_t i = 0; i < codes.size(); ++i) e[i] |= std::uint8_t(verdict(c[i]) == PixelCertificates::kUncertain);
  if (!slivers.empty()) {
    const std::uint8_t* __restrict marked = slivers.data();
    for (std::size_t i = 0; i < codes.size(); ++i) e[i] |= std::uint8_t(marked[i] != 0);
  }
  return edge;
}

void settle_certified_frame(RenderResult& result, const RenderRequest& request,
                            const std::function<bool()>& stop_requested) {
  if (!result.certificates) return;
  const auto start = std::chrono::steady_clock::now();
  const PixelCertificates& c = *result.certificates;
  const int w = request.width, h = request.height;
  const std::vector<std::uint8_t> cast = pixels_to_ray_cast(c, w, h, silhouette_ring(request));
  std::vector<std::size_t> indices;
  // Most pixels are not cast: skip eight at a time.
  indices.reserve(cast.size() / 16);
  std::size_t i = 0;
  for (; i + 8 <= cast.size(); i += 8) {
    std::uint64_t eight;
    std::memcpy(&eight, cast.data() + i, 8);
    if (eight == 0) continue;
    for (std::size_t k = i; k < i + 8; ++k)
      if (cast[k]) indices.push_back(k);
  }
  for (; i < cast.size(); ++i)
    if (cast[i]) indices.push_back(i);
  CertifiedShare share;
  share.pixels = cast.size();
  share.ray_cast = indices.size();
  if (!indices.empty()) {
    const ExactView view(request, stop_requested);
    const std::vector<ExactPixel> exact = view.pixels_at(indices, stop_requested);
    Image& image = result.image;
    for (std::size_t k = 0; k < indices.size(); ++k) {
      const std::size_t i = indices[k];
      // The "exact" output's value (exact_image): no geometry is lit.
      const double v = exact[k].geometry ? exact[k].visibility : 1.0;
      if (image.channels == 1) {
        image.pixels[i] = std::uint8_t(std::lround(255.0 * v));
      } else if (v < 0.5) {
        // A light of no size: v is 0 or 1, and the main pass drew 1.
        for (int c3 = 0; c3 < 3; ++c3) image.pixels[3 * i + c3] = c.unlit.pixels[3 * i + c3];
      }
    }
  }
  result.certified = share;
  result.certificates.reset();
  result.timings.settle_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace umbra
