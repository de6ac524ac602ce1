// What one render job hands back.
#pragma once

#include <cstddef>
#include <optional>
#include <string>

#include "core/image.hpp"
#include "reference/shadow_error.hpp"

namespace umbra {

struct RenderResult {
  Image image;
  FrameTimings timings;
  /// Output "error" only: the error measures of the rendered shadow term
  /// against the exact reference.
  std::optional<ShadowError> error;
  /// How the light's shadow was laid out, when a shadow pass ran:
  /// "single", "cascades" or "cube"; the number of views and the texels per
  /// side of each (e.g. "cascades; views=3; size=2048").
  std::string shadow_views;
  /// The shadow map from an earlier frame served this one (nothing it
  /// depends on changed), so no shadow pass ran.
  bool shadow_reused = false;
  /// The scene's meshes had to be uploaded (not among the cached scenes).
  bool scene_uploaded = false;
  /// The frame allocated its shadow map: a size or layer count the kept one
  /// lacks, or none was kept.
  bool shadow_map_allocated = false;
  /// Umbras the main pass drew dark without the shadow lookup
  /// (renderer/plan/umbras.hpp): where a box or sphere hides a light of no size
  /// from a floor.
  std::size_t umbras = 0;
};

}  // namespace umbra
