#include "reference/certified_frame.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "core/raster_outline.hpp"
#include "reference/ray_cast.hpp"
#include "reference/worker_pool.hpp"

namespace umbra {

namespace {

// The object and the side of the light its surface turns to.
std::uint32_t surface_code(std::uint32_t code) { return code >> PixelCertificates::kSurfaceShift; }
std::uint32_t verdict(std::uint32_t code) { return code & PixelCertificates::kVerdictMask; }

}  // namespace

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

// Calls band(y0, y1) for bands of rows covering [0, height), at once on
// the workers (worker_pool.hpp): the passes below touch every pixel of
// every certified frame, and a GPU machine's cores are many and slow (on
// the H200 machine the ring of a 960x540 frame took a median 2.2 ms on
// one).
void for_each_band(int height, const std::function<void(int, int)>& band) {
  const int bands = std::clamp(height / 32, 1, worker_count());
  run_on_workers(bands, [&](int i) {
    band(int(std::int64_t(height) * i / bands), int(std::int64_t(height) * (i + 1) / bands));
  });
}

// Down a band of rows, each row of `edge` (width w, `height` rows): 1
// where the pixel's surface differs from a 4-neighbour's, and along the
// image's border. Writes the band's rows only; each pair of rows is
// compared once (the row below's comparison is the next row's above).
// Branch-free loops, which the compiler vectorises.
class ChangeFinder {
 public:
  ChangeFinder(const std::uint32_t* codes, std::size_t w, int height, int first_row)
      : codes_(codes), w_(w), height_(height), right_(w, 0), above_(w, 0), below_(w, 0) {
    if (first_row > 0) compare_with_next(first_row - 1, above_);
  }

  // Row y: the band's rows in order, from first_row.
  void row(int y, std::uint8_t* edge) {
    const std::uint32_t* c = codes_ + std::size_t(y) * w_;
    std::uint8_t* e = edge + std::size_t(y) * w_;
    if (y + 1 < height_)
      compare_with_next(y, below_);
    else
      std::fill(below_.begin(), below_.end(), std::uint8_t(0));
    for (std::size_t x = 0; x + 1 < w_; ++x) right_[x] = std::uint8_t(surface_code(c[x] ^ c[x + 1]) != 0);
    const std::uint8_t *above = above_.data(), *below = below_.data(), *right = right_.data();
    e[0] = std::uint8_t(above[0] | below[0] | (w_ > 1 ? right[0] : 0));
    for (std::size_t x = 1; x < w_; ++x) e[x] = std::uint8_t(above[x] | below[x] | right[x] | right[x - 1]);
    if (w_ > 1) e[w_ - 1] = std::uint8_t(above[w_ - 1] | below[w_ - 1] | right[w_ - 2]);
    // Outside the image is another surface: nothing past the border shows
    // whether the raster and the reference part there (an outline on the
    // border row that the snapped triangle covers and the true one misses;
    // a curved shape whose true surface bulges onto the image from faces
    // just off it), so the border pixels count as beside a change.
    if (y == 0 || y == height_ - 1) std::fill(e, e + w_, std::uint8_t(1));
    e[0] = e[w_ - 1] = 1;
    above_.swap(below_);
  }

 private:
  // out[x]: rows y and y + 1 see different surfaces at x.
  void compare_with_next(int y, std::vector<std::uint8_t>& out) const {
    const std::uint32_t* c = codes_ + std::size_t(y) * w_;
    const std::uint32_t* next = c + w_;
    for (std::size_t x = 0; x < w_; ++x) out[x] = std::uint8_t(surface_code(c[x] ^ next[x]) != 0);
  }

  const std::uint32_t* codes_;
  std::size_t w_;
  int height_;
  std::vector<std::uint8_t> right_, above_, below_;
};

// Adds to row y of `cast` the pixels the certificates leave uncertain and
// those the sliver pass marked.
void add_uncertain(const PixelCertificates& certificates, std::size_t w, int y, std::uint8_t* cast) {
  const std::size_t first = std::size_t(y) * w;
  std::uint8_t* __restrict e = cast + first;
  const std::uint32_t* __restrict c = certificates.codes.data() + first;
  for (std::size_t x = 0; x < w; ++x) e[x] |= std::uint8_t(verdict(c[x]) == PixelCertificates::kUncertain);
  if (!certificates.slivers.empty()) {
    const std::uint8_t* __restrict marked = certificates.slivers.data() + first;
    for (std::size_t x = 0; x < w; ++x) e[x] |= std::uint8_t(marked[x] != 0);
  }
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
  // pass, then a column pass), then the uncertain and marked pixels. In
  // bands of rows at once; each band writes its own rows only.
  // A ring wider than the image covers it: every pixel is within it.
  const int r = std::min(std::max(0, ring - 1), std::max(width, height));
  if (r == 0) {
    for_each_band(height, [&](int y0, int y1) {
      ChangeFinder changes(codes.data(), w, height, y0);
      for (int y = y0; y < y1; ++y) {
        changes.row(y, edge.data());
        add_uncertain(certificates, w, y, edge.data());
      }
    });
    return edge;
  }
  std::vector<std::uint8_t> rows(codes.size());
  for_each_band(height, [&](int y0, int y1) {
    ChangeFinder changes(codes.data(), w, height, y0);
    std::vector<std::uint8_t> a, b;
    for (int y = y0; y < y1; ++y) {
      changes.row(y, edge.data());
      dilate_row(edge.data() + std::size_t(y) * w, rows.data() + std::size_t(y) * w, width, r, a, b);
    }
  });
  // The columns: count[x] is how many rows of the window [t - r, t + r]
  // have rows[x] set, slid down the band.
  for_each_band(height, [&](int t0, int t1) {
    std::vector<std::uint32_t> count(w, 0);
    const auto add = [&](int y, std::uint32_t sign) {
      if (y < 0 || y >= height) return;
      const std::uint8_t* row = rows.data() + std::size_t(y) * w;
      for (std::size_t x = 0; x < w; ++x) count[x] += sign * row[x];
    };
    for (int y = t0 - r; y < t0 + r; ++y) add(y, 1u);
    for (int t = t0; t < t1; ++t) {
      add(t + r, 1u);
      std::uint8_t* e = edge.data() + std::size_t(t) * w;
      for (std::size_t x = 0; x < w; ++x) e[x] = std::uint8_t(count[x] != 0);
      add_uncertain(certificates, w, t, edge.data());
      add(t - r, std::uint32_t(-1));
    }
  });
  return edge;
}

void settle_certified_frame(RenderResult& result, const RenderRequest& request,
                            const std::function<bool()>& stop_requested) {
  if (!result.certificates) return;
  const auto start = std::chrono::steady_clock::now();
  const PixelCertificates& c = *result.certificates;
  const int w = request.width, h = request.height;
  const std::size_t pixels = std::size_t(w) * std::size_t(h);
  std::vector<std::size_t> indices;
  if (c.listed) {
    // The GPU listed them (for silhouette_ring's ring; it lists nothing
    // where an object may be misplaced).
    if (!misplaced_rectangles(request, w, h).empty())
      throw std::logic_error("settle_certified_frame: a listed frame with misplaced objects");
    indices.reserve(c.listed->size());
    for (const PixelCertificates::ListedPixel& p : *c.listed) {
      if (p.index >= pixels)
        throw std::logic_error("settle_certified_frame: listed pixel " + std::to_string(p.index) + " of " +
                               std::to_string(pixels));
      indices.push_back(p.index);
    }
  } else {
    std::vector<std::uint8_t> cast = pixels_to_ray_cast(c, w, h, silhouette_ring(request));
    mark_misplaced_objects(request, w, h, cast);
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
  }
  CertifiedShare share;
  share.pixels = pixels;
  share.ray_cast = indices.size();
  if (!indices.empty()) {
    const ExactView view(request, stop_requested);
    Image& image = result.image;
    // Each pixel written by the thread that cast it.
    view.each_pixel_at(
        indices,
        [&](std::size_t k, const ExactPixel& exact) {
          const std::size_t i = indices[k];
          // The "exact" output's value (exact_image): no geometry is lit.
          const double v = exact.geometry ? exact.visibility : 1.0;
          if (image.channels == 1) {
            image.pixels[i] = std::uint8_t(std::lround(255.0 * v));
          } else if (v < 0.5) {
            // A light of no size: v is 0 or 1, and the main pass drew 1.
            if (c.listed) {
              const std::uint32_t unlit = (*c.listed)[k].unlit;
              for (int c3 = 0; c3 < 3; ++c3) image.pixels[3 * i + c3] = std::uint8_t(unlit >> (8 * c3));
            } else {
              for (int c3 = 0; c3 < 3; ++c3) image.pixels[3 * i + c3] = c.unlit.pixels[3 * i + c3];
            }
          }
        },
        stop_requested);
  }
  result.certified = share;
  result.certificates.reset();
  result.timings.settle_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace umbra
