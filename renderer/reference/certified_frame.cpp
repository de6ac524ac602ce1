#include "reference/certified_frame.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
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

std::vector<std::uint8_t> pixels_to_ray_cast(const PixelCertificates& certificates, int width, int height,
                                             int ring) {
  const std::vector<std::uint32_t>& codes = certificates.codes;
  const std::vector<std::uint8_t>& slivers = certificates.slivers;
  if (codes.size() != std::size_t(width) * std::size_t(height) || (!slivers.empty() && slivers.size() != codes.size()))
    throw std::invalid_argument("pixels_to_ray_cast: " + std::to_string(codes.size()) + " codes and " +
                                std::to_string(slivers.size()) + " sliver marks for " + std::to_string(width) +
                                " x " + std::to_string(height) + " pixels");
  const auto at = [width](int x, int y) { return std::size_t(y) * width + x; };
  // Pixels beside a change of object, or of the side of the light the
  // surface turns to (a crease: the reference's camera ray may meet the
  // other face), then grown by ring - 1 each way (a separable max: a row
  // pass, then a column pass).
  std::vector<std::uint8_t> edge(codes.size(), 0);
  // Outside the image is another surface: nothing past the border shows
  // whether the raster and the reference part there (an outline on the
  // border row that the snapped triangle covers and the true one misses; a
  // curved shape whose true surface bulges onto the image from faces just
  // off it), so the border pixels count as beside a change.
  for (int x = 0; x < width; ++x) edge[at(x, 0)] = edge[at(x, height - 1)] = 1;
  for (int y = 0; y < height; ++y) edge[at(0, y)] = edge[at(width - 1, y)] = 1;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const std::uint32_t o = surface_code(codes[at(x, y)]);
      if (x + 1 < width && o != surface_code(codes[at(x + 1, y)])) edge[at(x, y)] = edge[at(x + 1, y)] = 1;
      if (y + 1 < height && o != surface_code(codes[at(x, y + 1)])) edge[at(x, y)] = edge[at(x, y + 1)] = 1;
    }
  }
  const int r = std::max(0, ring - 1);
  if (r > 0) {
    std::vector<std::uint8_t> rows(codes.size(), 0);
    for (int y = 0; y < height; ++y) {
      int last = -1 - r;  // the last edge pixel seen on this row, left of x + r
      for (int x = 0; x < width + r; ++x) {
        if (x < width && edge[at(x, y)]) last = x;
        const int target = x - r;
        if (target >= 0 && target < width) {
          // An edge within [target - r, target + r]: the last one at or
          // before target + r = x, and not before target - r.
          rows[at(target, y)] = last >= target - r ? 1 : 0;
        }
      }
    }
    // The columns, a row at a time (the image is row-major): each
    // column's last edge row seen.
    std::vector<int> last(std::size_t(width), -1 - r);
    for (int y = 0; y < height + r; ++y) {
      if (y < height)
        for (int x = 0; x < width; ++x)
          if (rows[at(x, y)]) last[std::size_t(x)] = y;
      const int target = y - r;
      if (target >= 0 && target < height)
        for (int x = 0; x < width; ++x) edge[at(x, target)] = last[std::size_t(x)] >= target - r ? 1 : 0;
    }
  }
  for (std::size_t i = 0; i < codes.size(); ++i)
    if (verdict(codes[i]) == PixelCertificates::kUncertain || (!slivers.empty() && slivers[i])) edge[i] = 1;
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
  for (std::size_t i = 0; i < cast.size(); ++i)
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
