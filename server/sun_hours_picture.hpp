// The image/png answer of POST /api/sun-hours: hours of direct sun per pixel
// of a camera view, coloured as Ladybug's Direct Sun Hours colours them, with
// a legend drawn in. Pure: no GL, no I/O, no threads, no shared state.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "core/image.hpp"

namespace umbra {

/// What the legend says besides the scale.
struct SunHoursLegend {
  double max_hours = 0.0;  ///< top of the colour scale, hours (> 0; the period's sun-up hours, or the largest value)
  double require_hours = std::numeric_limits<double>::quiet_NaN();  ///< threshold marked on the scale; NaN: none
  std::vector<std::string> lines;  ///< text lines under the title: the place, the period and step, the pass share...
};

/// The colour of `hours` on the scale [0, max_hours]: Ladybug's default legend
/// colours for hours (dark blue through yellow to red), linearly interpolated.
/// Values outside the scale take its end colours; NaN hours take the first
/// colour; with max_hours not > 0 (or NaN), hours > 0 are the last colour.
void hours_colour(double hours, double max_hours, unsigned char rgb[3]);

/// width x height RGB: each pixel the colour of its hours (row 0 at the top,
/// hours.size() == width * height; NaN: no geometry there, drawn as a light
/// grey background), and a legend drawn in at the right edge: a title "HOURS
/// OF DIRECT SUN", the colour bar with tick values (0 .. max_hours, 4-6 round
/// ticks, e.g. 0 2 4 6 8 10 12), the threshold marked on the bar when given,
/// and the lines. Text in a 5x7 bitmap font of this file, upper case (lower
/// case letters are drawn as upper case), scaled by an integer factor that
/// suits the image (1 below ~480 px wide, 2 above); the legend's panel is opaque
/// white with a thin dark border so it reads on any colour. Images too small to
/// hold the legend (e.g. under 200 x 120) get the colours only.
///
/// Layout, top to bottom inside the panel: the title, the lines (wrapped at
/// spaces to at most half the image's width; lines that do not fit the
/// image's height are left out, last first), then the bar, max_hours at its
/// top and 0 at its bottom, tick labels on its right. The threshold is a dark
/// line across the bar with a triangle pointing at it from the left, and a
/// triangle pointing back at the bar before the label "2 H REQUIRED" in a
/// column right of the tick labels, level with the line.
/// Throws std::invalid_argument unless width, height > 0 and
/// hours.size() == width * height.
Image sun_hours_picture(const std::vector<float>& hours, int width, int height, const SunHoursLegend& legend);

/// The tick values the legend's bar labels: 0, step, 2 step, ... up to
/// max_hours, step a round number (1, 2 or 5 times a power of ten, else 2.5,
/// 4 or 3 times one) chosen for 4 to 7 labels. Empty unless max_hours > 0
/// and finite.
std::vector<double> sun_hours_ticks(double max_hours);

/// The legend font's glyph for a Unicode code point: 7 rows top to bottom,
/// 5 columns in the low bits of each, bit 4 the leftmost. Lower case ASCII
/// letters get the upper case glyph; a code point the font lacks gets '?'s.
std::array<std::uint8_t, 7> legend_glyph(char32_t code_point);

}  // namespace umbra
