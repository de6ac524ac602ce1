// How far a rendered "shadow" image is from the exact reference: the one
// implementation that tests, the benchmark and the server all use.
#pragma once

#include <cstddef>
#include <vector>

#include "image.hpp"
#include "ray_cast.hpp"

namespace umbra {

/// Pixels with |N.L| below this are "grazing": the shadow test is
/// ill-conditioned there for any technique, so they are not measured.
inline constexpr double kGrazingNDotL = 0.05;

struct ShadowError {
  /// Pixels measured: they see geometry, are not on a geometric silhouette
  /// (every 4-neighbour sees the same object) and are not grazing.
  std::size_t pixels = 0;
  /// Mean |v - v_exact|, v in [0, 1].
  double mae = 0.0;
  /// Share of measured pixels with |v - v_exact| > 0.5, in [0, 1] ...
  double wrong = 0.0;
  /// ... split by direction: rendered dark where exactly lit (acne,
  /// over-shadowing) ...
  double false_shadow = 0.0;
  /// ... and rendered lit where exactly dark (peter panning, shadows cut off
  /// by the light's frustum, leaks).
  double false_light = 0.0;
};

/// `rendered` is a 1-channel "shadow" image of the same size as `exact`
/// (width x height, row 0 at the top).
ShadowError measure_shadow_error(const Image& rendered, const std::vector<ExactPixel>& exact);

}  // namespace umbra
