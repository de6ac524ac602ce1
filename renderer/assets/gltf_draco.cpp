// KHR_draco_mesh_compression, decoded by Debian's libdraco: a primitive's
// indices and attributes come from one Draco stream in a buffer view, and
// its accessors have no buffer view of their own (draco_transcoder and
// Blender write these). Before Draco allocates anything, the stream's
// header is read here (the bitstream's own specification, version 2.2:
// github.com/KhronosGroup/glTF/tree/main/extensions/2.0/Khronos/KHR_draco_mesh_compression)
// and its face and point counts are held to the accessors' counts, which
// the loader has bounded and admitted: a stream that claims a billion faces
// is refused before it is decoded.
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <set>

#include <draco/compression/decode.h>
#include <draco/compression/mesh/mesh_edgebreaker_decoder.h>
#include <draco/compression/mesh/mesh_sequential_decoder.h>
#include <draco/mesh/mesh.h>
#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include "assets/gltf_compression.hpp"

namespace umbra {

namespace {

using json = nlohmann::json;

constexpr const char* kName = "KHR_draco_mesh_compression";

// Reads the Draco stream's header fields in order; any read past the end
// is a refusal naming the primitive.
class HeaderReader {
 public:
  HeaderReader(const unsigned char* data, std::size_t size, std::string where)
      : data_(data), size_(size), where_(std::move(where)) {}
  std::uint8_t byte() {
    if (at_ >= size_) refuse_gltf(400, where_ + ": its Draco stream ends inside its header");
    return data_[at_++];
  }
  std::uint32_t varint() {  // LEB128, at most 5 bytes
    std::uint64_t value = 0;
    for (int shift = 0; shift < 35; shift += 7) {
      const std::uint8_t b = byte();
      value |= std::uint64_t(b & 0x7f) << shift;
      if (!(b & 0x80)) {
        if (value > std::numeric_limits<std::uint32_t>::max()) break;
        return std::uint32_t(value);
      }
    }
    refuse_gltf(400, where_ + ": its Draco stream has a malformed number in its header");
  }
  void skip(std::size_t n) {
    if (n > size_ - at_) refuse_gltf(400, where_ + ": its Draco stream ends inside its metadata");
    at_ += n;
  }
  // Metadata (spec 4.4-4.6): entries of short keys and values, nested.
  void metadata_element(int depth) {
    if (depth > 32) refuse_gltf(422, where_ + ": its Draco metadata nests deeper than 32");
    const std::uint32_t entries = varint();
    for (std::uint32_t i = 0; i < entries; ++i) {
      skip(byte());
      skip(byte());
    }
    const std::uint32_t children = varint();
    for (std::uint32_t i = 0; i < children; ++i) {
      skip(byte());
      metadata_element(depth + 1);
    }
  }

 private:
  const unsigned char* data_;
  std::size_t size_, at_ = 0;
  std::string where_;
};

struct DracoCounts {
  int method = 0;              ///< 0 sequential, 1 edgebreaker
  std::uint32_t faces = 0;
  std::uint32_t vertices = 0;  ///< points (sequential) or encoded vertices (edgebreaker)
  /// Edgebreaker: attributes with seams of their own, each a corner table
  /// the decoder builds before any value is read.
  std::uint32_t attribute_seams = 0;
};

DracoCounts read_header(const unsigned char* data, std::size_t size, const std::string& where) {
  HeaderReader in(data, size, where);
  char magic[5];
  for (char& c : magic) c = char(in.byte());
  if (std::memcmp(magic, "DRACO", 5) != 0) refuse_gltf(400, where + ": its buffer view does not hold a Draco stream");
  const int major = in.byte(), minor = in.byte();
  const int encoder_type = in.byte(), method = in.byte();
  const std::uint16_t flags = std::uint16_t(in.byte() | (in.byte() << 8));
  // Draco 1.4 and later write 2.2; older streams lay out their header
  // otherwise, and are refused rather than guessed at.
  if (major != 2 || minor != 2)
    refuse_gltf(422, where + ": Draco bitstream version " + std::to_string(major) + "." + std::to_string(minor) +
                         " is not read (2.2 is, as Draco 1.4 and later write it): re-encode the model");
  if (encoder_type != 1) refuse_gltf(422, where + ": the Draco stream is a point cloud, not a triangle mesh");
  if (flags & 0x8000) {
    const std::uint32_t attribute_metadata = in.varint();
    for (std::uint32_t i = 0; i < attribute_metadata; ++i) {
      in.varint();
      in.metadata_element(0);
    }
    in.metadata_element(0);
  }
  DracoCounts counts;
  counts.method = method;
  if (method == 0) {  // sequential
    counts.faces = in.varint();
    counts.vertices = in.varint();
  } else if (method == 1) {  // edgebreaker
    in.byte();               // traversal type
    counts.vertices = in.varint();
    counts.faces = in.varint();
    counts.attribute_seams = in.byte();
  } else {
    refuse_gltf(400, where + ": Draco encoder method " + std::to_string(method) + " is unknown");
  }
  return counts;
}

// A Draco decoder (`Base`: edgebreaker or sequential) that counts what its
// attributes will hold before it decodes them: Draco decodes every
// attribute its stream holds, declared in the glTF or not, each of up to
// 255 components of up to 8 bytes (a red-team pass made a small file
// decode 4.9 GB of undeclared attributes). The attributes' kinds are known
// once the stream's attribute headers are read (DecodePointAttributes),
// before DecodeAllAttributes allocates their values.
template <class Base>
class CountedDecoder : public Base {
 public:
  CountedDecoder(DecodeBudget& budget, std::uint64_t entries, std::string where)
      : budget_(budget), entries_(entries), where_(std::move(where)) {}
  /// Set when the count refused the stream (the decode then failed).
  std::optional<GltfRefusal> refusal;

 protected:
  bool DecodeAllAttributes() override {
    const draco::PointCloud* cloud = this->point_cloud();
    const std::uint64_t entries = std::max<std::uint64_t>(entries_, cloud->num_points());
    std::uint64_t bytes = 0;
    for (int i = 0; i < cloud->num_attributes(); ++i) {
      const draco::PointAttribute* a = cloud->attribute(i);
      // Each value decoded as it is and once in its portable (integer) form.
      const std::uint64_t width = std::max<std::uint64_t>(4, std::uint64_t(draco::DataTypeLength(a->data_type())));
      bytes += entries * std::uint64_t(a->num_components()) * width * 2;
    }
    try {
      budget_.spend(bytes, where_ + " (its Draco stream's " + std::to_string(cloud->num_attributes()) + " attributes)");
    } catch (const GltfRefusal& r) {
      refusal = r;
      return false;
    }
    return Base::DecodeAllAttributes();
  }

 private:
  DecodeBudget& budget_;
  std::uint64_t entries_;
  std::string where_;
};

template <class Base>
std::unique_ptr<draco::Mesh> decode_counted(const unsigned char* stream, std::size_t size, std::uint64_t entries,
                                            DecodeBudget& budget, const std::string& where) {
  draco::DecoderBuffer input;
  input.Init(reinterpret_cast<const char*>(stream), size);
  CountedDecoder<Base> decoder(budget, entries, where);
  auto mesh = std::make_unique<draco::Mesh>();
  const draco::DecoderOptions options;
  const draco::Status status = decoder.Decode(options, &input, mesh.get());
  if (decoder.refusal) throw *decoder.refusal;
  if (!status.ok()) refuse_gltf(400, where + ": its Draco stream does not decode: " + status.error_msg_string());
  return mesh;
}

}  // namespace

void prepare_draco(json& document, CompressedParts& parts) {
  if (!document.contains("meshes") || !document["meshes"].is_array() || !document.contains("accessors")) return;
  json& accessors = document["accessors"];
  for (std::size_t m = 0; m < document["meshes"].size(); ++m) {
    json& mesh = document["meshes"][m];
    if (!mesh.is_object() || !mesh.contains("primitives") || !mesh["primitives"].is_array()) continue;
    for (std::size_t p = 0; p < mesh["primitives"].size(); ++p) {
      json& primitive = mesh["primitives"][p];
      if (!primitive.is_object() || !primitive.contains("extensions") || !primitive["extensions"].is_object() ||
          !primitive["extensions"].contains(kName))
        continue;
      const std::string where = "meshes[" + std::to_string(m) + "].primitives[" + std::to_string(p) + "]";
      const json& ext = primitive["extensions"][kName];
      if (!ext.is_object() || !ext.contains("bufferView") || !ext["bufferView"].is_number_unsigned())
        refuse_gltf(400, where + ".extensions." + kName + ".bufferView: is required, a buffer view's index");
      DracoPrimitive d;
      d.mesh = m;
      d.primitive = p;
      d.view = ext["bufferView"].get<std::size_t>();
      if (!ext.contains("attributes") || !ext["attributes"].is_object())
        refuse_gltf(400, where + ".extensions." + kName + ".attributes: is required, an object");
      for (const auto& [name, id] : ext["attributes"].items()) {
        if (!id.is_number_unsigned() || id.get<std::uint64_t>() > std::numeric_limits<std::uint32_t>::max())
          refuse_gltf(400, where + ".extensions." + kName + ".attributes." + name + ": must be a Draco attribute id");
        d.attributes[name] = id.get<std::uint32_t>();
      }
      // Its accessors have no buffer view: tinygltf refuses an index
      // accessor without one, so each gets a one-byte placeholder until
      // decode_draco gives it the decoded data.
      std::vector<const json*> ids;
      if (primitive.contains("indices")) ids.push_back(&primitive["indices"]);
      if (primitive.contains("attributes") && primitive["attributes"].is_object())
        for (const auto& item : primitive["attributes"].items()) ids.push_back(&item.value());
      for (const json* id : ids) {
        if (!id->is_number_unsigned() || !accessors.is_array() || id->get<std::size_t>() >= accessors.size()) continue;
        json& accessor = accessors[id->get<std::size_t>()];
        if (!accessor.is_object() || accessor.contains("bufferView")) continue;
        if (parts.placeholder_view < 0) {
          json& buffers = document["buffers"];
          json& views = document["bufferViews"];
          if (!buffers.is_array()) buffers = json::array();
          if (!views.is_array()) views = json::array();
          buffers.push_back({{"uri", "data:application/octet-stream;base64,AA=="}, {"byteLength", 1}});
          views.push_back({{"buffer", buffers.size() - 1}, {"byteLength", 1}});
          parts.placeholder_view = int(views.size() - 1);
        }
        accessor["bufferView"] = parts.placeholder_view;
      }
      parts.draco_primitives.push_back(std::move(d));
    }
  }
}

void decode_draco(tinygltf::Model& model, const CompressedParts& parts, const std::vector<bool>& meshes,
                  DecodeBudget& budget) {
  std::set<int> decoded;  // accessors given decoded data
  for (const DracoPrimitive& d : parts.draco_primitives) {
    if (d.mesh >= meshes.size() || !meshes[d.mesh]) continue;
    const std::string where = "meshes[" + std::to_string(d.mesh) + "].primitives[" + std::to_string(d.primitive) + "]";
    // Found in the JSON; tinygltf may have dropped what it could not read.
    if (d.mesh >= model.meshes.size() || d.primitive >= model.meshes[d.mesh].primitives.size())
      refuse_gltf(400, where + ": not a primitive tinygltf could read (its attributes?)");
    tinygltf::Primitive& primitive = model.meshes[d.mesh].primitives[d.primitive];
    // Points and lines cast no shadow: the loader skips them, compressed or not.
    if (primitive.mode != TINYGLTF_MODE_TRIANGLES) {
      if (primitive.mode == TINYGLTF_MODE_TRIANGLE_STRIP || primitive.mode == TINYGLTF_MODE_TRIANGLE_FAN)
        refuse_gltf(422, where + ": a Draco primitive must be TRIANGLES (mode 4), as the extension requires");
      continue;
    }
    if (primitive.indices < 0) refuse_gltf(400, where + ": a Draco primitive needs its indices accessor");
    if (d.view >= model.bufferViews.size())
      refuse_gltf(400, where + ".extensions." + kName + ".bufferView: " + std::to_string(d.view) + " is out of range");
    const tinygltf::BufferView& view = model.bufferViews[d.view];
    if (view.buffer < 0 || std::size_t(view.buffer) >= model.buffers.size())
      refuse_gltf(400, where + ": its Draco buffer view's buffer is out of range");
    const std::vector<unsigned char>& buffer = model.buffers[std::size_t(view.buffer)].data;
    if (view.byteOffset > buffer.size() || view.byteLength > buffer.size() - view.byteOffset)
      refuse_gltf(400, where + ": its Draco buffer view runs past the end of its buffer");
    const unsigned char* stream = buffer.data() + view.byteOffset;

    // The counts, from the header, against the accessors' (bounded by the
    // loader before anything was decoded).
    const auto accessor_count = [&](int id) -> std::size_t {
      if (id < 0 || std::size_t(id) >= model.accessors.size()) refuse_gltf(400, where + ": accessor " + std::to_string(id) + " is out of range");
      return model.accessors[std::size_t(id)].count;
    };
    const auto position = primitive.attributes.find("POSITION");
    if (position == primitive.attributes.end()) refuse_gltf(422, where + ": no POSITION attribute");
    const std::size_t corners = accessor_count(primitive.indices), points = accessor_count(position->second);
    const DracoCounts counts = read_header(stream, view.byteLength, where);
    if (std::uint64_t(counts.faces) * 3 != corners)
      refuse_gltf(400, where + ": its Draco stream holds " + std::to_string(counts.faces) + " triangles, its indices accessor " +
                           std::to_string(corners) + " corners");
    if (counts.vertices > points)
      refuse_gltf(400, where + ": its Draco stream holds " + std::to_string(counts.vertices) +
                           " vertices, its POSITION accessor " + std::to_string(points));
    // What the decoder holds: per face its corners and their opposites,
    // per attribute with seams a corner table of its own; then the decoded
    // copy here. The attributes' values are counted by CountedDecoder once
    // the stream has said what they are.
    budget.spend(std::uint64_t(counts.faces) * 48 * (1 + std::uint64_t(counts.attribute_seams)) +
                     std::uint64_t(corners) * 4 + std::uint64_t(points) * 48,
                 where + " (its Draco stream)");
    const std::uint64_t entries = std::max<std::uint64_t>(points, counts.vertices);
    const std::unique_ptr<draco::Mesh> mesh =
        counts.method == 0
            ? decode_counted<draco::MeshSequentialDecoder>(stream, view.byteLength, entries, budget, where)
            : decode_counted<draco::MeshEdgebreakerDecoder>(stream, view.byteLength, entries, budget, where);
    if (std::uint64_t(mesh->num_faces()) * 3 != corners || mesh->num_points() != points)
      refuse_gltf(400, where + ": its Draco stream decodes to " + std::to_string(mesh->num_faces()) + " triangles and " +
                           std::to_string(mesh->num_points()) + " points, its accessors say " + std::to_string(corners / 3) +
                           " and " + std::to_string(points));

    // The decoded data, in a buffer of its own: indices as UNSIGNED_INT,
    // each attribute the loader reads as FLOAT VEC3.
    tinygltf::Buffer out;
    const auto add_view = [&](std::size_t offset, std::size_t length) {
      tinygltf::BufferView v;
      v.buffer = int(model.buffers.size());
      v.byteOffset = offset;
      v.byteLength = length;
      model.bufferViews.push_back(v);
      return int(model.bufferViews.size() - 1);
    };
    const auto point_accessor = [&](int id, int view_index, int component_type) {
      if (id < 0 || std::size_t(id) >= model.accessors.size())
        refuse_gltf(400, where + ": accessor " + std::to_string(id) + " is out of range");
      if (!decoded.insert(id).second) refuse_gltf(422, where + ": accessors[" + std::to_string(id) + "] is shared by two Draco primitives");
      tinygltf::Accessor& a = model.accessors[std::size_t(id)];
      a.bufferView = view_index;
      a.byteOffset = 0;
      a.componentType = component_type;
      a.normalized = false;
      a.sparse.isSparse = false;
    };
    out.data.resize(corners * 4);
    for (draco::FaceIndex f(0); f < mesh->num_faces(); ++f)
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t index = mesh->face(f)[k].value();
        std::memcpy(out.data.data() + (std::size_t(f.value()) * 3 + std::size_t(k)) * 4, &index, 4);
      }
    const int index_view = add_view(0, corners * 4);
    point_accessor(primitive.indices, index_view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
    // The attributes the loader reads: positions and normals, and a skin's
    // joints and weights (a skinned model compressed would else pose as if
    // unskinned: its accessors have no data of their own).
    struct Read {
      const char* name;
      int components;
      bool joints;  // written as UNSIGNED_SHORT, else FLOAT
    };
    for (const Read& read : {Read{"POSITION", 3, false}, Read{"NORMAL", 3, false}, Read{"JOINTS_0", 4, true},
                             Read{"WEIGHTS_0", 4, false}}) {
      const char* name = read.name;
      const auto attribute = primitive.attributes.find(name);
      const auto id = d.attributes.find(name);
      if (attribute == primitive.attributes.end() || id == d.attributes.end()) continue;
      const draco::PointAttribute* source = mesh->GetAttributeByUniqueId(id->second);
      if (!source) refuse_gltf(400, where + ": its Draco stream has no attribute " + std::to_string(id->second) + " for " + name);
      if (source->num_components() != read.components)
        refuse_gltf(400, where + ": its Draco " + name + " has " + std::to_string(source->num_components()) +
                             " components, not " + std::to_string(read.components));
      const std::size_t element = std::size_t(read.components) * (read.joints ? 2 : 4);
      const std::size_t offset = out.data.size();
      out.data.resize(offset + points * element);
      for (draco::PointIndex i(0); i < mesh->num_points(); ++i) {
        float value[4] = {0, 0, 0, 0};
        const draco::AttributeValueIndex at = source->mapped_index(i);
        const bool converted = read.components == 3 ? source->ConvertValue<float, 3>(at, value)
                                                    : source->ConvertValue<float, 4>(at, value);
        if (at.value() >= source->size() || !converted)
          refuse_gltf(400, where + ": its Draco " + name + " does not convert to numbers");
        unsigned char* to = out.data.data() + offset + std::size_t(i.value()) * element;
        if (read.joints) {
          for (int c = 0; c < 4; ++c) {
            if (!(value[c] >= 0.0f && value[c] <= 65535.0f))
              refuse_gltf(400, where + ": its Draco " + name + " holds a joint index that is not one");
            const std::uint16_t joint = std::uint16_t(value[c]);
            std::memcpy(to + 2 * c, &joint, 2);
          }
        } else {
          std::memcpy(to, value, element);
        }
      }
      point_accessor(attribute->second, add_view(offset, points * element),
                     read.joints ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT : TINYGLTF_COMPONENT_TYPE_FLOAT);
    }
    model.buffers.push_back(std::move(out));
  }
}

}  // namespace umbra
