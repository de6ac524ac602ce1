// libFuzzer target: any bytes as an upload in another format (OBJ, STL,
// PLY, DAE, FBX, 3DS, IFC: the first byte picks which), converted as the
// server converts it: by umbra-model-import, a process of its own under
// its limits (here smaller: 2 s, 512 MiB), then loaded as the .glb the
// server would hold. Whatever Assimp does with the bytes, this side must
// never crash or hang: the answer is a model that keeps the loader's
// promises, or a refusal with a status the route sends (400, 422, 503) and
// a reason. A process per input: slow (tens of inputs a second), so this
// target reaches the converter's answers rather than Assimp's depths.
// Seeds: fuzz/corpus-import (small files of Debian's assimp-testmodels).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "assets/gltf_loader.hpp"
#include "assets/model_import.hpp"
#include "model_invariants.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const auto& formats = umbra::import_formats();
  const umbra::ImportFormat& format = formats[data[0] % formats.size()];
  umbra::ImportOptions options;
  options.importer = UMBRA_MODEL_IMPORTER;
  options.max_seconds = 2;
  options.max_memory_mib = 512;
  options.max_output_bytes = std::uint64_t(16) << 20;
  const umbra::ImportResult imported =
      umbra::import_model(std::string_view(reinterpret_cast<const char*>(data) + 1, size - 1), format, options);
  if (!imported.ok()) {
    const int s = imported.status;
    if ((s != 400 && s != 422 && s != 503) || imported.error.empty()) std::abort();
    return 0;
  }
  umbra::LoadOptions load;
  load.format = umbra::LoadOptions::Format::Binary;
  load.max_triangles = 1 << 18;
  const umbra::LoadResult result = umbra::load_gltf(imported.glb, load);
  if (!result.ok()) {
    if ((result.status != 400 && result.status != 422) || result.error.empty()) std::abort();
    return 0;
  }
  if (!umbra::model_keeps_its_promises(*result.model, load.max_triangles)) std::abort();
  return 0;
}
