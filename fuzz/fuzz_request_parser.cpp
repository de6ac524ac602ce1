// libFuzzer target: any bytes as a request body. The parser must answer
// every input with a request or an error naming a field, never crash, hang
// or hit undefined behaviour (the build adds ASan + UBSan), and what it
// accepts must be a request the renderer can take.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "request_parser.hpp"

namespace {

bool finite(const glm::dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const umbra::ParsedRequest parsed =
      umbra::parse_render_request(std::string_view(reinterpret_cast<const char*>(data), size));
  if (!parsed.ok()) {
    if (parsed.error.message.empty()) std::abort();  // every error says what is wrong
    return 0;
  }
  const umbra::RenderRequest& r = *parsed.request;
  // The parser's promises (request_parser.hpp): the renderer relies on them.
  if (r.width < 16 || r.width > 4096 || r.height < 16 || r.height > 4096) std::abort();
  if (r.shadow.map_size < 64 || r.shadow.map_size > 8192) std::abort();
  if (r.scene.objects.size() > umbra::RequestLimits::kMaxObjects) std::abort();
  if (!finite(r.camera.position) || !finite(r.camera.target) || r.camera.position == r.camera.target) std::abort();
  if (!finite(r.light.position) || !finite(r.light.target) || r.light.position == r.light.target) std::abort();
  if (!std::isfinite(r.time)) std::abort();
  return 0;
}
