// EXT_meshopt_compression (and KHR_meshopt_compression, its ratified
// name), decoded by Debian's libmeshoptimizer: a compressed buffer view's
// bytes live in another buffer, and decode into the view's place in a
// "fallback" buffer that has no data of its own (gltfpack -cc writes these).
// The extension's text:
// github.com/KhronosGroup/glTF/tree/main/extensions/2.0/Vendor/EXT_meshopt_compression
#include <algorithm>
#include <cstring>
#include <limits>

#include <meshoptimizer.h>
#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include "assets/gltf_compression.hpp"

namespace umbra {

namespace {

using json = nlohmann::json;

constexpr const char* kNames[] = {"EXT_meshopt_compression", "KHR_meshopt_compression"};

// The extension's object in `item`, and which of the two names it has.
const json* extension_of(const json& item, std::string& name) {
  if (!item.is_object()) return nullptr;
  const auto extensions = item.find("extensions");
  if (extensions == item.end() || !extensions->is_object()) return nullptr;
  for (const char* n : kNames) {
    const auto found = extensions->find(n);
    if (found != extensions->end()) {
      name = n;
      return &*found;
    }
  }
  return nullptr;
}

std::size_t unsigned_field(const json& object, const char* key, const std::string& where, bool required,
                           std::size_t fallback = 0) {
  const auto found = object.find(key);
  if (found == object.end()) {
    if (required) refuse_gltf(400, where + "." + key + ": is required");
    return fallback;
  }
  if (!found->is_number_unsigned() || found->get<std::uint64_t>() > std::numeric_limits<std::uint32_t>::max())
    refuse_gltf(400, where + "." + key + ": must be a whole number from 0 to 2^32 - 1");
  return std::size_t(found->get<std::uint64_t>());
}

}  // namespace

void prepare_meshopt(json& document, CompressedParts& parts) {
  json* buffers = document.contains("buffers") && document["buffers"].is_array() ? &document["buffers"] : nullptr;
  json* views =
      document.contains("bufferViews") && document["bufferViews"].is_array() ? &document["bufferViews"] : nullptr;
  if (!buffers || !views) return;
  // Fallback buffers: tinygltf would read them from the GLB's binary chunk
  // (or refuse a .gltf buffer without a uri), so each gets a one-byte
  // data: URI here, and its declared length back when decoded. One with a
  // uri of its own (gltfpack -cf writes a .fallback.bin beside the file
  // for loaders without the extension) is never read either: only the
  // compressed views refer to it (the extension's rule), and they are
  // decoded into it.
  for (std::size_t b = 0; b < buffers->size(); ++b) {
    json& buffer = (*buffers)[b];
    std::string name;
    const json* ext = extension_of(buffer, name);
    if (!ext || !ext->is_object() || ext->value("fallback", false) != true) continue;
    const std::string where = "buffers[" + std::to_string(b) + "]";
    parts.fallback_buffers[b] = unsigned_field(buffer, "byteLength", where, true);
    buffer["uri"] = "data:application/octet-stream;base64,AA==";
    buffer["byteLength"] = 1;
  }
  for (std::size_t v = 0; v < views->size(); ++v) {
    const json& view = (*views)[v];
    std::string name;
    const json* ext = extension_of(view, name);
    if (!ext) continue;
    const std::string where = "bufferViews[" + std::to_string(v) + "].extensions." + name;
    if (!ext->is_object()) refuse_gltf(400, where + ": must be an object");
    const std::size_t target = unsigned_field(view, "buffer", "bufferViews[" + std::to_string(v) + "]", true);
    // A view in a buffer with data of its own reads that data: decoding
    // would give the same bytes.
    if (!parts.fallback_buffers.count(target)) continue;
    MeshoptView m;
    m.view = v;
    m.source_buffer = unsigned_field(*ext, "buffer", where, true);
    m.source_offset = unsigned_field(*ext, "byteOffset", where, false);
    m.source_length = unsigned_field(*ext, "byteLength", where, true);
    m.stride = unsigned_field(*ext, "byteStride", where, true);
    m.count = unsigned_field(*ext, "count", where, true);
    const std::string mode = ext->value("mode", std::string());
    const std::string filter = ext->contains("filter") && (*ext)["filter"].is_string() ? (*ext)["filter"].get<std::string>()
                                                                                      : std::string("NONE");
    if (mode == "ATTRIBUTES") {
      m.mode = MeshoptView::Mode::Attributes;
      if (m.stride == 0 || m.stride % 4 != 0 || m.stride > 256)
        refuse_gltf(400, where + ".byteStride: " + std::to_string(m.stride) +
                             " for ATTRIBUTES must be a multiple of 4 up to 256");
    } else if (mode == "TRIANGLES" || mode == "INDICES") {
      m.mode = mode == "TRIANGLES" ? MeshoptView::Mode::Triangles : MeshoptView::Mode::Indices;
      if (m.stride != 2 && m.stride != 4)
        refuse_gltf(400, where + ".byteStride: " + std::to_string(m.stride) + " for " + mode + " must be 2 or 4");
      if (m.mode == MeshoptView::Mode::Triangles && m.count % 3 != 0)
        refuse_gltf(400, where + ".count: " + std::to_string(m.count) + " for TRIANGLES is not a multiple of 3");
    } else {
      refuse_gltf(400, where + ".mode: must be \"ATTRIBUTES\", \"TRIANGLES\" or \"INDICES\"");
    }
    if (filter == "NONE") {
      m.filter = MeshoptView::Filter::None;
    } else if (m.mode != MeshoptView::Mode::Attributes) {
      refuse_gltf(400, where + ".filter: " + filter + " applies to ATTRIBUTES only");
    } else if (filter == "OCTAHEDRAL") {
      m.filter = MeshoptView::Filter::Octahedral;
      if (m.stride != 4 && m.stride != 8) refuse_gltf(400, where + ".byteStride: OCTAHEDRAL needs 4 or 8");
    } else if (filter == "QUATERNION") {
      m.filter = MeshoptView::Filter::Quaternion;
      if (m.stride != 8) refuse_gltf(400, where + ".byteStride: QUATERNION needs 8");
    } else if (filter == "EXPONENTIAL") {
      m.filter = MeshoptView::Filter::Exponential;
    } else {
      refuse_gltf(422, where + ".filter: " + filter + " is not a filter this server's meshoptimizer " +
                           std::to_string(MESHOPTIMIZER_VERSION / 1000) + "." +
                           std::to_string(MESHOPTIMIZER_VERSION % 1000) + " decodes");
    }
    const std::size_t view_length = unsigned_field(view, "byteLength", "bufferViews[" + std::to_string(v) + "]", true);
    if (std::uint64_t(m.count) * m.stride > view_length)
      refuse_gltf(400, where + ": " + std::to_string(m.count) + " elements of " + std::to_string(m.stride) +
                           " bytes do not fit the view's byteLength " + std::to_string(view_length));
    parts.meshopt_views.push_back(m);
  }
}

void decode_meshopt(tinygltf::Model& model, const CompressedParts& parts, DecodeBudget& budget) {
  std::vector<bool> needed(model.buffers.size(), false);
  for (const MeshoptView& m : parts.meshopt_views)
    if (m.view < model.bufferViews.size() && std::size_t(model.bufferViews[m.view].buffer) < needed.size())
      needed[std::size_t(model.bufferViews[m.view].buffer)] = true;
  for (const auto& [b, length] : parts.fallback_buffers) {
    if (b >= needed.size() || !needed[b]) continue;
    budget.spend(length, "buffers[" + std::to_string(b) + "] (a meshopt fallback buffer)");
    model.buffers[b].data.assign(length, 0);
  }
  // Bytes decoded into each buffer so far. Views of one file decode into
  // their own stretches of its fallback buffer; views decoding over each
  // other are work the buffer's length does not bound (a red-team pass:
  // 5000 views of 16 MB from one 250 KB source, a 1.1 MB upload, 24 s of
  // CPU), so what they decode past the buffer's length is charged too.
  std::vector<std::uint64_t> decoded(model.buffers.size(), 0);
  for (const MeshoptView& m : parts.meshopt_views) {
    const std::string where = "bufferViews[" + std::to_string(m.view) + "]";
    if (m.view >= model.bufferViews.size() || model.bufferViews[m.view].buffer < 0 ||
        std::size_t(model.bufferViews[m.view].buffer) >= model.buffers.size())
      refuse_gltf(400, where + ": out of range, or its buffer is");
    const tinygltf::BufferView& view = model.bufferViews[m.view];
    std::vector<unsigned char>& target = model.buffers[std::size_t(view.buffer)].data;
    const std::uint64_t bytes = std::uint64_t(m.count) * m.stride;
    if (view.byteOffset > target.size() || bytes > target.size() - view.byteOffset)
      refuse_gltf(400, where + ": " + std::to_string(bytes) + " decoded bytes from byte " +
                           std::to_string(view.byteOffset) + " run past the end of its fallback buffer (" +
                           std::to_string(target.size()) + " bytes)");
    std::uint64_t& into = decoded[std::size_t(view.buffer)];
    into += bytes;
    if (into > target.size()) budget.spend(bytes, where + " (meshopt views decoding over each other)");
    if (m.source_buffer >= model.buffers.size())
      refuse_gltf(400, where + ": the compressed data's buffer " + std::to_string(m.source_buffer) + " is out of range");
    const std::vector<unsigned char>& source = model.buffers[m.source_buffer].data;
    if (parts.fallback_buffers.count(m.source_buffer) || m.source_offset > source.size() ||
        m.source_length > source.size() - m.source_offset || m.source_length == 0)
      refuse_gltf(400, where + ": the compressed bytes " + std::to_string(m.source_offset) + " + " +
                           std::to_string(m.source_length) + " are not inside buffers[" +
                           std::to_string(m.source_buffer) + "] (" + std::to_string(source.size()) + " bytes)");
    const unsigned char* in = source.data() + m.source_offset;
    // The first byte names the codec's version: a newer one than this
    // meshoptimizer reads is a valid file this server cannot decode (422).
    const bool vertices = m.mode == MeshoptView::Mode::Attributes;
    const int version = in[0] & 0x0f, highest = m.mode == MeshoptView::Mode::Triangles ? 1 : 0;
    if ((in[0] & 0xf0) == (vertices ? 0xa0 : m.mode == MeshoptView::Mode::Triangles ? 0xe0 : 0xd0) && version > highest)
      refuse_gltf(422, where + ": meshopt " + (vertices ? "vertex" : "index") + " codec version " +
                           std::to_string(version) + " is newer than this server's meshoptimizer " +
                           std::to_string(MESHOPTIMIZER_VERSION / 1000) + "." +
                           std::to_string(MESHOPTIMIZER_VERSION % 1000) + " reads");
    unsigned char* out = target.data() + view.byteOffset;
    int rc = 0;
    switch (m.mode) {
      case MeshoptView::Mode::Attributes:
        rc = meshopt_decodeVertexBuffer(out, m.count, m.stride, in, m.source_length);
        break;
      case MeshoptView::Mode::Triangles:
        rc = meshopt_decodeIndexBuffer(out, m.count, m.stride, in, m.source_length);
        break;
      case MeshoptView::Mode::Indices:
        rc = meshopt_decodeIndexSequence(out, m.count, m.stride, in, m.source_length);
        break;
    }
    if (rc != 0) refuse_gltf(400, where + ": its meshopt-compressed bytes do not decode (meshoptimizer error " + std::to_string(rc) + ")");
    switch (m.filter) {
      case MeshoptView::Filter::None: break;
      case MeshoptView::Filter::Octahedral: meshopt_decodeFilterOct(out, m.count, m.stride); break;
      case MeshoptView::Filter::Quaternion: meshopt_decodeFilterQuat(out, m.count, m.stride); break;
      case MeshoptView::Filter::Exponential: meshopt_decodeFilterExp(out, m.count, m.stride); break;
    }
  }
}

}  // namespace umbra
