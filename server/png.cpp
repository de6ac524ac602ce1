#include "png.hpp"

#include <cstdlib>
#include <stdexcept>

#include <zlib.h>

namespace umbra {
namespace {

// stb_image_write's deflate is simple and slow; zlib's is fast at low
// levels. stb passes its compression level as `quality`.
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
}  // namespace umbra

// A private copy of stb_image_write's implementation (the header from
// Debian's libstb-dev), built with zlib as its deflate.
#define STB_IMAGE_WRITE_STATIC
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STBI_WRITE_NO_STDIO
#define STBIW_ZLIB_COMPRESS umbra::zlib_compress
#include <stb_image_write.h>

namespace umbra {
namespace {

void append(void* context, void* data, int size) {
  static_cast<std::string*>(context)->append(static_cast<const char*>(data), std::size_t(size));
}

}  // namespace

void set_png_settings(const PngSettings& settings) {
  if (settings.level < 1 || settings.level > 9 || settings.filter < -1 || settings.filter > 4)
    throw std::invalid_argument("PNG level must be 1..9 and filter -1..4");
  stbi_write_png_compression_level = settings.level;
  stbi_write_force_png_filter = settings.filter;
}

// stb starts at its own defaults (level 8): ours apply from the start.
const bool png_defaults_applied = (set_png_settings(PngSettings{}), true);

std::string encode_png(const Image& image) {
  std::string out;
  out.reserve(std::size_t(image.width) * image.height * image.channels / 2);
  if (!stbi_write_png_to_func(append, &out, image.width, image.height, image.channels, image.pixels.data(),
                              image.width * image.channels))
    throw std::runtime_error("PNG encoding failed");
  return out;
}

}  // namespace umbra
