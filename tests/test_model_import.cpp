// Other model formats through umbra-model-import (Assimp), on the files
// Debian's assimp-testmodels ships (written by other tools), and the limits
// that keep a file Assimp mishandles from reaching the server.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "assets/gltf_loader.hpp"
#include "assets/model_import.hpp"

namespace umbra {
namespace {

namespace fs = std::filesystem;

const fs::path kModels = "/usr/share/assimp/models";

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

ImportOptions importer(std::string up = "file", std::string unit = "file") {
  ImportOptions options;
  options.importer = UMBRA_MODEL_IMPORTER;
  options.up = std::move(up);
  options.unit = std::move(unit);
  return options;
}

// Converted and loaded as an upload is.
LoadResult import_and_load(const fs::path& path, const ImportOptions& options, ImportResult* imported = nullptr) {
  const std::string ext = [&] {
    std::string e = path.extension().string().substr(1);
    for (char& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
    return e;
  }();
  const ImportFormat* format = import_format_named(ext);
  EXPECT_NE(format, nullptr) << path;
  ImportResult converted = import_model(read_file(path), *format, options);
  LoadResult loaded;
  if (converted.ok()) {
    LoadOptions load;
    load.format = LoadOptions::Format::Binary;
    loaded = load_gltf(converted.glb, load);
  } else {
    loaded.status = converted.status;
    loaded.error = converted.error;
  }
  if (imported) *imported = std::move(converted);
  return loaded;
}

bool assimp_testmodels_installed() {
  const bool ok = fs::exists(kModels / "IFC/AC14-FZK-Haus.ifc");
  EXPECT_TRUE(ok) << "needs Debian's assimp-testmodels: bash scripts/install-deps.sh installs it";
  return ok;
}

TEST(ModelImport, EveryTestModelWithTrianglesLoads) {
  if (!assimp_testmodels_installed()) return;
  // Files of points or lines only: valid, nothing to cast a shadow (422).
  const std::set<std::string> no_triangles = {"point_cloud.obj", "testline.obj", "testpoints.obj", "issue623.ply",
                                              "points.ply", "pond.0.ply"};
  // Files Debian's Assimp 5.2.5 cannot read (its own parse errors): 400.
  const std::set<std::string> unreadable = {"library_animation_clips.dae", "transparentTest.fbx"};
  int loaded = 0;
  for (const char* folder : {"OBJ", "STL", "PLY", "Collada", "FBX", "3DS", "IFC"})
    for (const auto& entry : fs::directory_iterator(kModels / folder)) {
      std::string ext = entry.path().extension().string();
      for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
      if (!entry.is_regular_file() || !import_format_named(ext)) continue;
      const std::string name = entry.path().filename().string();
      const LoadResult r = import_and_load(entry.path(), importer());
      if (no_triangles.count(name)) {
        EXPECT_EQ(r.status, 422) << name << ": " << r.error;
      } else if (unreadable.count(name)) {
        EXPECT_EQ(r.status, 400) << name << ": " << r.error;
        EXPECT_NE(r.error.find("Assimp can read"), std::string::npos) << r.error;
      } else {
        ASSERT_TRUE(r.ok()) << name << ": " << r.status << " " << r.error;
        EXPECT_GT(r.model->triangle_count(), 0u) << name;
        ++loaded;
      }
    }
  EXPECT_GE(loaded, 80);
}

TEST(ModelImport, UnitsAndUpAxesAreApplied) {
  if (!assimp_testmodels_installed()) return;
  // The same spider as OBJ (no unit: as given) and FBX (in centimetres,
  // UnitScaleFactor 1: scaled to metres here): the same bounds.
  const LoadResult obj = import_and_load(kModels / "OBJ/spider.obj", importer());
  const LoadResult fbx = import_and_load(kModels / "FBX/spider.fbx", importer());
  ASSERT_TRUE(obj.ok() && fbx.ok()) << obj.error << fbx.error;
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(fbx.model->bounds.min[k], obj.model->bounds.min[k], 1e-3);
    EXPECT_NEAR(fbx.model->bounds.max[k], obj.model->bounds.max[k], 1e-3);
  }
  // The FZK house (IFC: metres, Z up, turned to Y up): two storeys and a
  // roof, about 6.3 m over its ground floor, on a 12 x 10 m plan.
  const LoadResult house = import_and_load(kModels / "IFC/AC14-FZK-Haus.ifc", importer());
  ASSERT_TRUE(house.ok()) << house.error;
  const Aabb& b = house.model->bounds;
  EXPECT_NEAR(b.max.y, 6.32, 0.05);
  EXPECT_GT(b.max.x - b.min.x, 12.0);
  EXPECT_GT(b.max.z - b.min.z, 10.0);
  EXPECT_LT(b.max.y - b.min.y, b.max.x - b.min.x);
  // Told: Z up turns (x, y, z) to (x, z, -y); millimetres scale by 1/1000.
  const LoadResult as_is = import_and_load(kModels / "3DS/fels.3ds", importer());
  const LoadResult z_up = import_and_load(kModels / "3DS/fels.3ds", importer("z"));
  const LoadResult mm = import_and_load(kModels / "3DS/fels.3ds", importer("file", "mm"));
  ASSERT_TRUE(as_is.ok() && z_up.ok() && mm.ok());
  EXPECT_NEAR(z_up.model->bounds.max.y, as_is.model->bounds.max.z, 1e-4);
  EXPECT_NEAR(z_up.model->bounds.min.z, -as_is.model->bounds.max.y, 1e-4);
  EXPECT_NEAR(mm.model->bounds.max.x, as_is.model->bounds.max.x / 1000.0, 1e-6);
}

TEST(ModelImport, TheImportersLimitsEndItNotTheServer) {
  if (!assimp_testmodels_installed()) return;
  const fs::path house = kModels / "IFC/AC14-FZK-Haus.ifc";
  // More glTF out than allowed: stopped, named.
  ImportOptions small = importer();
  small.max_output_bytes = 1000;
  EXPECT_EQ(import_and_load(house, small).error, "the IFC file converts to more than 0 MiB of glTF");
  // Too little memory for Assimp: the importer ends, the caller goes on.
  ImportOptions starved = importer();
  starved.max_memory_mib = 24;
  const LoadResult r = import_and_load(house, starved);
  EXPECT_EQ(r.status, 422) << r.error;
  EXPECT_NE(r.error.find("could not be read within 24 MiB"), std::string::npos) << r.error;
  // Garbage: Assimp's own words (a text OBJ reads anything as an empty
  // model: no triangles, 422).
  const ImportFormat& obj = *import_format_named("obj");
  const ImportResult garbage = import_model("this is no model", *import_format_named("ply"), importer());
  EXPECT_EQ(garbage.status, 400);
  EXPECT_NE(garbage.error.find("not a PLY file Assimp can read"), std::string::npos) << garbage.error;
  const ImportResult empty = import_model("this is no model", obj, importer());
  EXPECT_EQ(empty.status, 422);
  EXPECT_NE(empty.error.find("the Wavefront OBJ file has no triangles"), std::string::npos) << empty.error;
  // No importer: 503, not a crash.
  ImportOptions missing = importer();
  missing.importer = "/nonexistent/umbra-model-import";
  EXPECT_EQ(import_model("v 0 0 0", obj, missing).status, 503);
}

// Stand-in importers: one that never ends, one that exits without reading
// a large input (its pipe closed under the writer: no SIGPIPE here).
TEST(ModelImport, AHungOrVanishingImporterIsSurvived) {
  const fs::path dir = fs::temp_directory_path() / ("umbra-import-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const auto script = [&](const char* name, const char* body) {
    const fs::path path = dir / name;
    std::ofstream(path) << "#!/bin/sh\n" << body << "\n";
    fs::permissions(path, fs::perms::owner_all);
    return path.string();
  };
  const ImportFormat& stl = *import_format_named("stl");
  ImportOptions hung = importer();
  hung.importer = script("hung", "exec sleep 60");
  hung.max_seconds = 1;
  const auto start = std::chrono::steady_clock::now();
  const ImportResult waited = import_model("solid x", stl, hung);
  EXPECT_EQ(waited.status, 422);
  EXPECT_NE(waited.error.find("took longer than 2 s"), std::string::npos) << waited.error;
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(30));
  // A client that has gone: the importer is ended within about a second
  // of its first question (a hung one here; the wall limit is a minute).
  ImportOptions left = importer();
  left.importer = hung.importer;
  int asked = 0;
  left.stop = [&asked] { return ++asked >= 2; };
  const ImportResult stopped = import_model("solid x", stl, left);
  EXPECT_EQ(stopped.status, 499) << stopped.error;
  EXPECT_EQ(asked, 2);
  EXPECT_NE(stopped.error.find("the client has gone"), std::string::npos) << stopped.error;
  ImportOptions gone = importer();
  gone.importer = script("gone", "exit 3");
  const ImportResult vanished = import_model(std::string(8 << 20, 'x'), stl, gone);
  EXPECT_EQ(vanished.status, 503);
  EXPECT_NE(vanished.error.find("failed (3)"), std::string::npos) << vanished.error;
  fs::remove_all(dir);
}

// The importer's CPU time grows with the file: a small file of huge n-gons
// (quadratic in Assimp's ear clipping) holds a load place for seconds, not
// the whole minute.
TEST(ModelImport, CpuTimeGrowsWithTheFile) {
  EXPECT_EQ(import_cpu_seconds(0), 5u);
  EXPECT_EQ(import_cpu_seconds(std::uint64_t(1) << 20), 7u);
  EXPECT_EQ(import_cpu_seconds(std::uint64_t(10) << 20), 25u);
  EXPECT_EQ(import_cpu_seconds(std::uint64_t(1) << 30), 60u);
  EXPECT_EQ(import_cpu_seconds(std::uint64_t(1) << 30, 30), 30u);
}

}  // namespace
}  // namespace umbra
