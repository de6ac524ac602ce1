#include "core/mesh_instance.hpp"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/matrix.hpp>
#include <glm/trigonometric.hpp>

#include "core/model.hpp"
#include "core/shell_cores.hpp"

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

std::vector<Aabb> mesh_cluster_bounds(const SceneObject& o, int fewest, int most) {
  if (!o.model) return {};
  std::uint32_t shells = 0;
  const std::vector<std::uint32_t> shell_of = triangle_shells(*o.model, shells);
  return mesh_cluster_bounds(o, shell_of, shells, fewest, most);
}

std::vector<Aabb> mesh_cluster_bounds(const SceneObject& o, const std::vector<std::uint32_t>& shell_of,
                                      std::uint32_t shell_count, int fewest, int most) {
  std::vector<Aabb> out;
  if (!o.model || shell_of.empty()) return out;
  struct Triangle {
    glm::dvec3 centre;
    Aabb box;
  };
  // The triangles in world space, in order of shell (a counting sort).
  std::vector<std::size_t> start(std::size_t(shell_count) + 1, 0);
  for (const std::uint32_t s : shell_of) ++start[s + 1];
  for (std::size_t s = 0; s < shell_count; ++s) start[s + 1] += start[s];
  std::vector<std::size_t> next(start.begin(), start.end() - 1);
  std::vector<Triangle> triangles(shell_of.size());
  const glm::dmat4 m = mesh_transform(o);
  std::vector<glm::dvec3> world;
  std::size_t index = 0;
  for (const ModelPart& part : o.model->parts) {
    world.resize(part.positions.size());
    for (std::size_t i = 0; i < world.size(); ++i) world[i] = glm::dvec3(m * glm::dvec4(glm::dvec3(part.positions[i]), 1.0));
    for (std::size_t t = 0; t < part.triangle_count(); ++t, ++index) {
      const glm::dvec3 &a = world[part.indices[3 * t]], &b = world[part.indices[3 * t + 1]],
                       &c = world[part.indices[3 * t + 2]];
      Triangle& tri = triangles[next[shell_of[index]]++];
      tri.box.min = glm::min(glm::min(a, b), c);
      tri.box.max = glm::max(glm::max(a, b), c);
      tri.centre = 0.5 * (tri.box.min + tri.box.max);
    }
  }
  // A cluster: triangles [first, last) and their box.
  struct Cluster {
    std::size_t first, last;
    Aabb box;
  };
  const auto cluster_of = [&](std::size_t first, std::size_t last) {
    Cluster c{first, last, {}};
    for (std::size_t i = first; i < last; ++i)
      c.box.min = glm::min(c.box.min, triangles[i].box.min), c.box.max = glm::max(c.box.max, triangles[i].box.max);
    return c;
  };
  const auto longest_axis = [](const Aabb& b) {
    const glm::dvec3 e = b.extent();
    return e.x >= e.y && e.x >= e.z ? 0 : (e.y >= e.z ? 1 : 2);
  };
  std::vector<Cluster> clusters;
  // The shells, each a run of the sorted triangles.
  for (std::size_t s = 0; s < shell_count; ++s)
    if (start[s] < start[s + 1]) clusters.push_back(cluster_of(start[s], start[s + 1]));
  if (int(clusters.size()) > most) {
    // More shells than boxes: the shells halved at the median of their
    // boxes' centres along the longest side, and the halves again.
    std::vector<Cluster> shells = std::move(clusters);
    clusters.clear();
    int depth = 0;
    while (depth < 30 && (2 << depth) <= most) ++depth;
    const auto split = [&](auto&& self, std::size_t first, std::size_t last, int levels) -> void {
      if (levels == 0 || last - first < 2) {
        Cluster c{0, 0, {}};
        for (std::size_t i = first; i < last; ++i) c.box.extend(shells[i].box);
        clusters.push_back(c);
        return;
      }
      Aabb centres;
      for (std::size_t i = first; i < last; ++i) centres.extend(shells[i].box.center());
      const int axis = longest_axis(centres);
      const std::size_t middle = first + (last - first) / 2;
      std::nth_element(shells.begin() + std::ptrdiff_t(first), shells.begin() + std::ptrdiff_t(middle),
                       shells.begin() + std::ptrdiff_t(last), [axis](const Cluster& a, const Cluster& b) {
                         return a.box.center()[axis] < b.box.center()[axis];
                       });
      self(self, first, middle, levels - 1);
      self(self, middle, last, levels - 1);
    };
    split(split, 0, shells.size(), depth);
  } else {
    // Fewer: the cluster of most triangles halved at the median of their
    // centres along the longest side of those, until there are `fewest`.
    while (int(clusters.size()) < fewest) {
      const auto biggest = std::max_element(clusters.begin(), clusters.end(), [](const Cluster& a, const Cluster& b) {
        return a.last - a.first < b.last - b.first;
      });
      if (biggest->last - biggest->first < 2) break;
      const std::size_t first = biggest->first, last = biggest->last, middle = first + (last - first) / 2;
      Aabb centres;
      for (std::size_t i = first; i < last; ++i)
        centres.min = glm::min(centres.min, triangles[i].centre), centres.max = glm::max(centres.max, triangles[i].centre);
      const int axis = longest_axis(centres);
      std::nth_element(triangles.begin() + std::ptrdiff_t(first), triangles.begin() + std::ptrdiff_t(middle),
                       triangles.begin() + std::ptrdiff_t(last),
                       [axis](const Triangle& a, const Triangle& b) { return a.centre[axis] < b.centre[axis]; });
      *biggest = cluster_of(first, middle);
      clusters.push_back(cluster_of(middle, last));
    }
  }
  for (const Cluster& c : clusters) out.push_back(c.box);
  return out;
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
