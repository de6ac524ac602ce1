// The PNG encoders umbra-png-bench weighs against each other, each built the
// way Umbra would use it: whole image in memory, PNG bytes out in a string.
// Only the benchmark uses these; server/png.cpp has the one Umbra ships.
#pragma once

#include <string>

#include "core/image.hpp"

namespace umbra::bench {

/// Row filter, the same for every row, or chosen per row by the library's
/// heuristic ("adaptive": stb, libpng and libspng all pick the filter with
/// the smallest sum of absolute differences among all five).
enum class Filter { none, sub, up, adaptive };

/// zlib strategy. `library` leaves the library's own choice, which for libpng
/// and libspng is Z_FILTERED when rows are filtered and Z_DEFAULT_STRATEGY
/// when they are not. Z_FILTERED only changes anything from level 4 up
/// (zlib's levels 1-3 ignore it); Z_RLE ignores the level.
enum class Strategy { library, rle, filtered };

const char* name(Filter filter);
const char* name(Strategy strategy);

/// A private copy of stb_image_write (Debian's libstb-dev header) with
/// zlib's compress2 as its deflate: what server/png.cpp used before this
/// comparison, at level 6 with no filter. 8-bit only: stb writes no 16-bit
/// PNG.
std::string stb_zlib_png(const Image& image, int level, Filter filter);

/// libpng 1.6, rows written one by one from the image.
std::string libpng_png(const Image& image, int level, Filter filter, Strategy strategy);

/// libspng 0.7, whole image in one call, PNG assembled in its own buffer.
std::string libspng_png(const Image& image, int level, Filter filter, Strategy strategy);

}  // namespace umbra::bench
