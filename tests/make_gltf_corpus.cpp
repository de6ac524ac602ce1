// Writes the fuzz seed corpus fuzz/corpus-gltf: small valid and broken
// .glb/.gltf files, made by the unit tests' builder.
//   build/tests/umbra_make_gltf_corpus fuzz/corpus-gltf
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "gltf_builder.hpp"

using umbra::test::GltfBuilder;
using json = nlohmann::json;

namespace {

GltfBuilder cube(json node = json::object(), int index_width = 32, bool normals = false) {
  GltfBuilder b;
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices;
  umbra::test::unit_cube(positions, indices);
  const int p = b.vec3s(positions);
  int i = -1;
  if (index_width == 8) i = b.indices_u8(std::vector<std::uint8_t>(indices.begin(), indices.end()));
  if (index_width == 16) i = b.indices_u16(std::vector<std::uint16_t>(indices.begin(), indices.end()));
  if (index_width == 32) i = b.indices_u32(indices);
  const int n = normals ? b.vec3s(positions) : -1;
  const int red = b.material({1, 0, 0});
  node["mesh"] = b.mesh(p, i, n, red);
  b.scene({b.node(node)});
  return b;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s FOLDER\n", argv[0]);
    return 2;
  }
  const std::filesystem::path out = argv[1];
  std::filesystem::create_directories(out);
  const auto write = [&](const std::string& name, const std::string& bytes) {
    std::ofstream(out / name, std::ios::binary) << bytes;
  };
  const auto both = [&](const std::string& name, const GltfBuilder& b) {
    write(name + ".glb", b.glb());
    write(name + ".gltf", b.gltf());
  };
  // Valid.
  both("cube-u32", cube());
  both("cube-u16-normals", cube(json::object(), 16, true));
  write("cube-u8.glb", cube(json::object(), 8).glb());
  write("cube-trs.glb", cube({{"translation", {1, 2, 3}}, {"rotation", {0, 0.7071, 0, 0.7071}}, {"scale", {-1, 2, 1}}}).glb());
  {
    GltfBuilder b = cube();
    b.doc["nodes"].push_back({{"children", {0}}, {"matrix", {2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 1, 1, 1, 1}}});
    b.doc["nodes"].push_back({{"mesh", 0}, {"translation", {3, 0, 0}}});
    b.scene({1, 2});
    both("nested-matrix-instanced", b);
  }
  for (int mode : {5, 6}) {
    GltfBuilder b;
    b.scene({b.node({{"mesh", b.mesh(b.vec3s({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}}), -1, -1, -1, mode)}})});
    write(mode == 5 ? "strip.glb" : "fan.gltf", mode == 5 ? b.glb() : b.gltf());
  }
  {
    GltfBuilder b = cube();
    b.doc.erase("scene");
    b.doc.erase("scenes");
    write("no-scene.glb", b.glb());
  }
  // Broken or refused.
  {
    GltfBuilder b = cube();
    b.doc["meshes"][0]["primitives"][0]["mode"] = 1;
    write("lines.glb", b.glb());
  }
  {
    GltfBuilder b = cube();
    b.doc["accessors"][0]["sparse"] = {{"count", 1},
                                       {"indices", {{"bufferView", 1}, {"componentType", 5125}}},
                                       {"values", {{"bufferView", 0}}}};
    write("sparse.gltf", b.gltf());
  }
  {
    GltfBuilder b = cube();
    b.doc["extensionsUsed"] = {"KHR_draco_mesh_compression"};
    b.doc["extensionsRequired"] = {"KHR_draco_mesh_compression"};
    write("draco-required.glb", b.glb());
  }
  {
    GltfBuilder b = cube();
    b.doc["accessors"][0]["count"] = 4000000000u;
    write("accessor-past-view.glb", b.glb());
    b = cube();
    b.doc["bufferViews"][0]["byteStride"] = 4;
    write("short-stride.gltf", b.gltf());
  }
  {
    GltfBuilder b = cube();
    b.doc["nodes"][0]["children"] = {0};
    write("cycle.glb", b.glb());
  }
  write("external-uri.gltf", cube().gltf_external("../outside.bin"));
  // Animated: node channels (LINEAR, STEP), a skin, a morph target.
  write("animated-cube.glb", umbra::test::sliding_cube());
  write("animated-cube-step.glb", umbra::test::sliding_cube("STEP"));
  write("skinned-strip.glb", umbra::test::bending_strip(1.5707964f));
  {
    const std::string glb = cube().glb();
    write("truncated.glb", glb.substr(0, glb.size() / 2));
  }
  {
    GltfBuilder b = cube();
    b.doc["images"] = {{{"uri", "data:image/png;base64,"}}};
    write("empty-image.gltf", b.gltf());
  }
  return 0;
}
