// CityJSON city models, and the polygon triangulation their walls and roofs
// need (a facade with its windows cut out).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <random>

#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include "assets/cityjson_loader.hpp"
#include "assets/glb_writer.hpp"
#include "assets/gltf_loader.hpp"
#include "core/polygon_triangulation.hpp"

namespace umbra {
namespace {

using json = nlohmann::json;
using Ring = std::vector<glm::dvec3>;

double area_of(const std::vector<Ring>& rings, const PolygonTriangles& t, const glm::dvec3& normal) {
  std::vector<glm::dvec3> flat;
  for (const Ring& r : rings) flat.insert(flat.end(), r.begin(), r.end());
  double area = 0.0;
  for (std::size_t k = 0; k + 2 < t.indices.size(); k += 3) {
    const glm::dvec3 n = glm::cross(flat[t.indices[k + 1]] - flat[t.indices[k]], flat[t.indices[k + 2]] - flat[t.indices[k]]);
    EXPECT_GE(glm::dot(n, normal), -1e-9) << "a triangle wound against its polygon";
    area += 0.5 * glm::length(n);
  }
  return area;
}

// A square ring in the plane z = 0, counter-clockwise seen from +z.
Ring square(double x0, double y0, double side, bool clockwise = false) {
  Ring r = {{x0, y0, 0}, {x0 + side, y0, 0}, {x0 + side, y0 + side, 0}, {x0, y0 + side, 0}};
  if (clockwise) std::reverse(r.begin(), r.end());
  return r;
}

TEST(PolygonTriangulation, ConvexConcaveAndHoledPolygonsAreCoveredExactly) {
  const glm::dvec3 up(0, 0, 1);
  PolygonTriangles t = triangulate_polygon({square(0, 0, 2)});
  EXPECT_EQ(t.indices.size(), 6u);
  EXPECT_NEAR(area_of({square(0, 0, 2)}, t, up), 4.0, 1e-12);
  // An L: concave.
  const Ring ell = {{0, 0, 0}, {3, 0, 0}, {3, 1, 0}, {1, 1, 0}, {1, 3, 0}, {0, 3, 0}};
  t = triangulate_polygon({ell});
  EXPECT_EQ(t.indices.size(), 12u);
  EXPECT_NEAR(area_of({ell}, t, up), 5.0, 1e-12);
  EXPECT_FALSE(t.fell_back);
  // Holes, given either way round: a wall of 10 x 4 with two windows.
  const std::vector<Ring> wall = {square(0, 0, 10), square(2, 2, 2), square(6, 3, 1, true)};
  t = triangulate_polygon(wall);
  EXPECT_NEAR(area_of(wall, t, up), 100.0 - 4.0 - 1.0, 1e-9);
  EXPECT_FALSE(t.fell_back);
  // Upright, far from the origin, as a facade in a national grid (metres).
  std::vector<Ring> facade;
  for (const Ring& r : wall) {
    Ring f;
    for (const glm::dvec3& p : r) f.push_back({85000.0 + p.x, 446000.0, 2.0 + p.y});
    facade.push_back(f);
  }
  t = triangulate_polygon(facade);
  EXPECT_NEAR(area_of(facade, t, {0, -1, 0}), 95.0, 1e-6);
  // Collinear points and a repeated point are no trouble; no area, no triangles.
  const Ring with_collinear = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {2, 2, 0}, {2, 2, 0}, {0, 2, 0}};
  t = triangulate_polygon({with_collinear});
  EXPECT_NEAR(area_of({with_collinear}, t, up), 4.0, 1e-12);
  EXPECT_TRUE(triangulate_polygon({{{0, 0, 0}, {1, 1, 1}, {2, 2, 2}}}).indices.empty());
}

TEST(PolygonTriangulation, RandomStarsWithHolesKeepTheirArea) {
  std::mt19937 random(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int trial = 0; trial < 300; ++trial) {
    // A star-shaped outer ring about the origin (radius 5..10) and up to
    // three small square holes well inside its inner radius.
    Ring outer;
    const int n = 5 + int(unit(random) * 30);
    for (int k = 0; k < n; ++k) {
      const double a = 2.0 * M_PI * (k + 0.5 * unit(random)) / n, r = 5.0 + 5.0 * unit(random);
      outer.push_back({r * std::cos(a), r * std::sin(a), 0});
    }
    std::vector<Ring> rings = {outer};
    double holes = 0.0;
    const int h = int(unit(random) * 4);
    for (int k = 0; k < h; ++k) {
      const double side = 0.5 + 0.5 * unit(random);
      rings.push_back(square(-3.5 + 2.2 * k, -1.0 + unit(random), side, unit(random) < 0.5));
      holes += side * side;
    }
    double expected = 0.0;
    for (std::size_t i = 0, j = outer.size() - 1; i < outer.size(); j = i++)
      expected += (outer[j].x * outer[i].y - outer[i].x * outer[j].y) * 0.5;
    const PolygonTriangles t = triangulate_polygon(rings);
    EXPECT_FALSE(t.fell_back) << trial;
    EXPECT_NEAR(area_of(rings, t, {0, 0, 1}), expected - holes, 1e-9 * expected) << trial;
  }
}

// A city: one building at LoD 1 (a box solid) and LoD 2 (the box with a
// gable roof), and a MultiSurface facade with a window at LoD 2, in a
// national grid (metres, z up, y north), with a transform; a point cloud.
json city() {
  json vertices = json::array();
  // Scaled by 0.001 and moved to (85000, 446000, 0) by the transform.
  for (const auto& [x, y, z] : std::vector<std::array<int, 3>>{
           {0, 0, 0}, {10000, 0, 0}, {10000, 6000, 0}, {0, 6000, 0},          // 0-3 ground
           {0, 0, 3000}, {10000, 0, 3000}, {10000, 6000, 3000}, {0, 6000, 3000},  // 4-7 eaves
           {0, 3000, 5000}, {10000, 3000, 5000},                              // 8-9 ridge
           {20000, 0, 0}, {30000, 0, 0}, {30000, 0, 4000}, {20000, 0, 4000},  // 10-13 facade
           {22000, 0, 1000}, {24000, 0, 1000}, {24000, 0, 2000}, {22000, 0, 2000}})  // 14-17 window
    vertices.push_back({x, y, z});
  const json lod1 = {{"type", "Solid"}, {"lod", "1"}, {"boundaries", {{
      {{0, 3, 2, 1}}, {{4, 5, 6, 7}}, {{0, 1, 5, 4}}, {{1, 2, 6, 5}}, {{2, 3, 7, 6}}, {{3, 0, 4, 7}}}}}};
  const json lod2 = {{"type", "Solid"}, {"lod", "2.2"}, {"boundaries", {{
      {{0, 3, 2, 1}}, {{0, 1, 5, 4}}, {{2, 3, 7, 6}},
      {{1, 2, 6, 9, 5}}, {{3, 0, 4, 8, 7}},            // gable walls
      {{4, 5, 9, 8}}, {{6, 7, 8, 9}}}}}};              // roof
  // The facade faces south (-y): its boundary runs counter-clockwise seen from there.
  const json facade = {{"type", "MultiSurface"}, {"lod", 2.2}, {"boundaries", {{{10, 11, 12, 13}, {14, 17, 16, 15}}}}};
  return {{"type", "CityJSON"}, {"version", "2.0"},
          {"transform", {{"scale", {0.001, 0.001, 0.001}}, {"translate", {85000, 446000, 0}}}},
          {"CityObjects", {{"house", {{"type", "Building"}, {"geometry", {lod1, lod2}}}},
                           {"wall", {{"type", "OtherConstruction"}, {"geometry", {facade}}}},
                           {"trees", {{"type", "SolitaryVegetationObject"},
                                      {"geometry", {{{"type", "MultiPoint"}, {"lod", "1"}, {"boundaries", {0, 1}}}}}}}}},
          {"vertices", vertices}};
}

CityJsonResult load(const json& doc, const std::string& lod = "") {
  CityJsonOptions options;
  options.lod = lod;
  return load_cityjson(doc.dump(), options);
}

TEST(CityJson, ABuildingAtEachLevelOfDetailInUmbrasFrame) {
  const CityJsonResult highest = load(city());
  ASSERT_TRUE(highest.ok()) << highest.error;
  EXPECT_EQ(highest.lods, (std::vector<std::string>{"1", "2.2"}));
  EXPECT_EQ(highest.objects, 2u);
  EXPECT_EQ(highest.left_out, 1u);  // the trees' points
  EXPECT_EQ(highest.fell_back, 0u);
  // Plan middle at the origin, standing on y = 0, the ridge 5 m up; north
  // (+y in the grid) is -z: the facade (grid y = 0, the south edge) at +3 m.
  const Aabb& b = highest.model->bounds;
  EXPECT_NEAR(b.min.x, -15.0, 1e-4);
  EXPECT_NEAR(b.max.x, 15.0, 1e-4);
  EXPECT_NEAR(b.min.y, 0.0, 1e-4);
  EXPECT_NEAR(b.max.y, 5.0, 1e-4);
  EXPECT_NEAR(b.max.z, 3.0, 1e-4);
  EXPECT_NEAR(b.min.z, -3.0, 1e-4);
  // The house's gabled solid: 2 + 2 + 2 + 3 + 3 + 2 + 2 triangles; the
  // facade with its window: 8.
  EXPECT_EQ(highest.model->triangle_count(), 16u + 8u);
  EXPECT_EQ(highest.model->skipped_primitives, 1u);
  const CityJsonResult box = load(city(), "1");
  ASSERT_TRUE(box.ok()) << box.error;
  EXPECT_EQ(box.objects, 1u);  // the facade has no LoD 1
  EXPECT_EQ(box.model->triangle_count(), 12u);
  EXPECT_TRUE(box.model->closed);  // a valid solid, wound outwards
  EXPECT_NEAR(box.model->bounds.max.y, 3.0, 1e-4);
  const CityJsonResult none = load(city(), "3");
  EXPECT_EQ(none.status, 422);
  EXPECT_EQ(none.error, "no city object has LoD 3 (the file has LoD 1, 2.2)");
  // As the server holds it: written as a .glb and loaded back, the same.
  const LoadResult glb = load_gltf(write_glb(*highest.model), LoadOptions{});
  ASSERT_TRUE(glb.ok()) << glb.error;
  EXPECT_EQ(glb.model->triangle_count(), highest.model->triangle_count());
  EXPECT_EQ(glb.model->bounds.max, highest.model->bounds.max);
  EXPECT_EQ(glb.model->parts.size(), highest.model->parts.size());
}

// Trees as city models share them: one template (a pyramid "tree", in
// its own vertices) placed twice by GeometryInstance, moved by its matrix
// (twice the size for the second) and then to its reference point.
TEST(CityJson, TemplatesArePlacedAtTheirReferencePoints) {
  json doc = city();
  doc["geometry-templates"] = {
      {"templates", {{{"type", "Solid"}, {"lod", "2.2"},
                      {"boundaries", {{{{0, 2, 1}}, {{0, 1, 3}}, {{1, 2, 3}}, {{2, 0, 3}}}}}}}},
      {"vertices-templates", {{-1, -1, 0}, {1, -1, 0}, {0, 1, 0}, {0, 0, 4}}}};
  const std::size_t first = doc["vertices"].size();
  doc["vertices"].push_back({5000, 20000, 0});   // 5 m east, 20 m north of the grid origin
  doc["vertices"].push_back({15000, 20000, 0});
  const json identity = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  const json doubled = {2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1};
  doc["CityObjects"]["tree1"] = {{"type", "SolitaryVegetationObject"},
                                 {"geometry", {{{"type", "GeometryInstance"}, {"template", 0},
                                                {"boundaries", {first}}, {"transformationMatrix", identity}}}}};
  doc["CityObjects"]["tree2"] = {{"type", "SolitaryVegetationObject"},
                                 {"geometry", {{{"type", "GeometryInstance"}, {"template", 0},
                                                {"boundaries", {first + 1}}, {"transformationMatrix", doubled}}}}};
  const CityJsonResult r = load(doc);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.objects, 4u);
  EXPECT_EQ(r.model->triangle_count(), 16u + 8u + 4u + 4u);
  EXPECT_NEAR(r.model->bounds.max.y, 8.0, 1e-4);  // the doubled tree, 8 m tall
  // The trees' own colour; the houses' and the facade's.
  EXPECT_EQ(r.model->parts.size(), 3u);
  doc["CityObjects"]["tree2"]["geometry"][0]["template"] = 3;
  EXPECT_EQ(load(doc).error, "CityObjects[\"tree2\"].geometry[0].template: is not a template's index (1 templates)");
  doc["CityObjects"]["tree2"]["geometry"][0]["template"] = 0;
  doc["CityObjects"]["tree2"]["geometry"][0].erase("boundaries");  // found by fuzzing: read past a missing key
  EXPECT_EQ(load(doc).error, "CityObjects[\"tree2\"].geometry[0].boundaries: must be [the reference point's vertex index]");
  doc["CityObjects"]["tree2"]["geometry"][0]["boundaries"] = {first + 1};
  doc["CityObjects"]["tree2"]["geometry"][0]["transformationMatrix"] = {1, 2, 3};
  EXPECT_EQ(load(doc).error, "CityObjects[\"tree2\"].geometry[0].transformationMatrix: must be 16 numbers");
}

TEST(CityJson, BrokenFilesAreRefusedNamingThePlace) {
  json doc = city();
  doc["CityObjects"]["house"]["geometry"][1]["boundaries"][0][3][0][2] = 99;
  CityJsonResult r = load(doc);
  EXPECT_EQ(r.status, 400);
  EXPECT_EQ(r.error, "CityObjects[\"house\"].geometry[1].boundaries[0][3][0]: 99 is not a vertex index (18 vertices)");
  doc = city();
  doc["version"] = "0.9";
  EXPECT_EQ(load(doc).status, 422);
  doc = city();
  doc["type"] = "FeatureCollection";
  EXPECT_EQ(load(doc).error, "not a CityJSON file: its \"type\" must be \"CityJSON\"");
  doc = city();
  doc["vertices"][3] = {1, 2};
  EXPECT_EQ(load(doc).error, "vertices[3]: must be [x, y, z]");
  doc = city();
  doc["transform"]["scale"] = {1e308, 1e308, 1e308};
  EXPECT_EQ(load(doc).status, 400);
  EXPECT_EQ(load_cityjson("{\"type\": ", {}).error, "not a CityJSON file: not valid JSON");
  // Too many values to parse: refused before parsing, with advice.
  std::string huge = R"({"type": "CityJSON", "version": "2.0", "CityObjects": {}, "vertices": [)";
  for (std::size_t i = 0; i < kMaxCityJsonValues / 3 + 10; ++i) huge += "[1,2,3],";
  huge += "[1,2,3]]}";
  r = load_cityjson(huge, {});
  EXPECT_EQ(r.status, 422);
  EXPECT_NE(r.error.find("cjio subset"), std::string::npos) << r.error;
  // Coordinates past what floats hold: refused; huge but holdable ones
  // keep unit normals (found by fuzzing: the normal squared past a float).
  doc = city();
  doc.erase("transform");
  doc["vertices"][4] = {0, -7.7e22, 1};
  doc["vertices"][5] = {1, 0, 1e11};
  r = load(doc, "1");
  if (r.ok()) {
    for (const ModelPart& part : r.model->parts)
      for (const glm::vec3& n : part.normals) EXPECT_NEAR(glm::length(n), 1.0f, 1e-3f);
  } else {
    EXPECT_EQ(r.status, 400) << r.error;
  }
  doc["vertices"][5] = {1, 0, 1e300};
  r = load(doc, "1");
  EXPECT_EQ(r.status, 400);
  EXPECT_EQ(r.error, "a vertex lies too far from the others to be held in 32-bit floats");
  // Over the triangle limit: counted before any is built.
  CityJsonOptions few;
  few.max_triangles = 10;
  r = load_cityjson(city().dump(), few);
  EXPECT_EQ(r.status, 422);
  EXPECT_NE(r.error.find("more than 10 triangles"), std::string::npos) << r.error;
}

// The CityJSON conformance corpus of 3DGI (tests/data/cityjson-corpus,
// CC BY 4.0): 33 valid files written by others, each a feature of the
// specification. Every one with surfaces loads; every other is a 422 that
// says why; none is called invalid (400).
TEST(CityJson, TheConformanceCorpusOfOthers) {
  const std::filesystem::path folder = UMBRA_CITYJSON_CORPUS;
  std::map<std::string, std::string> outcome;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    if (entry.path().extension() != ".json") continue;
    std::ifstream in(entry.path(), std::ios::binary);
    std::stringstream bytes;
    bytes << in.rdbuf();
    const CityJsonResult r = load_cityjson(bytes.str(), {});
    const std::string name = entry.path().filename().string();
    if (r.ok()) {
      outcome[name] = "loaded";
      EXPECT_GT(r.model->triangle_count(), 0u) << name;
      continue;
    }
    EXPECT_EQ(r.status, 422) << name << ": " << r.error;
    const bool why = r.error.find("has no surfaces") != std::string::npos ||
                     r.error.find("surfaces have no area") != std::string::npos;
    EXPECT_TRUE(why) << name << ": " << r.error;
    outcome[name] = "refused";
  }
  ASSERT_EQ(outcome.size(), 33u);
  // Those whose geometry is a surface of area: a unit cube (solid,
  // multisolid, multisurface, with materials, semantics or textures' faces)
  // or the corpus's 'complete' files.
  for (const char* loads : {"appearance_complete.city.json", "cityjson_fake_complete.city.json",
                            "geometry_material_multisolid.city.json", "geometry_material_multisurface.city.json",
                            "geometry_material_solid.city.json", "geometry_semantics_multisolid.city.json",
                            "geometry_semantics_solid.city.json"})
    EXPECT_EQ(outcome[loads], "loaded") << loads;
  // A template that is a MultiPoint; a MultiSurface of collinear points.
  EXPECT_EQ(outcome["geometry_instance.city.json"], "refused");
  EXPECT_EQ(outcome["semantic_complete.city.json"], "refused");
}

}  // namespace
}  // namespace umbra
