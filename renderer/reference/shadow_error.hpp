// How far a rendered "shadow" image is from the exact reference: the one
// implementation that tests, the benchmark and the server all use.
#pragma once

#include <cstddef>
#include <vector>

#include "core/image.hpp"
#include "core/render_result.hpp"
#include "reference/ray_cast.hpp"

namespace umbra {

/// Pixels with |N.L| below this are "grazing": the shadow test is
/// ill-conditioned there for any technique, so they are not measured.
inline constexpr double kGrazingNDotL = 0.05;

/// How far (pixels, Chebyshev) an interior pixel keeps from edges.
inline constexpr int kArtifactMargin = 3;
/// Neighbours on one object whose unit normals have a smaller dot product
/// (more than about 2.6 degrees apart) are on a crease. A sphere's normals
/// turn by about 115 / (its diameter in pixels) degrees per pixel at its
/// centre and faster towards its outline, so only the middle of a sphere over
/// ~45 pixels across is interior: curved surfaces are left out, conservatively.
inline constexpr float kCreaseNDotN = 0.999f;
/// A rendered value off by more than this on an interior pixel is an artifact.
inline constexpr double kArtifactError = 0.1;
/// measure_shadow_error's finer look samples at most 1 / kFinerShare of the
/// image's pixels, at kCoverageSamples^2 = 16 samples each: at most one more
/// cast's worth of rays; or kFinerPixels on a smaller image, a cost too
/// small to matter.
inline constexpr std::size_t kFinerShare = 16;
inline constexpr std::size_t kFinerPixels = 4096;

// ShadowError: core/render_result.hpp (a frame's result carries it).

/// `rendered` is a 1-channel "shadow" image of the same size as `exact`
/// (width x height, row 0 at the top).
///
/// `finer` (optional: ExactView::coverage_of gives it) looks between pixel
/// centres before a pixel is called an artifact. The exact image samples
/// each pixel at its centre only, so a shadow edge can pass between centres
/// unseen: the thin lit wedge between two shadows narrows below a pixel's
/// width, its tip misses every centre for a few pixels, and a render that
/// shows the tip's light honestly (a pixel a quarter covered by it,
/// rendered 0.23) was counted as an artifact 5 pixels from the nearest edge
/// the centres saw. With `finer`, a pixel that would be an artifact counts
/// as one only if every pixel within kArtifactMargin is covered uniformly
/// by its own exact value (dark for 0, lit for 1; samples that see no
/// geometry are no edge); otherwise an edge passes nearby after all, and
/// the pixel leaves interior_pixels too, which therefore depends on the
/// render as well as on the exact image. Only those candidates'
/// neighbourhoods are sampled, and only while they cover at most
/// 1 / kFinerShare of the image (or kFinerPixels): a render with more
/// candidates than that keeps the centres' verdict (an upper bound), so the
/// finer look costs at most one more cast. Without `finer` the centres alone decide (the
/// measure on hand-made images).
ShadowError measure_shadow_error(const Image& rendered, const std::vector<ExactPixel>& exact,
                                 const PixelCoverageOf& finer = nullptr);

}  // namespace umbra
