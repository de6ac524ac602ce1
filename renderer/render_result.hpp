// What one render job hands back.
#pragma once

#include <optional>

#include "image.hpp"
#include "shadow_error.hpp"

namespace umbra {

struct RenderResult {
  Image image;
  FrameTimings timings;
  /// Output "error" only: the error measures of the rendered shadow term
  /// against the exact reference.
  std::optional<ShadowError> error;
};

}  // namespace umbra
