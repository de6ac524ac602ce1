#include "assets/json_shape.hpp"

namespace umbra {

JsonShape json_shape(std::string_view text, std::size_t max_depth, std::size_t max_values) {
  JsonShape shape;
  shape.values = 1;
  std::size_t depth = 0;
  bool in_string = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\')
        ++i;
      else if (c == '"')
        in_string = false;
      continue;
    }
    switch (c) {
      case '"': in_string = true; break;
      case '[':
      case '{':
        if (++depth > shape.depth) shape.depth = depth;
        if (depth > max_depth) {
          shape.over = true;
          return shape;
        }
        break;
      case ']':
      case '}':
        if (depth > 0) --depth;
        break;
      case ',':
      case ':':
        if (++shape.values > max_values) {
          shape.over = true;
          return shape;
        }
        break;
      default: break;
    }
  }
  return shape;
}

}  // namespace umbra
