#include "plan/draw_cost.hpp"

#include <algorithm>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vec4.hpp>

#include "core/mesh_instance.hpp"
#include "core/model.hpp"

namespace umbra {

double mesh_tile_tests(const SceneObject& o, const glm::dmat4& view_projection, double width, double height) {
  if (o.type != SceneObject::Type::Mesh || !o.model || o.model->bounds.empty()) return 0.0;
  // The bounds' rectangle in NDC (clipped to the view), their nearest clip
  // w (a linear function: least at a corner) and how far off axis they
  // reach; bounds reaching behind a perspective eye cover the whole view.
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300, w_min = 1e300;
  bool around_eye = false;
  for (const glm::dvec3& corner : object_bounds(o).corners()) {
    const glm::dvec4 clip = view_projection * glm::dvec4(corner, 1.0);
    if (!(clip.w > 1e-12)) {
      around_eye = true;
      break;
    }
    x0 = std::min(x0, clip.x / clip.w), x1 = std::max(x1, clip.x / clip.w);
    y0 = std::min(y0, clip.y / clip.w), y1 = std::max(y1, clip.y / clip.w);
    w_min = std::min(w_min, clip.w);
  }
  if (around_eye) x0 = y0 = -1.0, x1 = y1 = 1.0;
  x0 = std::max(x0, -1.0), y0 = std::max(y0, -1.0), x1 = std::min(x1, 1.0), y1 = std::min(y1, 1.0);
  if (!(x1 > x0 && y1 > y0)) return 0.0;
  const double rect_pixels = (x1 - x0) * 0.5 * width * (y1 - y0) * 0.5 * height;
  // Pixels per world unit along screen x and y: the gradient of x/w is
  // (row0 - (x/w) row3) / w, at most (|row0| + |x/w| |row3|) / w; the
  // model's scale stretches its edges by at most its largest factor.
  const glm::dmat4& m = view_projection;  // column-major: m[column][row]
  const glm::dvec3 row0(m[0][0], m[1][0], m[2][0]), row1(m[0][1], m[1][1], m[2][1]), row3(m[0][3], m[1][3], m[2][3]);
  const glm::dvec3 factors = glm::abs(o.mesh_scale);
  const double scale = std::max({factors.x, factors.y, factors.z});
  const double sx = (glm::length(row0) + std::max(-x0, x1) * glm::length(row3)) * scale * 0.5 * width;
  const double sy = (glm::length(row1) + std::max(-y0, y1) * glm::length(row3)) * scale * 0.5 * height;
  double pixels = 0.0;
  for (const EdgeLengthBin& bin : o.model->edge_lengths)
    pixels += around_eye ? bin.triangles * rect_pixels
                         : std::min(bin.squared_edges * sx * sy / (w_min * w_min), bin.triangles * rect_pixels);
  return pixels / (64.0 * 64.0);
}

double mesh_draw_ms(const SceneObject& o, const glm::dmat4& view_projection, double width, double height) {
  return double(mesh_triangle_count(o)) * kMsPerDrawnTriangle +
         mesh_tile_tests(o, view_projection, width, height) * kMsPerTileTest;
}

}  // namespace umbra
