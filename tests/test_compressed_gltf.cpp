// Compressed glTF as people's tools write it: Debian's gltfpack
// (KHR_mesh_quantization, EXT_meshopt_compression) and draco_transcoder
// (KHR_draco_mesh_compression) run here on a real CAD model written by
// others (the two-cylinder engine in Debian's assimp-testmodels), and the
// Draco file assimp-testmodels ships. Each variant must hold the same
// triangles as its uncompressed source, within the quantization step, and
// cast the same shadows (the exact ray cast, point for point).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <unistd.h>

#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include "assets/gltf_loader.hpp"
#include "core/model_rig.hpp"
#include "gltf_builder.hpp"
#include "core/request.hpp"
#include "reference/ray_cast.hpp"
#include "reference/sun_hours_ray_cast.hpp"

namespace umbra {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

const fs::path kModels = "/usr/share/assimp/models/glTF2";
const fs::path kEngine = kModels / "2CylinderEngine-glTF-Binary/2CylinderEngine.glb";

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

LoadResult load_file(const fs::path& path) {
  LoadOptions options;
  if (path.extension() == ".gltf") options.external_folder = path.parent_path().string();
  return load_gltf(read_file(path), options);
}

// The tools and the source, installed by scripts/install-deps.sh: missing,
// the test fails naming them (never a silent skip).
bool have_tools() {
  const bool ok = fs::exists(kEngine) && std::system("command -v gltfpack >/dev/null") == 0 &&
                  std::system("command -v draco_transcoder >/dev/null") == 0;
  EXPECT_TRUE(ok) << "needs Debian's gltfpack, draco (draco_transcoder) and assimp-testmodels: "
                     "bash scripts/install-deps.sh installs them";
  return ok;
}

// A fresh folder for this run's variants.
fs::path variants_folder() {
  const fs::path dir = fs::temp_directory_path() / ("umbra-compressed-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

fs::path run_tool(const std::string& command, const fs::path& out) {
  const std::string line = command + " > /dev/null 2>&1";
  EXPECT_EQ(std::system(line.c_str()), 0) << line;
  EXPECT_TRUE(fs::exists(out)) << line;
  return out;
}

double total_area(const TriangleModel& m) {
  double area = 0.0;
  for (const ModelPart& part : m.parts)
    for (std::size_t t = 0; t + 2 < part.indices.size(); t += 3) {
      const glm::dvec3 a(part.positions[part.indices[t]]), b(part.positions[part.indices[t + 1]]),
          c(part.positions[part.indices[t + 2]]);
      area += 0.5 * glm::length(glm::cross(b - a, c - a));
    }
  return area;
}

// The share of points on a grid under the model whose ray towards a low
// sun is blocked by one model and not the other: the shadows compared by
// the exact ray cast (analytic double precision and Embree, as the exact
// output and the sun-hours analysis cast them).
double shadow_difference(const std::shared_ptr<const TriangleModel>& a, const std::shared_ptr<const TriangleModel>& b) {
  const auto scene_of = [](const std::shared_ptr<const TriangleModel>& model) {
    Scene scene;
    SceneObject o;
    o.type = SceneObject::Type::Mesh;
    o.model = model;
    scene.objects.push_back(o);
    return scene;
  };
  const Scene sa = scene_of(a), sb = scene_of(b);
  const RayScene ra(sa), rb(sb);
  const glm::dvec3 sun = glm::normalize(glm::dvec3(0.35, 1.0, 0.2));
  const Aabb box = a->bounds;
  const double floor = box.min.y - 1.0;
  int differ = 0, points = 0, shadowed = 0;
  for (int i = 0; i < 200; ++i)
    for (int j = 0; j < 200; ++j) {
      const glm::dvec3 p(box.min.x - 200.0 + (box.max.x - box.min.x + 200.0) * (i + 0.5) / 200.0, floor,
                         box.min.z - 200.0 + (box.max.z - box.min.z + 200.0) * (j + 0.5) / 200.0);
      const bool lit = sees_sun(ra, p, sun);
      differ += lit != sees_sun(rb, p, sun) ? 1 : 0;
      shadowed += lit ? 0 : 1;
      ++points;
    }
  // The model's shadow covers a good part of the grid: the comparison
  // means something.
  EXPECT_GT(double(shadowed) / points, 0.1);
  return double(differ) / points;
}

void expect_same_model(const LoadResult& variant, const LoadResult& source, double step, const std::string& name,
                       bool same_triangles = true) {
  ASSERT_TRUE(variant.ok()) << name << ": " << variant.status << " " << variant.error;
  ASSERT_TRUE(source.ok()) << source.error;
  if (same_triangles) {
    EXPECT_EQ(variant.model->triangle_count(), source.model->triangle_count()) << name;
  }
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(variant.model->bounds.min[k], source.model->bounds.min[k], step) << name;
    EXPECT_NEAR(variant.model->bounds.max[k], source.model->bounds.max[k], step) << name;
  }
  EXPECT_NEAR(total_area(*variant.model), total_area(*source.model), 0.002 * total_area(*source.model)) << name;
  // Edges move by up to a quantization step: a few points along the
  // shadow's outline may change, nothing else.
  EXPECT_LT(shadow_difference(variant.model, source.model), 0.002) << name;
}

TEST(CompressedGltf, GltfpackVariantsHoldTheSameTriangles) {
  if (!have_tools()) return;
  const fs::path dir = variants_folder();
  const std::string in = " -i " + kEngine.string() + " -o ";
  // gltfpack welds and drops degenerate triangles: its own plain output
  // (-noq: no quantization, no compression) is the source to compare with.
  const LoadResult plain = load_file(run_tool("gltfpack" + in + (dir / "plain.glb").string() + " -noq", dir / "plain.glb"));
  ASSERT_TRUE(plain.ok()) << plain.error;
  const Aabb& b = plain.model->bounds;
  const double extent = std::max({b.max.x - b.min.x, b.max.y - b.min.y, b.max.z - b.min.z});
  // Positions quantized to 14 bits of the extent by default.
  const double step = extent / (1 << 14) * 2.0;
  struct Variant {
    const char* name;
    const char* flags;
    double step;
  };
  for (const Variant& v : {Variant{"quantized", "", step}, Variant{"meshopt", " -cc", step},
                           Variant{"meshopt-float", " -cc -noq", 1e-6 * extent}, Variant{"meshopt-c", " -c", step},
                           // -cf: the fallback buffer as a .fallback.bin beside the file, which an
                           // upload does not carry and a decoder never needs.
                           Variant{"meshopt-fallback-file", " -cc -cf", step}}) {
    const fs::path out = dir / (std::string(v.name) + ".glb");
    expect_same_model(load_file(run_tool("gltfpack" + in + out.string() + v.flags, out)), plain, v.step, v.name);
  }
  fs::remove_all(dir);
}

TEST(CompressedGltf, DracoVariantsHoldTheSameTriangles) {
  if (!have_tools()) return;
  const fs::path dir = variants_folder();
  const LoadResult source = load_file(kEngine);
  ASSERT_TRUE(source.ok()) << source.error;
  const Aabb& b = source.model->bounds;
  const double extent = std::max({b.max.x - b.min.x, b.max.y - b.min.y, b.max.z - b.min.z});
  // draco_transcoder quantizes positions to 11 bits by default; Draco
  // drops degenerate triangles (the source's area is the same).
  const fs::path out = dir / "draco.glb";
  const LoadResult draco = load_file(run_tool("draco_transcoder -i " + kEngine.string() + " -o " + out.string(), out));
  expect_same_model(draco, source, extent / (1 << 11) * 2.0, "draco_transcoder", false);
  // The Draco file Debian ships (written by another Draco encoder, with
  // an external .bin): the same model.
  const LoadResult shipped = load_file(kModels / "draco/2CylinderEngine.gltf");
  expect_same_model(shipped, source, extent / (1 << 11) * 2.0, "assimp-testmodels draco", false);
  // 14-bit positions: closer still.
  const fs::path fine = dir / "draco14.glb";
  const LoadResult draco14 =
      load_file(run_tool("draco_transcoder -qp 14 -i " + kEngine.string() + " -o " + fine.string(), fine));
  expect_same_model(draco14, source, extent / (1 << 14) * 2.0, "draco_transcoder -qp 14", false);
  fs::remove_all(dir);
}


// --- Hostile variants of real compressed files -----------------------------

const fs::path kBox = kModels / "BoxTextured-glTF-Binary/BoxTextured.glb";

// A GLB's JSON and binary chunk, and back.
struct Glb {
  nlohmann::json json;
  std::string bin;
};
Glb split(const std::string& bytes) {
  std::uint32_t json_length = 0, bin_length = 0;
  std::memcpy(&json_length, bytes.data() + 12, 4);
  std::memcpy(&bin_length, bytes.data() + 20 + json_length, 4);
  return {nlohmann::json::parse(bytes.substr(20, json_length)), bytes.substr(28 + json_length, bin_length)};
}
std::string join(const Glb& glb) {
  std::string json = glb.json.dump(), bin = glb.bin;
  while (json.size() % 4) json += ' ';
  while (bin.size() % 4) bin += '\0';
  std::string out = "glTF";
  const auto u32 = [&](std::uint32_t v) { out.append(reinterpret_cast<const char*>(&v), 4); };
  u32(2);
  u32(std::uint32_t(28 + json.size() + bin.size()));
  u32(std::uint32_t(json.size()));
  u32(0x4E4F534A);
  out += json;
  u32(std::uint32_t(bin.size()));
  u32(0x004E4942);
  return out + bin;
}

void expect_refused(const Glb& glb, int status, const std::string& expected, LoadOptions options = {}) {
  const LoadResult r = load_gltf(join(glb), options);
  ASSERT_FALSE(r.ok()) << "loaded, but expected: " << expected;
  EXPECT_EQ(r.status, status) << r.error;
  EXPECT_NE(r.error.find(expected), std::string::npos) << r.error;
}

TEST(CompressedGltf, MeshoptBombsAndBrokenStreamsAreRefused) {
  if (!have_tools()) return;
  const fs::path dir = variants_folder();
  const fs::path out = run_tool("gltfpack -i " + kBox.string() + " -o " + (dir / "box.glb").string() + " -cc",
                                dir / "box.glb");
  const Glb box = split(read_file(out));
  fs::remove_all(dir);
  ASSERT_TRUE(load_gltf(join(box), {}).ok());
  int fallback = -1;
  for (std::size_t b = 0; b < box.json["buffers"].size(); ++b)
    if (box.json["buffers"][b].contains("extensions")) fallback = int(b);
  ASSERT_GE(fallback, 0);
  // A fallback buffer that claims 4 GB: refused before it is allocated,
  // naming the decoded size.
  Glb bomb = box;
  bomb.json["buffers"][std::size_t(fallback)]["byteLength"] = 4000000000u;
  expect_refused(bomb, 422, "(a meshopt fallback buffer) decodes to about 3814 MiB, over the 32 MiB");
  // The budget, at most max_decoded_bytes.
  LoadOptions tight;
  tight.max_decoded_bytes = 16;
  expect_refused(box, 422, "(a meshopt fallback buffer) decodes to about 0 MiB, over the 0 MiB", tight);
  // Views decoding over each other (copies of one compressed view): the
  // bytes past the fallback buffer's length are charged (a red-team pass:
  // 5000 views of 16 MB from one source, 24 s of CPU for a 1.1 MB upload).
  Glb overlapping = box;
  std::size_t compressed_view = 0;
  for (std::size_t v = 0; v < box.json["bufferViews"].size(); ++v)
    if (box.json["bufferViews"][v].contains("extensions")) compressed_view = v;
  const json copy = box.json["bufferViews"][compressed_view];
  for (int k = 0; k < 4000; ++k) overlapping.json["bufferViews"].push_back(copy);
  ASSERT_TRUE(load_gltf(join(box), tight).status == 422);
  LoadOptions room;
  room.max_decoded_bytes = std::uint64_t(box.json["buffers"][std::size_t(fallback)]["byteLength"]) + 4096;
  ASSERT_TRUE(load_gltf(join(box), room).ok());
  expect_refused(overlapping, 422, "(meshopt views decoding over each other) decodes to about", room);
  // A compressed view whose bytes are cut short: the decoder says so.
  Glb cut = box;
  for (auto& view : cut.json["bufferViews"])
    if (view.contains("extensions")) view["extensions"]["EXT_meshopt_compression"]["byteLength"] = 4;
  expect_refused(cut, 400, "meshopt-compressed bytes do not decode");
  // Or lie outside their buffer.
  Glb outside = box;
  for (auto& view : outside.json["bufferViews"])
    if (view.contains("extensions")) view["extensions"]["EXT_meshopt_compression"]["byteOffset"] = 1u << 30;
  expect_refused(outside, 400, "are not inside buffers[");
  // A mode that is not one.
  Glb mode = box;
  for (auto& view : mode.json["bufferViews"])
    if (view.contains("extensions")) view["extensions"]["EXT_meshopt_compression"]["mode"] = "VOXELS";
  expect_refused(mode, 400, ".mode: must be");
  // More elements than the view holds.
  Glb count = box;
  for (auto& view : count.json["bufferViews"])
    if (view.contains("extensions")) view["extensions"]["EXT_meshopt_compression"]["count"] = 1u << 30;
  expect_refused(count, 400, "do not fit the view's byteLength");
}

// A Draco stream's header with the given counts (bitstream 2.2,
// edgebreaker), and junk after it.
std::string draco_header(std::uint32_t vertices, std::uint32_t faces, int major = 2, int minor = 2) {
  std::string s = "DRACO";
  s += char(major);
  s += char(minor);
  s += char(1);  // a triangle mesh
  s += char(1);  // edgebreaker
  s += std::string(2, '\0');
  s += char(0);  // traversal
  for (std::uint32_t v : {vertices, faces}) {
    do {
      s += char((v & 0x7f) | (v >= 0x80 ? 0x80 : 0));
      v >>= 7;
    } while (v);
  }
  return s + std::string(16, char(0x5a));
}

// The box as draco_transcoder writes it.
Glb draco_box() {
  const fs::path dir = variants_folder();
  const fs::path out = run_tool("draco_transcoder -i " + kBox.string() + " -o " + (dir / "box.glb").string(),
                                dir / "box.glb");
  Glb box = split(read_file(out));
  fs::remove_all(dir);
  return box;
}

TEST(CompressedGltf, DracoBombsAndBrokenStreamsAreRefusedBeforeDecoding) {
  if (!have_tools()) return;
  const Glb box = draco_box();
  ASSERT_TRUE(load_gltf(join(box), {}).ok());
  const nlohmann::json& ext = box.json["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"];
  const std::size_t view = ext["bufferView"];
  const std::size_t indices = box.json["meshes"][0]["primitives"][0]["indices"];
  const auto with_stream = [&](const std::string& stream) {
    Glb g = box;
    g.json["bufferViews"][view]["byteOffset"] = g.bin.size();
    g.json["bufferViews"][view]["byteLength"] = stream.size();
    g.bin += stream;
    g.json["buffers"][0]["byteLength"] = g.bin.size();
    return g;
  };
  const std::size_t corners = box.json["accessors"][indices]["count"];
  // A header claiming a quarter of a billion triangles: refused from the
  // header, nothing decoded.
  expect_refused(with_stream(draco_header(8, 0x0fffffff)), 400, "holds 268435455 triangles, its indices accessor");
  // ... and with accessors that agree: the loader's own limit, before any
  // decoding (the accessors' counts are what it bounds and admits).
  Glb agreed = with_stream(draco_header(8, 0x0fffffff));
  agreed.json["accessors"][indices]["count"] = 3u * 0x0fffffffu;
  expect_refused(agreed, 422, "triangles");
  // More vertices than the POSITION accessor holds.
  expect_refused(with_stream(draco_header(1u << 30, std::uint32_t(corners / 3))), 400, "vertices, its POSITION accessor");
  // An old bitstream: valid, not read, and said so.
  expect_refused(with_stream(draco_header(8, std::uint32_t(corners / 3), 2, 1)), 422, "Draco bitstream version 2.1");
  // Consistent counts, junk after them: Draco's own error.
  expect_refused(with_stream(draco_header(8, std::uint32_t(corners / 3))), 400, "its Draco stream does not decode");
  // Not Draco at all; cut inside the header.
  expect_refused(with_stream("PNG..........."), 400, "does not hold a Draco stream");
  expect_refused(with_stream("DRACO\x02\x02\x01\x01"), 400, "ends inside its header");
  // A Draco primitive tinygltf drops (its "attributes" misspelt): found
  // by fuzzing, it was read past the end of the mesh's primitives.
  Glb misspelt = box;
  json& primitive = misspelt.json["meshes"][0]["primitives"][0];
  primitive["attribuets"] = primitive["attributes"];
  primitive.erase("attributes");
  expect_refused(misspelt, 400, "meshes[0].primitives[0]: not a primitive tinygltf could read");
  // A Draco attribute whose accessor is out of range (tinygltf lets it
  // pass): found by fuzzing, it was written past the accessors.
  Glb out_of_range = box;
  out_of_range.json["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = 99;
  expect_refused(out_of_range, 400, "meshes[0].primitives[0].attributes.NORMAL: accessor 99 is out of range");
  // A budget smaller than the decoded box.
  LoadOptions tight;
  tight.max_decoded_bytes = 64;
  expect_refused(box, 422, "(its Draco stream) decodes to about", tight);
}

// A Draco stream of `points` points in a fan of triangles, its positions
// and `extra` undeclared attributes of 255 byte components each: what a
// glTF's extension does not name is decoded all the same.
std::string draco_stream_with_undeclared(int points, int extra, int& position_id) {
  draco::Mesh mesh;
  mesh.set_num_points(std::uint32_t(points));
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false, 12, 0);
  const int p = mesh.AddAttribute(position, true, std::uint32_t(points));
  for (int i = 0; i < points; ++i) {
    const float v[3] = {float(i % 50), float(i / 50), float((i * 7) % 3)};
    mesh.attribute(p)->SetAttributeValue(draco::AttributeValueIndex(i), v);
  }
  const std::vector<std::int8_t> zeros(255, 0);
  for (int a = 0; a < extra; ++a) {
    draco::GeometryAttribute generic;
    generic.Init(draco::GeometryAttribute::GENERIC, nullptr, 255, draco::DT_INT8, false, 255, 0);
    const int g = mesh.AddAttribute(generic, true, std::uint32_t(points));
    for (int i = 0; i < points; ++i) mesh.attribute(g)->SetAttributeValue(draco::AttributeValueIndex(i), zeros.data());
  }
  for (int i = 0; i + 2 < points; ++i)
    mesh.AddFace({draco::PointIndex(0), draco::PointIndex(std::uint32_t(i + 1)), draco::PointIndex(std::uint32_t(i + 2))});
  position_id = int(mesh.attribute(p)->unique_id());
  draco::Encoder encoder;
  encoder.SetEncodingMethod(draco::MESH_SEQUENTIAL_ENCODING);
  draco::EncoderBuffer buffer;
  EXPECT_TRUE(encoder.EncodeMeshToBuffer(mesh, &buffer).ok());
  return std::string(buffer.data(), buffer.size());
}

// A red-team pass: Draco decodes every attribute of its stream, declared
// or not, and a small file decoded 4.9 GB of undeclared ones. They are
// counted against the budget before their values are decoded.
TEST(CompressedGltf, DracoCountsTheAttributesItsStreamHoldsUndeclared) {
  if (!have_tools()) return;
  const Glb box = draco_box();
  const auto with_stream = [&](int points, int extra) {
    int position_id = 0;
    const std::string stream = draco_stream_with_undeclared(points, extra, position_id);
    Glb g = box;
    json& primitive = g.json["meshes"][0]["primitives"][0];
    json& ext = primitive["extensions"]["KHR_draco_mesh_compression"];
    const std::size_t view = ext["bufferView"];
    g.json["bufferViews"][view]["byteOffset"] = g.bin.size();
    g.json["bufferViews"][view]["byteLength"] = stream.size();
    g.bin += stream;
    g.json["buffers"][0]["byteLength"] = g.bin.size();
    ext["attributes"] = {{"POSITION", position_id}};
    for (auto it = primitive["attributes"].begin(); it != primitive["attributes"].end();)
      it = it.key() == "POSITION" ? std::next(it) : primitive["attributes"].erase(it);
    const std::size_t positions = primitive["attributes"]["POSITION"];
    g.json["accessors"][positions]["count"] = points;
    g.json["accessors"][positions]["min"] = {0, 0, 0};
    g.json["accessors"][positions]["max"] = {49, points / 50, 2};
    g.json["accessors"][std::size_t(primitive["indices"])]["count"] = 3 * (points - 2);
    return g;
  };
  LoadOptions budget;
  budget.max_decoded_bytes = std::uint64_t(16) << 20;
  // The positions alone decode within the budget...
  const LoadResult plain = load_gltf(join(with_stream(2000, 0)), budget);
  ASSERT_TRUE(plain.ok()) << plain.error;
  EXPECT_EQ(plain.model->triangle_count(), 1998u);
  // ... and 20 undeclared attributes of 255 bytes a point (about 10 MB
  // decoded as bytes, twice that as integers) are refused before decoding.
  expect_refused(with_stream(2000, 20), 422, "(its Draco stream's 21 attributes) decodes to about", budget);
}

// A skinned, animated model through draco_transcoder: its joints and
// weights come from the Draco stream (their accessors have no data of their
// own), so it bends as the plain file does (a review found it posed as if
// unskinned, silently).
TEST(CompressedGltf, ADracoSkinnedModelBendsAsThePlainOne) {
  if (!have_tools()) return;
  const double pi = std::acos(-1.0);
  const fs::path dir = variants_folder();
  {
    std::ofstream(dir / "skin.glb", std::ios::binary) << test::bending_strip(float(pi / 2));
  }
  const LoadResult plain = load_file(dir / "skin.glb");
  const LoadResult draco =
      load_file(run_tool("draco_transcoder -i " + (dir / "skin.glb").string() + " -o " + (dir / "draco.glb").string(),
                         dir / "draco.glb"));
  fs::remove_all(dir);
  ASSERT_TRUE(plain.ok()) << plain.error;
  ASSERT_TRUE(draco.ok()) << draco.error;
  ASSERT_TRUE(draco.model->rig);
  EXPECT_EQ(draco.model->rig->primitives.at(0).skin, 0);
  // Bent a quarter turn at the upper joint, within Draco's quantization.
  const TriangleModel a = pose_model(*plain.model->rig, 0, 1.0), b = pose_model(*draco.model->rig, 0, 1.0);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(b.bounds.min[k], a.bounds.min[k], 2e-3) << k;
    EXPECT_NEAR(b.bounds.max[k], a.bounds.max[k], 2e-3) << k;
  }
  EXPECT_NEAR(b.bounds.min.x, -1.0, 2e-3);  // not the rest pose's -0.5
}

}  // namespace
}  // namespace umbra
