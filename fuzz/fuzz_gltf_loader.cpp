// libFuzzer target: any bytes as an uploaded model (.glb or .gltf). The
// loader must never crash, hang, leak or hit undefined behaviour, and what
// it accepts must hold to what it promises: indices in range, finite
// positions, normals for every vertex, the triangle limit kept.
// Seeds: fuzz/corpus-gltf (tests/make_gltf_corpus.cpp writes them).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "assets/gltf_loader.hpp"
#include "model_invariants.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  umbra::LoadOptions options;  // no external folder: as an upload
  // Smaller limits than the server's keep each input fast; the code that
  // enforces them is the same.
  options.max_triangles = 1 << 16;
  options.max_nodes = 1000;
  const umbra::LoadResult result =
      umbra::load_gltf(std::string_view(reinterpret_cast<const char*>(data), size), options);
  if (!result.ok()) {
    if ((result.status != 400 && result.status != 422) || result.error.empty()) std::abort();
    return 0;
  }
  const umbra::TriangleModel& model = *result.model;
  if (!umbra::model_keeps_its_promises(model, options.max_triangles)) std::abort();
  return 0;
}
