#include "shadow_error.hpp"

#include <cmath>

namespace umbra {

ShadowError measure_shadow_error(const Image& rendered, const std::vector<ExactPixel>& exact) {
  ShadowError e;
  const int w = rendered.width, h = rendered.height;
  std::size_t wrong = 0, false_shadow = 0, false_light = 0;
  double sum = 0.0;
  const auto same_object = [&](int x, int y, int object) {
    if (x < 0 || y < 0 || x >= w || y >= h) return true;  // the image border is no silhouette
    const ExactPixel& n = exact[std::size_t(y) * w + x];
    return n.geometry && n.object == object;
  };
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
    }
  }
  if (e.pixels > 0) {
    const double n = double(e.pixels);
    e.mae = sum / n;
    e.wrong = wrong / n;
    e.false_shadow = false_shadow / n;
    e.false_light = false_light / n;
  }
  return e;
}

}  // namespace umbra
