// The image/png answer of POST /api/sun-hours without GL: Ladybug's colour
// ramp, the picture's pixels, and the legend drawn into it (panel, font,
// ticks, threshold mark).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "sun_hours_picture.hpp"

namespace umbra {
namespace {

using Rgb = std::array<int, 3>;

Rgb colour(double hours, double max_hours) {
  unsigned char c[3];
  hours_colour(hours, max_hours, c);
  return {c[0], c[1], c[2]};
}

Rgb pixel(const Image& image, int x, int y) {
  const std::uint8_t* p = image.at(x, y);
  return {p[0], p[1], p[2]};
}

bool white(const Rgb& c) { return c[0] == 255 && c[1] == 255 && c[2] == 255; }
bool dark(const Rgb& c) { return c[0] < 64 && c[1] < 64 && c[2] < 64; }

SunHoursLegend london_legend() {
  SunHoursLegend legend;
  legend.max_hours = 12.17;
  legend.lines = {"51.50 N, 0.12 W", "2026-03-21 TO 2026-03-22, EVERY 10 MIN", "62% OF POINTS >= 2 H",
                  "PATH: FOOTPRINTS, 0.3% RAY CAST"};
  return legend;
}

std::vector<float> uniform(int width, int height, float hours) {
  return std::vector<float>(std::size_t(width) * std::size_t(height), hours);
}

TEST(SunHoursPicture, RampEndsAreLadybugsFirstAndLastColours) {
  EXPECT_EQ(colour(0.0, 12.0), (Rgb{75, 107, 169}));
  EXPECT_EQ(colour(12.0, 12.0), (Rgb{234, 38, 0}));
  // Clamped outside the scale; NaN reads as 0.
  EXPECT_EQ(colour(-3.0, 12.0), (Rgb{75, 107, 169}));
  EXPECT_EQ(colour(40.0, 12.0), (Rgb{234, 38, 0}));
  EXPECT_EQ(colour(std::numeric_limits<double>::quiet_NaN(), 12.0), (Rgb{75, 107, 169}));
}

TEST(SunHoursPicture, RampPassesThroughEveryColourEvenlySpaced) {
  // Ten colours over [0, 9]: colour i at hours i.
  const Rgb ladybug[] = {{75, 107, 169}, {115, 147, 202}, {170, 200, 247}, {193, 213, 208}, {245, 239, 103},
                         {252, 230, 74}, {239, 156, 21},  {234, 123, 0},   {234, 74, 0},    {234, 38, 0}};
  for (int i = 0; i < 10; ++i) EXPECT_EQ(colour(double(i), 9.0), ladybug[i]) << i;
  // The middle of the scale is halfway between the 5th and 6th colours.
  const Rgb mid = colour(6.0, 12.0);
  EXPECT_NEAR(mid[0], 248.5, 0.5);
  EXPECT_NEAR(mid[1], 234.5, 0.5);
  EXPECT_NEAR(mid[2], 88.5, 0.5);
  // A quarter of the way from colour 1 to colour 2.
  const Rgb quarter = colour(1.25, 9.0);
  EXPECT_NEAR(quarter[0], 115 + 0.25 * (170 - 115), 0.5);
  EXPECT_NEAR(quarter[1], 147 + 0.25 * (200 - 147), 0.5);
  EXPECT_NEAR(quarter[2], 202 + 0.25 * (247 - 202), 0.5);
}

TEST(SunHoursPicture, SizeAndChannels) {
  const Image image = sun_hours_picture(uniform(960, 540, 3.0f), 960, 540, london_legend());
  EXPECT_EQ(image.width, 960);
  EXPECT_EQ(image.height, 540);
  EXPECT_EQ(image.channels, 3);
  EXPECT_EQ(image.bit_depth, 8);
  EXPECT_EQ(image.pixels.size(), std::size_t(960) * 540 * 3);
}

TEST(SunHoursPicture, RejectsHoursOfTheWrongCount) {
  EXPECT_THROW(sun_hours_picture(uniform(10, 10, 1.0f), 10, 11, london_legend()), std::invalid_argument);
  EXPECT_THROW(sun_hours_picture({}, 0, 0, london_legend()), std::invalid_argument);
}

TEST(SunHoursPicture, PixelsFarFromTheLegendHaveTheirHoursColour) {
  const int w = 960, h = 540;
  const SunHoursLegend legend = london_legend();
  std::vector<float> hours(std::size_t(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) hours[std::size_t(y) * w + x] = float(legend.max_hours * x / (w - 1));
  const float nan = std::numeric_limits<float>::quiet_NaN();
  hours[std::size_t(h - 20) * w + 20] = nan;
  const Image image = sun_hours_picture(hours, w, h, legend);
  // The legend is at the top right; the left half's bottom is far from it.
  for (int x : {0, 10, 200, 400})
    EXPECT_EQ(pixel(image, x, h - 10), colour(hours[std::size_t(h - 10) * w + x], legend.max_hours)) << x;
  EXPECT_EQ(pixel(image, 0, 0), colour(0.0, legend.max_hours));
  // No geometry: a light grey that is no colour of the ramp.
  const Rgb bg = pixel(image, 20, h - 20);
  EXPECT_EQ(bg[0], bg[1]);
  EXPECT_EQ(bg[1], bg[2]);
  EXPECT_GE(bg[0], 180);
  EXPECT_LT(bg[0], 255);
}

TEST(SunHoursPicture, LegendPanelAtTheRightEdgeOfALargeImage) {
  const int w = 960, h = 540;
  const Image image = sun_hours_picture(uniform(w, h, 6.0f), w, h, london_legend());
  const Rgb plain = colour(6.0, 12.17);
  ASSERT_FALSE(white(plain));
  ASSERT_FALSE(dark(plain));
  int whites = 0, darks = 0, others = 0, rightmost_white = -1, leftmost_white = w;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const Rgb c = pixel(image, x, y);
      if (white(c)) {
        ++whites;
        rightmost_white = std::max(rightmost_white, x);
        leftmost_white = std::min(leftmost_white, x);
      } else if (dark(c)) {
        ++darks;
      } else if (c != plain) {
        ++others;  // the colour bar
      }
    }
  EXPECT_GT(whites, 20000);
  EXPECT_GT(darks, 2000);  // text, border, ticks
  EXPECT_GT(others, 1000);
  EXPECT_GT(rightmost_white, w - 20);  // at the right edge...
  EXPECT_GT(leftmost_white, w / 2 - 1);  // ...and no wider than half the image
  // Scale 2 above 480 px: the 960 px image's text is twice the 400 px one's.
  const Image small = sun_hours_picture(uniform(400, 300, 6.0f), 400, 300, london_legend());
  int small_whites = 0;
  for (int y = 0; y < small.height; ++y)
    for (int x = 0; x < small.width; ++x) small_whites += white(pixel(small, x, y));
  EXPECT_GT(small_whites, 2000);
  EXPECT_LT(small_whites, whites / 2);
}

TEST(SunHoursPicture, SmallImagesGetTheColoursOnly) {
  const Image tiny = sun_hours_picture(uniform(100, 60, 6.0f), 100, 60, london_legend());
  const Rgb plain = colour(6.0, 12.17);
  for (int y = 0; y < tiny.height; ++y)
    for (int x = 0; x < tiny.width; ++x) ASSERT_EQ(pixel(tiny, x, y), plain) << x << "," << y;
  // 200 x 120 is large enough.
  const Image least = sun_hours_picture(uniform(200, 120, 6.0f), 200, 120, london_legend());
  int whites = 0;
  for (int y = 0; y < least.height; ++y)
    for (int x = 0; x < least.width; ++x) whites += white(pixel(least, x, y));
  EXPECT_GT(whites, 1000);
}

TEST(SunHoursPicture, EveryCharacterOfTheLegendHasItsOwnGlyph) {
  const auto unknown = legend_glyph(U'?');
  const std::string texts[] = {"HOURS OF DIRECT SUN",
                               "51.50 N, 0.12 W",
                               "2026-03-21 TO 2026-03-22, EVERY 10 MIN",
                               "62% OF POINTS >= 2 H",
                               "PATH: FOOTPRINTS, 0.3% RAY CAST",
                               "2026-03-21T00:00 TO 2026-03-22T00:00 UTC",
                               "< 2.5 H REQUIRED (+1/-1)",
                               "ABCDEFGHIJKLMNOPQRSTUVWXYZ 0123456789"};
  for (const std::string& text : texts)
    for (char c : text) EXPECT_NE(legend_glyph(char32_t(c)), unknown) << "'" << c << "' in " << text;
  EXPECT_NE(legend_glyph(U'\u00B0'), unknown);  // degree sign
  // Lower case is drawn as upper case; what the font lacks as '?'.
  for (char32_t c = U'a'; c <= U'z'; ++c) EXPECT_EQ(legend_glyph(c), legend_glyph(c - U'a' + U'A'));
  EXPECT_EQ(legend_glyph(U'#'), unknown);
  EXPECT_EQ(legend_glyph(U'\u00E9'), unknown);
  // Glyphs are 5 columns wide: nothing above bit 4.
  for (char32_t c = 32; c < 127; ++c)
    for (std::uint8_t row : legend_glyph(c)) EXPECT_EQ(row & ~0x1F, 0) << char(c);
}

TEST(SunHoursPicture, TicksAreRound) {
  EXPECT_EQ(sun_hours_ticks(12.17), (std::vector<double>{0, 2, 4, 6, 8, 10, 12}));
  EXPECT_EQ(sun_hours_ticks(4380.0), (std::vector<double>{0, 1000, 2000, 3000, 4000}));
  const std::vector<double> tenths = sun_hours_ticks(1.0);
  ASSERT_EQ(tenths.size(), 6u);
  EXPECT_DOUBLE_EQ(tenths[3], 0.6);
  for (double m : {0.05, 0.7, 1.0, 3.3, 7.0, 9.99, 14.0, 16.5, 24.0, 100.0, 744.0, 8760.0}) {
    const std::vector<double> t = sun_hours_ticks(m);
    ASSERT_GE(t.size(), 4u) << m;
    EXPECT_LE(t.size(), 8u) << m;
    EXPECT_EQ(t.front(), 0.0) << m;
    EXPECT_LE(t.back(), m * (1 + 1e-9)) << m;
    EXPECT_GT(t.back(), m / 2) << m;
  }
  EXPECT_TRUE(sun_hours_ticks(0.0).empty());
  EXPECT_TRUE(sun_hours_ticks(std::numeric_limits<double>::quiet_NaN()).empty());
}

TEST(SunHoursPicture, ThresholdMarkedOnlyWhenGiven) {
  const int w = 960, h = 540;
  SunHoursLegend none = london_legend();
  SunHoursLegend two = none, eight = none;
  two.require_hours = 2.0;
  eight.require_hours = 8.0;
  const std::vector<float> hours = uniform(w, h, 6.0f);
  const Image a = sun_hours_picture(hours, w, h, none);
  const Image b = sun_hours_picture(hours, w, h, two);
  const Image c = sun_hours_picture(hours, w, h, eight);
  int differ = 0, differ_left = 0, darker = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const Rgb pa = pixel(a, x, y), pb = pixel(b, x, y);
      if (pa == pb) continue;
      ++differ;
      differ_left += x < w / 2;
      darker += dark(pb) && !dark(pa);
    }
  EXPECT_GT(differ, 100);
  EXPECT_EQ(differ_left, 0);  // only in the legend
  EXPECT_GT(darker, 100);     // the mark and its label are dark
  EXPECT_NE(b.pixels, c.pixels);  // the mark moves with the threshold
  // The same with the legend left out: no mark either.
  const Image tiny_none = sun_hours_picture(uniform(100, 60, 6.0f), 100, 60, none);
  const Image tiny_two = sun_hours_picture(uniform(100, 60, 6.0f), 100, 60, two);
  EXPECT_EQ(tiny_none.pixels, tiny_two.pixels);
}

}  // namespace
}  // namespace umbra
