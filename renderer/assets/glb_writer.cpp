#include "assets/glb_writer.hpp"

#include <cstring>

#include <glm/common.hpp>
#include <nlohmann/json.hpp>

namespace umbra {

namespace {

template <class T>
std::size_t append(std::string& bin, const std::vector<T>& values) {
  while (bin.size() % 4) bin += '\0';
  const std::size_t at = bin.size();
  bin.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
  return at;
}

}  // namespace

std::string write_glb(const TriangleModel& model) {
  using json = nlohmann::json;
  json doc = {{"asset", {{"version", "2.0"}, {"generator", "Umbra"}}}};
  std::string bin;
  json primitives = json::array();
  for (const ModelPart& part : model.parts) {
    if (part.indices.empty()) continue;
    const std::size_t first = doc["bufferViews"].size();
    const std::size_t pos = append(bin, part.positions), nor = append(bin, part.normals), ind = append(bin, part.indices);
    doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", pos}, {"byteLength", part.positions.size() * 12}});
    doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", nor}, {"byteLength", part.normals.size() * 12}});
    doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", ind}, {"byteLength", part.indices.size() * 4}});
    glm::vec3 low(0.0f), high(0.0f);
    if (!part.positions.empty()) low = high = part.positions[0];
    for (const glm::vec3& p : part.positions) low = glm::min(low, p), high = glm::max(high, p);
    const std::size_t a = doc["accessors"].size();
    doc["accessors"].push_back({{"bufferView", first}, {"componentType", 5126}, {"count", part.positions.size()},
                                {"type", "VEC3"}, {"min", {low.x, low.y, low.z}}, {"max", {high.x, high.y, high.z}}});
    doc["accessors"].push_back({{"bufferView", first + 1}, {"componentType", 5126}, {"count", part.normals.size()}, {"type", "VEC3"}});
    doc["accessors"].push_back({{"bufferView", first + 2}, {"componentType", 5125}, {"count", part.indices.size()}, {"type", "SCALAR"}});
    const glm::vec3 c = part.base_color;
    doc["materials"].push_back({{"pbrMetallicRoughness", {{"baseColorFactor", {c.r, c.g, c.b, 1.0}}}}});
    json attributes = {{"POSITION", a}};
    if (part.normals.size() == part.positions.size()) attributes["NORMAL"] = a + 1;
    primitives.push_back({{"attributes", attributes}, {"indices", a + 2}, {"material", doc["materials"].size() - 1}});
  }
  while (bin.size() % 4) bin += '\0';
  doc["buffers"] = json::array({{{"byteLength", bin.size()}}});
  doc["meshes"] = json::array({{{"primitives", primitives}}});
  doc["nodes"] = json::array({{{"mesh", 0}}});
  doc["scenes"] = json::array({{{"nodes", {0}}}});
  doc["scene"] = 0;
  std::string chunk(8, '\0');
  const std::uint32_t bin_length = std::uint32_t(bin.size()), bin_type = 0x004E4942u;
  std::memcpy(chunk.data(), &bin_length, 4);
  std::memcpy(chunk.data() + 4, &bin_type, 4);
  return glb_container(doc.dump(), chunk + bin);
}

std::string glb_container(std::string json, std::string_view chunks) {
  while (json.size() % 4) json += ' ';
  std::string out = "glTF";
  const auto u32 = [&out](std::uint32_t v) { out.append(reinterpret_cast<const char*>(&v), 4); };
  u32(2);
  u32(std::uint32_t(20 + json.size() + chunks.size()));
  u32(std::uint32_t(json.size()));
  u32(0x4E4F534Au);
  out += json;
  out.append(chunks.data(), chunks.size());
  return out;
}

}  // namespace umbra
