#include "model.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include <glm/geometric.hpp>
#include <nettle/sha2.h>

namespace umbra {

std::size_t TriangleModel::triangle_count() const {
  std::size_t n = 0;
  for (const ModelPart& part : parts) n += part.triangle_count();
  return n;
}

std::size_t TriangleModel::bytes() const {
  std::size_t n = sizeof(*this) + parts.capacity() * sizeof(ModelPart);
  for (const ModelPart& part : parts)
    n += (part.positions.capacity() + part.normals.capacity()) * sizeof(glm::vec3) +
         part.indices.capacity() * sizeof(std::uint32_t);
  return n;
}

namespace {

// The bits of a position, with -0 read as +0 so that both weld together.
std::array<std::uint32_t, 3> position_key(const glm::vec3& p) {
  std::array<std::uint32_t, 3> key{};
  for (int i = 0; i < 3; ++i) {
    const float v = p[i] == 0.0f ? 0.0f : p[i];
    std::memcpy(&key[std::size_t(i)], &v, sizeof v);
  }
  return key;
}

// Union-find root of welded vertex v, halving paths as it goes.
std::uint32_t shell_root(std::vector<std::uint32_t>& parent, std::uint32_t v) {
  while (parent[v] != v) v = parent[v] = parent[parent[v]];
  return v;
}

// Whether each shell (vertices joined by triangles) of a watertight,
// consistently wound surface winds counter-clockwise seen from outside: its
// signed volume, the sum of a . (b x c) over its triangles, is positive.
// Positions are taken relative to one vertex of the shell, which leaves a
// closed surface's volume unchanged and keeps the products small.
// Triangles with two equal welded corners are left out, as by the edge test.
bool every_shell_faces_out(const std::vector<ModelPart>& parts,
                           const std::vector<std::vector<std::uint32_t>>& welded, std::uint32_t vertex_count) {
  std::vector<std::uint32_t> parent(vertex_count);
  for (std::uint32_t v = 0; v < vertex_count; ++v) parent[v] = v;
  std::vector<glm::dvec3> position(vertex_count);
  for (std::size_t p = 0; p < parts.size(); ++p)
    for (std::size_t v = 0; v < parts[p].positions.size(); ++v) position[welded[p][v]] = parts[p].positions[v];
  // Calls f(a, b, c) with the welded corners of every triangle with area.
  const auto for_each_triangle = [&](const auto& f) {
    for (std::size_t p = 0; p < parts.size(); ++p) {
      const std::vector<std::uint32_t>& indices = parts[p].indices;
      for (std::size_t t = 0; t + 2 < indices.size(); t += 3) {
        const std::uint32_t a = welded[p][indices[t]], b = welded[p][indices[t + 1]], c = welded[p][indices[t + 2]];
        if (a != b && b != c && c != a) f(a, b, c);
      }
    }
  };
  std::vector<bool> used(vertex_count, false);
  for_each_triangle([&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    const std::uint32_t root = shell_root(parent, a);
    parent[shell_root(parent, b)] = root;
    parent[shell_root(parent, c)] = root;
    used[a] = true;
  });
  std::vector<double> volume(vertex_count, 0.0);
  for_each_triangle([&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    const std::uint32_t root = shell_root(parent, a);
    const glm::dvec3 o = position[root];
    volume[root] += glm::dot(position[a] - o, glm::cross(position[b] - o, position[c] - o));
  });
  for (std::uint32_t v = 0; v < vertex_count; ++v)
    if (used[v] && volume[shell_root(parent, v)] <= 0.0) return false;
  return true;
}

}  // namespace

bool is_closed(const std::vector<ModelPart>& parts) {
  // Weld: one id per distinct position, over every part.
  struct Corner {
    std::array<std::uint32_t, 3> key;
    std::uint32_t part;
    std::uint32_t vertex;
  };
  std::vector<Corner> corners;
  std::size_t vertex_count = 0;
  for (const ModelPart& part : parts) vertex_count += part.positions.size();
  corners.reserve(vertex_count);
  for (std::size_t p = 0; p < parts.size(); ++p)
    for (std::size_t v = 0; v < parts[p].positions.size(); ++v)
      corners.push_back({position_key(parts[p].positions[v]), std::uint32_t(p), std::uint32_t(v)});
  std::sort(corners.begin(), corners.end(), [](const Corner& a, const Corner& b) { return a.key < b.key; });
  std::vector<std::vector<std::uint32_t>> welded(parts.size());
  for (std::size_t p = 0; p < parts.size(); ++p) welded[p].resize(parts[p].positions.size());
  std::uint32_t id = 0;
  for (std::size_t i = 0; i < corners.size(); ++i) {
    if (i > 0 && corners[i].key != corners[i - 1].key) ++id;
    welded[corners[i].part][corners[i].vertex] = id;
  }
  corners.clear();
  corners.shrink_to_fit();

  // Every directed edge, as from << 32 | to.
  std::vector<std::uint64_t> edges;
  for (std::size_t p = 0; p < parts.size(); ++p) {
    const std::vector<std::uint32_t>& indices = parts[p].indices;
    for (std::size_t t = 0; t + 2 < indices.size(); t += 3) {
      const std::uint32_t a = welded[p][indices[t]], b = welded[p][indices[t + 1]], c = welded[p][indices[t + 2]];
      if (a == b || b == c || c == a) continue;
      edges.push_back(std::uint64_t(a) << 32 | b);
      edges.push_back(std::uint64_t(b) << 32 | c);
      edges.push_back(std::uint64_t(c) << 32 | a);
    }
  }
  if (edges.empty()) return false;
  std::sort(edges.begin(), edges.end());
  // A directed edge twice: two triangles run the same way along it (a
  // flipped neighbour, or more than two triangles on one edge).
  if (std::adjacent_find(edges.begin(), edges.end()) != edges.end()) return false;
  // Each edge's opposite must be there too: else the edge is a border.
  for (std::uint64_t e : edges) {
    const std::uint64_t reverse = (e << 32) | (e >> 32);
    if (!std::binary_search(edges.begin(), edges.end(), reverse)) return false;
  }
  edges.clear();
  edges.shrink_to_fit();
  return every_shell_faces_out(parts, welded, id + 1);
}

std::vector<glm::vec3> area_weighted_normals(const std::vector<glm::vec3>& positions,
                                             const std::vector<std::uint32_t>& indices) {
  std::vector<glm::dvec3> sums(positions.size(), glm::dvec3(0.0));
  for (std::size_t t = 0; t + 2 < indices.size(); t += 3) {
    const glm::dvec3 a(positions[indices[t]]), b(positions[indices[t + 1]]), c(positions[indices[t + 2]]);
    const glm::dvec3 n = glm::cross(b - a, c - a);
    for (int k = 0; k < 3; ++k) sums[indices[t + std::size_t(k)]] += n;
  }
  std::vector<glm::vec3> normals(positions.size());
  for (std::size_t v = 0; v < positions.size(); ++v) {
    const double length = glm::length(sums[v]);
    normals[v] = length > 0.0 && std::isfinite(length) ? glm::vec3(sums[v] / length) : glm::vec3(0, 1, 0);
  }
  return normals;
}

void finish_model(TriangleModel& model) {
  model.bounds = Aabb{};
  for (ModelPart& part : model.parts) {
    part.positions.shrink_to_fit();
    part.normals.shrink_to_fit();
    part.indices.shrink_to_fit();
    for (const glm::vec3& p : part.positions) model.bounds.extend(glm::dvec3(p));
  }
  model.parts.shrink_to_fit();
  model.closed = is_closed(model.parts);
}

std::string model_id_for(std::string_view bytes) {
  sha256_ctx context;
  sha256_init(&context);
  // nettle takes a size_t length: the whole body in one call.
  sha256_update(&context, bytes.size(), reinterpret_cast<const std::uint8_t*>(bytes.data()));
  std::uint8_t digest[SHA256_DIGEST_SIZE];
  sha256_digest(&context, sizeof digest, digest);
  static const char kHex[] = "0123456789abcdef";
  std::string id = "sha256:";
  for (std::uint8_t b : digest) {
    id += kHex[b >> 4];
    id += kHex[b & 15];
  }
  return id;
}

std::string model_geometry_id(const TriangleModel& model) {
  std::string bytes;
  const auto append = [&](const void* data, std::size_t size) {
    bytes.append(static_cast<const char*>(data), size);
  };
  for (const ModelPart& part : model.parts) {
    append(part.positions.data(), part.positions.size() * sizeof(glm::vec3));
    append(part.normals.data(), part.normals.size() * sizeof(glm::vec3));
    append(part.indices.data(), part.indices.size() * sizeof(std::uint32_t));
    append(&part.base_color, sizeof part.base_color);
  }
  return model_id_for(bytes);
}

}  // namespace umbra
