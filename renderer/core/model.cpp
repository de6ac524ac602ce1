#include "core/model.hpp"
#include "core/model_rig.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <nettle/sha2.h>

namespace umbra {

std::size_t TriangleModel::triangle_count() const {
  std::size_t n = 0;
  for (const ModelPart& part : parts) n += part.triangle_count();
  return n;
}

void ModelPart::append(const std::vector<glm::vec3>& more_positions, const std::vector<glm::vec3>& more_normals,
                       const std::vector<std::uint32_t>& more_indices) {
  const std::uint32_t base = std::uint32_t(positions.size());
  positions.insert(positions.end(), more_positions.begin(), more_positions.end());
  normals.insert(normals.end(), more_normals.begin(), more_normals.end());
  // No reserve(size + n) here: with many instances of one mesh that would
  // reallocate (and copy) the whole index array once per instance, which
  // made 10,000 node instances take minutes. insert grows geometrically.
  const std::size_t first = indices.size();
  indices.insert(indices.end(), more_indices.begin(), more_indices.end());
  for (std::size_t k = first; k < indices.size(); ++k) indices[k] += base;
}

std::size_t TriangleModel::bytes() const {
  std::size_t n = sizeof(*this) + parts.capacity() * sizeof(ModelPart);
  for (const ModelPart& part : parts)
    n += (part.positions.capacity() + part.normals.capacity()) * sizeof(glm::vec3) +
         part.indices.capacity() * sizeof(std::uint32_t);
  return n + area_vectors.capacity() * sizeof(glm::dvec3) + edge_lengths.capacity() * sizeof(EdgeLengthBin) +
         (rig ? rig->bytes() : 0);
}

std::uint64_t model_bytes_bound(std::uint64_t triangles, std::uint64_t vertices, std::uint64_t parts) {
  // finish_model shrinks every vector to its size: bytes() is exactly this
  // for a model whose parts keep `vertices` positions in all.
  // The area vectors and edge lengths: one per bin some triangle falls in.
  return sizeof(TriangleModel) + parts * sizeof(ModelPart) + vertices * 2 * sizeof(glm::vec3) +
         triangles * 3 * sizeof(std::uint32_t) + std::min<std::uint64_t>(triangles, kAreaDirectionBins) * sizeof(glm::dvec3) +
         std::min<std::uint64_t>(triangles, kEdgeLengthBins) * sizeof(EdgeLengthBin);
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

// Union-find root of element v, halving paths as it goes.
std::uint32_t root_of(std::vector<std::uint32_t>& parent, std::uint32_t v) {
  while (parent[v] != v) v = parent[v] = parent[parent[v]];
  return v;
}

// Calls f(a, b, c) with the welded corners of every triangle with area
// (two equal welded corners: none), in the same order every time.
template <typename F>
void for_each_welded_triangle(const std::vector<ModelPart>& parts,
                              const std::vector<std::vector<std::uint32_t>>& welded, const F& f) {
  for (std::size_t p = 0; p < parts.size(); ++p) {
    const std::vector<std::uint32_t>& indices = parts[p].indices;
    for (std::size_t t = 0; t + 2 < indices.size(); t += 3) {
      const std::uint32_t a = welded[p][indices[t]], b = welded[p][indices[t + 1]], c = welded[p][indices[t + 2]];
      if (a != b && b != c && c != a) f(a, b, c);
    }
  }
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
  std::vector<glm::dvec3> position;  // per welded id
  for (std::size_t i = 0; i < corners.size(); ++i) {
    if (i == 0 || corners[i].key != corners[i - 1].key)
      position.push_back(parts[corners[i].part].positions[corners[i].vertex]);
    welded[corners[i].part][corners[i].vertex] = std::uint32_t(position.size() - 1);
  }
  corners.clear();
  corners.shrink_to_fit();

  // Every directed edge (from << 32 | to) and the triangle it belongs to.
  struct Edge {
    std::uint64_t key;
    std::uint32_t triangle;
  };
  std::vector<Edge> edges;
  // Reserved: grown by push_back, the old and new arrays together were the
  // peak of a million-triangle load (about 100 MiB).
  std::size_t corner_count = 0;
  for (const ModelPart& part : parts) corner_count += part.indices.size();
  edges.reserve(corner_count);
  std::uint32_t triangles = 0;
  for_each_welded_triangle(parts, welded, [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    edges.push_back({std::uint64_t(a) << 32 | b, triangles});
    edges.push_back({std::uint64_t(b) << 32 | c, triangles});
    edges.push_back({std::uint64_t(c) << 32 | a, triangles});
    ++triangles;
  });
  if (edges.empty()) return false;
  const auto by_key = [](const Edge& e, const Edge& f) { return e.key < f.key; };
  std::sort(edges.begin(), edges.end(), by_key);
  // A directed edge twice: two triangles run the same way along it (a
  // flipped neighbour, or more than two triangles on one edge).
  if (std::adjacent_find(edges.begin(), edges.end(), [](const Edge& e, const Edge& f) { return e.key == f.key; }) !=
      edges.end())
    return false;
  // Each edge's opposite must be there too, else the edge is a border. The
  // two triangles on an edge belong to one shell: shells are joined by
  // edges, not by a vertex two of them may merely touch at.
  std::vector<std::uint32_t> shell(triangles);
  for (std::uint32_t t = 0; t < triangles; ++t) shell[t] = t;
  for (const Edge& e : edges) {
    const Edge reverse{(e.key << 32) | (e.key >> 32), 0};
    const auto it = std::lower_bound(edges.begin(), edges.end(), reverse, by_key);
    if (it == edges.end() || it->key != reverse.key) return false;
    shell[root_of(shell, e.triangle)] = root_of(shell, it->triangle);
  }
  edges.clear();
  edges.shrink_to_fit();

  // Each shell must face out: wound counter-clockwise seen from outside, its
  // signed volume (the sum of a . (b x c) over its triangles) is positive.
  // An inside-out shell is not closed: culling front faces in the shadow
  // pass would drop the faces that look out, and culling back faces in the
  // main pass would show its inside. Positions are taken relative to a
  // corner of the shell's first triangle, which leaves a closed surface's
  // volume unchanged and keeps the products small.
  std::vector<double> volume(triangles, 0.0);
  std::vector<glm::dvec3> shell_origin(triangles);
  std::vector<bool> has_origin(triangles, false);
  std::uint32_t t = 0;
  for_each_welded_triangle(parts, welded, [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    const std::uint32_t root = root_of(shell, t++);
    if (!has_origin[root]) shell_origin[root] = position[a], has_origin[root] = true;
    const glm::dvec3& o = shell_origin[root];
    volume[root] += glm::dot(position[a] - o, glm::cross(position[b] - o, position[c] - o));
  });
  for (std::uint32_t k = 0; k < triangles; ++k)
    if (shell[k] == k && volume[k] <= 0.0) return false;
  return true;
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

namespace {

constexpr int kBinsPerSide = 8;
static_assert(6 * kBinsPerSide * kBinsPerSide == kAreaDirectionBins);

// Which of the 6 * kBinsPerSide^2 direction bins a non-zero vector falls in:
// the cube face its largest component points to, then the cell of that face
// that the vector crosses.
std::size_t direction_bin(const glm::dvec3& v) {
  const glm::dvec3 a = glm::abs(v);
  const int axis = a.x >= a.y && a.x >= a.z ? 0 : a.y >= a.z ? 1 : 2;
  const int face = 2 * axis + (v[axis] < 0.0 ? 1 : 0);
  const double u = v[(axis + 1) % 3] / a[axis], w = v[(axis + 2) % 3] / a[axis];  // each in [-1, 1]
  const auto cell = [](double t) { return std::clamp(int((t + 1.0) * 0.5 * kBinsPerSide), 0, kBinsPerSide - 1); };
  return std::size_t((face * kBinsPerSide + cell(u)) * kBinsPerSide + cell(w));
}

}  // namespace

std::vector<glm::dvec3> binned_area_vectors(const std::vector<ModelPart>& parts) {
  std::vector<glm::dvec3> bins(6 * kBinsPerSide * kBinsPerSide, glm::dvec3(0.0));
  for (const ModelPart& part : parts)
    for (std::size_t t = 0; t + 2 < part.indices.size(); t += 3) {
      const glm::dvec3 a(part.positions[part.indices[t]]), b(part.positions[part.indices[t + 1]]),
          c(part.positions[part.indices[t + 2]]);
      const glm::dvec3 area = 0.5 * glm::cross(b - a, c - a);
      if (area == glm::dvec3(0.0) || !std::isfinite(glm::dot(area, area))) continue;
      bins[direction_bin(area)] += area;
    }
  bins.erase(std::remove(bins.begin(), bins.end(), glm::dvec3(0.0)), bins.end());
  bins.shrink_to_fit();
  return bins;
}

std::vector<EdgeLengthBin> edge_length_bins(const std::vector<ModelPart>& parts) {
  std::vector<EdgeLengthBin> bins(kEdgeLengthBins);
  for (const ModelPart& part : parts)
    for (std::size_t t = 0; t + 2 < part.indices.size(); t += 3) {
      const glm::dvec3 a(part.positions[part.indices[t]]), b(part.positions[part.indices[t + 1]]),
          c(part.positions[part.indices[t + 2]]);
      const double squared = std::max({glm::dot(b - a, b - a), glm::dot(c - b, c - b), glm::dot(a - c, a - c)});
      if (!(squared > 0.0) || !std::isfinite(squared)) continue;
      // log2 of the edge's length is half that of its square.
      const int bin = std::clamp(int(std::floor(0.5 * std::log2(squared))) + int(kEdgeLengthBins / 2), 0,
                                 int(kEdgeLengthBins) - 1);
      bins[std::size_t(bin)].triangles += 1.0;
      bins[std::size_t(bin)].squared_edges += squared;
    }
  bins.erase(std::remove_if(bins.begin(), bins.end(), [](const EdgeLengthBin& b) { return b.triangles == 0.0; }),
             bins.end());
  bins.shrink_to_fit();
  return bins;
}

double projected_area(const TriangleModel& model, const glm::dvec3& direction) {
  double sum = 0.0;
  for (const glm::dvec3& a : model.area_vectors) sum += std::abs(glm::dot(direction, a));
  return sum;
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
  model.area_vectors = binned_area_vectors(model.parts);
  model.edge_lengths = edge_length_bins(model.parts);
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
