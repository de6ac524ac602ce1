#include "core/request.hpp"

namespace umbra {

const char* to_string(Output output) {
  switch (output) {
    case Output::Color: return "color";
    case Output::Depth: return "depth";
    case Output::Shadow: return "shadow";
    case Output::Exact: return "exact";
    case Output::Error: return "error";
  }
  return "?";
}

const char* to_string(LightProjection projection) {
  return projection == LightProjection::Orthographic ? "orthographic" : "perspective";
}

}  // namespace umbra
