#include "core/mesh_instance.hpp"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/matrix.hpp>
#include <glm/trigonometric.hpp>

#include "core/model.hpp"

namespace umbra {

glm::dmat4 mesh_transform(const SceneObject& o) {
  glm::dmat4 m = glm::translate(glm::dmat4(1.0), o.center);
  m = glm::rotate(m, glm::radians(o.rotation_deg.z), glm::dvec3(0.0, 0.0, 1.0));
  m = glm::rotate(m, glm::radians(o.rotation_deg.y), glm::dvec3(0.0, 1.0, 0.0));
  m = glm::rotate(m, glm::radians(o.rotation_deg.x), glm::dvec3(1.0, 0.0, 0.0));
  return glm::scale(m, o.mesh_scale);
}

Aabb mesh_bounds(const SceneObject& o) {
  Aabb b;
  if (!o.model || o.model->bounds.empty()) return b;
  const glm::dmat4 m = mesh_transform(o);
  for (const glm::dvec3& corner : o.model->bounds.corners()) b.extend(glm::dvec3(m * glm::dvec4(corner, 1.0)));
  return b;
}

Aabb mesh_surface_bounds(const SceneObject& o) {
  Aabb b;
  if (!o.model) return b;
  const glm::dmat4 m = mesh_transform(o);
  for (const ModelPart& part : o.model->parts)
    for (const glm::vec3& p : part.positions) b.extend(glm::dvec3(m * glm::dvec4(glm::dvec3(p), 1.0)));
  return b;
}

double mesh_layers_along(const SceneObject& o, const glm::dvec3& direction) {
  if (!o.model || o.model->bounds.empty()) return 0.0;
  // A model-space area vector a projects along d to world area
  // |(det(L) L^-1 d) . a|: the cofactor of the transform's linear part L
  // maps area vectors. So do the faces of the model's box.
  const glm::dmat3 linear(mesh_transform(o));
  const glm::dvec3 m = glm::determinant(linear) * (glm::inverse(linear) * direction);
  const glm::dvec3 e = o.model->bounds.extent();
  const double box = std::abs(m.x) * e.y * e.z + std::abs(m.y) * e.x * e.z + std::abs(m.z) * e.x * e.y;
  return box > 0.0 ? projected_area(*o.model, m) / box : 0.0;
}

double mesh_deepest_layers(const SceneObject& o, const glm::dvec3& also) {
  static const glm::dvec3 kDirections[] = {{1, 0, 0},  {0, 1, 0},  {0, 0, 1},  {1, 1, 0},  {1, -1, 0},
                                           {1, 0, 1},  {1, 0, -1}, {0, 1, 1},  {0, 1, -1}, {1, 1, 1},
                                           {1, 1, -1}, {1, -1, 1}, {-1, 1, 1}};
  double layers = also == glm::dvec3(0.0) ? 0.0 : mesh_layers_along(o, also);
  for (const glm::dvec3& d : kDirections) layers = std::max(layers, mesh_layers_along(o, d));
  return layers;
}

bool mesh_is_closed(const SceneObject& o) { return o.model && o.model->closed; }

std::uint64_t mesh_triangle_count(const SceneObject& o) { return o.model ? o.model->triangle_count() : 0; }

std::uint64_t mesh_vertex_count(const SceneObject& o) {
  std::uint64_t n = 0;
  if (o.model)
    for (const ModelPart& part : o.model->parts) n += part.positions.size();
  return n;
}

void append_mesh_instance(const SceneObject& o, Mesh& out) {
  if (!o.model) return;
  const glm::dmat4 m = mesh_transform(o);
  const glm::dmat3 linear(m);
  const glm::dmat3 normal_matrix = glm::transpose(glm::inverse(linear));
  const bool mirrored = glm::determinant(linear) < 0.0;
  for (const ModelPart& part : o.model->parts) {
    const glm::dvec3 color = o.mesh_color_override ? o.color : glm::dvec3(part.base_color);
    const auto first = std::uint32_t(out.vertices.size());
    for (std::size_t i = 0; i < part.positions.size(); ++i) {
      const glm::dvec3 p = glm::dvec3(m * glm::dvec4(glm::dvec3(part.positions[i]), 1.0)) - out.origin;
      const glm::dvec3 n = glm::normalize(normal_matrix * glm::dvec3(part.normals[i]));
      out.vertices.push_back({{float(p.x), float(p.y), float(p.z)},
                              {float(n.x), float(n.y), float(n.z)},
                              {float(color.x), float(color.y), float(color.z)}});
    }
    for (std::size_t t = 0; t + 2 < part.indices.size(); t += 3) {
      const std::uint32_t a = first + part.indices[t], b = first + part.indices[t + 1], c = first + part.indices[t + 2];
      if (mirrored)
        out.indices.insert(out.indices.end(), {a, c, b});
      else
        out.indices.insert(out.indices.end(), {a, b, c});
    }
  }
}

}  // namespace umbra
