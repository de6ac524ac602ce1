#include "assets/cityjson_loader.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <new>
#include <set>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/mat4x4.hpp>
#include <nlohmann/json.hpp>

#include "assets/json_shape.hpp"
#include "core/polygon_triangulation.hpp"

namespace umbra {

namespace {

using json = nlohmann::json;

struct Refused {
  int status;
  std::string message;
};
[[noreturn]] void refuse(int status, std::string message) { throw Refused{status, std::move(message)}; }

// A base colour per city object type (CityGML's modules), so the parts of
// a city read apart in a picture; anything else light grey.
glm::vec3 colour_of(const std::string& type) {
  static const std::vector<std::pair<const char*, glm::vec3>> colours = {
      {"Building", {0.86f, 0.83f, 0.78f}}, {"Bridge", {0.72f, 0.72f, 0.72f}},  {"Tunnel", {0.62f, 0.62f, 0.62f}},
      {"TINRelief", {0.56f, 0.6f, 0.46f}}, {"LandUse", {0.62f, 0.66f, 0.5f}},   {"PlantCover", {0.36f, 0.56f, 0.3f}},
      {"SolitaryVegetationObject", {0.36f, 0.56f, 0.3f}},                       {"WaterBody", {0.4f, 0.55f, 0.76f}},
      {"Road", {0.46f, 0.46f, 0.46f}},     {"Railway", {0.5f, 0.47f, 0.44f}},   {"TransportSquare", {0.5f, 0.5f, 0.5f}},
      {"Waterway", {0.4f, 0.55f, 0.76f}},  {"CityFurniture", {0.7f, 0.66f, 0.6f}}};
  for (const auto& [prefix, colour] : colours)
    if (type.rfind(prefix, 0) == 0) return colour;  // BuildingPart, BridgeConstructiveElement...
  return glm::vec3(0.8f);
}

// A LoD as written ("2.2", 2) and as a number to compare.
std::string lod_text(const json& lod) {
  if (lod.is_string()) return lod.get<std::string>();
  if (lod.is_number_integer()) return std::to_string(lod.get<long long>());
  if (lod.is_number()) {
    std::string t = std::to_string(lod.get<double>());
    while (t.size() > 1 && t.back() == '0') t.pop_back();
    if (!t.empty() && t.back() == '.') t.pop_back();
    return t;
  }
  return "";
}
double lod_value(const std::string& lod) {
  char* end = nullptr;
  const double v = std::strtod(lod.c_str(), &end);
  return end && *end == '\0' && std::isfinite(v) ? v : -1.0;
}

// One surface: rings of vertex indices, the first its boundary.
using Surface = std::vector<std::vector<std::size_t>>;

class Reader {
 public:
  Reader(const json& root, const CityJsonOptions& options) : root_(root), options_(options) {}
  CityJsonResult read();

 private:
  void read_vertices();
  Surface surface(const json& rings, const std::string& where, std::size_t vertex_count) const;
  void surfaces(const json& boundaries, int depth, const std::string& where, std::vector<Surface>& out,
                std::size_t vertex_count) const;
  void read_templates();
  std::vector<Surface> instance(const json& geometry, const std::string& where);

  const json& root_;
  const CityJsonOptions& options_;
  std::vector<glm::dvec3> vertices_;
  // Geometry templates (trees, street furniture): their geometries and
  // their own vertices, in real coordinates (no transform applies).
  const json* templates_ = nullptr;
  std::vector<glm::dvec3> template_vertices_;
};

void Reader::read_templates() {
  const auto section = root_.find("geometry-templates");
  if (section == root_.end()) return;
  const auto templates = section->find("templates");
  const auto vertices = section->find("vertices-templates");
  if (templates == section->end() || !templates->is_array() || vertices == section->end() || !vertices->is_array())
    refuse(400, "geometry-templates: must hold \"templates\" and \"vertices-templates\" arrays");
  templates_ = &*templates;
  for (std::size_t i = 0; i < vertices->size(); ++i) {
    const json& v = (*vertices)[i];
    if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
      refuse(400, "geometry-templates.vertices-templates[" + std::to_string(i) + "]: must be [x, y, z]");
    template_vertices_.emplace_back(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
  }
}

// A GeometryInstance's surfaces: its template's, each template vertex
// moved by the transformation matrix (row-major) and then by the reference
// point (a vertex of the model), added to the model's vertices.
std::vector<Surface> Reader::instance(const json& geometry, const std::string& where) {
  const json& t = geometry["template"];
  const json& template_geometry = (*templates_)[t.get<std::size_t>()];
  const json& m = geometry["transformationMatrix"];
  glm::dmat4 matrix;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) matrix[c][r] = m[std::size_t(r * 4 + c)].get<double>();  // glm is column-major
  // find, not []: a const json's operator[] on a missing key is undefined
  // (found by fuzzing: an instance without "boundaries").
  const auto reference = geometry.find("boundaries");
  if (reference == geometry.end() || !reference->is_array() || reference->size() != 1 ||
      !(*reference)[0].is_number_unsigned() || (*reference)[0].get<std::uint64_t>() >= vertices_.size())
    refuse(400, where + ".boundaries: must be [the reference point's vertex index]");
  const glm::dvec3 origin = vertices_[(*reference)[0].get<std::size_t>()];
  const std::string type = template_geometry["type"].get<std::string>();
  const int depth = type == "MultiSurface" || type == "CompositeSurface" ? 1 : type == "Solid" ? 2 : 3;
  std::vector<Surface> out;
  surfaces(template_geometry["boundaries"], depth, "geometry-templates.templates[" + std::to_string(t.get<std::size_t>()) + "].boundaries",
           out, template_vertices_.size());
  std::map<std::size_t, std::size_t> moved;
  for (Surface& surface : out)
    for (auto& ring : surface)
      for (std::size_t& i : ring) {
        const auto found = moved.find(i);
        if (found != moved.end()) {
          i = found->second;
          continue;
        }
        if (vertices_.size() >= 3 * options_.max_triangles)
          refuse(422, "the templates' instances make more vertices than a model of " +
                          std::to_string(options_.max_triangles) + " triangles may have");
        const glm::dvec4 p = matrix * glm::dvec4(template_vertices_[i], 1.0);
        const glm::dvec3 world = origin + glm::dvec3(p);
        if (!std::isfinite(world.x) || !std::isfinite(world.y) || !std::isfinite(world.z))
          refuse(400, where + ": a template vertex is not finite once placed");
        vertices_.push_back(world);
        moved.emplace(i, vertices_.size() - 1);
        i = vertices_.size() - 1;
      }
  return out;
}

void Reader::read_vertices() {
  const auto t = root_.find("transform");
  glm::dvec3 scale(1.0), translate(0.0);
  if (t != root_.end()) {
    for (const auto& [name, target] : {std::pair<const char*, glm::dvec3*>{"scale", &scale}, {"translate", &translate}}) {
      const auto v = t->find(name);
      if (v == t->end() || !v->is_array() || v->size() != 3 || !(*v)[0].is_number() || !(*v)[1].is_number() ||
          !(*v)[2].is_number())
        refuse(400, std::string("transform.") + name + ": must be three numbers");
      for (int k = 0; k < 3; ++k) (*target)[k] = (*v)[std::size_t(k)].get<double>();
    }
  }
  const auto vertices = root_.find("vertices");
  if (vertices == root_.end() || !vertices->is_array()) refuse(400, "vertices: is required, an array of [x, y, z]");
  if (vertices->size() > 3 * options_.max_triangles)
    refuse(422, "vertices: " + std::to_string(vertices->size()) + " vertices, more than a model of " +
                    std::to_string(options_.max_triangles) + " triangles may have");
  vertices_.reserve(vertices->size());
  for (std::size_t i = 0; i < vertices->size(); ++i) {
    const json& v = (*vertices)[i];
    if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
      refuse(400, "vertices[" + std::to_string(i) + "]: must be [x, y, z]");
    const glm::dvec3 p(v[0].get<double>() * scale.x + translate.x, v[1].get<double>() * scale.y + translate.y,
                       v[2].get<double>() * scale.z + translate.z);
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      refuse(400, "vertices[" + std::to_string(i) + "]: not finite once transformed");
    vertices_.push_back(p);
  }
}

Surface Reader::surface(const json& rings, const std::string& where, std::size_t vertex_count) const {
  if (!rings.is_array() || rings.empty()) refuse(400, where + ": a surface must be an array of rings");
  Surface out;
  for (std::size_t r = 0; r < rings.size(); ++r) {
    const json& ring = rings[r];
    if (!ring.is_array()) refuse(400, where + "[" + std::to_string(r) + "]: a ring must be an array of vertex indices");
    std::vector<std::size_t> indices;
    for (const json& i : ring) {
      if (!i.is_number_unsigned() || i.get<std::uint64_t>() >= vertex_count)
        refuse(400, where + "[" + std::to_string(r) + "]: " + i.dump().substr(0, 30) + " is not a vertex index (" +
                        std::to_string(vertex_count) + " vertices)");
      indices.push_back(i.get<std::size_t>());
    }
    out.push_back(std::move(indices));
  }
  return out;
}

// `depth` array levels above the surfaces: 1 for MultiSurface, 2 for a
// Solid's shells, 3 for MultiSolid's solids.
void Reader::surfaces(const json& boundaries, int depth, const std::string& where, std::vector<Surface>& out,
                      std::size_t vertex_count) const {
  if (!boundaries.is_array()) refuse(400, where + ": must be an array");
  if (depth == 1) {
    for (std::size_t s = 0; s < boundaries.size(); ++s)
      out.push_back(surface(boundaries[s], where + "[" + std::to_string(s) + "]", vertex_count));
    return;
  }
  // A solid's first shell is its outside; the others bound voids inside it,
  // which no ray from outside reaches.
  const std::size_t count = depth == 2 ? std::min<std::size_t>(1, boundaries.size()) : boundaries.size();
  for (std::size_t k = 0; k < count; ++k)
    surfaces(boundaries[k], depth - 1, where + "[" + std::to_string(k) + "]", out, vertex_count);
}

CityJsonResult Reader::read() {
  CityJsonResult result;
  const auto type = root_.find("type");
  if (type == root_.end() || *type != "CityJSON")
    refuse(400, "not a CityJSON file: its \"type\" must be \"CityJSON\"");
  const auto version = root_.find("version");
  const std::string v = version != root_.end() && version->is_string() ? version->get<std::string>() : "";
  if (v != "1.0" && v != "1.1" && v != "2.0")
    refuse(422, "CityJSON version '" + v.substr(0, 20) + "' is not read (1.0, 1.1 and 2.0 are: cjio upgrade converts older files)");
  read_vertices();
  read_templates();
  const auto objects = root_.find("CityObjects");
  if (objects == root_.end() || !objects->is_object()) refuse(400, "CityObjects: is required, an object");

  // Which geometry of each object: the LoD asked for, else its highest.
  struct Chosen {
    std::string type;
    std::vector<Surface> surfaces;
  };
  std::vector<Chosen> chosen;
  std::vector<std::string> lods;
  for (const auto& [id, object] : objects->items()) {
    const std::string where = "CityObjects[\"" + id.substr(0, 60) + "\"]";
    if (!object.is_object()) refuse(400, where + ": must be an object");
    const auto geometry = object.find("geometry");
    if (geometry == object.end()) continue;  // a parent, e.g. a Building of BuildingParts
    if (!geometry->is_array()) refuse(400, where + ".geometry: must be an array");
    const json* pick = nullptr;
    std::size_t pick_index = 0;
    double best = -1.0;
    for (std::size_t g = 0; g < geometry->size(); ++g) {
      const json& geom = (*geometry)[g];
      if (!geom.is_object() || !geom.contains("type") || !geom["type"].is_string())
        refuse(400, where + ".geometry[" + std::to_string(g) + "].type: is required");
      const std::string gtype = geom["type"].get<std::string>();
      const auto has_surfaces = [](const std::string& type) {
        return type == "MultiSurface" || type == "CompositeSurface" || type == "Solid" || type == "MultiSolid" ||
               type == "CompositeSolid";
      };
      // An instance of a template takes the template's type and LoD.
      const json* described = &geom;
      if (gtype == "GeometryInstance") {
        const std::string iwhere = where + ".geometry[" + std::to_string(g) + "]";
        if (!templates_) refuse(400, iwhere + ": a GeometryInstance, and the file has no geometry-templates");
        const auto t = geom.find("template");
        if (t == geom.end() || !t->is_number_unsigned() || t->get<std::uint64_t>() >= templates_->size())
          refuse(400, iwhere + ".template: is not a template's index (" + std::to_string(templates_->size()) + " templates)");
        const auto m = geom.find("transformationMatrix");
        if (m == geom.end() || !m->is_array() || m->size() != 16 ||
            !std::all_of(m->begin(), m->end(), [](const json& x) { return x.is_number(); }))
          refuse(400, iwhere + ".transformationMatrix: must be 16 numbers");
        described = &(*templates_)[t->get<std::size_t>()];
        if (!described->is_object() || !described->contains("type") || !(*described)["type"].is_string() ||
            !described->contains("boundaries"))
          refuse(400, "geometry-templates.templates[" + std::to_string(t->get<std::size_t>()) + "]: must have a type and boundaries");
      }
      if (!has_surfaces((*described)["type"].get<std::string>())) {
        ++result.left_out;  // MultiPoint, MultiLineString (or a template of them)
        continue;
      }
      const std::string lod = described->contains("lod") ? lod_text((*described)["lod"]) : "";
      if (std::find(lods.begin(), lods.end(), lod) == lods.end()) lods.push_back(lod);
      const double value = lod_value(lod);
      const bool wanted = options_.lod.empty() ? value > best : lod_value(options_.lod) == value;
      if (wanted && (options_.lod.empty() || !pick)) {
        pick = &geom;
        pick_index = g;
        best = value;
      }
    }
    if (!pick) continue;
    const std::string gwhere = where + ".geometry[" + std::to_string(pick_index) + "]";
    const std::string gtype = (*pick)["type"].get<std::string>();
    Chosen c;
    c.type = object.contains("type") && object["type"].is_string() ? object["type"].get<std::string>() : "";
    if (gtype == "GeometryInstance") {
      c.surfaces = instance(*pick, gwhere);
    } else {
      const int depth = gtype == "MultiSurface" || gtype == "CompositeSurface" ? 1 : gtype == "Solid" ? 2 : 3;
      if (!pick->contains("boundaries")) refuse(400, gwhere + ".boundaries: is required");
      surfaces((*pick)["boundaries"], depth, gwhere + ".boundaries", c.surfaces, vertices_.size());
    }
    if (!c.surfaces.empty()) chosen.push_back(std::move(c));
  }
  std::sort(lods.begin(), lods.end(), [](const std::string& a, const std::string& b) { return lod_value(a) < lod_value(b); });
  result.lods = lods;
  std::string lod_list;
  for (const std::string& l : lods) lod_list += (lod_list.empty() ? "" : ", ") + l;
  if (chosen.empty())
    refuse(422, options_.lod.empty() ? "the file has no surfaces (no MultiSurface, CompositeSurface or solid geometry)"
                                     : "no city object has LoD " + options_.lod.substr(0, 20) +
                                           " (the file has LoD " + (lod_list.empty() ? "none" : lod_list) + ")");
  result.objects = chosen.size();

  // Counted before anything is built: a ring of n points with h holes
  // makes n - 2 + 2h triangles.
  std::size_t triangles = 0;
  std::set<std::array<float, 3>> colours;  // one part each
  for (const Chosen& c : chosen) {
    const glm::vec3 colour = colour_of(c.type);
    colours.insert({colour.r, colour.g, colour.b});
    for (const Surface& s : c.surfaces) {
      std::size_t points = 0;
      for (const auto& ring : s) points += ring.size();
      triangles += points >= 2 ? points - 2 + 2 * (s.size() - 1) : 0;
      if (triangles > options_.max_triangles)
        refuse(422, "the city model has more than " + std::to_string(options_.max_triangles) +
                        " triangles at this LoD; that is the most one model may have");
    }
  }
  const std::uint64_t bound = model_bytes_bound(triangles, 3 * std::uint64_t(triangles), colours.size());
  if (options_.admit) {
    std::string why;
    if (const int status = options_.admit(bound, triangles, why)) refuse(status, why);
  }

  // The frame: the chosen geometry's plan middle and lowest point.
  glm::dvec3 low(1e300), high(-1e300);
  for (const Chosen& c : chosen)
    for (const Surface& s : c.surfaces)
      for (std::size_t i : s[0]) low = glm::min(low, vertices_[i]), high = glm::max(high, vertices_[i]);
  const glm::dvec3 origin(0.5 * (low.x + high.x), 0.5 * (low.y + high.y), low.z);
  // Every corner held in floats once moved: checked before any is built.
  const glm::vec3 reach(high - origin), reach_low(low - origin);
  if (!std::isfinite(reach.x) || !std::isfinite(reach.y) || !std::isfinite(reach.z) || !std::isfinite(reach_low.x) ||
      !std::isfinite(reach_low.y) || !std::isfinite(reach_low.z))
    refuse(400, "a vertex lies too far from the others to be held in 32-bit floats");
  const auto to_scene = [&](const glm::dvec3& p) {
    const glm::dvec3 q(p.x - origin.x, p.z - origin.z, -(p.y - origin.y));
    const glm::vec3 f(q);
    if (!std::isfinite(f.x) || !std::isfinite(f.y) || !std::isfinite(f.z))
      refuse(400, "a vertex lies too far from the others to be held in 32-bit floats");
    return q;
  };

  auto model = std::make_shared<TriangleModel>();
  std::map<std::array<float, 3>, std::size_t> part_of;
  std::vector<std::vector<glm::dvec3>> rings;
  for (const Chosen& c : chosen) {
    const glm::vec3 colour = colour_of(c.type);
    const auto found = part_of.emplace(std::array<float, 3>{colour.r, colour.g, colour.b}, model->parts.size());
    if (found.second) {
      model->parts.emplace_back();
      model->parts.back().base_color = colour;
    }
    ModelPart& part = model->parts[found.first->second];
    for (const Surface& s : c.surfaces) {
      rings.assign(s.size(), {});
      for (std::size_t r = 0; r < s.size(); ++r)
        for (std::size_t i : s[r]) rings[r].push_back(vertices_[i]);
      const PolygonTriangles t = triangulate_polygon(rings);
      result.fell_back += t.fell_back ? 1 : 0;
      std::vector<glm::dvec3> flat;
      for (const auto& ring : rings) flat.insert(flat.end(), ring.begin(), ring.end());
      // Flat shading: each triangle its own corners and the surface's normal.
      for (std::size_t k = 0; k + 2 < t.indices.size(); k += 3) {
        const glm::dvec3 a = to_scene(flat[t.indices[k]]), b = to_scene(flat[t.indices[k + 1]]),
                         cc = to_scene(flat[t.indices[k + 2]]);
        // The normal in double, scaled first: huge coordinates square past a float.
        const glm::dvec3 e1 = b - a, e2 = cc - a;
        const double size = std::max({glm::length(e1), glm::length(e2), 1e-300});
        const glm::dvec3 n = glm::cross(e1 / size, e2 / size);
        const double length = glm::length(n);
        const glm::vec3 fa(a), fb(b), fc(cc);
        if (!(length > 1e-12) || fa == fb || fb == fc || fc == fa) continue;  // no area once in floats
        const std::uint32_t base = std::uint32_t(part.positions.size());
        part.positions.insert(part.positions.end(), {fa, fb, fc});
        part.normals.insert(part.normals.end(), 3, glm::vec3(n / length));
        part.indices.insert(part.indices.end(), {base, base + 1, base + 2});
      }
    }
  }
  model->skipped_primitives = result.left_out;
  if (model->triangle_count() == 0) refuse(422, "the city model's surfaces have no area");
  finish_model(*model);
  result.model = std::move(model);
  return result;
}

}  // namespace

CityJsonResult load_cityjson(std::string_view bytes, const CityJsonOptions& options) {
  CityJsonResult result;
  try {
    const JsonShape shape = json_shape(bytes, kMaxCityJsonDepth, kMaxCityJsonValues);
    if (shape.depth > kMaxCityJsonDepth)
      refuse(422, "the CityJSON nests arrays and objects deeper than " + std::to_string(kMaxCityJsonDepth));
    if (shape.values > kMaxCityJsonValues)
      refuse(422, "the CityJSON has more than " + std::to_string(kMaxCityJsonValues) +
                      " values; split it into tiles (cjio subset) and upload each");
    const json root = json::parse(bytes.begin(), bytes.end(), nullptr, false);
    if (root.is_discarded()) refuse(400, "not a CityJSON file: not valid JSON");
    if (!root.is_object()) refuse(400, "not a CityJSON file: not a JSON object");
    result = Reader(root, options).read();
  } catch (const Refused& r) {
    result.model.reset();
    result.status = r.status;
    result.error = r.message;
  } catch (const std::bad_alloc&) {
    result.model.reset();
    result.status = 422;
    result.error = "the city model needs more memory than this server gives one model";
  } catch (const json::exception& e) {
    result.model.reset();
    result.status = 400;
    result.error = std::string("not a valid CityJSON file: ") + e.what();
  }
  return result;
}

}  // namespace umbra
