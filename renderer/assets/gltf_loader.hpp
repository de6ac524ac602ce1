// glTF 2.0 in, a TriangleModel out: the door for the user's own models.
// Every input is hostile: each refusal is a 400 (the file is not valid
// glTF) or a 422 (valid, but beyond what Umbra takes) with a message naming
// what and where ("meshes[2].primitives[0] (accessors[3]): 4 elements of
// 12 bytes every 12 from byte 0 run past the end of bufferViews[1]"). Memory and time are bounded by the limits below and the
// body size. Pure: no GL, no HTTP. Files are read only through
// LoadOptions::external_folder. Tested in tests/test_gltf_loader.cpp,
// fuzzed by fuzz/fuzz_gltf_loader.cpp.
//
// Parsing is Debian's tinygltf (compiled once, in tiny_gltf_impl.cpp,
// without image decoding or a file system); every index, offset and count
// it hands over is checked again here, in 64-bit arithmetic.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include "core/model.hpp"

namespace umbra {

/// Triangles in one model, summed over every node that instances a mesh.
constexpr std::size_t kMaxModelTriangles = std::size_t(4) << 20;
constexpr std::size_t kMaxModelNodes = 10000;
/// Node hierarchy depth (a root is depth 1). Walked without recursion: the
/// bound is on work, and CAD and COLLADA exports nest a hundred deep.
constexpr std::size_t kMaxNodeDepth = 1024;
/// Nesting of JSON arrays and objects: tinygltf converts `extras` and
/// `extensions` recursively, so deep nesting would exhaust the stack.
constexpr std::size_t kMaxJsonDepth = 64;
/// JSON values (numbers, strings, arrays, objects...) in the document: a
/// parsed value costs tens of bytes, so this bounds the parser's memory
/// whatever the body holds (large buffers belong in data: URIs or the
/// GLB's binary chunk, which are single strings).
constexpr std::size_t kMaxJsonValues = std::size_t(1) << 20;

struct LoadOptions {
  enum class Format {
    Detect,  ///< GLB if the bytes start with "glTF", else JSON
    Binary,  ///< .glb (model/gltf-binary)
    Json,    ///< .gltf (model/gltf+json)
  };
  Format format = Format::Detect;
  /// Empty: the model must be self-contained (buffers in the GLB's binary
  /// chunk or as data: URIs); any other URI is refused. Else a folder:
  /// external buffer files are read from inside it only (their real path,
  /// symlinks resolved, must lie inside the folder's real path).
  std::string external_folder;
  /// Largest external buffer file read, in bytes.
  std::size_t max_external_bytes = std::size_t(64) << 20;
  std::size_t max_triangles = kMaxModelTriangles;
  /// Bytes decoding compressed geometry may allocate (Draco's and
  /// meshopt's output, counted before each allocation; meshopt's fallback
  /// buffers at most 16 times the file's bytes, its buffers' included, +
  /// 32 MiB; Draco's counts must match the accessors', which the limits
  /// above bound): a small file that decodes to gigabytes is refused (422)
  /// naming its decoded size.
  std::uint64_t max_decoded_bytes = std::uint64_t(512) << 20;
  std::size_t max_nodes = kMaxModelNodes;
  /// Asked once what the model will hold is known from its accessors and
  /// node instances, before any vertex is read or any geometry built:
  /// `bytes` bounds the finished model's TriangleModel::bytes()
  /// (model_bytes_bound). Returns 0 to go on, or an HTTP status (422,
  /// 503, 507...) with `why` set, which refuses the load with them: so a
  /// caller counts a model against a budget before its memory is spent.
  /// Empty: every model within the limits above is built.
  std::function<int(std::uint64_t bytes, std::size_t triangles, std::string& why)> admit;
};

struct LoadResult {
  std::shared_ptr<TriangleModel> model;  ///< set on success
  int status = 0;                        ///< 0 on success, else 400 or 422
  std::string error;                     ///< what is wrong and where
  /// The bound `admit` was given (0 if the load stopped before it was
  /// known): TriangleModel::bytes() of `model` is at most this.
  std::uint64_t bytes_bound = 0;

  bool ok() const { return model != nullptr; }
};

/// Loads a .glb or .gltf held in `bytes`. Never throws; never reads a file
/// outside options.external_folder (none at all when it is empty).
/// Strips and fans are converted to triangle lists; points and lines are
/// left out and counted (TriangleModel::skipped_primitives), and a model
/// with no triangles at all is refused. Reads sparse accessors, integer
/// accessors (KHR_mesh_quantization), EXT_/KHR_meshopt_compression and
/// KHR_draco_mesh_compression (gltf_compression.hpp). Positions land in the space of the glTF scene's roots (every
/// node transform applied); the default scene is used, or every root node
/// when the file names none.
LoadResult load_gltf(std::string_view bytes, const LoadOptions& options);

}  // namespace umbra
