#include "reference/mesh_grid_shadow.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <tuple>

#include <glm/geometric.hpp>
#include <glm/matrix.hpp>

#include "core/model_shells.hpp"

namespace umbra {

struct MeshShadowModel {
  // Welded by exact position, model space (the model's own floats), in the
  // order the leaves' triangles first use them (a leaf's corners lie
  // together in memory; each placement carries them into the world as it
  // uses them, so ten placements share these 12 bytes a corner).
  std::vector<glm::vec3> corners;
  struct Triangle {
    std::uint32_t v[3];  // corners, in the model's own order
  };
  std::vector<Triangle> triangles;  // in leaf order
  // Unit normals (float: every test against them keeps kEdgeOn, far above
  // their rounding, between itself and a sign); zero for a triangle
  // without area, which no ray meets and which is left out of the count.
  std::vector<glm::vec3> normals;
  // Per triangle (model units), its longest edge times how far Embree's
  // own normal for it may stray in ulps (1 + that edge squared over twice
  // its area: 1/sin of its sharpest corner, about); per node, the largest
  // of its triangles'. The depth test's rounding grows with it, for a
  // sliver (see MeshGridShadow::draw).
  std::vector<float> skew;
  std::vector<float> node_skew;
  struct Leaf {
    std::uint32_t first, last;  // its triangles
    // Its inner edges (only its triangles run them) in `edges`: the open
    // ones (their uses do not cancel: a rim) and the shut ones.
    std::uint32_t open_first, open_last, shut_first, shut_last;
  };
  std::vector<Leaf> leaves;
  std::vector<std::uint32_t> node_of;  // per triangle, its leaf's node
  // The leaves' tree, as they were split (preorder: node 0 the whole
  // model): a node whose triangles all face one way settles its leaves and
  // the edges between them with one test.
  struct Node {
    std::uint32_t leaf_first, leaf_last;  // its leaves [first, last)
    std::int32_t left = -1, right = -1;   // children; -1 for a leaf
    // The groups whose two leaves part here (lowest common node).
    std::uint32_t group_first = 0, group_last = 0;
  };
  std::vector<Node> nodes;
  // Per node, the cone of its normals: axis, and the cosine and sine of the
  // largest angle from it (cos_spread <= 0: no cone). Arrays of their own:
  // the one test of a node reads them.
  std::vector<glm::dvec3> axes;
  std::vector<double> cos_spread, sin_spread;
  // An edge run by one or two triangles (one: direction[1] is 0), each
  // with its leaf and its direction: +1 from corner a to b, -1 back.
  struct Edge {
    std::uint32_t a, b;  // corners, a < b
    std::uint32_t triangle[2];
    std::uint32_t leaf[2];
    std::int8_t direction[2];
    std::int8_t sum;
  };
  // The leaves' open inner edges (in leaf order: a node's lie together),
  // their shut ones, the groups' (by node), then the loose ones (from
  // loose_first: run by two leaves without cancelling), so that each pass
  // reads them in order.
  std::vector<Edge> edges;
  // Edges run by the triangles of exactly two leaves, whose uses cancel
  // when both face one way: skipped at once when both leaves do.
  struct Group {
    std::uint32_t leaf_a, leaf_b, first, last;  // edges [first, last)
  };
  std::vector<Group> groups;
  std::uint32_t loose_first = 0;
  // Edges of more than two triangles (never in a real model's surface,
  // but possible): their uses listed, judged at every draw.
  struct Use {
    std::uint32_t triangle, leaf;
    std::int32_t direction;
  };
  struct Many {
    std::uint32_t a, b, first, count;  // uses [first, first + count)
  };
  std::vector<Many> many;
  std::vector<Use> uses;
  std::vector<std::uint32_t> no_area;  // triangles without area: always unsure
  // Per triangle, its three edges: an index into `edges`, or kManyEdge |
  // an index into `many` (kNoEdge for a triangle without area).
  static constexpr std::uint32_t kManyEdge = 0x80000000u, kNoEdge = 0xffffffffu;
  std::vector<std::array<std::uint32_t, 3>> triangle_edges;
};

namespace {

// A triangle whose normal is this near square to the sun (|cos|) is seen
// edge on: its sign is not trusted, it is left out of the count and its
// shadow is unsure.
constexpr double kEdgeOn = 1e-4;
// Crossings and unsure entries one draw gathers at most (beyond twice the
// grid's rows): about 30 MB while gathering, 8 MB of spans after.
constexpr std::size_t kMostGathered = std::size_t(1) << 20;

struct Point2 {
  double x, z;
};

}  // namespace

std::size_t mesh_shadow_model_bytes(const MeshShadowModel& m) {
  return sizeof(m) + m.corners.capacity() * sizeof(m.corners[0]) + m.triangles.capacity() * sizeof(m.triangles[0]) +
         m.normals.capacity() * sizeof(m.normals[0]) + m.leaves.capacity() * sizeof(m.leaves[0]) +
         m.node_of.capacity() * sizeof(std::uint32_t) +
         (m.skew.capacity() + m.node_skew.capacity()) * sizeof(float) +
         m.nodes.capacity() * sizeof(m.nodes[0]) +
         m.axes.capacity() * sizeof(m.axes[0]) + 2 * m.cos_spread.capacity() * sizeof(double) +
         m.edges.capacity() * sizeof(m.edges[0]) + m.groups.capacity() * sizeof(m.groups[0]) +
         m.many.capacity() * sizeof(m.many[0]) + m.uses.capacity() * sizeof(m.uses[0]) +
         m.no_area.capacity() * sizeof(std::uint32_t) + m.triangle_edges.capacity() * sizeof(m.triangle_edges[0]);
}

std::size_t mesh_shadow_model_triangles(const MeshShadowModel& m) { return m.triangles.size(); }

std::shared_ptr<const MeshShadowModel> mesh_shadow_model(const TriangleModel& model) {
  auto out = std::make_shared<MeshShadowModel>();
  MeshShadowModel& m = *out;
  // Corners welded by value, as triangle_shells welds them (Embree sees
  // equal floats as one point, whatever the indices).
  std::uint32_t ids = 0;
  const std::vector<std::array<std::uint32_t, 3>> welded = welded_corners(model, ids);
  m.corners.assign(ids, glm::vec3(0.0f));
  // Triangles, each with its unit normal (zero: no area).
  struct Input {
    MeshShadowModel::Triangle t;
    glm::vec3 normal;
    float skew;
    glm::dvec3 centre;
  };
  std::vector<Input> input;
  input.reserve(welded.size());
  for (const ModelPart& part : model.parts)
    for (std::size_t t = 0; t < part.triangle_count(); ++t) {
      Input in;
      for (int k = 0; k < 3; ++k) {
        in.t.v[k] = welded[input.size()][std::size_t(k)];
        m.corners[in.t.v[k]] = part.positions[part.indices[3 * t + std::size_t(k)]];
      }
      input.push_back(in);
    }
  for (Input& in : input) {
    const glm::dvec3 a(m.corners[in.t.v[0]]), b(m.corners[in.t.v[1]]), c(m.corners[in.t.v[2]]);
    const glm::dvec3 e1 = b - a, e2 = c - a;
    const glm::dvec3 n = glm::cross(e1, e2);
    const double length = glm::length(n);
    const bool area = in.t.v[0] != in.t.v[1] && in.t.v[1] != in.t.v[2] && in.t.v[0] != in.t.v[2] &&
                      length > 1e-12 * glm::length(e1) * glm::length(e2);
    in.normal = area ? glm::vec3(n / length) : glm::vec3(0.0f);
    const double longest = std::max({glm::length(e1), glm::length(e2), glm::length(c - b)});
    in.skew = area ? float(longest * (1.0 + longest * longest / length)) * 1.001f : 0.0f;
    in.centre = (a + b + c) / 3.0;
  }
  // Leaves: halved at the median along the longest side of their centres
  // or, where their normals spread wider than the leaf is long, of their
  // normals (scaled by the leaf's size), until a leaf holds at most
  // kMeshShadowLeaf triangles whose normals lie within about 10 degrees of
  // their axis (or at most 4 triangles): a leaf is one test while the sun
  // stays clear of square to all its normals, and the silhouette crosses
  // few.
  struct Cone {
    glm::dvec3 axis{0.0};
    double cos_spread = -1.0, sin_spread = 1.0;
  };
  const auto cone_of = [&](std::size_t first, std::size_t last) {
    Cone cone;
    glm::dvec3 sum(0.0);
    for (std::size_t i = first; i < last; ++i) sum += glm::dvec3(input[i].normal);
    if (glm::length(sum) == 0.0) return cone;
    const glm::dvec3 axis = glm::normalize(sum);
    double low = 1.0;
    // Each normal made unit in double first: a float normal can be a few
    // 1e-8 longer than 1, and a spread's sine taken from a cosine that
    // much too high comes out up to sqrt(2e-8) too small, more than
    // kEdgeOn for a tight cone (the red team's fold: a triangle 1e-4 from
    // edge on settled with its leaf).
    for (std::size_t i = first; i < last; ++i)
      if (input[i].normal != glm::vec3(0.0f))
        low = std::min(low, glm::dot(glm::normalize(glm::dvec3(input[i].normal)), axis));
    // A hair lower: the dot products' rounding.
    low -= 1e-9;
    if (low <= 0.05) return cone;
    cone.axis = axis;
    cone.cos_spread = low;
    cone.sin_spread = std::sqrt(std::max(0.0, 1.0 - low * low));
    return cone;
  };
  std::vector<std::pair<std::size_t, std::size_t>> leaves, node_triangles;
  std::vector<std::uint32_t> leaf_nodes;
  const auto split = [&](auto&& self, std::size_t first, std::size_t last) -> std::int32_t {
    const std::size_t count = last - first;
    const std::int32_t node = std::int32_t(m.nodes.size());
    m.nodes.push_back({std::uint32_t(leaves.size()), 0});
    node_triangles.emplace_back(first, last);
    if (count <= 4 || (count <= std::size_t(kMeshShadowLeaf) && cone_of(first, last).cos_spread >= 0.985)) {
      leaves.emplace_back(first, last);
      leaf_nodes.push_back(std::uint32_t(node));
      m.nodes[std::size_t(node)].leaf_last = std::uint32_t(leaves.size());
      return node;
    }
    Aabb centres, normals;
    for (std::size_t i = first; i < last; ++i) centres.extend(input[i].centre), normals.extend(glm::dvec3(input[i].normal));
    const glm::dvec3 e = centres.extent(), n = normals.extent() * 0.5 * std::max({e.x, e.y, e.z});
    int axis = 0;
    double longest = -1.0;
    for (int k = 0; k < 6; ++k) {
      const double side = k < 3 ? e[k] : n[k - 3];
      if (side > longest) longest = side, axis = k;
    }
    if (!(longest > 0.0)) {  // all alike: no split parts them
      leaves.emplace_back(first, last);
      leaf_nodes.push_back(std::uint32_t(node));
      m.nodes[std::size_t(node)].leaf_last = std::uint32_t(leaves.size());
      return node;
    }
    const std::size_t middle = first + count / 2;
    std::nth_element(input.begin() + std::ptrdiff_t(first), input.begin() + std::ptrdiff_t(middle),
                     input.begin() + std::ptrdiff_t(last), [axis](const Input& a, const Input& b) {
                       return axis < 3 ? a.centre[axis] < b.centre[axis] : a.normal[axis - 3] < b.normal[axis - 3];
                     });
    const std::int32_t left = self(self, first, middle), right = self(self, middle, last);
    m.nodes[std::size_t(node)].left = left, m.nodes[std::size_t(node)].right = right;
    m.nodes[std::size_t(node)].leaf_last = std::uint32_t(leaves.size());
    return node;
  };
  if (!input.empty()) split(split, 0, input.size());
  for (const auto& [first, last] : node_triangles) {
    float skew = 0.0f;
    for (std::size_t i = first; i < last; ++i) skew = std::max(skew, input[i].skew);
    m.node_skew.push_back(skew);
    const Cone cone = cone_of(first, last);
    m.axes.push_back(cone.axis);
    m.cos_spread.push_back(cone.cos_spread);
    m.sin_spread.push_back(cone.sin_spread);
  }
  // The corners renumbered in order of first use.
  std::vector<std::uint32_t> renumbered(m.corners.size(), std::numeric_limits<std::uint32_t>::max());
  std::vector<glm::vec3> corners;
  std::vector<std::uint32_t> leaf_of;
  m.triangles.reserve(input.size());
  m.normals.reserve(input.size());
  leaf_of.reserve(input.size());
  for (const auto& [first, last] : leaves) {
    m.leaves.push_back({std::uint32_t(first), std::uint32_t(last), 0, 0, 0, 0});
    for (std::size_t i = first; i < last; ++i) {
      MeshShadowModel::Triangle t = input[i].t;
      for (std::uint32_t& v : t.v) {
        if (renumbered[v] == std::numeric_limits<std::uint32_t>::max()) {
          renumbered[v] = std::uint32_t(corners.size());
          corners.push_back(m.corners[v]);
        }
        v = renumbered[v];
      }
      m.triangles.push_back(t);
      m.node_of.push_back(leaf_nodes[m.leaves.size() - 1]);
      m.normals.push_back(input[i].normal);
      m.skew.push_back(input[i].skew);
      leaf_of.push_back(std::uint32_t(m.leaves.size() - 1));
      if (input[i].normal == glm::vec3(0.0f)) m.no_area.push_back(std::uint32_t(i));
    }
  }
  m.corners = std::move(corners);
  // Edges: every triangle with area's three, by their corners.
  struct Run {
    std::uint32_t a, b, triangle;
    std::int32_t direction;
  };
  std::vector<Run> runs;
  runs.reserve(3 * m.triangles.size());
  for (std::uint32_t t = 0; t < m.triangles.size(); ++t) {
    if (m.normals[t] == glm::vec3(0.0f)) continue;
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t from = m.triangles[t].v[k], to = m.triangles[t].v[(k + 1) % 3];
      runs.push_back({std::min(from, to), std::max(from, to), t, from < to ? 1 : -1});
    }
  }
  std::sort(runs.begin(), runs.end(),
            [](const Run& x, const Run& y) { return std::tie(x.a, x.b, x.triangle) < std::tie(y.a, y.b, y.triangle); });
  // The lowest node holding both leaves.
  const auto parting = [&](std::uint32_t la, std::uint32_t lb) {
    std::size_t node = 0;
    while (m.nodes[node].left >= 0) {
      const MeshShadowModel::Node& left = m.nodes[std::size_t(m.nodes[node].left)];
      if (la >= left.leaf_first && la < left.leaf_last && lb >= left.leaf_first && lb < left.leaf_last)
        node = std::size_t(m.nodes[node].left);
      else if (la >= left.leaf_last && lb >= left.leaf_last)
        node = std::size_t(m.nodes[node].right);
      else
        break;
    }
    return std::uint32_t(node);
  };
  // Each edge's place: a leaf's inner edges (open, shut), a group between
  // two leaves (by the node where they part), or loose.
  struct Placed {
    int kind;  // 0 open inner, 1 shut inner, 2 group, 3 loose
    std::uint32_t key[3];
    MeshShadowModel::Edge edge;
  };
  std::vector<Placed> placed;
  for (std::size_t i = 0; i < runs.size();) {
    std::size_t j = i;
    while (j < runs.size() && runs[j].a == runs[i].a && runs[j].b == runs[i].b) ++j;
    if (j - i > 2) {
      m.many.push_back({runs[i].a, runs[i].b, std::uint32_t(m.uses.size()), std::uint32_t(j - i)});
      for (std::size_t k = i; k < j; ++k) m.uses.push_back({runs[k].triangle, leaf_of[runs[k].triangle], runs[k].direction});
      i = j;
      continue;
    }
    MeshShadowModel::Edge edge{};
    edge.a = runs[i].a, edge.b = runs[i].b;
    const std::size_t second = j - i == 2 ? i + 1 : i;
    edge.triangle[0] = runs[i].triangle, edge.triangle[1] = runs[second].triangle;
    edge.leaf[0] = leaf_of[edge.triangle[0]], edge.leaf[1] = leaf_of[edge.triangle[1]];
    edge.direction[0] = std::int8_t(runs[i].direction);
    edge.direction[1] = j - i == 2 ? std::int8_t(runs[second].direction) : std::int8_t(0);
    edge.sum = std::int8_t(edge.direction[0] + edge.direction[1]);
    const std::uint32_t la = std::min(edge.leaf[0], edge.leaf[1]), lb = std::max(edge.leaf[0], edge.leaf[1]);
    if (la == lb)
      placed.push_back({edge.sum != 0 ? 0 : 1, {la, 0, 0}, edge});
    else if (edge.sum == 0)
      placed.push_back({2, {parting(la, lb), la, lb}, edge});
    else
      placed.push_back({3, {0, 0, 0}, edge});
    i = j;
  }
  std::stable_sort(placed.begin(), placed.end(), [](const Placed& x, const Placed& y) {
    return std::tie(x.kind, x.key[0], x.key[1], x.key[2]) < std::tie(y.kind, y.key[0], y.key[1], y.key[2]);
  });
  m.edges.reserve(placed.size());
  for (const Placed& p : placed) m.edges.push_back(p.edge);
  std::size_t i = 0;
  for (std::uint32_t l = 0; l < m.leaves.size(); ++l) {
    m.leaves[l].open_first = std::uint32_t(i);
    while (i < placed.size() && placed[i].kind == 0 && placed[i].key[0] == l) ++i;
    m.leaves[l].open_last = std::uint32_t(i);
  }
  for (std::uint32_t l = 0; l < m.leaves.size(); ++l) {
    m.leaves[l].shut_first = std::uint32_t(i);
    while (i < placed.size() && placed[i].kind == 1 && placed[i].key[0] == l) ++i;
    m.leaves[l].shut_last = std::uint32_t(i);
  }
  for (; i < placed.size() && placed[i].kind == 2; ++i) {
    if (m.groups.empty() || m.groups.back().leaf_a != placed[i].key[1] || m.groups.back().leaf_b != placed[i].key[2]) {
      MeshShadowModel::Node& node = m.nodes[placed[i].key[0]];
      if (node.group_first == node.group_last) node.group_first = node.group_last = std::uint32_t(m.groups.size());
      m.groups.push_back({placed[i].key[1], placed[i].key[2], std::uint32_t(i), std::uint32_t(i)});
      node.group_last = std::uint32_t(m.groups.size());
    }
    m.groups.back().last = std::uint32_t(i + 1);
  }
  m.loose_first = std::uint32_t(i);
  m.triangle_edges.assign(m.triangles.size(), {MeshShadowModel::kNoEdge, MeshShadowModel::kNoEdge, MeshShadowModel::kNoEdge});
  const auto attach = [&](std::uint32_t t, std::uint32_t index) {
    for (std::uint32_t& slot : m.triangle_edges[t])
      if (slot == MeshShadowModel::kNoEdge) {
        slot = index;
        return;
      }
  };
  for (std::uint32_t e = 0; e < m.edges.size(); ++e) {
    attach(m.edges[e].triangle[0], e);
    if (m.edges[e].direction[1] != 0) attach(m.edges[e].triangle[1], e);
  }
  for (std::uint32_t e = 0; e < m.many.size(); ++e)
    for (std::uint32_t u = m.many[e].first; u < m.many[e].first + m.many[e].count; ++u)
      attach(m.uses[u].triangle, MeshShadowModel::kManyEdge | e);
  return out;
}

glm::dvec3 MeshGridShadow::corner(std::uint32_t i) const {
  return glm::dvec3(to_world_ * glm::dvec4(glm::dvec3(model_->corners[i]), 1.0));
}

namespace {

// A memory stays while the sun's direction (unit, model space) is within
// kDrift of the one it judged at (chord length): a triangle whose normal's
// cosine with it lay further than kEdgeOn + kDrift from 0 keeps its sign
// and its face till then. Its tracked triangles go in kBuckets by that
// room, so a draw re-judges only those with too little of it.
constexpr double kDrift = 0.06;
constexpr int kBuckets = 32;
constexpr std::uint8_t kSteady = 63;  // not tracked: settled with the whole drift to spare
// A memory's triangle in one byte: its sign + 1 (two bits), its bucket.
constexpr std::uint8_t pack(int sign, std::uint8_t bucket) { return std::uint8_t((sign + 1) | (bucket << 2)); }

}  // namespace

struct MeshGridShadow::Memory {
  bool valid = false;
  glm::dvec3 dm{0.0};                 // the direction judged at
  glm::dvec3 last{0.0};               // the last draw's, judged or not
  std::vector<std::int8_t> leaf_sign;  // then, per leaf (kMixed: per triangle)
  // Per triangle, pack(its sign then (a mixed leaf's), its room's bucket
  // or kSteady): a memory per time of day of a year's draws is a memory
  // per slot, a hundred of them a model.
  std::vector<std::uint8_t> state;
  std::vector<std::uint32_t> tracked, tracked_start;  // tracked triangles by bucket
  // Per tracked triangle (in tracked's order), its sign at the last draw;
  // the most buckets a draw has judged again since the start (a draw
  // judges at least those again, so that a triangle judged once stays
  // judged while the sun comes back).
  std::vector<std::int8_t> last_sign;
  int peak = 0;
  struct Kept {
    std::uint32_t a, b;  // the edge's corners (its part above the cut is drawn again)
    std::uint32_t edge;  // its index in the model's edges
    std::int32_t times;
    std::uint32_t bucket;  // the lower of its triangles'
  };
  std::vector<Kept> outline;  // the outline edges at the last draw
  std::size_t counted = 0;    // bytes counted in the placement's memory_held_
  std::size_t bytes() const {
    return leaf_sign.capacity() + state.capacity() +
           4 * (tracked.capacity() + tracked_start.capacity()) + last_sign.capacity() +
           sizeof(Kept) * outline.capacity();
  }
};

MeshGridShadow::~MeshGridShadow() = default;
MeshGridShadow::MeshGridShadow(MeshGridShadow&&) noexcept = default;

MeshGridShadow::MeshGridShadow(std::shared_ptr<const MeshShadowModel> model, const glm::dmat4& to_world,
                               double plane_y, double margin, int slots)
    : model_(std::move(model)),
      to_world_(to_world),
      to_model_(glm::inverse(glm::dmat3(to_world))),
      plane_y_(plane_y),
      margin_(margin) {
  const MeshShadowModel& m = *model_;
  height_.resize(m.corners.size());
  corner_y_.resize(m.corners.size());
  // Every corner in reach_: a triangle far below the plane may still be
  // met by a ray's line seen edge on (MeshGridShadow::draw's
  // triangle_unsure).
  for (std::size_t i = 0; i < m.corners.size(); ++i) {
    const glm::dvec3 p = corner(std::uint32_t(i));
    corner_y_[i] = p.y;
    height_[i] = p.y < plane_y - margin ? 0 : (p.y < plane_y + margin ? 1 : 2);
    reach_.extend(p);
  }
  // The columns' lengths are the placement's scales: placements are
  // translate x turn x scale (mesh_transform), never sheared (a shear
  // would stretch more than these tell).
  const glm::dmat3 linear(to_world);
  const double x = glm::length(linear[0]), y = glm::length(linear[1]), z = glm::length(linear[2]);
  stretch_ = std::min({x, y, z}) > 0.0 ? std::max({x, y, z}) / std::min({x, y, z}) : 1e300;
  scale_ = x + y + z;
  // Each node's lowest and highest corner, after its children (preorder,
  // backwards).
  node_low_.assign(m.nodes.size(), 1e300);
  node_high_.assign(m.nodes.size(), -1e300);
  for (std::size_t n = m.nodes.size(); n-- > 0;) {
    const MeshShadowModel::Node& node = m.nodes[n];
    if (node.left < 0) {
      const MeshShadowModel::Leaf& leaf = m.leaves[node.leaf_first];
      for (std::uint32_t t = leaf.first; t < leaf.last; ++t)
        for (const std::uint32_t c : m.triangles[t].v)
          node_low_[n] = std::min(node_low_[n], corner_y_[c]), node_high_[n] = std::max(node_high_[n], corner_y_[c]);
    } else {
      node_low_[n] = std::min(node_low_[std::size_t(node.left)], node_low_[std::size_t(node.right)]);
      node_high_[n] = std::max(node_high_[std::size_t(node.left)], node_high_[std::size_t(node.right)]);
    }
  }
  for (int i = 0; i < slots; ++i) memory_.push_back(std::make_unique<Memory>());
  memory_held_ = std::make_unique<std::atomic<std::size_t>>(0);
}

namespace {

// What a draw gathers before it sorts: crossings of rows by the outline
// (with the change in count) and unsure columns.
struct Crossing {
  int row;
  double x;
  int change;
};
struct Unsure {
  int row;
  ColumnSpan columns;
};

}  // namespace

void MeshGridShadow::draw(const glm::dvec3& d, const SunGrid& grid, int row_step, GridShadow& out, int slot,
                          std::size_t most_gathered, bool start_when_far) const {
  out.first_row = 0, out.last_row = -1;
  out.dark_start.clear(), out.unsure_start.clear(), out.dark.clear(), out.unsure.clear();
  out.work = 0.0;
  if (!(d.y > 0.0) || reach_.empty() || grid.rows <= 0 || grid.columns <= 0) return;
  const MeshShadowModel& m = *model_;
  const glm::dvec3 dm = glm::normalize(to_model_ * d);
  const glm::dvec3 origin = grid.origin();
  const double spacing = grid.spacing, cut = plane_y_ + margin_;
  // The largest magnitude the steps below meet: the rounding of each (a
  // slide, a crossing, a grid point) is a few 1e-16 of it.
  const double extent = std::max({1.0, std::abs(origin.x), std::abs(origin.z), std::abs(reach_.min.x),
                                  std::abs(reach_.max.x), std::abs(reach_.min.z), std::abs(reach_.max.z),
                                  (reach_.max.y - plane_y_) / d.y});
  // How far from the outline a point's ray may pass and still be judged:
  // the margin (the ray cast's rounding, across the ray) slid onto the
  // plane, where it stretches by 1 / d.y at most, and this code's own.
  const double reach = margin_ * (1.0 + 1e-6) / d.y + 1e-9 * extent;
  const auto slide = [&](const glm::dvec3& p) {
    const double t = (p.y - plane_y_) / d.y;
    return Point2{p.x - t * d.x, p.z - t * d.z};
  };
  const auto row_z = [&](int r) { return origin.z + double(r) * spacing; };

  thread_local std::vector<Crossing> crossings;
  thread_local std::vector<Unsure> unsure;
  thread_local std::vector<std::int8_t> own_sign, own_leaf_sign;
  crossings.clear(), unsure.clear();
  Memory* memory = slot >= 0 && std::size_t(slot) < memory_.size() ? memory_[std::size_t(slot)].get() : nullptr;
  // Samples further apart than half the drift (a year's, ten minutes
  // apart, in one slot) would each start a memory afresh, which costs more
  // than a fresh draw: those draw fresh, unless the caller's next draws in
  // the slot will be near this one (the first of a run of minutes, or a
  // time of day's first day): those start the memory now.
  if (memory) {
    const bool far = glm::length(dm - memory->last) > 0.5 * kDrift;
    memory->last = dm;
    if (far && !start_when_far)
      memory = nullptr;
    else if (far)
      memory->valid = false;  // starts afresh below
    // A slot that holds nothing yet starts only while the placement's
    // memories hold less than their budget (past it, its draws are fresh).
    if (memory && memory->counted == 0 && memory_budget_ > 0 &&
        memory_held_->load(std::memory_order_relaxed) >= memory_budget_)
      memory = nullptr;
  }
  std::vector<std::int8_t>& leaf_sign = memory ? memory->leaf_sign : own_leaf_sign;
  if (!memory && own_sign.size() < m.triangles.size()) own_sign.resize(m.triangles.size());
  if (memory && memory->state.size() < m.triangles.size()) memory->state.resize(m.triangles.size(), pack(0, kSteady));
  // A triangle's sign as its mixed leaf judged it, and its bucket.
  const auto triangle_sign = [&](std::uint32_t t) {
    return memory ? int(memory->state[t] & 3) - 1 : int(own_sign[t]);
  };
  const auto bucket_of = [&](std::uint32_t t) { return std::uint8_t(memory->state[t] >> 2); };
  if (leaf_sign.size() < m.leaves.size()) leaf_sign.resize(m.leaves.size());
  constexpr std::int8_t kMixed = 2;
  double work = double(m.leaves.size());

  // The rows (multiples of row_step in the grid) whose z lies in [low, high].
  // (Products by the inverse spacing, a row more each way: every row is
  // checked against its band below; the columns' rounding, a few 1e-16 of
  // the magnitudes, is far inside reach's 1e-9 of them.)
  const double inverse = 1.0 / spacing;
  const auto rows_between = [&](double low, double high, int& r0, int& r1) {
    const double from = std::max(0.0, std::ceil((low - origin.z) * inverse) - 1.0);
    const double to = std::min(double(grid.rows - 1), std::floor((high - origin.z) * inverse) + 1.0);
    if (!(from <= to)) return false;
    r0 = row_step == 1 ? int(from) : int(std::ceil(from / row_step)) * row_step, r1 = int(to);
    return r0 <= r1;
  };
  // The columns within `reach` of a convex polygon (1 to 5 points slid
  // onto the plane) in each row it comes near: unsure.
  // What one draw may gather: past it (a field of thin blades under a low
  // sun crossing every row each), the draw gives up its outline and takes
  // its whole slid box as unsure instead, so its memory stays bounded.
  const std::size_t most = (most_gathered > 0 ? most_gathered : kMostGathered) + 2 * std::size_t(grid.rows);
  bool overflow = false;
  const auto full = [&] {
    overflow = overflow || crossings.size() + unsure.size() >= most;
    return overflow;
  };
  const auto mark_unsure = [&](const Point2* p, int n) {
    if (full()) return;
    double z_low = p[0].z, z_high = p[0].z;
    for (int i = 1; i < n; ++i) z_low = std::min(z_low, p[i].z), z_high = std::max(z_high, p[i].z);
    int r0, r1;
    if (!rows_between(z_low - reach, z_high + reach, r0, r1)) return;
    for (int r = r0; r <= r1; r += row_step) {
      const double z = row_z(r), band_low = z - reach, band_high = z + reach;
      double x_low = 1e300, x_high = -1e300;
      const int edges = n == 2 ? 1 : n;
      for (int i = 0; i < edges; ++i) {
        const Point2& a = p[i];
        const Point2& b = p[(i + 1) % n];
        const double e_low = std::min(a.z, b.z), e_high = std::max(a.z, b.z);
        if (e_high < band_low || e_low > band_high) continue;
        if (a.z == b.z) {
          x_low = std::min({x_low, a.x, b.x}), x_high = std::max({x_high, a.x, b.x});
          continue;
        }
        for (const double at : {std::max(band_low, e_low), std::min(band_high, e_high)}) {
          const double s = std::clamp((at - a.z) / (b.z - a.z), 0.0, 1.0);
          const double x = a.x + s * (b.x - a.x);
          x_low = std::min(x_low, x), x_high = std::max(x_high, x);
        }
      }
      if (n == 1 && p[0].z >= band_low && p[0].z <= band_high) x_low = x_high = p[0].x;
      if (x_low > x_high) continue;
      const double c0 = std::max(0.0, std::ceil((x_low - reach - origin.x) * inverse));
      const double c1 = std::min(double(grid.columns - 1), std::floor((x_high + reach - origin.x) * inverse));
      if (c0 <= c1) unsure.push_back({r, {int(c0), int(c1)}});
      work += 1.0;
    }
  };
  // An outline edge from a to b counted `times` (the net of the triangles
  // that run it): its crossings of the rows, and its unsure columns (those
  // within `reach` of it, in the rows whose band of z within `reach` it
  // meets). One pass over its rows for both: the silhouette's edges are
  // most of a draw, and most meet no row at all.
  const auto outline = [&](const Point2& a, const Point2& b, int times) {
    work += 1.0;
    if (full()) return;
    const double low = std::min(a.z, b.z), high = std::max(a.z, b.z);
    // A row more each way than the products find: each is checked below.
    const double from = std::max(0.0, std::ceil((low - reach - origin.z) * inverse) - 1.0);
    const double to = std::min(double(grid.rows - 1), std::floor((high + reach - origin.z) * inverse) + 1.0);
    if (!(from <= to)) return;
    const int change = (b.z > a.z ? 1 : -1) * times;
    for (int r = row_step == 1 ? int(from) : int(std::ceil(from / row_step)) * row_step; r <= int(to); r += row_step) {
      const double z = row_z(r);
      if (high < z - reach || low > z + reach) continue;
      double x_low, x_high;
      if (a.z == b.z) {
        x_low = std::min(a.x, b.x), x_high = std::max(a.x, b.x);
      } else {
        const double s0 = std::clamp((z - reach - a.z) / (b.z - a.z), 0.0, 1.0);
        const double s1 = std::clamp((z + reach - a.z) / (b.z - a.z), 0.0, 1.0);
        x_low = a.x + s0 * (b.x - a.x), x_high = a.x + s1 * (b.x - a.x);
        if (x_low > x_high) std::swap(x_low, x_high);
        // Half open, so that two edges that meet at a row's height count once.
        if ((a.z <= z) != (b.z <= z)) crossings.push_back({r, a.x + (z - a.z) * (b.x - a.x) / (b.z - a.z), change});
      }
      const double c0 = std::max(0.0, std::ceil((x_low - reach - origin.x) * inverse));
      const double c1 = std::min(double(grid.columns - 1), std::floor((x_high + reach - origin.x) * inverse));
      if (c0 <= c1) unsure.push_back({r, {int(c0), int(c1)}});
    }
  };
  // Where the edge between corners i < j crosses the cut (the same point
  // for every triangle that runs it, so that their parts above still meet).
  const auto cut_point = [&](std::uint32_t i, std::uint32_t j) {
    const glm::dvec3 p = corner(i), q = corner(j);
    glm::dvec3 c = p + (cut - p.y) / (q.y - p.y) * (q - p);
    c.y = cut;
    return c;
  };
  // An edge (a < b), its part above the cut, counted `times`.
  // (With `keep`, also kept in the memory with that bucket.)
  const auto edge_outline = [&](std::uint32_t a, std::uint32_t b, int times, int keep = -1, std::uint32_t edge = 0) {
    const bool a_up = height_[a] == 2, b_up = height_[b] == 2;
    if (!a_up && !b_up) return;
    const glm::dvec3 p = a_up ? corner(a) : cut_point(a, b);
    const glm::dvec3 q = b_up ? corner(b) : cut_point(a, b);
    outline(slide(p), slide(q), times);
    if (keep >= 0) memory->outline.push_back({a, b, edge, times, std::uint32_t(keep)});
  };
  // A triangle seen edge on or without area, wherever it is: Embree's
  // depth test on it is noise (below the plane too), so every point whose
  // ray's line meets it is unsure.
  const auto triangle_unsure = [&](std::uint32_t t) {
    const auto& v = m.triangles[t].v;
    const Point2 p[3] = {slide(corner(v[0])), slide(corner(v[1])), slide(corner(v[2]))};
    mark_unsure(p, 3);
  };
  // A triangle near the plane: its part within `slab` of it is unsure (a
  // ray from the plane may meet it or not, whatever Embree's depth test
  // says), and its part above the cut ends in a cut edge from where its
  // outline leaves the part above to where it comes back.
  const auto near_plane = [&](std::uint32_t t, int s, double slab) {
    const auto& v = m.triangles[t].v;
    // The triangle clipped to plane_y +- slab (Sutherland-Hodgman).
    glm::dvec3 poly[7], next[7];
    int n = 3;
    for (int k = 0; k < 3; ++k) poly[k] = corner(v[k]);
    for (const double side : {-1.0, 1.0}) {
      const double bound = plane_y_ + side * slab;
      int kept = 0;
      for (int k = 0; k < n; ++k) {
        const glm::dvec3 &a = poly[k], &b = poly[(k + 1) % n];
        const bool a_in = side < 0 ? a.y >= bound : a.y <= bound, b_in = side < 0 ? b.y >= bound : b.y <= bound;
        if (a_in) next[kept++] = a;
        if (a_in != b_in) {
          glm::dvec3 c = a + (bound - a.y) / (b.y - a.y) * (b - a);
          c.y = bound;
          next[kept++] = c;
        }
      }
      n = kept;
      std::copy(next, next + n, poly);
      if (n == 0) break;
    }
    if (n > 0) {
      Point2 p[7];
      for (int k = 0; k < n; ++k) p[k] = slide(poly[k]);
      mark_unsure(p, n);
    }
    if (s == 0) return;
    int exit_edge = -1, entry_edge = -1;
    for (int k = 0; k < 3; ++k) {
      const bool from_up = height_[v[k]] == 2, to_up = height_[v[(k + 1) % 3]] == 2;
      if (from_up && !to_up) exit_edge = k;
      if (!from_up && to_up) entry_edge = k;
    }
    if (exit_edge < 0 || entry_edge < 0) return;
    const auto on = [&](int k) {
      const std::uint32_t i = v[k], j = v[(k + 1) % 3];
      return cut_point(std::min(i, j), std::max(i, j));
    };
    outline(slide(on(exit_edge)), slide(on(entry_edge)), s);
  };

  const auto sign_of = [&](std::uint32_t t, std::uint32_t leaf) {
    const int s = leaf_sign[leaf];
    return s == kMixed ? triangle_sign(t) : s;
  };
  // The net of the triangles that run an edge, each by `signs(t, leaf)`.
  const auto net = [&](const MeshShadowModel::Edge& e, const auto& signs) {
    return signs(e.triangle[0], e.leaf[0]) * e.direction[0] + signs(e.triangle[1], e.leaf[1]) * e.direction[1];
  };
  // The edges run by more than two triangles, judged at every draw.
  const auto judge_many = [&](const auto& signs) {
    for (const MeshShadowModel::Many& e : m.many) {
      int times = 0;
      for (std::uint32_t u = e.first; u < e.first + e.count; ++u)
        times += signs(m.uses[u].triangle, m.uses[u].leaf) * m.uses[u].direction;
      if (times != 0) edge_outline(e.a, e.b, times);
    }
  };
  // How near the plane a hit on a triangle may be misjudged. Embree's
  // depth test takes t from dot(v0 - O, Ng) / dot(D, Ng) in float: its
  // rounding, a few ulps of the coordinates and, for a sliver whose normal
  // Embree finds less well, of its length times 1/sin of its sharpest
  // corner (skew), against the origin's distance from the triangle's
  // plane, t times the cosine between the ray and the normal. Where that
  // exceeds twice the margin (1e-5 of the coordinates, a hundred times the
  // rounding) plus 1e-5 of the sliver's term, the hit's side is sure; the
  // parts of a triangle nearer the plane than that (in height: `slab`, at
  // least the margin) are unsure, above it (the ray may miss them) and
  // below it (the ray may meet them). Uneven stretching multiplies it.
  // (The slab is numerator / cosine, at least the margin.)
  const auto slab_numerator = [&](double skew, double dy) {
    return 2.0 * stretch_ * dy * (margin_ + 1e-5 * scale_ * skew);
  };
  const auto slab_of = [&](double skew, double cosine, double dy) {
    return std::max(margin_, slab_numerator(skew, dy) / cosine);
  };
  // A triangle with area judged alone: its sign (0 if it has no part above
  // the cut, or is seen edge on, its shadow then unsure), its cut outline
  // where it crosses the cut and its unsure slice near the plane.
  // (`low`, `high`: bounds on its corners' heights, its leaf's: a leaf
  // clear of the slab spares loading them.)
  const auto judge_triangle = [&](std::uint32_t t, double facing, double low, double high) -> std::int8_t {
    work += 1.0;
    if (std::abs(facing) <= kEdgeOn) {
      triangle_unsure(t);
      return 0;
    }
    const auto& v = m.triangles[t].v;
    const std::int8_t s =
        height_[v[0]] == 2 || height_[v[1]] == 2 || height_[v[2]] == 2 ? (facing > 0.0 ? 1 : -1) : 0;
    // Clear of the plane by more than its slab: (height) |cos| > the
    // slab's numerator, without a division (most triangles, a leaf far up).
    const double room = std::max(low - plane_y_, plane_y_ - high);
    if (room > margin_ && room * std::abs(facing) > slab_numerator(m.skew[t], d.y)) return s;
    const double slab = slab_of(m.skew[t], std::abs(facing), d.y);
    low = std::min({corner_y_[v[0]], corner_y_[v[1]], corner_y_[v[2]]});
    high = std::max({corner_y_[v[0]], corner_y_[v[1]], corner_y_[v[2]]});
    if (low < plane_y_ + slab && high > plane_y_ - slab) near_plane(t, s, slab);
    return s;
  };
  // The tracked triangles' buckets of room (Memory): 0 for none.
  const double bucket_width = kDrift / kBuckets;
  // (A hair more: the normals are floats, a few 1e-8 off unit length.)
  const double drift = memory && memory->valid ? glm::length(dm - memory->dm) * (1.0 + 1e-6) : 1e300;
  const int turned = int(std::min<double>(kBuckets, std::ceil(drift / bucket_width)));
  if (memory && turned < kBuckets) {
    // Since the memory's direction the sun has turned by `drift`: the
    // tracked triangles with no more room than that are judged again
    // (and those judged again since the start); the rest keep their sign.
    // This draw's signs of the re-judged triangles, and per triangle and
    // per edge the draw that last flipped or judged it: scratch of the
    // thread's own, not the memory's.
    thread_local std::vector<std::int8_t> now;
    thread_local std::vector<std::uint32_t> stamp, flip_stamp, flips;
    thread_local std::uint32_t clock = 0;
    if (now.size() < m.triangles.size()) now.resize(m.triangles.size());
    if (flip_stamp.size() < m.triangles.size()) flip_stamp.resize(m.triangles.size(), 0u);
    if (stamp.size() < m.edges.size()) stamp.resize(m.edges.size(), 0u);
    if (++clock == 0) {
      std::fill(stamp.begin(), stamp.end(), 0u), std::fill(flip_stamp.begin(), flip_stamp.end(), 0u);
      clock = 1;
    }
    const int judged = std::max(turned, memory->peak);
    memory->peak = judged;
    const std::uint32_t* tracked = memory->tracked.data();
    const std::size_t count = memory->tracked_start[std::size_t(judged) + 1];
    flips.clear();
    for (std::size_t i = memory->tracked_start[0]; i < count; ++i) {
      const std::uint32_t t = tracked[i];
      const std::int8_t s = judge_triangle(t, glm::dot(glm::dvec3(m.normals[t]), dm), node_low_[m.node_of[t]],
                                           node_high_[m.node_of[t]]);
      now[t] = s;
      if (s != memory->last_sign[i]) memory->last_sign[i] = s, flip_stamp[t] = clock, flips.push_back(t);
    }
    const auto sign_now = [&](std::uint32_t t, std::uint32_t leaf) {
      return bucket_of(t) <= judged ? int(now[t]) : sign_of(t, leaf);
    };
    // The memory's outline is the last draw's: an edge's net changes only
    // where one of its triangles flipped since, so the rest stands, and
    // the edges of those are judged again (and kept, where not zero).
    const auto flipped = [&](std::uint32_t t) { return flip_stamp[t] == clock; };
    std::size_t kept = 0;
    for (std::size_t i = 0; i < memory->outline.size(); ++i) {
      const Memory::Kept k = memory->outline[i];
      if (k.bucket <= std::uint32_t(judged)) {
        const MeshShadowModel::Edge& e = m.edges[k.edge];
        if (flipped(e.triangle[0]) || (e.direction[1] != 0 && flipped(e.triangle[1]))) continue;
      }
      edge_outline(k.a, k.b, k.times);
      memory->outline[kept++] = k;
    }
    memory->outline.resize(kept);
    for (const std::uint32_t t : flips)
      for (const std::uint32_t index : m.triangle_edges[t]) {
        if (index == MeshShadowModel::kNoEdge || (index & MeshShadowModel::kManyEdge)) continue;
        if (stamp[index] == clock) continue;
        stamp[index] = clock;
        const MeshShadowModel::Edge& e = m.edges[index];
        work += 0.25;
        const int times = net(e, sign_now);
        if (times != 0)
          edge_outline(e.a, e.b, times, int(std::min(bucket_of(e.triangle[0]), bucket_of(e.triangle[1]))), index);
      }
    judge_many(sign_now);
    for (const std::uint32_t t : m.no_area) triangle_unsure(t);
    work += double(memory->outline.size()) * 0.25;
  } else {
    if (memory) {
      memory->valid = true;
      memory->dm = dm;
      memory->state.assign(m.triangles.size(), pack(0, kSteady));
      memory->tracked.clear();
      memory->outline.clear();
    }
    const auto judge = [&](const MeshShadowModel::Edge& e) {
      const int times = net(e, sign_of);
      if (times == 0) return;
      edge_outline(e.a, e.b, times, memory ? int(std::min(bucket_of(e.triangle[0]), bucket_of(e.triangle[1]))) : -1,
                   std::uint32_t(&e - m.edges.data()));
    };
    // Whether all of a node's normals face the sun (+1), all face away (-1),
    // clear of square by kEdgeOn (with a memory, by the drift it allows
    // too), or neither (0): cos(angle to the axis -/+ the spread), the
    // nearest any normal comes to square, against that bar and a hair for
    // the rounding: c C - s S > bar with s = sqrt(1 - c^2), squared.
    const double bar = kEdgeOn + (memory ? kDrift : 0.0) + 1e-9;
    // And whether it lies clear of all its triangles' slabs (with a memory,
    // for any sun within its drift: the cosine less the drift, d.y at most
    // 1): a height `room` from the plane with room (c C - s S - drift) > K,
    // K the slab's numerator; squared, as above, without a root.
    // (The sun's height within the drift: its direction moves by at most
    // the drift in the model's space, twice the placement's stretch of it in
    // the world.)
    const double allowed = memory ? kDrift : 0.0, dy = memory ? std::min(1.0, d.y + 2.0 * kDrift * stretch_) : d.y;
    const auto facing_of = [&](std::size_t n, bool& clear) {
      if (!(m.cos_spread[n] > 0.0)) return 0;
      const double c = glm::dot(m.axes[n], dm), C = m.cos_spread[n], S = m.sin_spread[n];
      const double rest = (1.0 - c * c) * S * S;
      const double front = c * C - bar, back = -c * C - bar;
      const int facing = front > 0.0 && front * front > rest ? 1 : (back > 0.0 && back * back > rest ? -1 : 0);
      if (facing == 0) return 0;
      const double room = std::max(node_low_[n] - plane_y_, plane_y_ - node_high_[n]);
      const double k = slab_numerator(m.node_skew[n], dy);
      const double left = room * (facing * c * C - allowed) - k;
      clear = room > margin_ && left > 0.0 && left * left > room * room * rest;
      return facing;
    };
    // The tree, from its root: a node wholly below the plane counts nothing;
    // one wholly above facing one way settles its leaves, and every edge
    // between two of its triangles cancels but the open ones; any other is
    // split, down to leaves judged triangle by triangle, and then the edges
    // between its two halves are judged.
    const auto visit = [&](auto&& self, std::size_t n) -> void {
      const MeshShadowModel::Node& node = m.nodes[n];
      work += 1.0;
      bool clear = false;
      int facing = facing_of(n, clear);
      if (facing != 0 && clear && node_high_[n] < plane_y_) {  // wholly below: casts nothing, and surely
        std::fill(leaf_sign.begin() + node.leaf_first, leaf_sign.begin() + node.leaf_last, std::int8_t(0));
        return;
      }
      if (!clear) facing = 0;
      if (facing != 0) {
        std::fill(leaf_sign.begin() + node.leaf_first, leaf_sign.begin() + node.leaf_last, std::int8_t(facing));
        const std::uint32_t first = m.leaves[node.leaf_first].open_first, last = m.leaves[node.leaf_last - 1].open_last;
        for (std::uint32_t i = first; i < last; ++i) {
          edge_outline(m.edges[i].a, m.edges[i].b, facing * m.edges[i].sum, memory ? kSteady : -1, i);
        }
        return;
      }
      if (node.left >= 0) {
        self(self, std::size_t(node.left));
        self(self, std::size_t(node.right));
        for (std::uint32_t g = node.group_first; g < node.group_last; ++g) {
          const MeshShadowModel::Group& group = m.groups[g];
          if (leaf_sign[group.leaf_a] != kMixed && leaf_sign[group.leaf_a] == leaf_sign[group.leaf_b]) continue;
          work += 0.25 * double(group.last - group.first);
          for (std::uint32_t i = group.first; i < group.last; ++i) judge(m.edges[i]);
        }
        work += 0.05 * double(node.group_last - node.group_first);
        return;
      }
      const std::uint32_t l = node.leaf_first;
      const MeshShadowModel::Leaf& leaf = m.leaves[l];
      leaf_sign[l] = kMixed;
      // The one sign all its triangles with area take, if they do (kMixed
      // until the first).
      std::int8_t one_sign = kMixed;
      bool uniform = true;
      for (std::uint32_t t = leaf.first; t < leaf.last; ++t) {
        if (!memory) own_sign[t] = 0;
        if (m.normals[t] == glm::vec3(0.0f)) continue;  // no area: no_area's (a memory's: pack(0, kSteady))
        const double facing_t = glm::dot(glm::dvec3(m.normals[t]), dm);
        const std::int8_t s = judge_triangle(t, facing_t, node_low_[n], node_high_[n]);
        uniform = uniform && (one_sign == kMixed || s == one_sign);
        one_sign = s;
        if (!memory) {
          own_sign[t] = s;
          continue;
        }
        // Its room: how far the sun may turn before it may come edge on, or
        // its slab reach the plane (at `height` from it, the slab is the
        // numerator k over the cosine: while the cosine stays above
        // k / height). The leaf's height first, the triangle's own where it
        // tells.
        const double cosine = std::abs(facing_t), k = slab_numerator(m.skew[t], dy);
        double room = cosine - kEdgeOn, height = std::max(node_low_[n] - plane_y_, plane_y_ - node_high_[n]);
        if (height <= margin_ || cosine - k / height < room) {
          const auto& v = m.triangles[t].v;
          height = std::max(std::min({corner_y_[v[0]], corner_y_[v[1]], corner_y_[v[2]]}) - plane_y_,
                            plane_y_ - std::max({corner_y_[v[0]], corner_y_[v[1]], corner_y_[v[2]]}));
          room = height <= margin_ ? -1.0 : std::min(room, cosine - k / height);
        }
        memory->state[t] = pack(s, room <= 0.0 ? std::uint8_t(0)
                                                : std::uint8_t(std::min<double>(kBuckets, std::ceil(room / bucket_width))));
        memory->tracked.push_back(t);
      }
      // A leaf whose triangles all turned out one way (its cone only came
      // near square) is one sign, as a settled one: its shut edges cancel,
      // and so do the groups' edges to a leaf of that sign. (Its triangles
      // keep their own signs too: a memory tracks them.)
      if (uniform) {
        leaf_sign[l] = one_sign == kMixed ? std::int8_t(0) : one_sign;
        work += 0.25 * double(leaf.open_last - leaf.open_first);
        for (std::uint32_t i = leaf.open_first; i < leaf.open_last; ++i) judge(m.edges[i]);
        return;
      }
      work += 0.25 * double(leaf.open_last - leaf.open_first + leaf.shut_last - leaf.shut_first);
      for (std::uint32_t i = leaf.open_first; i < leaf.open_last; ++i) judge(m.edges[i]);
      for (std::uint32_t i = leaf.shut_first; i < leaf.shut_last; ++i) judge(m.edges[i]);
    };
    if (!m.nodes.empty()) visit(visit, 0);
    for (const std::uint32_t t : m.no_area) triangle_unsure(t);
    for (std::size_t i = m.loose_first; i < m.edges.size(); ++i) judge(m.edges[i]);
    judge_many(sign_of);
    work += 0.25 * double(m.edges.size() - m.loose_first + m.uses.size());
    if (memory) {
      // The tracked triangles by bucket (a counting sort).
      std::vector<std::uint32_t>& start = memory->tracked_start;
      start.assign(kBuckets + 2, 0);
      for (const std::uint32_t t : memory->tracked) ++start[std::size_t(bucket_of(t)) + 1];
      for (std::size_t b = 1; b < start.size(); ++b) start[b] += start[b - 1];
      std::vector<std::uint32_t> next(start.begin(), start.end() - 1), sorted(memory->tracked.size());
      for (const std::uint32_t t : memory->tracked) sorted[next[bucket_of(t)]++] = t;
      memory->tracked.swap(sorted);
      memory->last_sign.resize(memory->tracked.size());
      for (std::size_t i = 0; i < memory->tracked.size(); ++i)
        memory->last_sign[i] = std::int8_t(triangle_sign(memory->tracked[i]));
      memory->peak = 0;
      const std::size_t bytes = memory->bytes();
      memory_held_->fetch_add(bytes - memory->counted, std::memory_order_relaxed);  // (modulo 2^64: a shrink too)
      memory->counted = bytes;
    }
  }

  // Judged once more now that all is gathered: a draw that reached `most`
  // only with its last items overflows as one that reached it sooner
  // (fresh draws and draws from memory gather in different orders).
  overflow = overflow || crossings.size() + unsure.size() >= most;
  if (overflow) {
    // The whole box slid: every point a ray of this mesh could meet.
    crossings.clear(), unsure.clear();
    overflow = false;
    Point2 slid[8], hull[17];
    int n = 0;
    for (const glm::dvec3& c : reach_.corners()) slid[n++] = slide(c);
    std::sort(slid, slid + 8, [](const Point2& a, const Point2& b) { return a.x != b.x ? a.x < b.x : a.z < b.z; });
    const auto turn = [](const Point2& o, const Point2& a, const Point2& b) {
      return (a.x - o.x) * (b.z - o.z) - (a.z - o.z) * (b.x - o.x);
    };
    int k = 0;
    for (int i = 0; i < 8; ++i) {
      while (k >= 2 && turn(hull[k - 2], hull[k - 1], slid[i]) <= 0.0) --k;
      hull[k++] = slid[i];
    }
    for (int i = 6, lower = k + 1; i >= 0; --i) {
      while (k >= lower && turn(hull[k - 2], hull[k - 1], slid[i]) <= 0.0) --k;
      hull[k++] = slid[i];
    }
    mark_unsure(hull, std::max(1, k - 1));
  }
  // Row by row: the unsure columns merged, and the dark ones where the
  // count is not zero, less the unsure. Both lists go by row first (a
  // counting sort: a low sun's shadow crosses every row, tens of thousands
  // of crossings), then by x within each row (a few).
  work += 0.1 * double(crossings.size() + unsure.size());
  out.work = work;
  if (crossings.empty() && unsure.empty()) return;
  int first = std::numeric_limits<int>::max(), last = -1;
  for (const Crossing& c : crossings) first = std::min(first, c.row), last = std::max(last, c.row);
  for (const Unsure& u : unsure) first = std::min(first, u.row), last = std::max(last, u.row);
  thread_local std::vector<Crossing> crossings_by_row;
  thread_local std::vector<Unsure> unsure_by_row;
  thread_local std::vector<std::uint32_t> start, next;
  // `from` sorted into `to` by row, then by `less` within each row, and
  // swapped back.
  const auto by_row = [&](auto& from, auto& to, const auto& less) {
    start.assign(std::size_t(last - first + 2), 0);
    for (const auto& item : from) ++start[std::size_t(item.row - first) + 1];
    for (std::size_t r = 1; r < start.size(); ++r) start[r] += start[r - 1];
    to.resize(from.size());
    next.assign(start.begin(), start.end() - 1);
    for (const auto& item : from) to[next[std::size_t(item.row - first)]++] = item;
    for (std::size_t r = 0; r + 1 < start.size(); ++r)
      if (start[r + 1] - start[r] > 1) std::sort(to.begin() + start[r], to.begin() + start[r + 1], less);
    from.swap(to);
  };
  // By x, and at one x by change, so that the spans do not depend on the
  // order the outline was gathered in.
  by_row(crossings, crossings_by_row,
         [](const Crossing& a, const Crossing& b) { return a.x != b.x ? a.x < b.x : a.change < b.change; });
  by_row(unsure, unsure_by_row, [](const Unsure& a, const Unsure& b) { return a.columns.first < b.columns.first; });
  out.first_row = first, out.last_row = last;
  out.dark_start.assign(std::size_t(last - first + 2), 0);
  out.unsure_start.assign(std::size_t(last - first + 2), 0);
  std::size_t ci = 0, ui = 0;
  for (int r = first; r <= last; ++r) {
    const std::size_t row = std::size_t(r - first);
    out.unsure_start[row] = std::uint32_t(out.unsure.size());
    out.dark_start[row] = std::uint32_t(out.dark.size());
    const std::size_t unsure_first = out.unsure.size();
    for (; ui < unsure.size() && unsure[ui].row == r; ++ui) {
      const ColumnSpan& c = unsure[ui].columns;
      if (out.unsure.size() > unsure_first && c.first <= out.unsure.back().last + 1)
        out.unsure.back().last = std::max(out.unsure.back().last, c.last);
      else
        out.unsure.push_back(c);
    }
    const ColumnSpan* row_unsure = out.unsure.data() + unsure_first;
    const std::size_t row_unsure_count = out.unsure.size() - unsure_first;
    const std::size_t dark_first = out.dark.size();
    // Runs that meet (the count back to zero and on again at one crossing)
    // join, so a row's dark spans are merged as its unsure ones are.
    const auto dark = [&](int a, int b) {
      if (out.dark.size() > dark_first && a <= out.dark.back().last + 1)
        out.dark.back().last = std::max(out.dark.back().last, b);
      else
        out.dark.push_back({a, b});
    };
    int count = 0;
    double run_start = 0.0;
    for (; ci < crossings.size() && crossings[ci].row == r; ++ci) {
      const int before = count;
      count += crossings[ci].change;
      if (before == 0 && count != 0) run_start = crossings[ci].x;
      if (before != 0 && count == 0) {
        const double c0 = std::max(0.0, std::ceil((run_start - origin.x) / spacing));
        const double c1 = std::min(double(grid.columns - 1), std::floor((crossings[ci].x - origin.x) / spacing));
        if (c0 <= c1) {
          const ColumnSpan run{int(c0), int(c1)};
          for_each_difference(&run, 1, row_unsure, row_unsure_count, dark);
        }
      }
    }
  }
  out.unsure_start.back() = std::uint32_t(out.unsure.size());
  out.dark_start.back() = std::uint32_t(out.dark.size());
}

}  // namespace umbra
