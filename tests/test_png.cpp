// encode_png on its own: the bytes it writes, 16-bit grey, settings, threads.
// No GL and no server: images are made here.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <stb_image.h>
#include <zlib.h>

#include "png.hpp"

namespace umbra {
namespace {

std::uint32_t big_endian_u32(const std::string& bytes, std::size_t at) {
  return std::uint32_t(std::uint8_t(bytes[at])) << 24 | std::uint32_t(std::uint8_t(bytes[at + 1])) << 16 |
         std::uint32_t(std::uint8_t(bytes[at + 2])) << 8 | std::uint32_t(std::uint8_t(bytes[at + 3]));
}

struct Chunk {
  std::string type;
  std::string data;
};

// Splits a PNG into its chunks, checking the signature, every length and
// every CRC on the way: a chunk that fails any of them fails the test.
std::vector<Chunk> chunks(const std::string& png) {
  std::vector<Chunk> out;
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  std::size_t at = 8;
  while (at + 12 <= png.size()) {
    const std::size_t length = big_endian_u32(png, at);
    if (at + 12 + length > png.size()) break;
    Chunk chunk{png.substr(at + 4, 4), png.substr(at + 8, length)};
    const uLong crc = crc32(0, reinterpret_cast<const Bytef*>(png.data() + at + 4), uInt(4 + length));
    EXPECT_EQ(crc, big_endian_u32(png, at + 8 + length)) << "bad CRC on " << chunk.type;
    out.push_back(std::move(chunk));
    at += 12 + length;
  }
  EXPECT_EQ(at, png.size()) << "truncated chunk";
  EXPECT_FALSE(out.empty());
  if (!out.empty()) {
    EXPECT_EQ(out.front().type, "IHDR");
    EXPECT_EQ(out.back().type, "IEND");
  }
  return out;
}

struct Ihdr {
  std::uint32_t width = 0, height = 0;
  int bit_depth = 0, colour_type = 0, compression = -1, filter = -1, interlace = -1;
};

Ihdr ihdr(const std::vector<Chunk>& chunks) {
  Ihdr h;
  if (chunks.empty() || chunks.front().type != "IHDR" || chunks.front().data.size() != 13) {
    ADD_FAILURE() << "no 13-byte IHDR first";
    return h;
  }
  const std::string& d = chunks.front().data;
  h.width = big_endian_u32(d, 0);
  h.height = big_endian_u32(d, 4);
  h.bit_depth = std::uint8_t(d[8]);
  h.colour_type = std::uint8_t(d[9]);
  h.compression = std::uint8_t(d[10]);
  h.filter = std::uint8_t(d[11]);
  h.interlace = std::uint8_t(d[12]);
  return h;
}

// The IDAT chunks joined and inflated with zlib: the filtered scanlines.
std::string inflate_idat(const std::vector<Chunk>& chunks, std::size_t expected) {
  std::string stream;
  for (const Chunk& c : chunks)
    if (c.type == "IDAT") stream += c.data;
  // Room past the expected size, so a stream that inflates to more shows as
  // a wrong size rather than as a buffer error.
  std::string raw(expected + 64, '\0');
  uLongf size = uLongf(raw.size());
  const int result = uncompress(reinterpret_cast<Bytef*>(raw.data()), &size,
                                reinterpret_cast<const Bytef*>(stream.data()), uLong(stream.size()));
  EXPECT_EQ(result, Z_OK) << "IDAT is not one valid zlib stream";
  raw.resize(result == Z_OK ? size : 0);
  return raw;
}

// A 16-bit grey ramp whose high and low bytes both vary, so a byte-order
// mistake cannot go unseen.
std::vector<std::uint16_t> grey16_samples(int width, int height) {
  std::vector<std::uint16_t> samples(std::size_t(width) * height);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      samples[std::size_t(y) * width + x] = std::uint16_t((x * 65535 / (width - 1)) ^ (y * 0x0101 + x * 7));
  return samples;
}

Image grey16(int width, int height, const std::vector<std::uint16_t>& samples) {
  Image image{width, height, 1, std::vector<std::uint8_t>(samples.size() * 2)};
  image.bit_depth = 16;
  std::memcpy(image.pixels.data(), samples.data(), image.pixels.size());
  return image;
}

Image rgb8(int width, int height) {
  Image image{width, height, 3, std::vector<std::uint8_t>(std::size_t(width) * height * 3)};
  for (std::size_t i = 0; i < image.pixels.size(); ++i) image.pixels[i] = std::uint8_t(i * 31 / 7 + (i % 3) * 80);
  return image;
}

std::vector<std::uint8_t> decode8(const std::string& png, int channels) {
  int w = 0, h = 0, n = 0;
  stbi_uc* p =
      stbi_load_from_memory(reinterpret_cast<const stbi_uc*>(png.data()), int(png.size()), &w, &h, &n, channels);
  EXPECT_NE(p, nullptr) << "stb_image cannot decode it";
  if (!p) return {};
  std::vector<std::uint8_t> out(p, p + std::size_t(w) * h * channels);
  stbi_image_free(p);
  return out;
}

TEST(Png, RgbAndGreyHeadersAndPixelsRoundTrip) {
  const Image rgb = rgb8(37, 11);
  const std::string png = encode_png(rgb);
  const Ihdr h = ihdr(chunks(png));
  EXPECT_EQ(h.width, 37u);
  EXPECT_EQ(h.height, 11u);
  EXPECT_EQ(h.bit_depth, 8);
  EXPECT_EQ(h.colour_type, 2);  // truecolour
  EXPECT_EQ(h.compression, 0);
  EXPECT_EQ(h.filter, 0);
  EXPECT_EQ(h.interlace, 0);
  EXPECT_EQ(decode8(png, 3), rgb.pixels);

  Image grey{5, 3, 1, {0, 1, 2, 3, 4, 250, 251, 252, 253, 254, 9, 99, 199, 255, 128}};
  const std::string grey_png = encode_png(grey);
  EXPECT_EQ(ihdr(chunks(grey_png)).colour_type, 0);
  EXPECT_EQ(decode8(grey_png, 1), grey.pixels);
}

TEST(Png, EveryFilterAndLevelRoundTrips) {
  const Image rgb = rgb8(23, 9);
  for (int level = 1; level <= 9; ++level)
    for (int filter = -1; filter <= 4; ++filter)
      EXPECT_EQ(decode8(encode_png(rgb, {level, filter}), 3), rgb.pixels) << "level " << level << " filter " << filter;
}

TEST(Png, Grey16HeaderAndZlibStream) {
  const int width = 61, height = 17;
  const std::string png = encode_png(grey16(width, height, grey16_samples(width, height)));
  const std::vector<Chunk> c = chunks(png);
  const Ihdr h = ihdr(c);
  EXPECT_EQ(h.width, std::uint32_t(width));
  EXPECT_EQ(h.height, std::uint32_t(height));
  EXPECT_EQ(h.bit_depth, 16);
  EXPECT_EQ(h.colour_type, 0);  // greyscale
  EXPECT_EQ(h.interlace, 0);
  // One filter-type byte, then two bytes per sample, on every row.
  const std::size_t raw_size = std::size_t(height) * (1 + std::size_t(width) * 2);
  EXPECT_EQ(inflate_idat(c, raw_size).size(), raw_size);
}

TEST(Png, Grey16SamplesAreWrittenBigEndian) {
  const int width = 40, height = 6;
  const std::vector<std::uint16_t> samples = grey16_samples(width, height);
  // No filter: the inflated rows are the samples themselves.
  const std::vector<Chunk> c = chunks(encode_png(grey16(width, height, samples), {2, 0}));
  const std::string raw = inflate_idat(c, std::size_t(height) * (1 + width * 2));
  ASSERT_EQ(raw.size(), std::size_t(height) * (1 + width * 2));
  for (int y = 0; y < height; ++y) {
    const std::size_t row = std::size_t(y) * (1 + width * 2);
    EXPECT_EQ(raw[row], 0) << "row " << y << " is filtered";
    for (int x = 0; x < width; ++x) {
      const std::uint16_t value = samples[std::size_t(y) * width + x];
      ASSERT_EQ(std::uint8_t(raw[row + 1 + 2 * x]), value >> 8) << x << ", " << y;
      ASSERT_EQ(std::uint8_t(raw[row + 2 + 2 * x]), value & 0xff) << x << ", " << y;
    }
  }
}

TEST(Png, Grey16DecodesToTheSameSamplesWithEveryFilter) {
  const int width = 33, height = 21;
  const std::vector<std::uint16_t> samples = grey16_samples(width, height);
  const Image image = grey16(width, height, samples);
  for (int filter = -1; filter <= 4; ++filter) {
    const std::string png = encode_png(image, {2, filter});
    int w = 0, h = 0, n = 0;
    stbi_us* p = stbi_load_16_from_memory(reinterpret_cast<const stbi_uc*>(png.data()), int(png.size()), &w, &h, &n, 1);
    ASSERT_NE(p, nullptr) << "filter " << filter;
    EXPECT_EQ(std::vector<std::uint16_t>(p, p + samples.size()), samples) << "filter " << filter;
    stbi_image_free(p);
  }
}

TEST(Png, SettingsAreValidatedAndABadOneChangesNothing) {
  const PngSettings before = png_settings();
  EXPECT_EQ(before.level, 3);
  EXPECT_EQ(before.filter, 0);
  for (const PngSettings bad : {PngSettings{0, 0}, PngSettings{10, 0}, PngSettings{2, -2}, PngSettings{2, 5}}) {
    EXPECT_THROW(set_png_settings(bad), std::invalid_argument) << bad.level << ", " << bad.filter;
    EXPECT_THROW(encode_png(rgb8(4, 4), bad), std::invalid_argument) << bad.level << ", " << bad.filter;
    EXPECT_EQ(png_settings().level, before.level);
    EXPECT_EQ(png_settings().filter, before.filter);
  }
  for (const PngSettings good : {PngSettings{1, -1}, PngSettings{9, 4}}) {
    EXPECT_NO_THROW(set_png_settings(good));
    EXPECT_EQ(png_settings().level, good.level);
    EXPECT_EQ(png_settings().filter, good.filter);
    // The defaults are what encode_png(image) uses.
    EXPECT_EQ(encode_png(rgb8(9, 5)), encode_png(rgb8(9, 5), good));
  }
  set_png_settings(before);
}

TEST(Png, MalformedImagesAreRefused) {
  Image two_channels{2, 2, 2, std::vector<std::uint8_t>(8)};
  Image twelve_bit{2, 2, 1, std::vector<std::uint8_t>(8)};
  twelve_bit.bit_depth = 12;
  Image short_pixels{4, 4, 3, std::vector<std::uint8_t>(47)};
  Image grey16_sized_as_8{4, 4, 1, std::vector<std::uint8_t>(16)};
  grey16_sized_as_8.bit_depth = 16;
  Image empty{0, 4, 1, {}};
  for (const Image* image : {&two_channels, &twelve_bit, &short_pixels, &grey16_sized_as_8, &empty})
    EXPECT_THROW(encode_png(*image), std::invalid_argument);
}

TEST(Png, ConcurrentEncodesKeepTheirOwnSettings) {
  // encode_png runs on many HTTP workers at once; one worker's settings must
  // never leak into another's encode, even while the defaults change.
  const Image rgb = rgb8(64, 32);
  const Image grey = grey16(48, 16, grey16_samples(48, 16));
  const PngSettings settings[] = {{1, 0}, {6, -1}, {9, 2}, {3, 4}};
  std::vector<std::string> expected_rgb, expected_grey;
  for (const PngSettings& s : settings) {
    expected_rgb.push_back(encode_png(rgb, s));
    expected_grey.push_back(encode_png(grey, s));
  }
  const PngSettings before = png_settings();
  std::vector<std::thread> threads;
  std::vector<int> mismatches(4, 0);
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      for (int i = 0; i < 50; ++i) {
        mismatches[t] += encode_png(rgb, settings[t]) != expected_rgb[t];
        mismatches[t] += encode_png(grey, settings[t]) != expected_grey[t];
      }
    });
  }
  // An encode with the defaults must use one whole pair: the old or the new.
  int torn = 0;
  threads.emplace_back([&] {
    const std::string with_before = encode_png(rgb, before);
    for (int i = 0; i < 50; ++i) {
      const std::string png = encode_png(rgb);
      bool known = png == with_before;
      for (const std::string& e : expected_rgb) known = known || png == e;
      torn += !known;
    }
  });
  for (int i = 0; i < 200; ++i) set_png_settings(settings[i % 4]);
  for (std::thread& t : threads) t.join();
  set_png_settings(before);
  for (int t = 0; t < 4; ++t) EXPECT_EQ(mismatches[t], 0) << "thread " << t;
  EXPECT_EQ(torn, 0);
}

}  // namespace
}  // namespace umbra
