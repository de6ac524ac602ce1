// The error measures on hand-made images.
#include <gtest/gtest.h>

#include "shadow_error.hpp"

namespace umbra {
namespace {

// A 5 x 5 view of one object, exact visibility `v` everywhere.
std::vector<ExactPixel> flat(double v, int object = 0) {
  ExactPixel p;
  p.geometry = true;
  p.object = object;
  p.n_dot_l = 0.8;
  p.visibility = v;
  return std::vector<ExactPixel>(25, p);
}

Image grey(std::uint8_t value) { return Image{5, 5, 1, std::vector<std::uint8_t>(25, value)}; }

TEST(ShadowError, PerfectRenderHasNoError) {
  const ShadowError e = measure_shadow_error(grey(255), flat(1.0));
  EXPECT_EQ(e.pixels, 25u);
  EXPECT_EQ(e.mae, 0.0);
  EXPECT_EQ(e.wrong, 0.0);
}

TEST(ShadowError, DarkWhereLitIsFalseShadowAndTheReverseFalseLight) {
  Image rendered = grey(255);
  rendered.pixels[12] = 0;  // the centre rendered dark
  std::vector<ExactPixel> exact = flat(1.0);
  exact[6].visibility = 0.0;  // (1,1) exactly dark, rendered lit
  const ShadowError e = measure_shadow_error(rendered, exact);
  EXPECT_DOUBLE_EQ(e.false_shadow, 1.0 / 25.0);
  EXPECT_DOUBLE_EQ(e.false_light, 1.0 / 25.0);
  EXPECT_DOUBLE_EQ(e.wrong, 2.0 / 25.0);
  EXPECT_DOUBLE_EQ(e.mae, 2.0 / 25.0);
}

TEST(ShadowError, SmallDifferencesCountInMaeButAreNotWrong) {
  const ShadowError e = measure_shadow_error(grey(153), flat(1.0));  // v = 0.6
  EXPECT_NEAR(e.mae, 0.4, 1e-12);
  EXPECT_EQ(e.wrong, 0.0);
}

TEST(ShadowError, SilhouettesBackgroundAndGrazingPixelsAreNotMeasured) {
  std::vector<ExactPixel> exact = flat(1.0);
  exact[2].object = 1;            // top middle: another object
  exact[22].geometry = false;     // bottom middle: background
  exact[14].n_dot_l = 0.01;       // (4,2): grazing
  const ShadowError e = measure_shadow_error(grey(0), exact);
  // Not measured: the 2 odd pixels, their 4-neighbours that are on the
  // object (7 and 17 plus 1, 3, 21, 23), and the grazing one.
  EXPECT_EQ(e.pixels, 25u - 2u - 6u - 1u);
  EXPECT_DOUBLE_EQ(e.wrong, 1.0);
}

}  // namespace
}  // namespace umbra
