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

#include <stdexcept>

#include "assets/gltf_loader.hpp"
#include "core/model_rig.hpp"
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
  // An animated model, posed at a few instants of each animation: the same
  // promises, or a refusal that it is not finite there.
  if (model.rig)
    for (std::size_t a = 0; a < model.rig->animations.size() && a < 4; ++a)
      for (const double f : {0.0, 0.37, 1.0}) {
        try {
          const umbra::TriangleModel posed = umbra::pose_model(*model.rig, a, f * model.rig->animations[a].duration_s);
          if (posed.triangle_count() != model.triangle_count() ||
              !umbra::model_keeps_its_promises(posed, options.max_triangles))
            std::abort();
        } catch (const std::domain_error&) {
        }
      }
  return 0;
}
