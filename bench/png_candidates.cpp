#include "png_candidates.hpp"

#include <csetjmp>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>

#include <png.h>
#include <spng.h>
#include <zlib.h>

namespace umbra::bench {
namespace {

// stb hands its filtered rows to this as one buffer; stb passes the level as
// `quality`.
unsigned char* zlib_compress(unsigned char* data, int length, int* out_length, int quality) {
  uLongf size = compressBound(uLong(length));
  auto* out = static_cast<unsigned char*>(std::malloc(size));
  if (!out) return nullptr;
  if (compress2(out, &size, data, uLong(length), quality) != Z_OK) {
    std::free(out);
    return nullptr;
  }
  *out_length = int(size);
  return out;
}

}  // namespace
}  // namespace umbra::bench

// Static, so it cannot collide with libstb's own build of the same functions
// that png_bench.cpp links for the baseline.
#define STB_IMAGE_WRITE_STATIC
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STBI_WRITE_NO_STDIO
#define STBIW_ZLIB_COMPRESS umbra::bench::zlib_compress
#include <stb_image_write.h>

namespace umbra::bench {
namespace {

void append(void* context, void* data, int size) {
  static_cast<std::string*>(context)->append(static_cast<const char*>(data), std::size_t(size));
}

int stb_filter(Filter filter) {
  switch (filter) {
    case Filter::none: return 0;
    case Filter::sub: return 1;
    case Filter::up: return 2;
    case Filter::adaptive: return -1;
  }
  return -1;
}

int zlib_strategy(Strategy strategy) { return strategy == Strategy::rle ? Z_RLE : Z_FILTERED; }

void require_8_or_16_bit_grey_or_rgb(const Image& image) {
  if ((image.channels != 1 && image.channels != 3) || (image.bit_depth != 8 && image.bit_depth != 16))
    throw std::invalid_argument("bench encoders take 8/16-bit grey or RGB");
}

// libpng reports errors by longjmp: nothing with a destructor may live in this
// frame, so the output string belongs to the caller.
bool libpng_write(const Image& image, int level, Filter filter, Strategy strategy, std::string* out) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  if (!png) return false;
  png_infop info = png_create_info_struct(png);
  if (!info || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_set_write_fn(
      png, out,
      [](png_structp p, png_bytep data, png_size_t size) {
        static_cast<std::string*>(png_get_io_ptr(p))->append(reinterpret_cast<const char*>(data), size);
      },
      [](png_structp) {});
  png_set_IHDR(png, info, png_uint_32(image.width), png_uint_32(image.height), image.bit_depth,
               image.channels == 1 ? PNG_COLOR_TYPE_GRAY : PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_compression_level(png, level);
  const int filters[] = {PNG_FILTER_NONE, PNG_FILTER_SUB, PNG_FILTER_UP, PNG_ALL_FILTERS};
  png_set_filter(png, PNG_FILTER_TYPE_BASE, filters[int(filter)]);
  if (strategy != Strategy::library) png_set_compression_strategy(png, zlib_strategy(strategy));
  png_write_info(png, info);
  // Image keeps 16-bit samples in host order; PNG wants big-endian, so a
  // little-endian host has libpng swap them.
  const std::uint16_t one = 1;
  if (image.bit_depth == 16 && *reinterpret_cast<const unsigned char*>(&one) == 1) png_set_swap(png);
  for (int y = 0; y < image.height; ++y) png_write_row(png, image.row(y));
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);
  return true;
}

}  // namespace

const char* name(Filter filter) {
  static const char* const names[] = {"none", "sub", "up", "adaptive"};
  return names[int(filter)];
}

const char* name(Strategy strategy) {
  static const char* const names[] = {"", "Z_RLE", "Z_FILTERED"};
  return names[int(strategy)];
}

std::string stb_zlib_png(const Image& image, int level, Filter filter) {
  if (image.bit_depth != 8) throw std::invalid_argument("stb writes 8-bit PNGs only");
  stbi_write_png_compression_level = level;
  stbi_write_force_png_filter = stb_filter(filter);
  std::string out;
  out.reserve(std::size_t(image.width) * image.height * image.channels / 2);
  if (!stbi_write_png_to_func(append, &out, image.width, image.height, image.channels, image.pixels.data(),
                              image.width * image.channels))
    throw std::runtime_error("stb: PNG encoding failed");
  return out;
}

std::string libpng_png(const Image& image, int level, Filter filter, Strategy strategy) {
  require_8_or_16_bit_grey_or_rgb(image);
  std::string out;
  if (!libpng_write(image, level, filter, strategy, &out)) throw std::runtime_error("libpng: PNG encoding failed");
  return out;
}

std::string libspng_png(const Image& image, int level, Filter filter, Strategy strategy) {
  require_8_or_16_bit_grey_or_rgb(image);
  spng_ctx* ctx = spng_ctx_new(SPNG_CTX_ENCODER);
  if (!ctx) throw std::bad_alloc();
  const int filters[] = {SPNG_FILTER_CHOICE_NONE, SPNG_FILTER_CHOICE_SUB, SPNG_FILTER_CHOICE_UP,
                         SPNG_FILTER_CHOICE_ALL};
  spng_ihdr ihdr{};
  ihdr.width = std::uint32_t(image.width);
  ihdr.height = std::uint32_t(image.height);
  ihdr.bit_depth = std::uint8_t(image.bit_depth);
  ihdr.color_type = image.channels == 1 ? SPNG_COLOR_TYPE_GRAYSCALE : SPNG_COLOR_TYPE_TRUECOLOR;
  int error = spng_set_option(ctx, SPNG_ENCODE_TO_BUFFER, 1);
  if (!error) error = spng_set_option(ctx, SPNG_IMG_COMPRESSION_LEVEL, level);
  if (!error) error = spng_set_option(ctx, SPNG_FILTER_CHOICE, filters[int(filter)]);
  if (!error && strategy != Strategy::library)
    error = spng_set_option(ctx, SPNG_IMG_COMPRESSION_STRATEGY, zlib_strategy(strategy));
  if (!error) error = spng_set_ihdr(ctx, &ihdr);
  // SPNG_FMT_PNG: 16-bit samples in host order, which libspng swaps to big-endian.
  if (!error)
    error = spng_encode_image(ctx, image.pixels.data(), image.pixels.size(), SPNG_FMT_PNG, SPNG_ENCODE_FINALIZE);
  std::size_t size = 0;
  void* png = error ? nullptr : spng_get_png_buffer(ctx, &size, &error);
  spng_ctx_free(ctx);
  if (!png) throw std::runtime_error(std::string("libspng: ") + spng_strerror(error));
  std::string out(static_cast<const char*>(png), size);
  std::free(png);
  return out;
}

}  // namespace umbra::bench
