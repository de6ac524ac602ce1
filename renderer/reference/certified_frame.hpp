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

/// Which pixels (width x height, row 0 at the top) to ray cast: those the
/// certificates leave uncertain, those the sliver pass marked (if it ran:
/// `certificates.slivers` may be empty), and every pixel within `ring` of
/// two 4-neighbours that see different objects (or one sees none), or
/// surfaces turned to different sides of the light.
std::vector<std::uint8_t> pixels_to_ray_cast(const PixelCertificates& certificates, int width, int height, int ring);

/// Settles a certified frame of `request`: ray casts pixels_to_ray_cast
/// (and mark_misplaced_objects; or the pixels the GPU listed,
/// PixelCertificates::listed),
/// writes the reference's value into `result.image` there (the shadow
/// output: round(255 v), as the "exact" output; the colour output: the lit
/// or the unlit colour), drops `result.certificates`, and sets
/// `result.certified` and `timings.settle_ms`. `stop_requested` is asked
/// as ExactView asks it (CastStopped). Does nothing to a result without
/// certificates.
void settle_certified_frame(RenderResult& result, const RenderRequest& request,
                            const std::function<bool()>& stop_requested = nullptr);

}  // namespace umbra
