// umbra-model-import: one model file in a format Assimp reads (OBJ, STL,
// PLY, COLLADA, FBX, 3DS, IFC...) on stdin, the same model as a glTF binary
// on stdout, for the server's glTF loader (renderer/assets/model_import.hpp
// runs it). A process of its own because Assimp was not written for
// hostile files: a crash, a runaway allocation or an endless loop here ends
// this process under the limits it sets itself, never the server.
//
//   umbra-model-import FORMAT [--up file|y|z] [--unit file|m|cm|mm|in|ft] [--max-mib N] [--max-seconds S]
//
// FORMAT is the file's extension (obj, stl, ply, dae, fbx, 3ds, ifc...).
// The conventions (docs/api.md, "Other formats"): by default ("file") what
// the file itself states is applied (COLLADA's <unit> and <up_axis> and
// IFC's units and Z up, by Assimp; FBX's unit scale and UpAxis, here), and
// a file that states nothing (OBJ, STL, PLY, 3DS) is read as glTF is: Y up,
// metres. --up z turns a Z-up model to Y up (-90 degrees about X); --unit
// scales it to metres. Exit 0 with the .glb on stdout, else 2 (Assimp could
// not read the file), 4 (it holds no triangles) or 5 (out of memory) with
// one line on stderr saying why.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <assimp/Exporter.hpp>
#include <assimp/Importer.hpp>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <sys/resource.h>
#include <unistd.h>

namespace {

[[noreturn]] void fail(const std::string& why, int code = 2) {
  std::fprintf(stderr, "%s\n", why.c_str());
  std::exit(code);
}

void limit(int resource, rlim_t value) {
  const rlimit r{value, value};
  if (setrlimit(resource, &r) != 0) fail("cannot set a resource limit", 3);
}

double metres_per(const std::string& unit) {
  if (unit == "m") return 1.0;
  if (unit == "cm") return 0.01;
  if (unit == "mm") return 0.001;
  if (unit == "in") return 0.0254;
  if (unit == "ft") return 0.3048;
  fail("unknown unit " + unit, 3);
}

// glTF's JSON is UTF-8; names in older formats are often Latin-1
// ("Terraindäk"), which Assimp copies as they are. Each byte that is not
// part of valid UTF-8 becomes '?'.
void make_utf8(aiString& name) {
  std::string text(name.C_Str(), name.length);
  for (std::size_t i = 0; i < text.size();) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    const std::size_t length = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xe ? 3 : (c >> 3) == 0x1e ? 4 : 0;
    bool valid = length > 0 && i + length <= text.size();
    for (std::size_t k = 1; valid && k < length; ++k) valid = (static_cast<unsigned char>(text[i + k]) >> 6) == 0x2;
    if (!valid) {
      text[i++] = '?';
      continue;
    }
    i += length;
  }
  name.Set(text);
}

void make_utf8(aiNode& node) {
  make_utf8(node.mName);
  for (unsigned i = 0; i < node.mNumChildren; ++i) make_utf8(*node.mChildren[i]);
}

void valid_utf8_names(const aiScene& scene) {
  make_utf8(*scene.mRootNode);
  for (unsigned m = 0; m < scene.mNumMeshes; ++m) make_utf8(scene.mMeshes[m]->mName);
  for (unsigned m = 0; m < scene.mNumMaterials; ++m) {
    aiString name;
    if (scene.mMaterials[m]->Get(AI_MATKEY_NAME, name) != AI_SUCCESS) continue;
    make_utf8(name);
    scene.mMaterials[m]->AddProperty(&name, AI_MATKEY_NAME);
  }
}

// A text file saved as UTF-16 (its byte-order mark first), as some Windows
// tools write OBJ and COLLADA: Assimp reads UTF-8, so it is turned into that.
void utf16_to_utf8(std::vector<char>& text) {
  if (text.size() < 2) return;
  const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(text[i]); };
  const bool big = byte(0) == 0xfe && byte(1) == 0xff, little = byte(0) == 0xff && byte(1) == 0xfe;
  if (!big && !little) return;
  std::vector<char> out;
  const auto unit = [&](std::size_t i) { return big ? (byte(i) << 8 | byte(i + 1)) : (byte(i + 1) << 8 | byte(i)); };
  for (std::size_t i = 2; i + 1 < text.size(); i += 2) {
    unsigned code = unsigned(unit(i));
    if (code >= 0xd800 && code < 0xdc00 && i + 3 < text.size()) {
      const unsigned low = unsigned(unit(i + 2));
      if (low >= 0xdc00 && low < 0xe000) code = 0x10000 + ((code - 0xd800) << 10) + (low - 0xdc00), i += 2;
    }
    if (code < 0x80) {
      out.push_back(char(code));
    } else if (code < 0x800) {
      out.push_back(char(0xc0 | code >> 6)), out.push_back(char(0x80 | (code & 0x3f)));
    } else if (code < 0x10000) {
      out.push_back(char(0xe0 | code >> 12)), out.push_back(char(0x80 | (code >> 6 & 0x3f)));
      out.push_back(char(0x80 | (code & 0x3f)));
    } else {
      out.push_back(char(0xf0 | code >> 18)), out.push_back(char(0x80 | (code >> 12 & 0x3f)));
      out.push_back(char(0x80 | (code >> 6 & 0x3f))), out.push_back(char(0x80 | (code & 0x3f)));
    }
  }
  text = std::move(out);
}

// Meshes without faces are dropped, and the nodes' references renumbered.
void renumber(aiNode& node, const std::vector<int>& kept_as) {
  unsigned n = 0;
  for (unsigned i = 0; i < node.mNumMeshes; ++i)
    if (kept_as[node.mMeshes[i]] >= 0) node.mMeshes[n++] = unsigned(kept_as[node.mMeshes[i]]);
  node.mNumMeshes = n;
  for (unsigned i = 0; i < node.mNumChildren; ++i) renumber(*node.mChildren[i], kept_as);
}

void drop_empty_meshes(aiScene& scene) {
  std::vector<int> kept_as(scene.mNumMeshes, -1);
  unsigned n = 0;
  for (unsigned m = 0; m < scene.mNumMeshes; ++m)
    if (scene.mMeshes[m]->mNumFaces > 0 && scene.mMeshes[m]->mNumVertices > 0) {
      kept_as[m] = int(n);
      scene.mMeshes[n++] = scene.mMeshes[m];
    }
  // The dropped ones are left to the process's end (it is a short one).
  scene.mNumMeshes = n;
  renumber(*scene.mRootNode, kept_as);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) fail("usage: umbra-model-import FORMAT [--up y|z] [--unit m|cm|mm|in|ft] [--max-mib N] [--max-seconds S]", 3);
  const std::string format = argv[1];
  std::string up = "file", unit = "file";
  unsigned long max_mib = 2048, max_seconds = 60;
  for (int i = 2; i + 1 < argc; i += 2) {
    const std::string flag = argv[i], value = argv[i + 1];
    if (flag == "--up") up = value;
    else if (flag == "--unit") unit = value;
    else if (flag == "--max-mib") max_mib = std::strtoul(value.c_str(), nullptr, 10);
    else if (flag == "--max-seconds") max_seconds = std::strtoul(value.c_str(), nullptr, 10);
    else fail("unknown option " + flag, 3);
  }
  if (up != "file" && up != "y" && up != "z") fail("--up must be file, y or z", 3);
  double scale = unit == "file" ? 1.0 : metres_per(unit);
  // The limits first: address space, CPU time, what it may write (its
  // output, when that is a file), no core.
  limit(RLIMIT_AS, rlim_t(max_mib) << 20);
  limit(RLIMIT_CPU, rlim_t(max_seconds));
  limit(RLIMIT_FSIZE, rlim_t(max_mib) << 20);
  limit(RLIMIT_CORE, 0);

  std::vector<char> input;
  char chunk[65536];
  for (ssize_t n; (n = read(0, chunk, sizeof chunk)) != 0;) {
    if (n < 0) fail("cannot read the model from stdin", 3);
    input.insert(input.end(), chunk, chunk + n);
  }
  if (input.empty()) fail("the file is empty");
  utf16_to_utf8(input);

  Assimp::Importer importer;
  // Read as it is; meshes without faces dropped (an STL's empty solid
  // beside its triangles: Assimp's steps refuse the whole file for one);
  // then every face made triangles, split from points and lines (which the
  // glTF loader leaves out and counts).
  const aiScene* scene = importer.ReadFileFromMemory(input.data(), input.size(), 0, format.c_str());
  // Assimp catches an allocation that its address-space limit refused and
  // reports it as an error: out of memory (5), not an unreadable file.
  const auto failed = [&] {
    const std::string why = importer.GetErrorString();
    fail(why, why.find("bad_alloc") != std::string::npos ? 5 : 2);
  };
  if (!scene) failed();
  if (!scene->mRootNode) fail("the file holds no scene");
  drop_empty_meshes(const_cast<aiScene&>(*scene));
  // A file of points or lines only is valid, but has nothing to cast a
  // shadow with: said so, not called broken.
  if (scene->mNumMeshes == 0) fail("Assimp found no meshes with faces in it", 4);
  unsigned with_triangles = 0;
  for (unsigned m = 0; m < scene->mNumMeshes; ++m)
    with_triangles += scene->mMeshes[m]->mPrimitiveTypes & (aiPrimitiveType_TRIANGLE | aiPrimitiveType_POLYGON) ? 1 : 0;
  if (with_triangles == 0)
    fail(std::to_string(scene->mNumMeshes) + " meshes of points or lines, which cast no shadow", 4);
  scene = importer.ApplyPostProcessing(aiProcess_Triangulate | aiProcess_SortByPType | aiProcess_JoinIdenticalVertices |
                                       aiProcess_ValidateDataStructure);
  if (!scene) failed();
  valid_utf8_names(*scene);
  // The up axis: told, or the file's own where it states one that Assimp
  // leaves as it is (FBX's UpAxis metadata: 2 is Z).
  bool z_up = up == "z";
  int up_axis = 1, up_sign = 1;
  if (up == "file" && scene->mMetaData && scene->mMetaData->Get("UpAxis", up_axis)) {
    scene->mMetaData->Get("UpAxisSign", up_sign);
    z_up = up_axis == 2;
  }
  // The unit: told, or FBX's own (UnitScaleFactor: centimetres per unit).
  float centimetres = 0.0f;  // Assimp stores it as a float
  if (unit == "file" && scene->mMetaData && scene->mMetaData->Get("UnitScaleFactor", centimetres) &&
      centimetres > 0.0f && std::isfinite(centimetres))
    scale = double(centimetres) / 100.0;
  aiMatrix4x4 convert;
  if (z_up) aiMatrix4x4::RotationX(float(up_sign < 0 ? M_PI / 2 : -M_PI / 2), convert);
  aiMatrix4x4 scaling;
  aiMatrix4x4::Scaling(aiVector3D(float(scale)), scaling);
  scene->mRootNode->mTransformation = scaling * convert * scene->mRootNode->mTransformation;

  // Animations are not carried over: Assimp's glTF writer fails on some
  // (nested COLLADA ones) and writes others with key times that are not
  // numbers (a 3DS file's), which the loader rightly refuses. A converted
  // model is its rest pose; animated models come as glTF.
  const_cast<aiScene*>(scene)->mNumAnimations = 0;  // (their memory goes with the process)
  Assimp::Exporter exporter;
  const aiExportDataBlob* blob = exporter.ExportToBlob(scene, "glb2");
  if (!blob) fail(std::string("cannot write it as glTF: ") + exporter.GetErrorString());
  for (std::size_t at = 0; at < blob->size;) {
    const ssize_t n = write(1, static_cast<const char*>(blob->data) + at, blob->size - at);
    if (n <= 0) fail("cannot write the result", 3);
    at += std::size_t(n);
  }
  return 0;
}
