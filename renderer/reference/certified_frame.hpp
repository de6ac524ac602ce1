// Filter "exact", the CPU's half: the main pass gave every pixel a verdict
// (PixelCertificates: certainly lit, certainly dark, or uncertain); the
// pixels it could not prove, and those where the rasterised surface may
// not be the one the reference's camera ray meets, are ray cast here with
// the exact reference itself (ExactView), so the frame's shadow term is
// the reference's at every pixel. Why the verdicts are sound:
// docs/certified-shadows.md.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "core/render_result.hpp"
#include "core/request.hpp"

namespace umbra {

/// Below this, the float rounding of what the raster draws (in pixels) is
/// left to the sliver marks' band (kSliverPixels: 1/32) and the ring of 1.
inline constexpr double kMisplacedPixels = 1.0 / 64.0;
/// An object at most this many roundings across may lose its outline, or
/// a part of it, to the rounding (mark_misplaced_objects).
inline constexpr double kMisplacedSizes = 64.0;

/// How many pixels (Chebyshev) around a change of object in the
/// certificates are ray cast: 1, plus the most that an object's outline
/// on screen can lie from where the raster draws it: a curved shape's
/// tessellation distance, and where it is more than kMisplacedPixels the
/// raster's float rounding (its positions are floats relative to the
/// scene's centre, Mesh::origin: an object far from it seen from close by
/// moves by pixels), each seen from the camera where the outline can be
/// nearest (a plane: its border).
int silhouette_ring(const RenderRequest& request);

/// Marks (1) in `marks` (width x height, row 0 at the top) the pixels of an
/// object that the raster's rounding may misplace by more than
/// kMisplacedPixels and that is at most kMisplacedSizes roundings across:
/// it may vanish, or lose a part, where no change between neighbours
/// shows (a red-team pass: a 3 mm sphere 10^4 from the scene's centre,
/// seen from 8 mm, 222 pixels wrong). Its bounds' rectangle on screen,
/// grown by the rounding and 2 pixels, is cast whole (the whole image if
/// it reaches behind the camera).
void mark_misplaced_objects(const RenderRequest& request, int width, int height, std::vector<std::uint8_t>& marks);

/// Which pixels (width x height, row 0 at the top) to ray cast: those the
/// certificates leave uncertain, those the sliver pass marked (if it ran:
/// `certificates.slivers` may be empty), and every pixel within `ring` of
/// two 4-neighbours that see different objects (or one sees none), or
/// surfaces turned to different sides of the light.
std::vector<std::uint8_t> pixels_to_ray_cast(const PixelCertificates& certificates, int width, int height, int ring);

/// Settles a certified frame of `request`: ray casts pixels_to_ray_cast,
/// writes the reference's value into `result.image` there (the shadow
/// output: round(255 v), as the "exact" output; the colour output: the lit
/// or the unlit colour), drops `result.certificates`, and sets
/// `result.certified` and `timings.settle_ms`. `stop_requested` is asked
/// as ExactView asks it (CastStopped). Does nothing to a result without
/// certificates.
void settle_certified_frame(RenderResult& result, const RenderRequest& request,
                            const std::function<bool()>& stop_requested = nullptr);

}  // namespace umbra
