// Compressed glTF: the extensions that store geometry other than as plain
// accessors, decoded by Debian's maintained libraries into what the loader
// reads (gltf_loader.cpp). Each extension is one file and one row of
// kCompressionExtensions (gltf_loader.cpp):
//   EXT_meshopt_compression / KHR_meshopt_compression: gltf_meshopt.cpp
//     (libmeshoptimizer), buffer views decoded into their fallback buffer;
//   KHR_draco_mesh_compression: gltf_draco.cpp (libdraco), a primitive's
//     accessors decoded from its Draco stream.
// KHR_mesh_quantization needs no step of its own: the loader reads integer
// accessors (gltf_loader.cpp, read_vec3).
//
// Each works in two steps, because tinygltf refuses what these files hold
// (a fallback buffer with no data; an accessor with no buffer view):
//   prepare: before tinygltf, on the document's JSON: reads and checks the
//     extension's fields and rewrites the document so that tinygltf takes
//     it (a one-byte data: URI for a fallback buffer, a placeholder buffer
//     view for a Draco accessor), noting in CompressedParts what to decode;
//   decode: once the loader knows the model's size and has admitted it,
//     decodes into the tinygltf::Model, every decoded size checked against
//     DecodeBudget before its memory is spent.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

namespace tinygltf {
class Model;
}

namespace umbra {

/// A refusal from anywhere in the loader: status 400 (not valid glTF) or
/// 422 (valid, but beyond what Umbra takes), and what and where.
struct GltfRefusal {
  int status;
  std::string message;
};
[[noreturn]] void refuse_gltf(int status, std::string message);

/// One meshopt-compressed buffer view (EXT_meshopt_compression's fields).
struct MeshoptView {
  std::size_t view = 0;  ///< the buffer view it decodes into
  std::size_t source_buffer = 0, source_offset = 0, source_length = 0;
  std::size_t stride = 0, count = 0;
  enum class Mode { Attributes, Triangles, Indices } mode = Mode::Attributes;
  enum class Filter { None, Octahedral, Quaternion, Exponential } filter = Filter::None;
};

/// One Draco-compressed primitive (KHR_draco_mesh_compression's fields).
struct DracoPrimitive {
  std::size_t mesh = 0, primitive = 0;
  std::size_t view = 0;  ///< the buffer view holding its Draco stream
  /// The glTF attribute name (POSITION, NORMAL...) and its Draco unique id.
  std::map<std::string, std::uint32_t> attributes;
};

/// What prepare found to decode, and the bytes decoding will allocate.
struct CompressedParts {
  /// Fallback buffers (no data of their own) and their declared lengths.
  std::map<std::size_t, std::size_t> fallback_buffers;
  std::vector<MeshoptView> meshopt_views;
  std::vector<DracoPrimitive> draco_primitives;
  /// The placeholder buffer view Draco accessors point at until decoded.
  int placeholder_view = -1;
};

/// Bytes decoding may allocate for one model, counted before each
/// allocation.
struct DecodeBudget {
  std::uint64_t limit = 0;
  std::uint64_t spent = 0;
  /// Counts `bytes` for `what`, or refuses 422 naming the decoded size.
  void spend(std::uint64_t bytes, const std::string& what);
};

void prepare_meshopt(nlohmann::json& document, CompressedParts& parts);
void decode_meshopt(tinygltf::Model& model, const CompressedParts& parts, DecodeBudget& budget);

void prepare_draco(nlohmann::json& document, CompressedParts& parts);
/// Decodes the Draco primitives of `meshes` (those the scene instances).
/// Their triangle and vertex counts are checked against the accessors'
/// (which the loader has bounded and admitted) before the stream is
/// decoded.
void decode_draco(tinygltf::Model& model, const CompressedParts& parts, const std::vector<bool>& meshes,
                  DecodeBudget& budget);

}  // namespace umbra
