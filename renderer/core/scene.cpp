#include "core/scene.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <glm/trigonometric.hpp>

#include "core/builtin_models.hpp"
#include "core/shapes/shape.hpp"

namespace umbra {

glm::dvec3 rotate_y(const glm::dvec3& v, double degrees) {
  // The ray casts turn each ray into every turned box's frame it meets:
  // the scene's few angles, millions of times, where sin and cos were a
  // third of a sun-hours walk. Each thread keeps the last angles' values
  // (by their bits, so -0 and 0 stay apart): the same numbers, computed
  // once.
  struct Turn {
    std::uint64_t bits = 0;  // the angle +0, whose cos and sin these are
    double c = 1.0, s = 0.0;
  };
  thread_local Turn turns[64];
  std::uint64_t bits;
  std::memcpy(&bits, &degrees, sizeof bits);
  Turn& turn = turns[(bits * 0x9E3779B97F4A7C15ull) >> 58];
  if (turn.bits != bits) {
    const double a = glm::radians(degrees);
    turn = {bits, std::cos(a), std::sin(a)};
  }
  const double c = turn.c, s = turn.s;
  return {c * v.x + s * v.z, v.y, -s * v.x + c * v.z};
}

void Aabb::extend(const glm::dvec3& p) {
  min = glm::min(min, p);
  max = glm::max(max, p);
}

void Aabb::extend(const Aabb& other) {
  if (other.empty()) return;
  extend(other.min);
  extend(other.max);
}

std::vector<glm::dvec3> Aabb::corners() const {
  std::vector<glm::dvec3> out;
  out.reserve(8);
  for (int i = 0; i < 8; ++i)
    out.emplace_back(i & 1 ? max.x : min.x, i & 2 ? max.y : min.y, i & 4 ? max.z : min.z);
  return out;
}

namespace {

SceneObject plane(glm::dvec3 center, double sx, double sz, glm::dvec3 color) {
  SceneObject o;
  o.type = SceneObject::Type::Plane;
  o.center = center;
  o.size = {sx, 0.0, sz};
  o.color = color;
  return o;
}

SceneObject box(glm::dvec3 center, glm::dvec3 size, double rotation_y_deg, glm::dvec3 color) {
  SceneObject o;
  o.type = SceneObject::Type::Box;
  o.center = center;
  o.size = size;
  o.rotation_y_deg = rotation_y_deg;
  o.color = color;
  return o;
}

SceneObject mesh(const std::string& builtin_model, glm::dvec3 position, glm::dvec3 rotation_deg, double scale) {
  const BuiltinModel* m = find_builtin_model(builtin_model);
  SceneObject o;
  o.type = SceneObject::Type::Mesh;
  o.model = m->model;
  o.model_id = m->id;
  o.center = position;
  o.rotation_deg = rotation_deg;
  o.mesh_scale = glm::dvec3(scale);
  return o;
}

constexpr glm::dvec3 kFloorColor{0.72, 0.66, 0.58};

}  // namespace

Aabb object_bounds(const SceneObject& o) { return shape_kind(o.type).bounds(o); }

double largest_coordinate(const Aabb& box, const glm::dvec3& origin) {
  if (box.empty()) return 0.0;
  double largest = 0.0;
  for (int i = 0; i < 3; ++i) largest = std::max({largest, std::abs(box.min[i] - origin[i]), std::abs(box.max[i] - origin[i])});
  return largest;
}

Aabb scene_bounds(const Scene& scene) {
  Aabb b;
  for (const auto& o : scene.objects) b.extend(object_bounds(o));
  return b;
}

const std::vector<BuiltinScene>& builtin_scenes() {
  // The seeds' scene: a 50 x 50 floor at y = -0.5 and a unit cube resting on
  // it, lit from (-2, 4, -1) towards the origin.
  static const std::vector<BuiltinScene> scenes = {
      {"cube-on-plane",
       "The seeds' scene: one unit cube resting on a 50 x 50 floor.",
       {plane({0.0, -0.5, 0.0}, 50.0, 50.0, kFloorColor),
        box({0.0, 0.0, 0.0}, {1.0, 1.0, 1.0}, 0.0, {0.85, 0.35, 0.25})},
       {2.5, 3.0, 5.0},
       {0.6, -0.3, 0.6},
       {-2.0, 4.0, -1.0}},
      {"three-cubes",
       "Three cubes of different sizes and rotations on a 50 x 50 floor.",
       {plane({0.0, -0.5, 0.0}, 50.0, 50.0, kFloorColor),
        box({-1.2, 0.25, 0.3}, {1.5, 1.5, 1.5}, 15.0, {0.85, 0.35, 0.25}),
        box({1.4, 0.0, -0.6}, {1.0, 1.0, 1.0}, 40.0, {0.3, 0.55, 0.85}),
        box({0.6, -0.2, 1.6}, {0.6, 0.6, 0.6}, 65.0, {0.4, 0.75, 0.35})},
       {3.5, 4.0, 6.5},
       {0.3, -0.2, 0.6},
       {-2.0, 4.0, -1.0}},
      // A real model: the spout, handle and lid shadow the pot itself, and
      // its surface is open, so the shadow pass draws both sides.
      {"teapot",
       "The Utah teapot (102,400 triangles) on a 50 x 50 floor.",
       {plane({0.0, -0.5, 0.0}, 50.0, 50.0, kFloorColor), mesh("teapot", {0.0, -0.5, 0.0}, {0.0, -30.0, 0.0}, 0.5)},
       {-2.5, 3.0, 4.8},
       {0.4, 0.3, 0.3},
       {-2.0, 4.0, -1.0}},
      // A closed model that shadows itself along the whole of its length.
      {"torus-knot",
       "A closed torus knot (16,384 triangles) hovering over a 50 x 50 floor.",
       {plane({0.0, -0.5, 0.0}, 50.0, 50.0, kFloorColor), mesh("torus-knot", {0.0, 0.75, 0.0}, {25.0, 0.0, 0.0}, 1.0)},
       {3.6, 3.2, 5.0},
       {0.0, 0.3, 0.0},
       {-2.0, 4.0, -1.0}},
  };
  return scenes;
}

const BuiltinScene* find_builtin_scene(const std::string& name) {
  for (const auto& s : builtin_scenes())
    if (s.name == name) return &s;
  return nullptr;
}

SceneViewDefaults default_view_for(const Scene& scene) {
  const Aabb bounds = scene_bounds(scene);
  const glm::dvec3 center = bounds.empty() ? glm::dvec3(0.0) : bounds.center();
  const double radius = bounds.empty() ? 1.0 : std::max(0.5 * glm::length(bounds.extent()), 1e-6);
  SceneViewDefaults v;
  v.camera_target = center;
  // Far enough for the bounding sphere to fit a 45 degree view (1 / sin(22.5) ~ 2.61).
  v.camera_position = center + glm::normalize(glm::dvec3(0.45, 0.55, 1.0)) * (2.8 * radius);
  // The light target is the API's fixed default, the origin; place the light
  // beyond the scene along the built-in scenes' light direction from it.
  v.light_target = glm::dvec3(0.0);
  const double reach = glm::length(center - v.light_target) + 2.0 * radius;
  v.light_position = v.light_target + glm::normalize(glm::dvec3(-2.0, 4.0, -1.0)) * reach;
  return v;
}

namespace {

// Mesh::smooth_normal_span of the triangles in indices [0, count).
double smooth_normal_span(const std::vector<Vertex>& vertices, const std::vector<std::uint32_t>& indices,
                          std::uint32_t count) {
  const auto position = [&](std::uint32_t i) { return glm::dvec3(glm::make_vec3(vertices[i].position)); };
  const auto normal = [&](std::uint32_t i) { return glm::make_vec3(vertices[i].normal); };
  double span = 0.0;
  for (std::uint32_t t = 0; t + 2 < count; t += 3) {
    const std::uint32_t a = indices[t], b = indices[t + 1], c = indices[t + 2];
    if (normal(a) == normal(b) && normal(b) == normal(c)) continue;
    span = std::max({span, glm::distance(position(a), position(b)), glm::distance(position(b), position(c)),
                     glm::distance(position(c), position(a))});
  }
  return span;
}

}  // namespace

Mesh tessellate(const Scene& scene) {
  Mesh mesh;
  const Aabb bounds = scene_bounds(scene);
  mesh.origin = bounds.empty() ? glm::dvec3(0.0) : bounds.center();
  // Appends object i's triangles with `append` and records where they lie.
  const auto record = [&mesh](std::size_t i, auto&& append) {
    const auto first = std::uint32_t(mesh.indices.size());
    append();
    mesh.object_ranges.push_back({i, first, std::uint32_t(mesh.indices.size()) - first});
  };
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    const SceneObject& o = scene.objects[i];
    const ShapeKind& kind = shape_kind(o.type);
    if (kind.closed(o)) record(i, [&] { kind.tessellate(o, mesh); });
  }
  mesh.closed_index_count = std::uint32_t(mesh.indices.size());
  mesh.smooth_normal_span = smooth_normal_span(mesh.vertices, mesh.indices, mesh.closed_index_count);
  // Open surfaces (planes, open meshes: a terrain, a leaf) are never culled
  // in the shadow pass: culling either side would drop the side that faces
  // the light as a caster.
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    const SceneObject& o = scene.objects[i];
    const ShapeKind& kind = shape_kind(o.type);
    if (!kind.closed(o) && !kind.horizontal_plane) record(i, [&] { kind.tessellate(o, mesh); });
  }
  // Planes last, each with its own range: the shadow pass leaves out those
  // that cannot shadow anything under the frame's light.
  for (const auto& o : scene.objects) mesh.bounds.push_back(object_bounds(o));
  // Where the other objects lie against each plane: a turned mesh's bounds
  // are not tight (mesh_surface_bounds), and a floor they reach under would
  // be drawn into every layer of the map.
  std::vector<Aabb> surfaces;
  for (std::size_t j = 0; j < scene.objects.size(); ++j)
    surfaces.push_back(shape_kind(scene.objects[j].type).surface_bounds(scene.objects[j]));
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    const SceneObject& o = scene.objects[i];
    const ShapeKind& kind = shape_kind(o.type);
    if (!kind.horizontal_plane) continue;
    PlaneRange range;
    range.object = i;
    record(i, [&] { kind.tessellate(o, mesh); });
    range.height = o.center.y;
    range.color = o.color;
    for (std::size_t j = 0; j < scene.objects.size(); ++j) {
      if (j == i) continue;
      range.lowest_other = std::min(range.lowest_other, surfaces[j].min.y);
      range.highest_other = std::max(range.highest_other, surfaces[j].max.y);
    }
    mesh.planes.push_back(range);
  }
  mesh.open_index_count = std::uint32_t(mesh.indices.size()) - mesh.closed_index_count;
  return mesh;
}

bool closed_meshes_seen_from_outside(const Mesh& mesh, const Camera& camera, double aspect) {
  const double tan_half = std::tan(glm::radians(camera.fov_y_deg) * 0.5);
  const double reach = camera.near_plane * std::sqrt(1.0 + tan_half * tan_half * (1.0 + aspect * aspect));
  for (const ObjectRange& range : mesh.object_ranges) {
    if (range.first_index >= mesh.closed_index_count || range.index_count == 0) continue;
    const Aabb& box = mesh.bounds[range.object];
    const glm::dvec3 outside = glm::max(glm::max(box.min - camera.position, camera.position - box.max), 0.0);
    // Slack for rounding: of the near plane's reach, and of float positions
    // relative to the mesh origin, whose error grows with the scene's size.
    const double slack = 1e-3 * reach + 1e-6 * (glm::length(camera.position - mesh.origin) + glm::length(box.extent()));
    if (glm::length(outside) <= reach + slack) return false;
  }
  return true;
}

}  // namespace umbra
