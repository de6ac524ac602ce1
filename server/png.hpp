// Image -> PNG bytes. Runs on HTTP worker threads, never on the GL thread,
// so encoding one frame overlaps rendering the next. Many workers encode at
// once: every encode has its own libspng context, and the settings are read
// once per call, so nothing is shared between encodes.
#pragma once

#include <string>

#include "core/image.hpp"

namespace umbra {

/// How PNGs are compressed (libspng, with Debian's zlib as its deflate).
///
/// The encoder and the defaults were chosen by measurement (umbra-png-bench;
/// bench/results/png.md) among stb_image_write + zlib, libpng and libspng at
/// zlib levels 1-3 and 6 with filters none / sub / up / adaptive, and the
/// strategies Z_RLE and Z_FILTERED, on the default frame, shadow mask and
/// depth map. The rule: of the settings whose PNG is at most 2x the bytes of
/// what Umbra used before (stb + zlib, level 6, no filter: 16 KiB and 7-9 ms
/// for the default 960x540 frame) on all three images, the fastest on the
/// frame; times within 10 % tie (load on a shared machine moves them that
/// much), and of a tie the smallest frame PNG wins.
///
/// That is level 3 with no filter: 3.3 ms for 29 KiB in the committed run
/// (0.4x the time, 1.8x the bytes of before). Levels 1 and 2 were within 5 %
/// of it and 1-3 KiB larger; level 6 takes 2.4x as long. Row filters cost
/// time at every level and, on these smooth images at levels 1-3, make the
/// PNG larger, not smaller. Z_RLE halves the grey images in the same time
/// but makes the RGB frame 685 KiB unfiltered (31 KiB and slower filtered),
/// so it is not used.
///
/// Unfiltered, the libraries differ only in how they feed zlib: libpng and
/// libspng write the same bytes, their times within the noise; stb + zlib is
/// ~10 % slower, keeps its options in process-wide globals and writes no
/// 16-bit PNG. Of libpng and libspng, libspng is used: it takes 16-bit
/// samples in host order as they are, and reports errors by return code
/// where libpng longjmps, which would skip the C++ destructors in between.
struct PngSettings {
  /// zlib deflate effort: 1 (fastest) .. 9 (smallest). Default 3.
  int level = 3;
  /// PNG row filter: -1 lets libspng pick one per row (the one with the
  /// smallest sum of absolute differences); 0..4 forces none, sub, up,
  /// average or Paeth for every row. Default 0 (none). libspng filters more
  /// slowly than libpng: on the frame at level 3, sub takes 6.0 against
  /// 4.4 ms and adaptive 24 against 13 ms.
  int filter = 0;
};

/// Throws std::invalid_argument unless level is 1..9 and filter -1..4.
void validate_png_settings(const PngSettings& settings);

/// Sets the defaults that every later encode_png(image) uses. Safe to call
/// while other threads encode: each encode reads the settings once, so it
/// uses either the old or the new pair, never a mix. Throws
/// std::invalid_argument (and changes nothing) if the settings are invalid.
void set_png_settings(const PngSettings& settings);

/// The defaults encode_png(image) uses now.
PngSettings png_settings();

/// Encodes a grey (1 channel) or RGB (3 channel) image of 8 or 16 bits per
/// sample (16-bit samples in host byte order, see Image) with the current
/// defaults. Throws std::invalid_argument if the image is malformed (other
/// channel count or bit depth, a zero or over 2^31-1 side, pixels not
/// height * row_bytes() long), std::runtime_error if libspng fails (out of
/// memory).
std::string encode_png(const Image& image);

/// The same with the given settings for this call only (validated as
/// set_png_settings does); the defaults are left alone.
std::string encode_png(const Image& image, const PngSettings& settings);

}  // namespace umbra
