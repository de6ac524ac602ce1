#include "png.hpp"

#include <stdexcept>

#include <stb_image_write.h>

namespace umbra {

namespace {
void append(void* context, void* data, int size) {
  static_cast<std::string*>(context)->append(static_cast<const char*>(data), std::size_t(size));
}
}  // namespace

std::string encode_png(const Image& image) {
  std::string out;
  out.reserve(std::size_t(image.width) * image.height * image.channels / 2);
  if (!stbi_write_png_to_func(append, &out, image.width, image.height, image.channels, image.pixels.data(),
                              image.width * image.channels))
    throw std::runtime_error("PNG encoding failed");
  return out;
}

}  // namespace umbra
