// What one render job hands back.
#pragma once

#include <cstddef>
#include <optional>
#include <cstdint>
#include <string>
#include <vector>

#include "core/image.hpp"

namespace umbra {

/// How far a rendered "shadow" image is from the exact reference
/// (reference/shadow_error.hpp measures it).
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

  /// Pixels where any shadow technique should be exact, so that a small
  /// error there is a visible artifact, not blur: they see geometry, are not
  /// grazing, are exactly lit or exactly dark (never penumbra), and lie more
  /// than kArtifactMargin pixels (Chebyshev) from every pixel of a 4-neighbour
  /// pair that differs by
  /// - a silhouette: `geometry` or `object` differs,
  /// - a shadow edge: the exact visibility differs at all,
  /// - a crease: same object, normals' dot product below kCreaseNDotN (a
  ///   box's edge).
  /// Filtering and resolution limits blur shadows near those, honestly; away
  /// from them a value off by 0.1 is something a viewer sees (a dotted line
  /// along a cascade seam). The image border is no edge. With a finer look
  /// (measure_shadow_error), an edge between pixel centres near a pixel
  /// that would be an artifact counts too. Reported so that artifacts = 0
  /// can be told from "nothing measured".
  std::size_t interior_pixels = 0;
  /// Share of interior pixels with |v - v_exact| > kArtifactError, in [0, 1]:
  /// thin artifacts that `wrong` misses because they stay within 0.5.
  double artifacts = 0.0;
};

/// Filter "exact": what the main pass proved of each pixel, read back
/// beside the image for the CPU to settle the rest
/// (reference/certified_frame.hpp).
struct PixelCertificates {
  /// Per pixel (width x height, row 0 at the top): (object + 1) << 3 |
  /// facing << 2 | verdict: object = the scene object the pixel sees (0:
  /// none, the background), facing = 1 where its surface turns towards the
  /// light (N.L > 0), verdict = kCertainlyLit, kCertainlyDark or kUncertain.
  std::vector<std::uint32_t> codes;
  /// The colour output only: each pixel shaded with visibility 0 (ambient
  /// alone), what an uncertain pixel that the ray cast finds dark shows.
  /// `image` holds it shaded with visibility 1 there.
  Image unlit;
  /// Per pixel: 1 where an edge of an object other than the one drawn
  /// there passes within a fraction of a pixel of its centre, in front of
  /// what was drawn (the sliver pass): the reference may see that object.
  std::vector<std::uint8_t> slivers;
  /// Where the GPU listed the pixels to ray cast itself (ShadowRenderer, on
  /// a GPU): exactly pixels_to_ray_cast's pixels (reference/
  /// certified_frame.hpp) for silhouette_ring's ring, in no order, each
  /// with its unlit colour for the colour output. `codes`, `slivers` and
  /// `unlit` are then empty: they were not read back.
  struct ListedPixel {
    std::uint32_t index;  ///< row * width + column, row 0 at the top
    std::uint32_t unlit;  ///< the colour output: R | G << 8 | B << 16; else 0
  };
  std::optional<std::vector<ListedPixel>> listed;
  static constexpr std::uint32_t kCertainlyLit = 0, kCertainlyDark = 1, kUncertain = 2;
  static constexpr std::uint32_t kVerdictMask = 3;  ///< codes[i] & kVerdictMask: the verdict
  static constexpr unsigned kSurfaceShift = 2;      ///< codes[i] >> kSurfaceShift: object and facing
  static constexpr unsigned kObjectShift = 3;       ///< codes[i] >> kObjectShift: object + 1
};

/// How filter "exact" settled a frame's pixels.
struct CertifiedShare {
  std::size_t pixels = 0;     ///< width x height
  std::size_t ray_cast = 0;   ///< pixels the maps could not settle (or on a silhouette), ray cast
};

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
  /// Filter "exact", before the CPU settles it: the main pass's verdicts.
  std::optional<PixelCertificates> certificates;
  /// Filter "exact", once settled: how many pixels were ray cast.
  std::optional<CertifiedShare> certified;
  /// Filter "exact": how the frame was certified: "maps", "proofs" (no
  /// maps: every pixel but the proved plane parts' ray cast) or "ray-cast"
  /// (every pixel); empty for other frames (CertifiedPath, frame_plan.hpp).
  std::string certified_path;
};

}  // namespace umbra
