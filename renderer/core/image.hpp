// Pixels and timings handed from the renderer to whoever encodes them.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

namespace umbra {

/// Image, rows top to bottom, `channels` interleaved samples per pixel
/// (1 = grey, 3 = RGB) of `bit_depth` bits each.
///
/// bit_depth 8: one byte per sample. bit_depth 16 (for a depth preview finer
/// than 256 steps): two bytes per sample in the host's native byte order, so
/// `pixels` holds exactly what glReadPixels(..., GL_UNSIGNED_SHORT, ...) or a
/// std::memcpy from a uint16_t array writes (a uint16_t* cast of the bytes
/// would break C++'s aliasing rules). encode_png swaps to PNG's big-endian.
struct Image {
  int width = 0;
  int height = 0;
  int channels = 0;
  std::vector<std::uint8_t> pixels;
  // Last, so that the brace-initialised 8-bit images (Image{w, h, c, pixels})
  // elsewhere keep compiling unchanged.
  int bit_depth = 8;

  std::size_t bytes_per_pixel() const { return std::size_t(channels) * std::size_t(bit_depth / 8); }
  std::size_t row_bytes() const { return std::size_t(width) * bytes_per_pixel(); }
  std::uint8_t* row(int y) { return pixels.data() + std::size_t(y) * row_bytes(); }
  const std::uint8_t* row(int y) const { return pixels.data() + std::size_t(y) * row_bytes(); }
  const std::uint8_t* at(int x, int y) const { return row(y) + std::size_t(x) * bytes_per_pixel(); }

  /// Turns the rows upside down: GL reads row 0 at the bottom, images start
  /// at the top.
  void flip_rows() {
    const std::size_t stride = row_bytes();
    std::vector<std::uint8_t> swap(stride);
    for (int y = 0; y < height / 2; ++y) {
      std::uint8_t* a = row(y);
      std::uint8_t* b = row(height - 1 - y);
      std::copy(a, a + stride, swap.data());
      std::copy(b, b + stride, a);
      std::copy(swap.data(), swap.data() + stride, b);
    }
  }
};

/// Milliseconds spent in each stage of one frame (0 for a stage not run).
struct FrameTimings {
  double shadow_ms = 0.0;
  double main_ms = 0.0;
  double readback_ms = 0.0;
  /// The CPU ray cast of the exact reference ("exact", "error"), which runs
  /// beside the GL passes, not inside any of them; nullopt when none ran.
  std::optional<double> ray_cast_ms;
  /// Filter "exact": the CPU ray cast of the pixels the shadow maps could
  /// not settle (reference/certified_frame.hpp); nullopt for other filters.
  std::optional<double> settle_ms;
};

}  // namespace umbra
