// Appends vertices and quads to a Mesh: what the analytic shapes'
// tessellations are made of (core/shapes/*.cpp).
#pragma once

#include <cstdint>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "core/scene.hpp"

namespace umbra {

struct MeshBuilder {
  Mesh& mesh;

  std::uint32_t vertex(const glm::dvec3& p, const glm::dvec3& n, const glm::dvec3& c) {
    const glm::dvec3 local = p - mesh.origin;
    mesh.vertices.push_back({{float(local.x), float(local.y), float(local.z)},
                             {float(n.x), float(n.y), float(n.z)},
                             {float(c.x), float(c.y), float(c.z)}});
    return std::uint32_t(mesh.vertices.size() - 1);
  }

  // A rectangle centred at `center` spanning +-u and +-v, facing u x v.
  void quad(const glm::dvec3& center, const glm::dvec3& u, const glm::dvec3& v, const glm::dvec3& color) {
    const glm::dvec3 n = glm::normalize(glm::cross(u, v));
    const std::uint32_t a = vertex(center - u - v, n, color);
    const std::uint32_t b = vertex(center + u - v, n, color);
    const std::uint32_t c = vertex(center + u + v, n, color);
    const std::uint32_t d = vertex(center - u + v, n, color);
    mesh.indices.insert(mesh.indices.end(), {a, b, c, a, c, d});
  }
};

}  // namespace umbra
