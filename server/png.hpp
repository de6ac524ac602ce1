// Image -> PNG bytes. Runs on HTTP worker threads, never on the GL thread,
// so encoding one frame overlaps rendering the next.
#pragma once

#include <string>

#include "image.hpp"

namespace umbra {

/// How PNGs are compressed. The defaults were chosen by measurement
/// (umbra-png-bench; bench/results/png.md): on the default 960x540 frame,
/// zlib level 6 with no row filter takes 5 ms for 16 KiB, where stb's own
/// deflate (level 8, adaptive filter) took 27-40 ms for 48 KiB. Levels 1-3
/// save 3 ms but double the bytes; adaptive filtering costs time and, on
/// these smooth synthetic images, even makes them larger.
struct PngSettings {
  /// zlib deflate effort (Debian's zlib1g, plugged into stb_image_write),
  /// 1 (fastest) .. 9 (smallest). Default 6.
  int level = 6;
  /// PNG row filter: -1 lets stb pick one per row (the one with the
  /// smallest sum of absolute differences); 0..4 forces none, sub, up,
  /// average or Paeth for every row. Default 0 (none).
  int filter = 0;
};

/// Sets how every later encode_png() compresses. stb keeps these in
/// process-wide variables: call it before encoding starts on any thread.
void set_png_settings(const PngSettings& settings);

/// Encodes a grey (1 channel) or RGB (3 channel) image. Throws
/// std::runtime_error if encoding fails (out of memory).
std::string encode_png(const Image& image);

}  // namespace umbra
