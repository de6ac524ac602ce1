// libFuzzer target: any bytes as an uploaded CityJSON file. The reader and
// the polygon triangulation must never crash, hang or hit undefined
// behaviour, and what they accept must hold to what they promise: indices
// in range, finite positions, unit normals, the triangle limit kept; and
// the .glb the server holds it as must load back to the same triangles.
// Seeds: fuzz/corpus-cityjson.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "assets/cityjson_loader.hpp"
#include "assets/glb_writer.hpp"
#include "assets/gltf_loader.hpp"
#include "model_invariants.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  umbra::CityJsonOptions options;
  options.max_triangles = 1 << 16;  // smaller than the server's, the same code
  const umbra::CityJsonResult result =
      umbra::load_cityjson(std::string_view(reinterpret_cast<const char*>(data), size), options);
  if (!result.ok()) {
    if ((result.status != 400 && result.status != 422) || result.error.empty()) std::abort();
    return 0;
  }
  const umbra::TriangleModel& model = *result.model;
  if (!umbra::model_keeps_its_promises(model, options.max_triangles)) std::abort();
  const umbra::LoadResult held = umbra::load_gltf(umbra::write_glb(model), umbra::LoadOptions{});
  if (!held.ok() || held.model->triangle_count() != model.triangle_count()) std::abort();
  return 0;
}
