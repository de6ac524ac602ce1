// Builds small glTF 2.0 files in code, as .gltf (JSON, the buffer as a
// data: URI) or .glb: the loader's tests and the fuzz seed corpus
// (tests/make_gltf_corpus.cpp) use it. Each call appends to buffer 0.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>
#include <nlohmann/json.hpp>

namespace umbra::test {

inline std::string base64(const std::string& bytes) {
  static const char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const std::uint32_t v = std::uint32_t(std::uint8_t(bytes[i])) << 16 | std::uint32_t(std::uint8_t(bytes[i + 1])) << 8 |
                            std::uint8_t(bytes[i + 2]);
    for (int s = 18; s >= 0; s -= 6) out += kAlphabet[(v >> s) & 63];
  }
  if (i + 1 == bytes.size()) {
    const std::uint32_t v = std::uint32_t(std::uint8_t(bytes[i])) << 16;
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += "==";
  } else if (i + 2 == bytes.size()) {
    const std::uint32_t v = std::uint32_t(std::uint8_t(bytes[i])) << 16 | std::uint32_t(std::uint8_t(bytes[i + 1])) << 8;
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += kAlphabet[(v >> 6) & 63];
    out += '=';
  }
  return out;
}

struct GltfBuilder {
  nlohmann::json doc = {{"asset", {{"version", "2.0"}}}};
  std::string bin;  ///< buffer 0

  static constexpr int kByte = 5121, kShort = 5123, kInt = 5125, kFloat = 5126;

  int push(const char* array, nlohmann::json value) {
    doc[array].push_back(std::move(value));
    return int(doc[array].size()) - 1;
  }

  /// A buffer view over `bytes` appended to buffer 0 (4-byte aligned).
  int view(const std::string& bytes, int stride = 0) {
    while (bin.size() % 4) bin += '\0';
    nlohmann::json v = {{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes.size()}};
    if (stride) v["byteStride"] = stride;
    bin += bytes;
    return push("bufferViews", v);
  }
  int accessor(int view_index, int component_type, std::size_t count, const char* type, std::size_t offset = 0) {
    nlohmann::json a = {{"bufferView", view_index}, {"componentType", component_type}, {"count", count}, {"type", type}};
    if (offset) a["byteOffset"] = offset;
    return push("accessors", a);
  }
  template <class T>
  static std::string bytes_of(const std::vector<T>& values) {
    std::string s(values.size() * sizeof(T), '\0');
    if (!values.empty()) std::memcpy(s.data(), values.data(), s.size());
    return s;
  }
  int vec3s(const std::vector<glm::vec3>& values) {
    return accessor(view(bytes_of(values)), kFloat, values.size(), "VEC3");
  }
  int indices_u8(const std::vector<std::uint8_t>& v) { return accessor(view(bytes_of(v)), kByte, v.size(), "SCALAR"); }
  int indices_u16(const std::vector<std::uint16_t>& v) { return accessor(view(bytes_of(v)), kShort, v.size(), "SCALAR"); }
  int indices_u32(const std::vector<std::uint32_t>& v) { return accessor(view(bytes_of(v)), kInt, v.size(), "SCALAR"); }

  /// A mesh of one primitive; `indices` < 0: not indexed, `normals` < 0: none.
  int mesh(int positions, int indices = -1, int normals = -1, int material = -1, int mode = 4) {
    nlohmann::json primitive = {{"attributes", {{"POSITION", positions}}}};
    if (normals >= 0) primitive["attributes"]["NORMAL"] = normals;
    if (indices >= 0) primitive["indices"] = indices;
    if (material >= 0) primitive["material"] = material;
    if (mode != 4) primitive["mode"] = mode;
    return push("meshes", {{"primitives", nlohmann::json::array({primitive})}});
  }
  int material(const glm::vec3& color) {
    return push("materials", {{"pbrMetallicRoughness", {{"baseColorFactor", {color.r, color.g, color.b, 1.0}}}}});
  }
  int node(nlohmann::json node) { return push("nodes", std::move(node)); }
  /// A scene of the given root nodes, made the default.
  void scene(const std::vector<int>& roots) {
    doc["scenes"] = nlohmann::json::array({{{"nodes", roots}}});
    doc["scene"] = 0;
  }

  nlohmann::json with_buffer(const std::string& uri_or_empty) const {
    nlohmann::json d = doc;
    if (!bin.empty() || d.contains("bufferViews")) {
      nlohmann::json buffer = {{"byteLength", bin.size()}};
      if (!uri_or_empty.empty()) buffer["uri"] = uri_or_empty;
      d["buffers"] = nlohmann::json::array({buffer});
    }
    return d;
  }
  /// A self-contained .gltf: the buffer as a data: URI.
  std::string gltf() const {
    return with_buffer("data:application/octet-stream;base64," + base64(bin)).dump();
  }
  /// A .gltf whose buffer is the external file `uri`.
  std::string gltf_external(const std::string& uri) const { return with_buffer(uri).dump(); }
  /// A .glb: JSON chunk, then the buffer as the BIN chunk.
  std::string glb() const {
    std::string json = with_buffer("").dump();
    while (json.size() % 4) json += ' ';
    std::string body = bin;
    while (body.size() % 4) body += '\0';
    std::string out = "glTF";
    const auto u32 = [&](std::uint32_t v) { out.append(reinterpret_cast<const char*>(&v), 4); };
    const bool has_bin = !bin.empty();
    u32(2);
    u32(std::uint32_t(12 + 8 + json.size() + (has_bin ? 8 + body.size() : 0)));
    u32(std::uint32_t(json.size()));
    u32(0x4E4F534A);
    out += json;
    if (has_bin) {
      u32(std::uint32_t(body.size()));
      u32(0x004E4942);
      out += body;
    }
    return out;
  }
};

/// The 8 corners and 12 counter-clockwise (outward) triangles of the box
/// [-h, h]^3, corners shared (a welded cube).
inline void unit_cube(std::vector<glm::vec3>& positions, std::vector<std::uint32_t>& indices, float h = 0.5f) {
  positions = {{-h, -h, -h}, {h, -h, -h}, {h, h, -h}, {-h, h, -h}, {-h, -h, h}, {h, -h, h}, {h, h, h}, {-h, h, h}};
  indices = {0, 3, 2, 0, 2, 1,   // -z
             4, 5, 6, 4, 6, 7,   // +z
             0, 1, 5, 0, 5, 4,   // -y
             3, 7, 6, 3, 6, 2,   // +y
             0, 4, 7, 0, 7, 3,   // -x
             1, 2, 6, 1, 6, 5};  // +x
}

/// Issue 29's hostile model: `quads` squares of edge `size` facing +Y,
/// stacked `spacing` apart (the first at y = 0), as a .glb of positions
/// only (6 a quad, not indexed; normals from the loader): 4,000 of them
/// are 288 KB, every pixel of the stack drawn 4,000 times.
inline std::string stacked_quads_glb(int quads, float size = 40.0f, float spacing = 0.0005f) {
  const float h = size / 2;
  std::vector<glm::vec3> positions;
  positions.reserve(std::size_t(quads) * 6);
  for (int i = 0; i < quads; ++i) {
    const float y = float(i) * spacing;
    for (const auto& [x, z] : {std::pair{-h, h}, {h, h}, {h, -h}, {-h, h}, {h, -h}, {-h, -h}})
      positions.push_back({x, y, z});
  }
  GltfBuilder b;
  b.scene({b.node({{"mesh", b.mesh(b.vec3s(positions))}})});
  return b.glb();
}

/// Issue 29's slivers: `count` triangles each running corner to corner
/// across a 100 x 100 square facing +Z and 1e-4 wide (almost no area), a
/// thousand side by side 1e-3 apart in each layer, layers 1e-3 apart
/// towards -Z; positions only, not indexed. llvmpipe tests each against
/// every 64 x 64 tile its bounding box covers: 200,000 across a 4096^2
/// shadow map are 8e8 tile tests, seconds, for a 9.6 MB upload.
inline std::string slivers_glb(int count) {
  std::vector<glm::vec3> positions;
  positions.reserve(std::size_t(count) * 3);
  for (int t = 0; t < count; ++t) {
    const float d = float(t % 1000) * 1e-3f, z = -float(t / 1000) * 1e-3f;
    positions.insert(positions.end(), {{-50.0f, -50.0f + d, z}, {50.0f, 50.0f + d, z}, {50.0f, 50.0f + d + 1e-4f, z}});
  }
  GltfBuilder b;
  b.scene({b.node({{"mesh", b.mesh(b.vec3s(positions))}})});
  return b.glb();
}

/// Issue 29's blinds: `quads` quads in planes x = const spread over x in
/// [-10, 10], each spanning y in [-120, 120] and z in [-10, -0.2]; positions
/// only. Seen from the origin looking down -Z they are edge on at their
/// centre, yet a wide view looks through thousands of them towards +-Y.
inline std::string blinds_glb(int quads) {
  std::vector<glm::vec3> positions;
  positions.reserve(std::size_t(quads) * 6);
  for (int i = 0; i < quads; ++i) {
    const float x = -10.0f + 20.0f * float(i) / float(std::max(1, quads - 1));
    const glm::vec3 a{x, -120, -10}, b{x, 120, -10}, c{x, 120, -0.2f}, d{x, -120, -0.2f};
    positions.insert(positions.end(), {a, b, c, a, c, d});
  }
  GltfBuilder b;
  b.scene({b.node({{"mesh", b.mesh(b.vec3s(positions))}})});
  return b.glb();
}

// A unit cube under a parent node; the parent slides +X by 4 over 2 s and
// the child turns a quarter about Y over the same time.
inline std::string sliding_cube(const std::string& interpolation = "LINEAR") {
  GltfBuilder b;
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices;
  unit_cube(positions, indices);
  const int mesh = b.mesh(b.vec3s(positions), b.indices_u32(indices));
  const int child = b.node({{"mesh", mesh}, {"translation", {1, 0, 0}}});
  const int parent = b.node({{"children", {child}}});
  b.scene({parent});
  const float h = float(std::sqrt(0.5));
  const int times = b.accessor(b.view(GltfBuilder::bytes_of(std::vector<float>{0, 2})), GltfBuilder::kFloat, 2, "SCALAR");
  const int moves = b.vec3s({{0, 0, 0}, {4, 0, 0}});
  const int turns = b.accessor(b.view(GltfBuilder::bytes_of(std::vector<float>{0, 0, 0, 1, 0, h, 0, h})),
                               GltfBuilder::kFloat, 2, "VEC4");
  b.doc["animations"] = nlohmann::json::array(
      {{{"name", "slide"},
        {"samplers", {{{"input", times}, {"output", moves}, {"interpolation", interpolation}},
                      {{"input", times}, {"output", turns}, {"interpolation", interpolation}}}},
        {"channels", {{{"sampler", 0}, {"target", {{"node", parent}, {"path", "translation"}}}},
                      {{"sampler", 1}, {"target", {{"node", child}, {"path", "rotation"}}}}}}}});
  return b.glb();
}

// Two joints along +Y: the root at the origin, the second at y = 1; a
// vertical strip of quads from y = 0 to 2, its lower half weighted to the
// root and its upper half to the second joint (the middle row half each).
// `weight_sum`: every vertex's weights scaled to sum to it (glTF asks 1;
// the loader makes them so).
inline std::string bending_strip(float turn_z, float weight_sum = 1.0f) {
  GltfBuilder b;
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices;
  std::vector<std::uint16_t> joints;
  std::vector<float> weights;
  for (int row = 0; row <= 2; ++row)
    for (int col = 0; col <= 1; ++col) {
      positions.push_back({float(col) - 0.5f, float(row), 0.0f});
      joints.insert(joints.end(), {0, 1, 0, 0});
      const float upper = row == 0 ? 0.0f : row == 1 ? 0.5f : 1.0f;
      weights.insert(weights.end(), {weight_sum * (1.0f - upper), weight_sum * upper, 0.0f, 0.0f});
    }
  for (std::uint32_t row = 0; row < 2; ++row) {
    const std::uint32_t a = row * 2, c = a + 2;
    indices.insert(indices.end(), {a, a + 1, c + 1, a, c + 1, c});
  }
  const int position_accessor = b.vec3s(positions);
  const int joint_accessor = b.accessor(b.view(GltfBuilder::bytes_of(joints)), GltfBuilder::kShort, 6, "VEC4");
  const int weight_accessor = b.accessor(b.view(GltfBuilder::bytes_of(weights)), GltfBuilder::kFloat, 6, "VEC4");
  b.doc["meshes"] = nlohmann::json::array({{{"primitives",
                                   {{{"attributes",
                                      {{"POSITION", position_accessor}, {"JOINTS_0", joint_accessor}, {"WEIGHTS_0", weight_accessor}}},
                                     {"indices", b.indices_u32(indices)}}}}}});
  const int upper = b.node({{"translation", {0, 1, 0}}});
  const int root = b.node({{"children", {upper}}});
  // The skinned node is placed far away: glTF ignores its transform.
  const int skinned = b.node({{"mesh", 0}, {"skin", 0}, {"translation", {100, 0, 0}}});
  std::vector<float> inverse_binds(32, 0.0f);
  for (int m = 0; m < 2; ++m)
    for (int d = 0; d < 4; ++d) inverse_binds[std::size_t(m * 16 + d * 5)] = 1.0f;
  inverse_binds[16 + 13] = -1.0f;  // the second joint's bind: y = 1
  b.doc["skins"] = nlohmann::json::array(
      {{{"joints", {root, upper}},
        {"inverseBindMatrices", b.accessor(b.view(GltfBuilder::bytes_of(inverse_binds)), GltfBuilder::kFloat, 2, "MAT4")}}});
  b.scene({root, skinned});
  const float s = std::sin(turn_z / 2), c = std::cos(turn_z / 2);
  const int times = b.accessor(b.view(GltfBuilder::bytes_of(std::vector<float>{0, 1})), GltfBuilder::kFloat, 2, "SCALAR");
  const int turns = b.accessor(b.view(GltfBuilder::bytes_of(std::vector<float>{0, 0, 0, 1, 0, 0, s, c})),
                               GltfBuilder::kFloat, 2, "VEC4");
  b.doc["animations"] = nlohmann::json::array({{{"samplers", {{{"input", times}, {"output", turns}}}},
                                      {"channels", {{{"sampler", 0}, {"target", {{"node", upper}, {"path", "rotation"}}}}}}}});
  return b.glb();
}

}  // namespace umbra::test
