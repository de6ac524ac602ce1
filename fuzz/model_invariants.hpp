// What a loader promises of a model it accepts, checked by the fuzz
// targets of every model reader: triangles within the limit, indices in
// range, finite positions, a unit normal for every vertex.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "core/model.hpp"

namespace umbra {

inline bool model_keeps_its_promises(const TriangleModel& model, std::size_t max_triangles) {
  if (model.triangle_count() == 0 || model.triangle_count() > max_triangles) return false;
  for (const ModelPart& part : model.parts) {
    if (part.normals.size() != part.positions.size() || part.indices.size() % 3 != 0) return false;
    for (std::uint32_t i : part.indices)
      if (i >= part.positions.size()) return false;
    for (const auto& p : part.positions)
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) return false;
    for (const auto& n : part.normals)
      if (!(std::abs(n.x * n.x + n.y * n.y + n.z * n.z - 1.0f) < 1e-3f)) return false;
  }
  return true;
}

}  // namespace umbra
