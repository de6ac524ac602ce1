// Image -> PNG bytes (stb_image_write). Runs on HTTP worker threads, never on
// the GL thread, so encoding one frame overlaps rendering the next.
#pragma once

#include <string>

#include "image.hpp"

namespace umbra {

/// Encodes a grey (1 channel) or RGB (3 channel) image. Throws
/// std::runtime_error if stb fails (out of memory).
std::string encode_png(const Image& image);

}  // namespace umbra
