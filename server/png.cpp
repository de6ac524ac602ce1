#include "png.hpp"

#include <cstdlib>
#include <memory>
#include <mutex>
#include <new>
#include <stdexcept>

#include <spng.h>

namespace umbra {
namespace {

// A mutex, not an atomic per field: a reader must never pair the new level
// with the old filter. It is held for a copy of two ints, never during an
// encode, so the workers do not queue on it.
std::mutex settings_mutex;
PngSettings current_settings;

struct ContextFree {
  void operator()(spng_ctx* ctx) const { spng_ctx_free(ctx); }
};
struct BufferFree {
  void operator()(void* buffer) const { std::free(buffer); }
};

int filter_choice(int filter) {
  switch (filter) {
    case -1: return SPNG_FILTER_CHOICE_ALL;
    case 0: return SPNG_FILTER_CHOICE_NONE;
    case 1: return SPNG_FILTER_CHOICE_SUB;
    case 2: return SPNG_FILTER_CHOICE_UP;
    case 3: return SPNG_FILTER_CHOICE_AVG;
    default: return SPNG_FILTER_CHOICE_PAETH;
  }
}

void validate_image(const Image& image) {
  if (image.width <= 0 || image.height <= 0) throw std::invalid_argument("PNG: image has no pixels");
  if (image.channels != 1 && image.channels != 3) throw std::invalid_argument("PNG: channels must be 1 or 3");
  if (image.bit_depth != 8 && image.bit_depth != 16) throw std::invalid_argument("PNG: bit_depth must be 8 or 16");
  if (image.pixels.size() != image.row_bytes() * std::size_t(image.height))
    throw std::invalid_argument("PNG: pixels must be height * row_bytes() long");
}

void check(int error) {
  if (error == SPNG_EMEM) throw std::bad_alloc();
  if (error) throw std::runtime_error(std::string("PNG encoding failed: ") + spng_strerror(error));
}

}  // namespace

void validate_png_settings(const PngSettings& settings) {
  if (settings.level < 1 || settings.level > 9 || settings.filter < -1 || settings.filter > 4)
    throw std::invalid_argument("PNG level must be 1..9 and filter -1..4");
}

void set_png_settings(const PngSettings& settings) {
  validate_png_settings(settings);
  std::lock_guard<std::mutex> lock(settings_mutex);
  current_settings = settings;
}

PngSettings png_settings() {
  std::lock_guard<std::mutex> lock(settings_mutex);
  return current_settings;
}

std::string encode_png(const Image& image) { return encode_png(image, png_settings()); }

std::string encode_png(const Image& image, const PngSettings& settings) {
  validate_png_settings(settings);
  validate_image(image);
  const std::unique_ptr<spng_ctx, ContextFree> ctx(spng_ctx_new(SPNG_CTX_ENCODER));
  if (!ctx) throw std::bad_alloc();
  spng_ihdr ihdr{};
  ihdr.width = std::uint32_t(image.width);
  ihdr.height = std::uint32_t(image.height);
  ihdr.bit_depth = std::uint8_t(image.bit_depth);
  ihdr.color_type = image.channels == 1 ? SPNG_COLOR_TYPE_GRAYSCALE : SPNG_COLOR_TYPE_TRUECOLOR;
  // The zlib strategy is left to libspng (Z_FILTERED for filtered rows, the
  // default for unfiltered ones). Z_FILTERED on unfiltered rows changed
  // nothing measurable; Z_RLE halves the grey images but makes the RGB frame
  // 685 KiB (bench/results/png.md).
  check(spng_set_option(ctx.get(), SPNG_ENCODE_TO_BUFFER, 1));
  check(spng_set_option(ctx.get(), SPNG_IMG_COMPRESSION_LEVEL, settings.level));
  check(spng_set_option(ctx.get(), SPNG_FILTER_CHOICE, filter_choice(settings.filter)));
  check(spng_set_ihdr(ctx.get(), &ihdr));
  // SPNG_FMT_PNG: samples as PNG lays them out, except that 16-bit ones are
  // in host order and libspng swaps them to big-endian (SPNG_FMT_RAW would
  // take them big-endian already). Host order is what Image documents.
  check(spng_encode_image(ctx.get(), image.pixels.data(), image.pixels.size(), SPNG_FMT_PNG, SPNG_ENCODE_FINALIZE));
  std::size_t size = 0;
  int error = 0;
  const std::unique_ptr<void, BufferFree> png(spng_get_png_buffer(ctx.get(), &size, &error));
  check(png ? 0 : error ? error : SPNG_EINTERNAL);
  return std::string(static_cast<const char*>(png.get()), size);
}

}  // namespace umbra
