// Pixels and timings handed from the renderer to whoever encodes them.
#pragma once

#include <cstdint>
#include <vector>

namespace umbra {

/// 8-bit image, rows top to bottom, `channels` interleaved bytes per pixel
/// (1 = grey, 3 = RGB).
struct Image {
  int width = 0;
  int height = 0;
  int channels = 0;
  std::vector<std::uint8_t> pixels;

  std::uint8_t* row(int y) { return pixels.data() + std::size_t(y) * width * channels; }
  const std::uint8_t* row(int y) const { return pixels.data() + std::size_t(y) * width * channels; }
  const std::uint8_t* at(int x, int y) const { return row(y) + std::size_t(x) * channels; }
};

/// Milliseconds spent in each stage of one frame (0 for a stage not run).
struct FrameTimings {
  double shadow_ms = 0.0;
  double main_ms = 0.0;
  double readback_ms = 0.0;
};

}  // namespace umbra
