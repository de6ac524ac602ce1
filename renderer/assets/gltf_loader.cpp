#include "assets/gltf_loader.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <new>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>
#include <glm/gtc/matrix_inverse.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <sys/stat.h>
#include <tiny_gltf.h>

#include "assets/folder_file.hpp"
#include "assets/glb_writer.hpp"
#include "assets/gltf_compression.hpp"
#include "assets/json_shape.hpp"
#include "core/model_rig.hpp"

namespace umbra {

void refuse_gltf(int status, std::string message) { throw GltfRefusal{status, std::move(message)}; }

void DecodeBudget::spend(std::uint64_t bytes, const std::string& what) {
  if (bytes > limit - std::min(limit, spent))
    refuse_gltf(422, what + " decodes to about " + std::to_string(bytes >> 20) + " MiB, over the " +
                         std::to_string(limit >> 20) + " MiB this server decodes for one model" +
                         (spent ? " (" + std::to_string(spent >> 20) + " MiB decoded already)" : std::string()));
  spent += bytes;
}

namespace {

[[noreturn]] void refuse(int status, std::string message) { refuse_gltf(status, std::move(message)); }

std::string index_of(const char* array, std::size_t i) { return std::string(array) + "[" + std::to_string(i) + "]"; }

// What tinygltf says, on one line and short: its messages may quote a
// whole data: URI.
std::string short_message(std::string text) {
  for (char& c : text)
    if (c == '\n' || c == '\r') c = ' ';
  while (!text.empty() && text.back() == ' ') text.pop_back();
  constexpr std::size_t kMax = 300;
  if (text.size() > kMax) text = text.substr(0, kMax) + "...";
  return text;
}

std::uint32_t read_u32(std::string_view bytes, std::size_t at) {
  std::uint32_t v = 0;
  std::memcpy(&v, bytes.data() + at, 4);  // glTF is little-endian, as is every machine Umbra builds on
  return v;
}

// The GLB container (glTF 2.0 §4.4), checked before tinygltf sees it;
// returns the JSON chunk.
std::string_view glb_json_chunk(std::string_view bytes) {
  if (bytes.size() < 20) refuse(400, "glTF binary: " + std::to_string(bytes.size()) + " bytes is too short for a header");
  if (bytes.size() > std::numeric_limits<std::uint32_t>::max()) refuse(422, "glTF binary: larger than 4 GiB");
  const std::uint32_t version = read_u32(bytes, 4), length = read_u32(bytes, 8);
  if (version != 2) refuse(422, "glTF binary: version " + std::to_string(version) + "; only glTF 2.0 is read");
  if (length != bytes.size())
    refuse(400, "glTF binary: the header says " + std::to_string(length) + " bytes but there are " +
                    std::to_string(bytes.size()));
  const std::uint64_t json_length = read_u32(bytes, 12);
  if (read_u32(bytes, 16) != 0x4E4F534Au) refuse(400, "glTF binary: the first chunk is not JSON");
  if (json_length == 0 || 20 + json_length > bytes.size())
    refuse(400, "glTF binary: the JSON chunk's length " + std::to_string(json_length) + " does not fit the file");
  const std::uint64_t rest = bytes.size() - 20 - json_length;
  if (rest > 0) {
    if (rest < 8) refuse(400, "glTF binary: a truncated chunk after the JSON");
    const std::uint64_t bin_length = read_u32(bytes, std::size_t(20 + json_length));
    if (read_u32(bytes, std::size_t(24 + json_length)) != 0x004E4942u)
      refuse(400, "glTF binary: the second chunk is not BIN");
    if (bin_length > rest - 8)
      refuse(400, "glTF binary: the BIN chunk's length " + std::to_string(bin_length) + " does not fit the file");
  }
  return bytes.substr(20, std::size_t(json_length));
}

// The JSON's nesting and size before tinygltf parses it (json_shape.hpp).
void check_json_shape(std::string_view text) {
  const JsonShape shape = json_shape(text, kMaxJsonDepth, kMaxJsonValues);
  if (shape.depth > kMaxJsonDepth)
    refuse(422, "the glTF JSON nests arrays and objects deeper than " + std::to_string(kMaxJsonDepth));
  if (shape.values > kMaxJsonValues)
    refuse(422, "the glTF JSON has more than " + std::to_string(kMaxJsonValues) +
                    " values; put geometry in buffers, not in JSON");
}

// --- Files, only through these callbacks ------------------------------------

struct FileAccess {
  const LoadOptions* options;
  std::string refused;  ///< the first external file asked for and refused, and why
};

bool file_exists(const std::string& path, void* user) {
  auto& access = *static_cast<FileAccess*>(user);
  std::string real;
  if (file_inside_folder(access.options->external_folder, path, real)) return true;
  if (access.refused.empty())
    access.refused = access.options->external_folder.empty()
                         ? "refers to the external file '" + short_message(path) +
                               "': an uploaded model must be self-contained (a .glb, or a .gltf with data: URIs)"
                         : "refers to '" + short_message(path) + "', which is missing or outside the models folder";
  return false;
}

std::string expand_file_path(const std::string& path, void*) { return path; }  // no ~ or $VAR expansion

bool read_whole_file(std::vector<unsigned char>* out, std::string* err, const std::string& path, void* user) {
  auto& access = *static_cast<FileAccess*>(user);
  std::string real;
  if (!file_inside_folder(access.options->external_folder, path, real)) {
    if (err) *err = "outside the models folder";
    return false;
  }
  struct stat info {};
  if (stat(real.c_str(), &info) != 0 || std::uint64_t(info.st_size) > access.options->max_external_bytes) {
    access.refused = "refers to '" + short_message(path) + "', larger than " +
                     std::to_string(access.options->max_external_bytes >> 20) + " MiB";
    if (err) *err = "too large";
    return false;
  }
  std::ifstream in(real, std::ios::binary);
  out->assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  // A file that grew since stat() is cut at the limit rather than trusted.
  if (out->size() > access.options->max_external_bytes) out->resize(access.options->max_external_bytes);
  return bool(in) || in.eof();
}

bool write_whole_file(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  if (err) *err = "writing is not allowed";
  return false;
}

// Textures are not used: an image is never decoded, whatever it holds.
bool ignore_image(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*) {
  return true;
}

// --- Accessors, checked here whatever tinygltf checked ----------------------

std::size_t component_bytes(int type) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
  }
}

const char* component_name(int type) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: return "BYTE";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return "UNSIGNED_BYTE";
    case TINYGLTF_COMPONENT_TYPE_SHORT: return "SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return "UNSIGNED_SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return "UNSIGNED_INT";
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return "FLOAT";
    default: return "unknown";
  }
}

// Components of an accessor type (SCALAR, VEC3, VEC4, MAT4 are read).
std::size_t type_components(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR: return 1;
    case TINYGLTF_TYPE_VEC2: return 2;
    case TINYGLTF_TYPE_VEC3: return 3;
    case TINYGLTF_TYPE_VEC4: return 4;
    case TINYGLTF_TYPE_MAT4: return 16;
    default: return 0;
  }
}

const char* type_name(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR: return "SCALAR";
    case TINYGLTF_TYPE_VEC2: return "VEC2";
    case TINYGLTF_TYPE_VEC3: return "VEC3";
    case TINYGLTF_TYPE_VEC4: return "VEC4";
    case TINYGLTF_TYPE_MAT4: return "MAT4";
    default: return "an unread type";
  }
}

// The bytes of an accessor's elements: element i starts at base + i * stride;
// no base: the accessor has no buffer view, and its elements are zeros.
struct ElementView {
  const unsigned char* base = nullptr;
  std::size_t stride = 0;
  std::size_t count = 0;
  int component_type = 0;
  bool normalized = false;
};

// One component as a number: an integer's value, or with `normalized` its
// value mapped to [0, 1] (unsigned) or [-1, 1] (signed), as glTF 2.0
// §3.11 says (KHR_mesh_quantization stores positions and normals so).
double component_at(const unsigned char* at, int type, bool normalized) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      std::int8_t x;
      std::memcpy(&x, at, 1);
      return normalized ? std::max(x / 127.0, -1.0) : x;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? *at / 255.0 : *at;
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      std::int16_t x;
      std::memcpy(&x, at, 2);
      return normalized ? std::max(x / 32767.0, -1.0) : x;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      std::uint16_t x;
      std::memcpy(&x, at, 2);
      return normalized ? x / 65535.0 : x;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
      std::uint32_t x;
      std::memcpy(&x, at, 4);
      return x;
    }
    default: {
      float x;
      std::memcpy(&x, at, 4);
      return x;
    }
  }
}

// The extensions a model may require: one row each. Those that store
// geometry compressed rewrite the document for tinygltf first (prepare,
// gltf_compression.hpp) and are decoded by the loader once admitted.
struct ReadExtension {
  const char* name;
  void (*prepare)(nlohmann::json& document, CompressedParts& parts);
};
constexpr ReadExtension kReadExtensions[] = {
    {"KHR_mesh_quantization", nullptr},  // integer accessors: read_vec3
    {"EXT_meshopt_compression", prepare_meshopt},
    {"KHR_meshopt_compression", prepare_meshopt},
    {"KHR_draco_mesh_compression", prepare_draco},
};

const ReadExtension* read_extension(const std::string& name) {
  for (const ReadExtension& e : kReadExtensions)
    if (name == e.name) return &e;
  return nullptr;
}

std::string read_extension_list() {
  std::string list;
  for (const ReadExtension& e : kReadExtensions) list += (list.empty() ? "" : ", ") + std::string(e.name);
  return list;
}

// The document as tinygltf will take it: with a compression extension in
// extensionsUsed, each such extension's prepare step rewrites it (see
// gltf_compression.hpp). Else `bytes` unchanged (empty `rewritten`).
void prepare_compressed(std::string_view bytes, bool glb, std::string& rewritten, CompressedParts& parts) {
  const std::string_view text = glb ? glb_json_chunk(bytes) : bytes;
  // Cheap test first: most models use none of these.
  bool mentioned = false;
  for (const ReadExtension& e : kReadExtensions)
    mentioned |= e.prepare && text.find(e.name) != std::string_view::npos;
  if (!mentioned) return;
  nlohmann::json document = nlohmann::json::parse(text.begin(), text.end(), nullptr, false);
  if (document.is_discarded() || !document.is_object()) return;  // tinygltf names what is wrong
  const auto used = document.find("extensionsUsed");
  if (used == document.end() || !used->is_array()) return;
  bool changed = false;
  for (const ReadExtension& e : kReadExtensions) {
    if (!e.prepare || std::find(used->begin(), used->end(), e.name) == used->end()) continue;
    e.prepare(document, parts);
    changed = true;
  }
  if (!changed) return;
  const std::string json = document.dump();
  // A GLB keeps the chunks after its JSON (its BIN) as they are.
  rewritten = glb ? glb_container(json, bytes.substr(20 + read_u32(bytes, 12))) : json;
}

class Loader {
 public:
  Loader(tinygltf::Model& model, const LoadOptions& options, const CompressedParts& compressed,
         std::uint64_t input_bytes)
      : gltf_(model), options_(options), compressed_(compressed), input_bytes_(input_bytes) {}

  std::shared_ptr<TriangleModel> build();
  /// What check_primitives found the model will hold at most.
  std::uint64_t bytes_bound() const { return bytes_bound_; }

 private:
  struct Instance {
    std::size_t node;
    std::size_t mesh;
    glm::dmat4 world;
  };

  const tinygltf::Accessor& accessor(int index, const std::string& where) const;
  const unsigned char* elements(int buffer_view, std::size_t offset, std::size_t count, std::size_t element,
                                bool strided, const std::string& name, std::size_t& stride) const;
  ElementView view(int index, const std::string& where, int type, std::initializer_list<int> component_types) const;
  /// Calls set(element, component values) for each of the accessor's
  /// sparse substitutions (none unless it is sparse).
  void apply_sparse(int index, const std::string& where, int type,
                    const std::function<void(std::size_t, const unsigned char*)>& set) const;
  std::vector<glm::vec3> read_vec3(int index, const std::string& where) const;
  /// Every component of every element, as numbers (normalized integers
  /// mapped as glTF says), finite, sparse substitutions applied.
  std::vector<float> read_floats(int index, const std::string& where, int type,
                                 std::initializer_list<int> component_types) const;
  std::vector<std::uint32_t> read_indices(int index, const std::string& where, std::size_t vertex_count) const;
  glm::dmat4 local_matrix(std::size_t node) const;
  std::vector<Instance> instances() const;
  struct Size {
    std::size_t triangles = 0;
    std::uint64_t bytes = 0;  // model_bytes_bound of what the instances will build
    std::size_t skipped = 0;  // primitive instances of points or lines
  };
  Size check_primitives(const std::vector<Instance>& instances) const;
  glm::vec3 base_color(int material, const std::string& where) const;
  void add_primitive(const Instance& instance, std::size_t p, TriangleModel& out, std::map<std::array<float, 3>, std::size_t>& parts) const;
  // Animation (core/model_rig.hpp): only for a file that has animations.
  /// What the rig of these instances will hold at most, in bytes; refuses
  /// morph targets or keyframes over their limits.
  std::uint64_t rig_bytes_bound(const std::vector<Instance>& instances) const;
  /// The primitive's mesh-space geometry, joints, weights and morph
  /// targets, for the vertices it keeps (`used`), added to rig_.
  void add_rig_primitive(const Instance& instance, std::size_t p, std::size_t part,
                         const std::vector<glm::vec3>& positions, const std::vector<glm::vec3>& normals,
                         const std::vector<std::uint32_t>& used, const std::vector<std::uint32_t>& triangles) const;
  /// Nodes, skins and animations, checked; rig_ done.
  void finish_rig(const TriangleModel& model);

  tinygltf::Model& gltf_;  // decoding fills its compressed buffers
  const LoadOptions& options_;
  const CompressedParts& compressed_;
  std::uint64_t input_bytes_;  // the document's (the buffers' are counted once loaded)
  std::uint64_t bytes_bound_ = 0;
  std::unique_ptr<ModelRig> rig_;  // set while a file with animations is built
};

const tinygltf::Accessor& Loader::accessor(int index, const std::string& where) const {
  if (index < 0 || std::size_t(index) >= gltf_.accessors.size())
    refuse(400, where + ": accessor " + std::to_string(index) + " is out of range (" +
                    std::to_string(gltf_.accessors.size()) + " accessors)");
  return gltf_.accessors[std::size_t(index)];
}

// `count` elements of `element` bytes from byte `offset` of a buffer view,
// every `stride` bytes (the view's byteStride when `strided`, else packed),
// checked to lie inside the view and the view inside its buffer.
const unsigned char* Loader::elements(int buffer_view, std::size_t offset, std::size_t count, std::size_t element,
                                      bool strided, const std::string& name, std::size_t& stride) const {
  if (buffer_view < 0 || std::size_t(buffer_view) >= gltf_.bufferViews.size())
    refuse(400, name + ": bufferView " + std::to_string(buffer_view) + " is out of range (" +
                    std::to_string(gltf_.bufferViews.size()) + " buffer views)");
  const tinygltf::BufferView& bv = gltf_.bufferViews[std::size_t(buffer_view)];
  const std::string bv_name = index_of("bufferViews", std::size_t(buffer_view));
  if (bv.buffer < 0 || std::size_t(bv.buffer) >= gltf_.buffers.size())
    refuse(400, bv_name + ": buffer " + std::to_string(bv.buffer) + " is out of range (" +
                    std::to_string(gltf_.buffers.size()) + " buffers)");
  const std::size_t buffer_size = gltf_.buffers[std::size_t(bv.buffer)].data.size();
  // Each step compares before it adds or multiplies: nothing can wrap.
  if (bv.byteOffset > buffer_size || bv.byteLength > buffer_size - bv.byteOffset)
    refuse(400, bv_name + ": bytes " + std::to_string(bv.byteOffset) + " + " + std::to_string(bv.byteLength) +
                    " run past the end of its buffer (" + std::to_string(buffer_size) + " bytes)");
  stride = strided && bv.byteStride != 0 ? bv.byteStride : element;
  if (stride < element)
    refuse(400, bv_name + ": byteStride " + std::to_string(bv.byteStride) + " is less than the element size " +
                    std::to_string(element) + " of " + name);
  if (offset > bv.byteLength || element > bv.byteLength - offset || count - 1 > (bv.byteLength - offset - element) / stride)
    refuse(400, name + ": " + std::to_string(count) + " elements of " + std::to_string(element) + " bytes every " +
                    std::to_string(stride) + " from byte " + std::to_string(offset) + " run past the end of " +
                    bv_name + " (" + std::to_string(bv.byteLength) + " bytes)");
  return gltf_.buffers[std::size_t(bv.buffer)].data.data() + bv.byteOffset + offset;
}

ElementView Loader::view(int index, const std::string& where, int type, std::initializer_list<int> component_types) const {
  const tinygltf::Accessor& a = accessor(index, where);
  const std::string name = where + " (" + index_of("accessors", std::size_t(index)) + ")";
  if (a.type != type)
    refuse(400, name + ": type " + std::to_string(a.type) + " where " + type_name(type) + " is required");
  if (std::find(component_types.begin(), component_types.end(), a.componentType) == component_types.end()) {
    std::string allowed;
    for (int t : component_types) allowed += (allowed.empty() ? "" : ", ") + std::string(component_name(t));
    refuse(422, name + ": component type " + std::to_string(a.componentType) + " (" + component_name(a.componentType) +
                    ") is not supported here; use " + allowed);
  }
  ElementView v;
  v.count = a.count;
  v.component_type = a.componentType;
  v.normalized = a.normalized;
  // Without a buffer view the elements are zeros (glTF 2.0 §3.6.2.1),
  // sparse substitutions aside.
  if (a.count == 0 || a.bufferView < 0) return v;
  const std::size_t components = type_components(type);
  v.base = elements(a.bufferView, a.byteOffset, a.count, components * component_bytes(a.componentType), true, name,
                    v.stride);
  return v;
}

void Loader::apply_sparse(int index, const std::string& where, int type,
                          const std::function<void(std::size_t, const unsigned char*)>& set) const {
  const tinygltf::Accessor& a = accessor(index, where);
  if (!a.sparse.isSparse) return;
  const std::string name = where + " (" + index_of("accessors", std::size_t(index)) + ").sparse";
  if (a.sparse.count < 1 || std::size_t(a.sparse.count) > a.count)
    refuse(400, name + ".count: " + std::to_string(a.sparse.count) + " is not from 1 to the accessor's count " +
                    std::to_string(a.count));
  const std::size_t count = std::size_t(a.sparse.count);
  const int index_type = a.sparse.indices.componentType;
  if (index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
      index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
    refuse(400, name + ".indices.componentType: " + std::to_string(index_type) +
                    " is not UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT");
  if (a.sparse.indices.byteOffset < 0 || a.sparse.values.byteOffset < 0)
    refuse(400, name + ": a byteOffset is negative");
  std::size_t index_stride = 0, value_stride = 0;
  const std::size_t index_bytes = component_bytes(index_type);
  const std::size_t value_bytes = type_components(type) * component_bytes(a.componentType);
  const unsigned char* indices = elements(a.sparse.indices.bufferView, std::size_t(a.sparse.indices.byteOffset), count,
                                          index_bytes, false, name + ".indices", index_stride);
  const unsigned char* values = elements(a.sparse.values.bufferView, std::size_t(a.sparse.values.byteOffset), count,
                                         value_bytes, false, name + ".values", value_stride);
  for (std::size_t k = 0; k < count; ++k) {
    const double i = component_at(indices + k * index_stride, index_type, false);
    if (i >= double(a.count))
      refuse(400, name + ".indices: element " + std::to_string(k) + " is " + std::to_string(std::uint64_t(i)) +
                      ", out of range (" + std::to_string(a.count) + " elements)");
    set(std::size_t(i), values + k * value_stride);
  }
}

std::vector<glm::vec3> Loader::read_vec3(int index, const std::string& where) const {
  // FLOAT, or the integers KHR_mesh_quantization allows (normalized or not).
  const ElementView v = view(index, where, TINYGLTF_TYPE_VEC3,
                             {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE,
                              TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT,
                              TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT});
  const std::size_t size = component_bytes(v.component_type);
  const auto element = [&](const unsigned char* at) {
    if (v.component_type == TINYGLTF_COMPONENT_TYPE_FLOAT) {  // most files: copied as they are
      glm::vec3 f;
      std::memcpy(&f, at, sizeof f);
      return f;
    }
    return glm::vec3(float(component_at(at, v.component_type, v.normalized)),
                     float(component_at(at + size, v.component_type, v.normalized)),
                     float(component_at(at + 2 * size, v.component_type, v.normalized)));
  };
  std::vector<glm::vec3> out(v.count, glm::vec3(0.0f));
  if (v.base)
    for (std::size_t i = 0; i < v.count; ++i) out[i] = element(v.base + i * v.stride);
  apply_sparse(index, where, TINYGLTF_TYPE_VEC3, [&](std::size_t i, const unsigned char* at) { out[i] = element(at); });
  for (std::size_t i = 0; i < v.count; ++i)
    if (!std::isfinite(out[i].x) || !std::isfinite(out[i].y) || !std::isfinite(out[i].z))
      refuse(400, where + " (" + index_of("accessors", std::size_t(index)) + "): element " + std::to_string(i) +
                      " is not finite (NaN or infinity)");
  return out;
}

std::vector<float> Loader::read_floats(int index, const std::string& where, int type,
                                       std::initializer_list<int> component_types) const {
  const ElementView v = view(index, where, type, component_types);
  const std::size_t components = type_components(type), size = component_bytes(v.component_type);
  std::vector<float> out(v.count * components, 0.0f);
  const auto element = [&](std::size_t i, const unsigned char* at) {
    for (std::size_t c = 0; c < components; ++c)
      out[i * components + c] = float(component_at(at + c * size, v.component_type, v.normalized));
  };
  if (v.base)
    for (std::size_t i = 0; i < v.count; ++i) element(i, v.base + i * v.stride);
  apply_sparse(index, where, type, element);
  for (std::size_t i = 0; i < out.size(); ++i)
    if (!std::isfinite(out[i]))
      refuse(400, where + " (" + index_of("accessors", std::size_t(index)) + "): element " +
                      std::to_string(i / components) + " is not finite (NaN or infinity)");
  return out;
}

std::vector<std::uint32_t> Loader::read_indices(int index, const std::string& where, std::size_t vertex_count) const {
  const ElementView v = view(index, where, TINYGLTF_TYPE_SCALAR,
                             {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                              TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT});
  const auto element = [&](const unsigned char* at) {
    return std::uint32_t(component_at(at, v.component_type, false));
  };
  std::vector<std::uint32_t> out(v.count, 0);
  if (v.base)
    for (std::size_t i = 0; i < v.count; ++i) out[i] = element(v.base + i * v.stride);
  apply_sparse(index, where, TINYGLTF_TYPE_SCALAR, [&](std::size_t i, const unsigned char* at) { out[i] = element(at); });
  for (std::size_t i = 0; i < v.count; ++i)
    if (out[i] >= vertex_count)
      refuse(400, where + " (" + index_of("accessors", std::size_t(index)) + "): index " + std::to_string(out[i]) +
                      " at element " + std::to_string(i) + " is out of range (" + std::to_string(vertex_count) +
                      " vertices)");
  return out;
}

bool all_finite(const std::vector<double>& values) {
  return std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); });
}

glm::dmat4 Loader::local_matrix(std::size_t n) const {
  const tinygltf::Node& node = gltf_.nodes[n];
  const std::string name = index_of("nodes", n);
  if (!node.matrix.empty()) {
    if (node.matrix.size() != 16) refuse(400, name + ".matrix: " + std::to_string(node.matrix.size()) + " numbers, not 16");
    if (!all_finite(node.matrix)) refuse(400, name + ".matrix: not finite (NaN or infinity)");
    glm::dmat4 m;
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) m[c][r] = node.matrix[std::size_t(c * 4 + r)];  // column-major, as glm
    return m;
  }
  const auto check = [&](const std::vector<double>& v, std::size_t size, const char* field) {
    if (!v.empty() && v.size() != size)
      refuse(400, name + "." + field + ": " + std::to_string(v.size()) + " numbers, not " + std::to_string(size));
    if (!all_finite(v)) refuse(400, name + "." + field + ": not finite (NaN or infinity)");
  };
  check(node.translation, 3, "translation");
  check(node.rotation, 4, "rotation");
  check(node.scale, 3, "scale");
  glm::dmat4 m(1.0);
  if (!node.translation.empty()) m[3] = glm::dvec4(node.translation[0], node.translation[1], node.translation[2], 1.0);
  if (!node.rotation.empty()) {
    // glTF stores x, y, z, w; glm's constructor takes w first.
    glm::dquat q(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]);
    const double length = glm::length(q);
    if (!(length > 0.0) || !std::isfinite(length)) refuse(400, name + ".rotation: not a unit quaternion");
    m = m * glm::dmat4(glm::mat3_cast(q / length));
  }
  if (!node.scale.empty()) m = m * glm::scale(glm::dmat4(1.0), glm::dvec3(node.scale[0], node.scale[1], node.scale[2]));
  return m;
}

std::vector<Loader::Instance> Loader::instances() const {
  const std::size_t node_count = gltf_.nodes.size();
  if (node_count > options_.max_nodes)
    refuse(422, "the model has " + std::to_string(node_count) + " nodes; at most " + std::to_string(options_.max_nodes) +
                    " are taken");
  // One parent at most: then the hierarchy from real roots is a forest, and
  // a cycle can only hang off a node listed as a root while it has a parent.
  constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
  std::vector<std::size_t> parent(node_count, kNone);
  for (std::size_t n = 0; n < node_count; ++n) {
    const auto& children = gltf_.nodes[n].children;
    for (std::size_t k = 0; k < children.size(); ++k) {
      const int c = children[k];
      if (c < 0 || std::size_t(c) >= node_count)
        refuse(400, index_of("nodes", n) + ".children[" + std::to_string(k) + "]: node " + std::to_string(c) +
                        " is out of range (" + std::to_string(node_count) + " nodes)");
      if (parent[std::size_t(c)] != kNone)
        refuse(400, index_of("nodes", std::size_t(c)) + " is a child of both " +
                        index_of("nodes", parent[std::size_t(c)]) + " and " + index_of("nodes", n) +
                        " (a node has one parent at most)");
      parent[std::size_t(c)] = n;
    }
  }
  std::vector<std::size_t> roots;
  if (gltf_.defaultScene >= 0 || !gltf_.scenes.empty()) {
    const std::size_t s = gltf_.defaultScene >= 0 ? std::size_t(gltf_.defaultScene) : 0;
    if (s >= gltf_.scenes.size())
      refuse(400, "scene: " + std::to_string(gltf_.defaultScene) + " is out of range (" +
                      std::to_string(gltf_.scenes.size()) + " scenes)");
    const auto& listed = gltf_.scenes[s].nodes;
    for (std::size_t k = 0; k < listed.size(); ++k) {
      const std::string where = index_of("scenes", s) + ".nodes[" + std::to_string(k) + "]";
      if (listed[k] < 0 || std::size_t(listed[k]) >= node_count)
        refuse(400, where + ": node " + std::to_string(listed[k]) + " is out of range (" + std::to_string(node_count) +
                        " nodes)");
      const std::size_t n = std::size_t(listed[k]);
      if (parent[n] != kNone)
        refuse(400, where + ": " + index_of("nodes", n) + " is listed as a root but is a child of " +
                        index_of("nodes", parent[n]) + " (a cycle, or not a root)");
      roots.push_back(n);
    }
  } else {
    for (std::size_t n = 0; n < node_count; ++n)
      if (parent[n] == kNone) roots.push_back(n);
  }

  std::vector<Instance> out;
  std::vector<bool> visited(node_count, false);
  struct Step {
    std::size_t node;
    glm::dmat4 parent_world;
    std::size_t depth;
  };
  std::vector<Step> stack;
  for (auto it = roots.rbegin(); it != roots.rend(); ++it) stack.push_back({*it, glm::dmat4(1.0), 1});
  while (!stack.empty()) {
    const Step step = stack.back();
    stack.pop_back();
    const std::string name = index_of("nodes", step.node);
    if (visited[step.node]) refuse(400, name + " is reached twice from the scene's roots");
    visited[step.node] = true;
    if (step.depth > kMaxNodeDepth)
      refuse(422, name + ": the node hierarchy is deeper than " + std::to_string(kMaxNodeDepth) + " levels");
    const tinygltf::Node& node = gltf_.nodes[step.node];
    const glm::dmat4 world = step.parent_world * local_matrix(step.node);
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r)
        if (!std::isfinite(world[c][r])) refuse(400, name + ": its transform, with its parents', is not finite");
    if (node.mesh >= 0 || node.mesh < -1) {
      if (node.mesh < 0 || std::size_t(node.mesh) >= gltf_.meshes.size())
        refuse(400, name + ".mesh: " + std::to_string(node.mesh) + " is out of range (" +
                        std::to_string(gltf_.meshes.size()) + " meshes)");
      out.push_back({step.node, std::size_t(node.mesh), world});
    }
    for (auto c = node.children.rbegin(); c != node.children.rend(); ++c)
      stack.push_back({std::size_t(*c), world, step.depth + 1});
  }
  return out;
}

bool is_triangles(int mode) {
  return mode == TINYGLTF_MODE_TRIANGLES || mode == TINYGLTF_MODE_TRIANGLE_STRIP || mode == TINYGLTF_MODE_TRIANGLE_FAN;
}

std::string primitive_name(std::size_t mesh, std::size_t p) {
  return index_of("meshes", mesh) + ".primitives[" + std::to_string(p) + "]";
}

// Modes, attributes and counts of every instanced primitive, before any
// vertex is read: what the model will cost is known and bounded first.
Loader::Size Loader::check_primitives(const std::vector<Instance>& instances) const {
  std::vector<std::size_t> mesh_triangles(gltf_.meshes.size(), 0), mesh_vertices(gltf_.meshes.size(), 0);
  // Vertices an instance keeps (only those its triangles use: at most the
  // accessor's count and at most one per corner).
  std::vector<std::size_t> mesh_kept(gltf_.meshes.size(), 0), mesh_skipped(gltf_.meshes.size(), 0);
  std::uint64_t kept_vertices = 0, primitive_instances = 0;
  std::vector<bool> checked(gltf_.meshes.size(), false);
  const std::size_t max_vertices = 3 * options_.max_triangles;
  std::size_t triangles = 0, vertices = 0, skipped = 0;
  for (const Instance& instance : instances) {
    const std::size_t m = instance.mesh;
    if (!checked[m]) {
      checked[m] = true;
      for (std::size_t p = 0; p < gltf_.meshes[m].primitives.size(); ++p) {
        const tinygltf::Primitive& primitive = gltf_.meshes[m].primitives[p];
        const std::string name = primitive_name(m, p);
        const int mode = primitive.mode;
        // Points and lines cast no shadow: left out, and counted.
        if (!is_triangles(mode)) {
          if (mode < TINYGLTF_MODE_POINTS || mode > TINYGLTF_MODE_LINE_STRIP)
            refuse(400, name + ": mode " + std::to_string(mode) + " is not a glTF primitive mode (0 to 6)");
          ++mesh_skipped[m];
          continue;
        }
        const auto position = primitive.attributes.find("POSITION");
        if (position == primitive.attributes.end()) refuse(422, name + ": no POSITION attribute");
        const std::size_t vertex_count = accessor(position->second, name + ".attributes.POSITION").count;
        // NORMAL is read too: one per position, known before a byte of it is
        // (an accessor without a buffer view reads as zeros: a count of a
        // billion was 12 GB of them; found by the red-team pass).
        const auto normal = primitive.attributes.find("NORMAL");
        if (normal != primitive.attributes.end()) {
          const std::size_t normals = accessor(normal->second, name + ".attributes.NORMAL").count;
          if (normals != vertex_count)
            refuse(400, name + ": " + std::to_string(normals) + " normals for " + std::to_string(vertex_count) +
                            " positions");
        }
        const std::size_t corners =
            primitive.indices >= 0 ? accessor(primitive.indices, name + ".indices").count : vertex_count;
        if (vertex_count > max_vertices || corners > max_vertices)
          refuse(422, name + ": more than " + std::to_string(options_.max_triangles) + " triangles");
        std::size_t count = 0;
        if (mode == TINYGLTF_MODE_TRIANGLES) {
          if (corners % 3 != 0)
            refuse(400, name + ": " + std::to_string(corners) + " corners is not a multiple of 3 for TRIANGLES");
          count = corners / 3;
        } else {
          count = corners >= 3 ? corners - 2 : 0;
        }
        mesh_triangles[m] += count;
        mesh_vertices[m] += vertex_count;
        mesh_kept[m] += std::min(vertex_count, corners);
        if (mesh_triangles[m] > options_.max_triangles || mesh_vertices[m] > max_vertices)
          refuse(422, index_of("meshes", m) + ": more than " + std::to_string(options_.max_triangles) + " triangles");
      }
    }
    triangles += mesh_triangles[m];
    vertices += mesh_vertices[m];
    kept_vertices += mesh_kept[m];
    skipped += mesh_skipped[m];
    primitive_instances += gltf_.meshes[m].primitives.size();
    if (triangles > options_.max_triangles || vertices > max_vertices)
      refuse(422, "the model has more than " + std::to_string(options_.max_triangles) +
                      " triangles (or 3 times as many vertices), counting every node that instances a mesh; "
                      "that is the most one model may have");
  }
  // One part per base colour: at most one per material and the default.
  const std::uint64_t parts = std::min<std::uint64_t>(primitive_instances, gltf_.materials.size() + 1);
  return {triangles, model_bytes_bound(triangles, kept_vertices, parts), skipped};
}

glm::vec3 Loader::base_color(int material, const std::string& where) const {
  if (material < 0) return glm::vec3(1.0f);  // glTF's default material is white
  if (std::size_t(material) >= gltf_.materials.size())
    refuse(400, where + ".material: " + std::to_string(material) + " is out of range (" +
                    std::to_string(gltf_.materials.size()) + " materials)");
  const std::vector<double>& factor = gltf_.materials[std::size_t(material)].pbrMetallicRoughness.baseColorFactor;
  const std::string name = index_of("materials", std::size_t(material)) + ".pbrMetallicRoughness.baseColorFactor";
  if (factor.size() != 4) refuse(400, name + ": " + std::to_string(factor.size()) + " numbers, not 4");
  if (!all_finite(factor)) refuse(400, name + ": not finite (NaN or infinity)");
  glm::vec3 c;
  for (int i = 0; i < 3; ++i) c[i] = float(std::clamp(factor[std::size_t(i)], 0.0, 1.0));
  return c;
}

void Loader::add_primitive(const Instance& instance, std::size_t p, TriangleModel& out,
                           std::map<std::array<float, 3>, std::size_t>& parts) const {
  const tinygltf::Primitive& primitive = gltf_.meshes[instance.mesh].primitives[p];
  if (!is_triangles(primitive.mode)) return;  // counted by check_primitives
  const std::string name = primitive_name(instance.mesh, p);
  std::vector<glm::vec3> positions = read_vec3(primitive.attributes.at("POSITION"), name + ".attributes.POSITION");
  std::vector<std::uint32_t> corners;
  if (primitive.indices >= 0) {
    corners = read_indices(primitive.indices, name + ".indices", positions.size());
  } else {
    corners.resize(positions.size());
    for (std::size_t i = 0; i < corners.size(); ++i) corners[i] = std::uint32_t(i);
  }
  std::vector<std::uint32_t> triangles;
  if (primitive.mode == TINYGLTF_MODE_TRIANGLES) {
    triangles = std::move(corners);
  } else {
    // Strips alternate their winding; fans turn about their first corner.
    for (std::size_t i = 0; i + 2 < corners.size(); ++i) {
      if (primitive.mode == TINYGLTF_MODE_TRIANGLE_FAN)
        triangles.insert(triangles.end(), {corners[0], corners[i + 1], corners[i + 2]});
      else if (i % 2 == 0)
        triangles.insert(triangles.end(), {corners[i], corners[i + 1], corners[i + 2]});
      else
        triangles.insert(triangles.end(), {corners[i + 1], corners[i], corners[i + 2]});
    }
  }
  if (triangles.empty()) return;

  std::vector<glm::vec3> normals;
  const auto normal = primitive.attributes.find("NORMAL");
  if (normal != primitive.attributes.end()) {
    normals = read_vec3(normal->second, name + ".attributes.NORMAL");
    if (normals.size() != positions.size())
      refuse(400, name + ": " + std::to_string(normals.size()) + " normals for " + std::to_string(positions.size()) +
                      " positions");
  }

  // Only the vertices the triangles use are kept (a primitive may index a
  // few vertices of a large shared accessor).
  constexpr std::uint32_t kUnused = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> remap(positions.size(), kUnused);
  std::vector<std::uint32_t> used;
  for (std::uint32_t& i : triangles) {
    if (remap[i] == kUnused) {
      remap[i] = std::uint32_t(used.size());
      used.push_back(i);
    }
    i = remap[i];
  }

  const glm::vec3 color = base_color(primitive.material, name);
  const auto found = parts.emplace(std::array<float, 3>{color.r, color.g, color.b}, out.parts.size());
  if (found.second) {
    out.parts.emplace_back();
    out.parts.back().base_color = color;
  }
  if (rig_) add_rig_primitive(instance, p, found.first->second, positions, normals, used, triangles);

  const glm::dmat4& world = instance.world;
  const glm::dmat3 linear(world);
  const double determinant = glm::determinant(linear);
  // A mirroring transform turns counter-clockwise into clockwise.
  if (determinant < 0.0)
    for (std::size_t t = 0; t < triangles.size(); t += 3) std::swap(triangles[t + 1], triangles[t + 2]);
  std::vector<glm::vec3> world_positions(used.size());
  for (std::size_t v = 0; v < used.size(); ++v) {
    const glm::dvec3 w = glm::dvec3(world * glm::dvec4(glm::dvec3(positions[used[v]]), 1.0));
    const glm::vec3 f(w);
    if (!std::isfinite(f.x) || !std::isfinite(f.y) || !std::isfinite(f.z))
      refuse(400, name + " under " + index_of("nodes", instance.node) +
                      ": a position is not finite once transformed (too large for 32-bit floats)");
    world_positions[v] = f;
  }
  std::vector<glm::vec3> world_normals;
  if (!normals.empty() && determinant != 0.0) {
    const glm::dmat3 normal_matrix = glm::inverseTranspose(linear);
    world_normals.resize(used.size());
    for (std::size_t v = 0; v < used.size(); ++v) {
      const glm::dvec3 n = normal_matrix * glm::dvec3(normals[used[v]]);
      const double length = glm::length(n);
      if (!(length > 0.0) || !std::isfinite(length)) {
        world_normals.clear();  // a zero normal in the file: make them all, consistently
        break;
      }
      world_normals[v] = glm::vec3(n / length);
    }
  }
  if (world_normals.empty()) world_normals = area_weighted_normals(world_positions, triangles);

  out.parts[found.first->second].append(world_positions, world_normals, triangles);
}

// --- Animation: the rig (core/model_rig.hpp) --------------------------------

const std::initializer_list<int> kFloatOrNormalized = {
    TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
    TINYGLTF_COMPONENT_TYPE_SHORT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT};

std::uint64_t Loader::rig_bytes_bound(const std::vector<Instance>& instances) const {
  // Keyframes: every sampler's times and values, bounded before any is read
  // (an accessor without a buffer view reads as zeros, whatever its count).
  if (gltf_.animations.size() > kMaxAnimations)
    refuse(422, "the model has " + std::to_string(gltf_.animations.size()) + " animations; at most " +
                    std::to_string(kMaxAnimations) + " are taken");
  std::uint64_t floats = 0;
  for (std::size_t a = 0; a < gltf_.animations.size(); ++a)
    for (std::size_t k = 0; k < gltf_.animations[a].samplers.size(); ++k) {
      const tinygltf::AnimationSampler& sampler = gltf_.animations[a].samplers[k];
      const std::string where = index_of("animations", a) + ".samplers[" + std::to_string(k) + "]";
      const tinygltf::Accessor& input = accessor(sampler.input, where + ".input");
      const tinygltf::Accessor& output = accessor(sampler.output, where + ".output");
      floats += std::uint64_t(input.count) + std::uint64_t(output.count) * std::max<std::size_t>(1, type_components(output.type));
      if (floats > kMaxAnimationFloats)
        refuse(422, "the model's animations hold more than " + std::to_string(kMaxAnimationFloats) +
                        " keyframe numbers, the most one model may (at " + where + ")");
    }
  std::uint64_t bytes = floats * sizeof(float) + gltf_.nodes.size() * (sizeof(RigNode) + 16 + kMaxMorphTargets * sizeof(float));
  // The animations', samplers' and channels' own records (80,000 empty
  // animations are 20 MB of them).
  for (const tinygltf::Animation& animation : gltf_.animations)
    bytes += sizeof(RigAnimation) + animation.name.size() + animation.samplers.size() * sizeof(RigSampler) +
             animation.channels.size() * sizeof(RigChannel);
  for (const tinygltf::Skin& skin : gltf_.skins) bytes += skin.joints.size() * (sizeof(std::size_t) + sizeof(glm::dmat4));
  // Each instanced primitive's kept vertices (at most one a corner and at
  // most its accessor's count): position, normal, joints and weights, and
  // an offset of each for every morph target.
  for (const Instance& instance : instances)
    for (std::size_t p = 0; p < gltf_.meshes[instance.mesh].primitives.size(); ++p) {
      const tinygltf::Primitive& primitive = gltf_.meshes[instance.mesh].primitives[p];
      if (!is_triangles(primitive.mode)) continue;
      const std::string name = primitive_name(instance.mesh, p);
      if (primitive.targets.size() > kMaxMorphTargets)
        refuse(422, name + ": " + std::to_string(primitive.targets.size()) + " morph targets; at most " +
                        std::to_string(kMaxMorphTargets) + " are taken");
      const std::uint64_t vertices = accessor(primitive.attributes.at("POSITION"), name + ".attributes.POSITION").count;
      const std::uint64_t corners =
          primitive.indices >= 0 ? accessor(primitive.indices, name + ".indices").count : vertices;
      const std::uint64_t kept = std::min(vertices, corners);
      bytes += sizeof(RigPrimitive) + kept * (2 * sizeof(glm::vec3) + 8 + sizeof(glm::vec4)) + corners * 4 +
               kept * primitive.targets.size() * 2 * sizeof(glm::vec3);
    }
  return bytes;
}

void Loader::add_rig_primitive(const Instance& instance, std::size_t p, std::size_t part,
                               const std::vector<glm::vec3>& positions, const std::vector<glm::vec3>& normals,
                               const std::vector<std::uint32_t>& used, const std::vector<std::uint32_t>& triangles) const {
  const tinygltf::Primitive& primitive = gltf_.meshes[instance.mesh].primitives[p];
  const std::string name = primitive_name(instance.mesh, p);
  RigPrimitive r;
  r.node = instance.node;
  r.part = part;
  r.indices = triangles;
  r.positions.reserve(used.size());
  for (const std::uint32_t v : used) r.positions.push_back(positions[v]);
  if (!normals.empty()) {
    r.normals.reserve(used.size());
    for (const std::uint32_t v : used) r.normals.push_back(normals[v]);
  }
  // Skinned: the node names a skin and the primitive has its joints and
  // weights (glTF 2.0 §3.7.3: JOINTS_0 and WEIGHTS_0).
  const int skin = gltf_.nodes[instance.node].skin;
  const auto joints = primitive.attributes.find("JOINTS_0"), weights = primitive.attributes.find("WEIGHTS_0");
  if (skin >= 0 && joints != primitive.attributes.end() && weights != primitive.attributes.end()) {
    if (std::size_t(skin) >= gltf_.skins.size())
      refuse(400, index_of("nodes", instance.node) + ".skin: " + std::to_string(skin) + " is out of range (" +
                      std::to_string(gltf_.skins.size()) + " skins)");
    const std::size_t joint_count = gltf_.skins[std::size_t(skin)].joints.size();
    // glTF 2.0 §3.7.3.3: joint indices are plain integers, weights floats
    // or normalized integers (255 taken as 255, a cube was 255 m across).
    if (accessor(joints->second, name + ".attributes.JOINTS_0").normalized)
      refuse(400, name + ".attributes.JOINTS_0: joint indices must not be normalized");
    const tinygltf::Accessor& weight_accessor = accessor(weights->second, name + ".attributes.WEIGHTS_0");
    if (weight_accessor.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT && !weight_accessor.normalized)
      refuse(400, name + ".attributes.WEIGHTS_0: integer weights must be normalized (\"normalized\": true)");
    const std::vector<float> j = read_floats(joints->second, name + ".attributes.JOINTS_0", TINYGLTF_TYPE_VEC4,
                                             {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT});
    const std::vector<float> w = read_floats(weights->second, name + ".attributes.WEIGHTS_0", TINYGLTF_TYPE_VEC4,
                                             {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                                              TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT});
    if (j.size() != positions.size() * 4 || w.size() != positions.size() * 4)
      refuse(400, name + ": JOINTS_0 and WEIGHTS_0 must have one element per position (" +
                      std::to_string(positions.size()) + ")");
    r.skin = skin;
    r.joints.reserve(used.size());
    r.weights.reserve(used.size());
    for (const std::uint32_t v : used) {
      std::array<std::uint16_t, 4> joint{};
      for (int k = 0; k < 4; ++k) {
        const float index = j[std::size_t(v) * 4 + std::size_t(k)], weight = w[std::size_t(v) * 4 + std::size_t(k)];
        if (weight != 0.0f && index >= float(joint_count))
          refuse(400, name + ".attributes.JOINTS_0: joint " + std::to_string(std::uint32_t(index)) +
                          " is out of range (its skin has " + std::to_string(joint_count) + " joints)");
        joint[std::size_t(k)] = weight != 0.0f ? std::uint16_t(index) : 0;
      }
      r.joints.push_back(joint);
      glm::vec4 weight(w[std::size_t(v) * 4], w[std::size_t(v) * 4 + 1], w[std::size_t(v) * 4 + 2],
                       w[std::size_t(v) * 4 + 3]);
      if (weight.x < 0.0f || weight.y < 0.0f || weight.z < 0.0f || weight.w < 0.0f)
        refuse(400, name + ".attributes.WEIGHTS_0: element " + std::to_string(v) + " has a negative weight");
      // Their sum must be 1 (glTF); exporters round, so it is made so
      // rather than letting a sum of 1.02 grow the model by 2 %.
      const float sum = weight.x + weight.y + weight.z + weight.w;
      if (sum > 0.0f) weight /= sum;
      r.weights.push_back(weight);
    }
  }
  // Morph targets: offsets of positions and normals (tangents are not read).
  for (std::size_t t = 0; t < primitive.targets.size(); ++t) {
    std::vector<glm::vec3> kept_positions, kept_normals;
    for (const auto& [attribute, index] : primitive.targets[t]) {
      if (attribute != "POSITION" && attribute != "NORMAL") continue;
      const std::string where = name + ".targets[" + std::to_string(t) + "]." + attribute;
      const std::vector<glm::vec3> offsets = read_vec3(index, where);
      if (offsets.size() != positions.size())
        refuse(400, where + ": " + std::to_string(offsets.size()) + " elements for " + std::to_string(positions.size()) +
                        " positions");
      std::vector<glm::vec3>& kept = attribute == "POSITION" ? kept_positions : kept_normals;
      kept.reserve(used.size());
      for (const std::uint32_t v : used) kept.push_back(offsets[v]);
    }
    r.target_positions.push_back(std::move(kept_positions));
    r.target_normals.push_back(std::move(kept_normals));
  }
  rig_->primitives.push_back(std::move(r));
}

void Loader::finish_rig(const TriangleModel& model) {
  ModelRig& rig = *rig_;
  for (const ModelPart& part : model.parts) rig.part_colors.push_back(part.base_color);
  // Nodes: their rest transforms (checked by local_matrix), parents, and
  // morph weights (node.weights, else its mesh's, else zeros).
  const std::size_t node_count = gltf_.nodes.size();
  rig.nodes.resize(node_count);
  for (std::size_t n = 0; n < node_count; ++n) {
    const tinygltf::Node& node = gltf_.nodes[n];
    RigNode& r = rig.nodes[n];
    const glm::dmat4 local = local_matrix(n);  // refuses what is not a transform
    if (!node.matrix.empty()) r.matrix = local;
    if (!node.translation.empty()) r.translation = {node.translation[0], node.translation[1], node.translation[2]};
    if (!node.rotation.empty())
      r.rotation = glm::normalize(glm::dquat(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]));
    if (!node.scale.empty()) r.scale = {node.scale[0], node.scale[1], node.scale[2]};
    for (const int c : node.children) rig.nodes[std::size_t(c)].parent = int(n);  // checked by instances()
    if (node.mesh >= 0 && std::size_t(node.mesh) < gltf_.meshes.size()) {
      const tinygltf::Mesh& mesh = gltf_.meshes[std::size_t(node.mesh)];
      std::size_t targets = 0;
      for (const tinygltf::Primitive& primitive : mesh.primitives) targets = std::max(targets, primitive.targets.size());
      const std::vector<double>& given = !node.weights.empty() ? node.weights : mesh.weights;
      r.weights.assign(targets, 0.0f);
      for (std::size_t k = 0; k < std::min(targets, given.size()); ++k) {
        if (!std::isfinite(given[k])) refuse(400, index_of("nodes", n) + ": a morph weight is not finite");
        r.weights[k] = float(given[k]);
      }
    }
  }
  // Parents before children: from every node without a parent, depth first
  // (a cycle has no such node and is never reached: its nodes are not posed).
  std::vector<std::size_t> stack;
  for (std::size_t n = node_count; n-- > 0;)
    if (rig.nodes[n].parent < 0) stack.push_back(n);
  std::vector<bool> reached(node_count, false);
  while (!stack.empty()) {
    const std::size_t n = stack.back();
    stack.pop_back();
    if (reached[n]) continue;
    reached[n] = true;
    rig.order.push_back(n);
    const auto& children = gltf_.nodes[n].children;
    for (auto c = children.rbegin(); c != children.rend(); ++c) stack.push_back(std::size_t(*c));
  }
  // Skins: joints among the posed nodes, one inverse bind matrix each.
  for (std::size_t s = 0; s < gltf_.skins.size(); ++s) {
    const tinygltf::Skin& skin = gltf_.skins[s];
    const std::string where = index_of("skins", s);
    RigSkin r;
    for (std::size_t k = 0; k < skin.joints.size(); ++k) {
      const int j = skin.joints[k];
      if (j < 0 || std::size_t(j) >= node_count || !reached[std::size_t(j)])
        refuse(400, where + ".joints[" + std::to_string(k) + "]: node " + std::to_string(j) +
                        " is out of range or in a cycle of nodes");
      r.joints.push_back(std::size_t(j));
    }
    r.inverse_bind.assign(skin.joints.size(), glm::dmat4(1.0));
    if (skin.inverseBindMatrices >= 0) {
      const std::vector<float> m = read_floats(skin.inverseBindMatrices, where + ".inverseBindMatrices",
                                               TINYGLTF_TYPE_MAT4, {TINYGLTF_COMPONENT_TYPE_FLOAT});
      if (m.size() < skin.joints.size() * 16)
        refuse(400, where + ".inverseBindMatrices: " + std::to_string(m.size() / 16) + " matrices for " +
                        std::to_string(skin.joints.size()) + " joints");
      for (std::size_t k = 0; k < skin.joints.size(); ++k) r.inverse_bind[k] = glm::dmat4(glm::make_mat4(&m[k * 16]));
    }
    rig.skins.push_back(std::move(r));
  }
  // Animations: samplers (times increasing), channels onto nodes' TRS or
  // morph weights.
  for (std::size_t a = 0; a < gltf_.animations.size(); ++a) {
    const tinygltf::Animation& animation = gltf_.animations[a];
    const std::string where = index_of("animations", a);
    // glTF 2.0: an animation has at least one channel and one sampler.
    if (animation.channels.empty() || animation.samplers.empty())
      refuse(400, where + ": an animation needs at least one channel and one sampler");
    RigAnimation r;
    r.name = animation.name;
    // Each sampler's width is known from the channel that reads it.
    std::vector<std::size_t> width(animation.samplers.size(), 0);
    std::vector<RigPath> kind(animation.samplers.size(), RigPath::Translation);
    for (std::size_t c = 0; c < animation.channels.size(); ++c) {
      const tinygltf::AnimationChannel& channel = animation.channels[c];
      const std::string name = where + ".channels[" + std::to_string(c) + "]";
      if (channel.sampler < 0 || std::size_t(channel.sampler) >= animation.samplers.size())
        refuse(400, name + ".sampler: " + std::to_string(channel.sampler) + " is out of range");
      if (channel.target_node < 0) continue;  // no node: glTF says to ignore it
      if (std::size_t(channel.target_node) >= node_count)
        refuse(400, name + ".target.node: " + std::to_string(channel.target_node) + " is out of range");
      const std::size_t node = std::size_t(channel.target_node);
      RigChannel out{node, RigPath::Translation, std::size_t(channel.sampler)};
      std::size_t w = 3;
      if (channel.target_path == "translation") {
        out.path = RigPath::Translation;
      } else if (channel.target_path == "rotation") {
        out.path = RigPath::Rotation, w = 4;
      } else if (channel.target_path == "scale") {
        out.path = RigPath::Scale;
      } else if (channel.target_path == "weights") {
        out.path = RigPath::Weights, w = rig.nodes[node].weights.size();
        if (w == 0) refuse(400, name + ": animates the morph weights of " + index_of("nodes", node) + ", which has no morph targets");
      } else {
        continue;  // "pointer" and other extensions' paths: not read (nothing Umbra draws moves by them)
      }
      if (rig.nodes[node].matrix)
        refuse(400, name + ": animates " + index_of("nodes", node) + ", which has a matrix (glTF: only TRS nodes are animated)");
      if (width[std::size_t(channel.sampler)] != 0 && width[std::size_t(channel.sampler)] != w)
        refuse(400, name + ": its sampler is read by channels of different widths");
      width[std::size_t(channel.sampler)] = w;
      kind[std::size_t(channel.sampler)] = out.path;
      r.channels.push_back(out);
    }
    for (std::size_t k = 0; k < animation.samplers.size(); ++k) {
      const tinygltf::AnimationSampler& sampler = animation.samplers[k];
      const std::string name = where + ".samplers[" + std::to_string(k) + "]";
      RigSampler out;
      out.width = width[k];
      if (sampler.interpolation == "STEP")
        out.interpolation = RigInterpolation::Step;
      else if (sampler.interpolation == "CUBICSPLINE")
        out.interpolation = RigInterpolation::CubicSpline;
      else if (sampler.interpolation.empty() || sampler.interpolation == "LINEAR")
        out.interpolation = RigInterpolation::Linear;
      else
        refuse(400, name + ".interpolation: must be LINEAR, STEP or CUBICSPLINE");
      if (out.width == 0) {  // read by no channel
        r.samplers.push_back(std::move(out));
        continue;
      }
      out.times = read_floats(sampler.input, name + ".input", TINYGLTF_TYPE_SCALAR, {TINYGLTF_COMPONENT_TYPE_FLOAT});
      if (out.times.empty()) refuse(400, name + ".input: no keyframes");
      if (out.times.front() < 0.0f) refuse(400, name + ".input: key times must not be negative");
      for (std::size_t i = 1; i < out.times.size(); ++i)
        if (!(out.times[i] > out.times[i - 1]))
          refuse(400, name + ".input: key times must increase (element " + std::to_string(i) + ")");
      const tinygltf::Accessor& output = accessor(sampler.output, name + ".output");
      const int type = output.type;
      // What its channels move says what each key holds: a translation or
      // scale VEC3, a rotation VEC4, morph weights SCALAR.
      const int expected = kind[k] == RigPath::Rotation  ? TINYGLTF_TYPE_VEC4
                           : kind[k] == RigPath::Weights ? TINYGLTF_TYPE_SCALAR
                                                         : TINYGLTF_TYPE_VEC3;
      if (type != expected)
        refuse(400, name + ".output: type " + std::string(type_name(type)) + " where its channel needs " +
                        type_name(expected));
      out.values = read_floats(sampler.output, name + ".output", type, kFloatOrNormalized);
      const std::size_t per_key = out.width * (out.interpolation == RigInterpolation::CubicSpline ? 3 : 1);
      if (out.values.size() != out.times.size() * per_key)
        refuse(400, name + ".output: " + std::to_string(out.values.size()) + " numbers for " +
                        std::to_string(out.times.size()) + " keys of " + std::to_string(per_key));
      r.duration_s = std::max(r.duration_s, double(out.times.back()));
      r.samplers.push_back(std::move(out));
    }
    rig.animations.push_back(std::move(r));
  }
  rig.order.shrink_to_fit();
}

std::shared_ptr<TriangleModel> Loader::build() {
  for (const std::string& extension : gltf_.extensionsRequired)
    if (!read_extension(extension))
      refuse(422, "extensionsRequired: " + short_message(extension) + " is not supported (Umbra reads glTF 2.0 with " +
                      read_extension_list() + ")");
  const std::vector<Instance> all = instances();
  const Size size = check_primitives(all);
  bytes_bound_ = size.bytes;
  // A rig for a file that moves (animations), or whose rest pose needs one
  // (skins, morph targets): glTF places a skinned mesh by its joints, not
  // by its node. Kept with the model only when it has animations.
  bool deformable = !gltf_.skins.empty();
  for (const Instance& instance : all)
    for (const tinygltf::Primitive& primitive : gltf_.meshes[instance.mesh].primitives)
      deformable = deformable || !primitive.targets.empty();
  if (!gltf_.animations.empty() || deformable) {
    bytes_bound_ += rig_bytes_bound(all);
    rig_ = std::make_unique<ModelRig>();
  }
  if (options_.admit) {
    std::string why;
    if (const int status = options_.admit(bytes_bound_, size.triangles, why)) refuse(status, why);
  }
  // Compressed data is decoded only now, the model's size known and
  // admitted; every decoded size counted against the budget first.
  // meshopt's fallback buffers declare their own lengths: at most what a
  // file of these bytes can fairly hold (the bound an upload has once
  // loaded: 16 times its bytes and 32 MiB), so a small file cannot claim
  // the whole budget. Draco's counts are the accessors' (bounded and
  // admitted above: Draco packs a dense mesh 30 times smaller than that
  // rule would allow): only max_decoded_bytes holds for them.
  std::uint64_t input = input_bytes_;
  for (const tinygltf::Buffer& buffer : gltf_.buffers) input += buffer.data.size();
  DecodeBudget fallback{std::min<std::uint64_t>(options_.max_decoded_bytes, 16 * input + (std::uint64_t(32) << 20)), 0};
  decode_meshopt(gltf_, compressed_, fallback);
  DecodeBudget budget{options_.max_decoded_bytes, fallback.spent};
  std::vector<bool> instanced(gltf_.meshes.size(), false);
  for (const Instance& instance : all) instanced[instance.mesh] = true;
  decode_draco(gltf_, compressed_, instanced, budget);
  auto model = std::make_shared<TriangleModel>();
  model->skipped_primitives = size.skipped;
  std::map<std::array<float, 3>, std::size_t> parts;
  for (const Instance& instance : all)
    for (std::size_t p = 0; p < gltf_.meshes[instance.mesh].primitives.size(); ++p)
      add_primitive(instance, p, *model, parts);
  if (model->triangle_count() == 0)
    refuse(422, "the model has no triangles (in the nodes of its scene, or in any root node when it names no scene)" +
                    (size.skipped ? ": " + std::to_string(size.skipped) +
                                        " primitives of points or lines were left out, as they cast no shadow"
                                  : std::string()));
  finish_model(*model);
  if (rig_) {
    finish_rig(*model);
    if (rig_deforms(*rig_)) {
      try {
        *model = pose_rest(*rig_);
      } catch (const std::domain_error& e) {
        refuse(400, std::string("its rest pose: ") + e.what());
      }
      model->skipped_primitives = size.skipped;
    }
    if (!rig_->animations.empty()) model->rig = std::move(rig_);
  }
  return model;
}

}  // namespace

LoadResult load_gltf(std::string_view bytes, const LoadOptions& options) {
  LoadResult result;
  try {
    const bool glb = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
    if (options.format == LoadOptions::Format::Binary && !glb)
      refuse(400, "not a glTF binary (.glb): it does not start with \"glTF\"; send a .gltf as model/gltf+json");
    if (options.format == LoadOptions::Format::Json && glb)
      refuse(400, "this is a glTF binary (.glb), not JSON: send it as model/gltf-binary");
    if (bytes.size() > std::numeric_limits<std::uint32_t>::max()) refuse(422, "the model is larger than 4 GiB");
    check_json_shape(glb ? glb_json_chunk(bytes) : bytes);
    CompressedParts compressed;
    std::string rewritten;
    prepare_compressed(bytes, glb, rewritten, compressed);
    if (!rewritten.empty()) bytes = rewritten;

    FileAccess access{&options, ""};
    tinygltf::TinyGLTF parser;
    parser.SetImageLoader(ignore_image, nullptr);
    parser.SetFsCallbacks(tinygltf::FsCallbacks{file_exists, expand_file_path, read_whole_file, write_whole_file, &access});
    parser.SetStoreOriginalJSONForExtrasAndExtensions(false);
    tinygltf::Model gltf;
    std::string err, warn;
    const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
    const auto size = static_cast<unsigned int>(bytes.size());
    const bool parsed = glb ? parser.LoadBinaryFromMemory(&gltf, &err, &warn, data, size, options.external_folder)
                            : parser.LoadASCIIFromString(&gltf, &err, &warn, bytes.data(), size, options.external_folder);
    if (!access.refused.empty()) refuse(options.external_folder.empty() ? 422 : 400, "a buffer " + access.refused);
    if (!parsed) refuse(400, "not a valid glTF 2.0 file: " + short_message(err.empty() ? "unreadable" : err));
    Loader loader(gltf, options, compressed, bytes.size());
    result.model = loader.build();
    result.bytes_bound = loader.bytes_bound();
  } catch (const GltfRefusal& r) {
    result.model.reset();
    result.status = r.status;
    result.error = r.message;
  } catch (const std::bad_alloc&) {
    result.model.reset();
    result.status = 422;
    result.error = "the model needs more memory than this server gives one model";
  } catch (const std::exception& e) {
    // tinygltf reads some fields with at() and nlohmann's accessors.
    result.model.reset();
    result.status = 400;
    result.error = "not a valid glTF 2.0 file: " + short_message(e.what());
  }
  return result;
}

}  // namespace umbra
