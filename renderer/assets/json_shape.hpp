// How deep a JSON text nests and how many values it holds, found by one
// scan that skips strings, before any parser builds it: a parser that
// recurses per level, or spends tens of bytes per value, never meets a
// document that would exhaust its stack or the memory. Pure.
#pragma once

#include <cstddef>
#include <string_view>

namespace umbra {

struct JsonShape {
  std::size_t depth = 0;   ///< deepest nesting of arrays and objects
  std::size_t values = 0;  ///< an upper bound on the values (separators + 1)
  /// The scan stopped early: `depth` or `values` passed the limit given.
  bool over = false;
};

/// Scans `text` until it is done or past `max_depth` or `max_values`.
/// Malformed JSON is left to the parser.
JsonShape json_shape(std::string_view text, std::size_t max_depth, std::size_t max_values);

}  // namespace umbra
