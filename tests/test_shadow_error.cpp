// The error measures on hand-made images.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "reference/shadow_error.hpp"

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

// The artifact measure needs room for its 3-pixel margin: a 20 x 20 view
// of one flat object facing the viewer, exactly lit.
constexpr int kSide = 20;

std::size_t at(int x, int y) { return std::size_t(y) * kSide + x; }

std::vector<ExactPixel> lit_square() {
  ExactPixel p;
  p.geometry = true;
  p.object = 0;
  p.n_dot_l = 0.8;
  p.visibility = 1.0;
  p.normal = {0.0f, 0.0f, 1.0f};
  return std::vector<ExactPixel>(kSide * kSide, p);
}

// The columns x >= first changed by `change`.
std::vector<ExactPixel> split_at(int first, const std::function<void(ExactPixel&)>& change) {
  std::vector<ExactPixel> exact = lit_square();
  for (int y = 0; y < kSide; ++y)
    for (int x = first; x < kSide; ++x) change(exact[at(x, y)]);
  return exact;
}

// What a perfect renderer would output for `exact`.
Image rendered_exactly(const std::vector<ExactPixel>& exact) {
  Image image{kSide, kSide, 1, std::vector<std::uint8_t>(exact.size())};
  for (std::size_t i = 0; i < exact.size(); ++i)
    image.pixels[i] = std::uint8_t(std::lround(255.0 * (exact[i].geometry ? exact[i].visibility : 1.0)));
  return image;
}

TEST(ShadowArtifacts, OffByAFifthFarFromEdgesIsOneArtifactThatWrongMisses) {
  const std::vector<ExactPixel> exact = lit_square();
  Image rendered = rendered_exactly(exact);
  rendered.pixels[at(10, 10)] = 204;  // v = 0.8 on a lit floor
  const ShadowError e = measure_shadow_error(rendered, exact);
  EXPECT_EQ(e.interior_pixels, 400u);
  EXPECT_DOUBLE_EQ(e.artifacts, 1.0 / 400.0);
  EXPECT_EQ(e.pixels, 400u);
  EXPECT_NEAR(e.mae, 0.2 / 400.0, 1e-12);
  EXPECT_EQ(e.wrong, 0.0);
}

TEST(ShadowArtifacts, OffByAFifthWithin3PixelsOfAnEdgeIsNot) {
  struct Feature {
    const char* name;
    std::function<void(ExactPixel&)> change;
  };
  const Feature features[] = {
      {"shadow edge", [](ExactPixel& p) { p.visibility = 0.0; }},
      {"silhouette against another object", [](ExactPixel& p) { p.object = 1; }},
      {"silhouette against the background", [](ExactPixel& p) { p.geometry = false; }},
      {"crease", [](ExactPixel& p) { p.normal = {0.0f, std::sqrt(0.5f), std::sqrt(0.5f)}; }},
  };
  for (const Feature& f : features) {
    // The edge runs between columns first - 1 and first. Both are marked, so
    // column 10 is within 3 pixels of it while first <= 14.
    for (int first : {14, 15}) {
      const std::vector<ExactPixel> exact = split_at(first, f.change);
      Image rendered = rendered_exactly(exact);
      rendered.pixels[at(10, 10)] = 204;
      const ShadowError e = measure_shadow_error(rendered, exact);
      EXPECT_EQ(e.artifacts > 0.0, first == 15) << f.name << ", changed from column " << first;
      EXPECT_GT(e.interior_pixels, 0u) << f.name;
    }
  }
}

TEST(ShadowArtifacts, ANormalTurnedByOneDegreeIsNoCrease) {
  const double one_degree = 3.14159265358979323846 / 180.0;
  const std::vector<ExactPixel> exact = split_at(
      14, [&](ExactPixel& p) { p.normal = glm::vec3(0.0, std::sin(one_degree), std::cos(one_degree)); });
  Image rendered = rendered_exactly(exact);
  rendered.pixels[at(10, 10)] = 204;
  const ShadowError e = measure_shadow_error(rendered, exact);
  EXPECT_EQ(e.interior_pixels, 400u);
  EXPECT_DOUBLE_EQ(e.artifacts, 1.0 / 400.0);
}

TEST(ShadowArtifacts, OffByATwentiethIsNotAnArtifact) {
  const std::vector<ExactPixel> exact = lit_square();
  Image rendered = rendered_exactly(exact);
  rendered.pixels[at(10, 10)] = 242;  // v = 0.949
  const ShadowError e = measure_shadow_error(rendered, exact);
  EXPECT_EQ(e.interior_pixels, 400u);
  EXPECT_EQ(e.artifacts, 0.0);
  EXPECT_GT(e.mae, 0.0);
}

TEST(ShadowArtifacts, PenumbraIsNeverInterior) {
  const std::vector<ExactPixel> exact = split_at(0, [](ExactPixel& p) { p.visibility = 0.5; });
  const ShadowError e = measure_shadow_error(Image{kSide, kSide, 1, std::vector<std::uint8_t>(400, 0)}, exact);
  EXPECT_EQ(e.pixels, 400u);  // measured by the other fields ...
  EXPECT_EQ(e.interior_pixels, 0u);  // ... but never interior, however far off
  EXPECT_EQ(e.artifacts, 0.0);
}

TEST(ShadowArtifacts, InteriorPixelsOfKnownGrids) {
  const auto interior = [](const std::vector<ExactPixel>& exact) {
    return measure_shadow_error(rendered_exactly(exact), exact).interior_pixels;
  };
  // The image border is no edge.
  EXPECT_EQ(interior(lit_square()), 400u);
  EXPECT_EQ(interior(split_at(0, [](ExactPixel& p) { p.visibility = 0.0; })), 400u);
  // A shadow edge between columns 9 and 10 marks both; dilated by 3 that
  // leaves out columns 6..13: 8 of the 20.
  EXPECT_EQ(interior(split_at(10, [](ExactPixel& p) { p.visibility = 0.0; })), 12u * 20u);
  // Background in one corner: (0,0) and its neighbours (1,0), (0,1) are
  // marked, so the 5 x 5 corner goes, all but (4,4), 4 pixels from each.
  std::vector<ExactPixel> exact = lit_square();
  exact[at(0, 0)].geometry = false;
  EXPECT_EQ(interior(exact), 400u - 24u);
  // A grazing pixel is not measured, but it is no edge either.
  exact = lit_square();
  exact[at(10, 10)].n_dot_l = 0.01;
  EXPECT_EQ(interior(exact), 399u);
}

// MAE, wrong, false shadow and false light keep their pixels and numbers,
// edges or not; artifacts count only away from the edge.
TEST(ShadowArtifacts, TheOtherMeasuresAreAsTheyWere) {
  const std::vector<ExactPixel> exact = split_at(10, [](ExactPixel& p) { p.visibility = 0.0; });
  Image rendered = rendered_exactly(exact);
  rendered.pixels[at(2, 2)] = 0;     // lit, rendered dark: false shadow, and an artifact
  rendered.pixels[at(11, 5)] = 255;  // dark, rendered lit: false light, but by the edge
  rendered.pixels[at(16, 16)] = 51;  // dark, rendered 0.2: an artifact only
  const ShadowError e = measure_shadow_error(rendered, exact);
  EXPECT_EQ(e.pixels, 400u);
  EXPECT_NEAR(e.mae, 2.2 / 400.0, 1e-12);
  EXPECT_DOUBLE_EQ(e.wrong, 2.0 / 400.0);
  EXPECT_DOUBLE_EQ(e.false_shadow, 1.0 / 400.0);
  EXPECT_DOUBLE_EQ(e.false_light, 1.0 / 400.0);
  EXPECT_EQ(e.interior_pixels, 240u);
  EXPECT_DOUBLE_EQ(e.artifacts, 2.0 / 240.0);
}

// A side x side view of one flat object, exactly lit everywhere, with no
// edge, silhouette or crease: every pixel is interior.
std::vector<ExactPixel> lit_floor(int side) {
  ExactPixel lit;
  lit.geometry = true;
  lit.object = 0;
  lit.n_dot_l = 0.8;
  lit.normal = {0.0f, 1.0f, 0.0f};
  return std::vector<ExactPixel>(std::size_t(side) * side, lit);
}

// The finer look (measure_shadow_error's `finer`) is asked about exactly the
// 7 x 7 neighbourhood of each candidate, and a candidate next to a pixel an
// edge crosses is neither an artifact nor interior.
TEST(ShadowError, TheFinerLookSamplesTheCandidatesNeighbourhoodsOnly) {
  constexpr int kSide = 20;
  const std::vector<ExactPixel> exact = lit_floor(kSide);
  Image rendered{kSide, kSide, 1, std::vector<std::uint8_t>(kSide * kSide, 255)};
  rendered.pixels[5 * kSide + 5] = 0;    // candidate (5, 5)
  rendered.pixels[14 * kSide + 14] = 0;  // candidate (14, 14)
  std::vector<std::uint8_t> asked;
  const auto finer = [&](const std::vector<std::uint8_t>& which) {
    asked = which;
    std::vector<PixelCoverage> coverage(which.size(), PixelCoverage::lit);
    coverage[12 * kSide + 16] = PixelCoverage::mixed;  // within 3 px of (14, 14)
    return coverage;
  };
  const ShadowError centres = measure_shadow_error(rendered, exact);
  const ShadowError e = measure_shadow_error(rendered, exact, finer);
  EXPECT_EQ(centres.artifacts * centres.interior_pixels, 2.0);
  EXPECT_EQ(e.artifacts * e.interior_pixels, 1.0);
  EXPECT_EQ(e.interior_pixels, centres.interior_pixels - 1);
  ASSERT_EQ(asked.size(), exact.size());
  for (int y = 0; y < kSide; ++y)
    for (int x = 0; x < kSide; ++x) {
      const bool near_one = (std::abs(x - 5) <= 3 && std::abs(y - 5) <= 3) || (std::abs(x - 14) <= 3 && std::abs(y - 14) <= 3);
      EXPECT_EQ(asked[y * kSide + x] != 0, near_one) << x << "," << y;
    }
}

// Past kFinerPixels (and 1 / kFinerShare of the image) of neighbourhoods the
// finer look is not taken: the centres' verdict stands, and the cost stays
// bounded whatever the render.
TEST(ShadowError, ManyCandidatesKeepTheCentresVerdict) {
  constexpr int kSide = 100;
  const std::vector<ExactPixel> exact = lit_floor(kSide);
  const Image dark{kSide, kSide, 1, std::vector<std::uint8_t>(kSide * kSide, 0)};
  bool asked = false;
  const auto finer = [&](const std::vector<std::uint8_t>& which) {
    asked = true;
    return std::vector<PixelCoverage>(which.size(), PixelCoverage::mixed);
  };
  const ShadowError e = measure_shadow_error(dark, exact, finer);
  EXPECT_FALSE(asked);
  EXPECT_EQ(e.interior_pixels, std::size_t(kSide * kSide));
  EXPECT_EQ(e.artifacts, 1.0);
}

}  // namespace
}  // namespace umbra
