// Model formats other than glTF, as the tools architects and planners use
// write them (SketchUp and Rhino: OBJ, DAE, STL; Revit and ArchiCAD: IFC;
// FBX, PLY, 3DS), converted to a glTF binary by umbra-model-import
// (server/model_import_main.cpp, Debian's libassimp) in a process of its
// own, under limits of memory, time and output, so that a file Assimp
// mishandles ends that process, never the server. The .glb it writes is
// then loaded as an uploaded .glb is (gltf_loader.hpp: every limit holds).
// A format is one row of import_formats().
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace umbra {

struct ImportFormat {
  const char* extension;  ///< "obj": the `format` an upload names
  /// Media types that name it ("model/obj"), none where none is registered.
  std::vector<const char*> media_types;
  const char* name;        ///< "Wavefront OBJ"
  /// Its unit and up axis as the file gives them, and what is applied.
  const char* convention;
};

/// Every format read through umbra-model-import.
const std::vector<ImportFormat>& import_formats();
/// The format with this extension (any case, without the dot) or media type.
const ImportFormat* import_format_named(std::string_view extension_or_media_type);

struct ImportOptions {
  std::string importer;                 ///< the umbra-model-import executable
  std::string up = "file";              ///< file, y or z (umbra-model-import --up)
  std::string unit = "file";            ///< file, m, cm, mm, in or ft
  std::uint64_t max_output_bytes = std::uint64_t(256) << 20;
  unsigned max_memory_mib = 2048;       ///< the importer's address space
  unsigned max_seconds = 60;            ///< its CPU time, and the wall time waited for it
  /// Asked about once a second while the importer runs: true ends it (the
  /// client that sent the file has gone), answered 499 "stopped".
  std::function<bool()> stop;
};

/// The importer's CPU seconds for a file of `bytes`: 5 s and 2 s a MiB, at
/// most `ceiling`. Real files convert well within it (the FZK-Haus IFC,
/// 2.5 MB: under a second); a small file of huge n-gons, which Assimp's ear
/// clipping takes quadratic time over, no longer holds a load place for
/// the whole minute (a red-team pass: two such OBJs blocked every upload).
unsigned import_cpu_seconds(std::uint64_t bytes, unsigned ceiling = 60);

struct ImportResult {
  std::string glb;    ///< set on success
  int status = 0;     ///< 0, or 400 (Assimp cannot read the file), 422 (over a limit), 499 (stopped), 503 (no importer)
  std::string error;  ///< why, naming the format
  bool ok() const { return status == 0; }
};

/// Converts `bytes`, a file in `format`, to a glTF binary.
ImportResult import_model(std::string_view bytes, const ImportFormat& format, const ImportOptions& options);

/// The umbra-model-import beside the running program (/proc/self/exe).
std::string default_importer_path();

}  // namespace umbra
