// Where the raster may draw an object's outline on screen, against where
// the exact reference sees it: a curved shape's tessellation, and the float
// rounding of positions far from the scene's centre. Filter "exact" casts
// the pixels between the two (docs/certified-shadows.md, "What the CPU
// casts"). Pure: no GL.
#pragma once

#include <cstdint>
#include <vector>

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

/// Pixels [x0, x1) x [y0, y1), row 0 at the top.
struct PixelRect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};
/// The rectangles mark_misplaced_objects marks, one per such object (none
/// in most frames).
std::vector<PixelRect> misplaced_rectangles(const RenderRequest& request, int width, int height);

}  // namespace umbra
