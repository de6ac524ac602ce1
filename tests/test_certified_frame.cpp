// Filter "exact"'s CPU half without GL: which pixels it ray casts.
#include <gtest/gtest.h>

#include <random>
#include <tuple>

#include <algorithm>

#include "core/raster_outline.hpp"
#include "reference/certified_frame.hpp"
#include "scene_support.hpp"

namespace umbra {
namespace {

constexpr std::uint32_t kLit = PixelCertificates::kCertainlyLit, kDark = PixelCertificates::kCertainlyDark,
                        kUncertain = PixelCertificates::kUncertain;

std::uint32_t code(std::uint32_t object_plus_one, bool facing, std::uint32_t verdict) {
  return (object_plus_one << PixelCertificates::kObjectShift) | (facing ? 4u : 0u) | verdict;
}


// pixels_to_ray_cast of these codes, without sliver marks.
std::vector<std::uint8_t> to_cast(const std::vector<std::uint32_t>& codes, int width, int height, int ring) {
  PixelCertificates c;
  c.codes = codes;
  return pixels_to_ray_cast(c, width, height, ring);
}

// The pixels `ring` or more from the image's border (those nearer it are
// always cast: PixelsToRayCast.TheBorderIsAChangeOfSurface).
std::size_t count_inside(const std::vector<std::uint8_t>& cast, int width, int height, int ring) {
  std::size_t n = 0;
  for (int y = ring; y < height - ring; ++y)
    for (int x = ring; x < width - ring; ++x) n += cast[std::size_t(y * width + x)] != 0;
  return n;
}

TEST(PixelsToRayCast, OnlyUncertainPixelsOfOneSurface) {
  std::vector<std::uint32_t> codes(8 * 6, code(1, true, kLit));
  codes[2 * 8 + 3] = code(1, true, kUncertain);
  codes[4 * 8 + 5] = code(1, true, kDark);
  const std::vector<std::uint8_t> cast = to_cast(codes, 8, 6, 1);
  EXPECT_EQ(count_inside(cast, 8, 6, 1), 1u);
  EXPECT_EQ(cast[2 * 8 + 3], 1);
}

TEST(PixelsToRayCast, BothSidesOfAChangeOfObjectOrOfFacing) {
  // Columns 0-7 see object 1, 8-15 object 2: columns 7 and 8 are cast.
  const int w = 16, h = 8;
  std::vector<std::uint32_t> codes(w * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) codes[y * w + x] = code(x < 8 ? 1 : 2, true, kLit);
  std::vector<std::uint8_t> cast = to_cast(codes, w, h, 1);
  EXPECT_EQ(count_inside(cast, w, h, 1), 2u * (h - 2));
  for (int y = 0; y < h; ++y) EXPECT_TRUE(cast[y * w + 7] && cast[y * w + 8]);
  // A crease: one object, its faces turned to both sides of the light.
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) codes[y * w + x] = code(1, x < 8, x < 8 ? kLit : kDark);
  cast = to_cast(codes, w, h, 1);
  EXPECT_EQ(count_inside(cast, w, h, 1), 2u * (h - 2));
  // Ring 3: two more columns each side (columns 5 to 10).
  cast = to_cast(codes, w, h, 3);
  EXPECT_EQ(count_inside(cast, w, h, 3), 6u * (h - 6));
  EXPECT_FALSE(cast[4 * w + 4]);
  EXPECT_TRUE(cast[4 * w + 5]);
  EXPECT_TRUE(cast[4 * w + 10]);
  EXPECT_FALSE(cast[4 * w + 11]);
}

// Outside the image is another surface (what lies past the border is not
// drawn): the pixels within `ring` of the border are cast, one surface
// everywhere or not.
TEST(PixelsToRayCast, TheBorderIsAChangeOfSurface) {
  const int w = 10, h = 7;
  const std::vector<std::uint32_t> codes(w * h, code(1, true, kLit));
  for (int ring = 1; ring <= 3; ++ring) {
    const std::vector<std::uint8_t> cast = to_cast(codes, w, h, ring);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const bool near_border = x < ring || y < ring || x >= w - ring || y >= h - ring;
        EXPECT_EQ(cast[std::size_t(y * w + x)] != 0, near_border) << "ring " << ring << " at " << x << ", " << y;
      }
  }
}

// The ring grows each change of surface by ring - 1 pixels every way (a
// square), as a brute force over random codes finds it: on images small,
// and tall enough to be split into several bands of rows (one a thread),
// and with rings past the image's size.
TEST(PixelsToRayCast, TheRingIsASquareAroundEachChange) {
  std::mt19937 random(3);
  for (const std::tuple<int, int, int>& size : {std::tuple{13, 11, 20}, std::tuple{1, 40, 4}, std::tuple{40, 1, 4},
                                                std::tuple{37, 130, 3}, std::tuple{120, 97, 2}})
  for (int round = 0; round < std::get<2>(size); ++round) {
    // Plain variables: lambdas below capture them (clang 14 refuses
    // structured bindings there).
    const int w = std::get<0>(size), h = std::get<1>(size);
    std::vector<std::uint32_t> codes(std::size_t(w * h));
    for (std::uint32_t& c : codes) c = code(random() % 7 == 0 ? 2 : 1, true, random() % 11 == 0 ? kUncertain : kLit);
    const auto surface = [&](int x, int y) { return codes[std::size_t(y * w + x)] >> 2; };
    std::vector<std::uint8_t> change(codes.size(), 0);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (const auto& [dx, dy] : {std::pair{1, 0}, std::pair{-1, 0}, std::pair{0, 1}, std::pair{0, -1}})
          if (x + dx >= 0 && x + dx < w && y + dy >= 0 && y + dy < h && surface(x, y) != surface(x + dx, y + dy))
            change[std::size_t(y * w + x)] = 1;
    for (const int ring : {1, 2, 3, 4, 9, 200}) {
      const std::vector<std::uint8_t> cast = to_cast(codes, w, h, ring);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          bool expected = (codes[std::size_t(y * w + x)] & 3u) == kUncertain || x < ring || y < ring ||
                          x >= w - ring || y >= h - ring;
          for (int v = std::max(0, y - ring + 1); v <= std::min(h - 1, y + ring - 1); ++v)
            for (int u = std::max(0, x - ring + 1); u <= std::min(w - 1, x + ring - 1); ++u) expected |= change[std::size_t(v * w + u)] != 0;
          ASSERT_EQ(cast[std::size_t(y * w + x)] != 0, expected) << "ring " << ring << " at " << x << ", " << y;
        }
    }
  }
}

TEST(PixelsToRayCast, RefusesCodesOfAnotherSize) {
  EXPECT_THROW(to_cast(std::vector<std::uint32_t>(10), 4, 4, 1), std::invalid_argument);
  PixelCertificates c;
  c.codes.assign(16, 0);
  c.slivers.assign(15, 0);
  EXPECT_THROW(pixels_to_ray_cast(c, 4, 4, 1), std::invalid_argument);
}

TEST(PixelsToRayCast, PixelsTheSliverPassMarked) {
  PixelCertificates c;
  c.codes.assign(8 * 6, code(1, true, kLit));
  c.slivers.assign(c.codes.size(), 0);
  c.slivers[3 * 8 + 2] = 1;
  const std::vector<std::uint8_t> cast = pixels_to_ray_cast(c, 8, 6, 1);
  EXPECT_EQ(count_inside(cast, 8, 6, 1), 1u);
  EXPECT_EQ(cast[3 * 8 + 2], 1);
}

TEST(SilhouetteRing, FlatShapesNeedOnePixelCurvedOnesCloseUpMore) {
  RenderRequest r = test::builtin_request("cube-on-plane");
  r.scene.objects.clear();
  SceneObject box;
  box.type = SceneObject::Type::Box;
  r.scene.objects.push_back(box);
  EXPECT_EQ(silhouette_ring(r), 1);
  SceneObject sphere;
  sphere.type = SceneObject::Type::Sphere;
  sphere.radius = 0.5;
  r.scene.objects.push_back(sphere);
  // A half-unit sphere 6 units away on a 540-pixel image: its tessellation
  // moves the outline by a tenth of a pixel.
  EXPECT_EQ(silhouette_ring(r), 2);
  // A sphere of radius 50 whose surface is 1 unit from the camera: about
  // 0.1 units, tens of pixels.
  sphere.radius = 50.0;
  sphere.center = r.camera.position + glm::dvec3(0.0, 0.0, -51.0);
  r.scene.objects.push_back(sphere);
  EXPECT_GT(silhouette_ring(r), 20);
}

}  // namespace
}  // namespace umbra
