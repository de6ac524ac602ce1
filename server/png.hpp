// Image -> PNG bytes. Runs on HTTP worker threads, never on the GL thread,
// so encoding one frame overlaps rendering the next. Many workers encode at
// once: every encode has its own libspng context, and the settings are read
// once per call, so nothing is shared between encodes.
#pragma once

#include <string>

#include "image.hpp"

namespace umbra {

/// How PNGs are compressed (libspng, with Debian's zlib as its deflate).
///
/// The encoder and the defaults were chosen by measurement (umbra-png-bench;
/// bench/results/png.md) among stb_image_write + zlib, libpng and libspng at
/// zlib levels 1-3 and 6 with filters none / sub / up / adaptive, and the
/// strategies Z_RLE and Z_FILTERED. The rule: the fastest encode whose PNG is
/// at most 2x the bytes of what Umbra used before (stb + zlib, level 6, no
/// filter: 5-9 ms and 16 KiB for the default 960x540 frame), where times
/// within 10 % count as a tie (the spread between runs on a shared machine).
/// Level 2 with no filter is that fastest, for all three libraries alike,
/// about 3x faster than before at 1.9x the bytes (30 KiB). Unfiltered, the
/// libraries differ only in how they feed zlib: libpng and libspng tie,
/// stb is ~20 % slower (it filters into a second buffer first). Of the tie,
/// libspng is the one that takes 16-bit samples in host order, keeps every
/// option in a per-call context (stb's are process-wide globals) and reports
/// errors by return code (libpng's longjmp would skip C++ destructors).
/// Level 1 is no faster and at the edge of the budget (2.0x); level 3 saves
/// 3 % of the bytes but searches 4x longer match chains. Row filters cost
/// time at every level and, on these smooth images at levels 1-3, make the
/// PNG larger, not smaller.
struct PngSettings {
  /// zlib deflate effort: 1 (fastest) .. 9 (smallest). Default 2.
  int level = 2;
  /// PNG row filter: -1 lets libspng pick one per row (the one with the
  /// smallest sum of absolute differences); 0..4 forces none, sub, up,
  /// average or Paeth for every row. Default 0 (none).
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
