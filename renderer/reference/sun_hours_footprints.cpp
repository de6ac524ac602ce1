#include "reference/sun_hours_footprints.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include <glm/matrix.hpp>

#include "core/mesh_instance.hpp"
#include "core/model.hpp"
#include "core/shapes/shape.hpp"
#include "core/model_shells.hpp"
#include "reference/mesh_grid_shadow.hpp"
#include "reference/ray_cast.hpp"
#include "reference/sun_hours_ray_cast.hpp"

namespace umbra {

namespace {

struct Point2 {
  double x, z;
};

double cross(const Point2& o, const Point2& a, const Point2& b) {
  return (a.x - o.x) * (b.z - o.z) - (a.z - o.z) * (b.x - o.x);
}

// Andrew's monotone chain: the convex hull of n points (at most n + 1
// slots of `hull` are written), in order.
int convex_hull(Point2* p, int n, Point2* hull) {
  std::sort(p, p + n, [](const Point2& a, const Point2& b) { return a.x < b.x || (a.x == b.x && a.z < b.z); });
  int k = 0;
  for (int i = 0; i < n; ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], p[i]) <= 0.0) --k;
    hull[k++] = p[i];
  }
  for (int i = n - 2, t = k + 1; i >= 0; --i) {
    while (k >= t && cross(hull[k - 2], hull[k - 1], p[i]) <= 0.0) --k;
    hull[k++] = p[i];
  }
  return std::max(1, k - 1);
}

double max_abs(const glm::dvec3& v) { return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}); }

// The largest |coordinate| of the grid's points: the rays' origins.
double grid_reach(const SunGrid& grid) {
  const glm::dvec3 a = grid.origin(), b = grid.point(grid.points() - 1);
  return std::max(max_abs(a), max_abs(b));
}

// Stretches of consecutive samples with the sun up: [first, end).
struct Stretch {
  std::size_t first, end;
};

std::vector<Stretch> daylight_stretches(const std::vector<SunSample>& samples) {
  std::vector<Stretch> stretches;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    if (!samples[k].up()) continue;
    if (stretches.empty() || stretches.back().end != k) stretches.push_back({k, k});
    stretches.back().end = k + 1;
  }
  return stretches;
}

// Threads wait here until all have come (std::barrier is C++20).
class Barrier {
 public:
  explicit Barrier(int count) : count_(count) {}
  void wait() {
    std::unique_lock<std::mutex> lock(mutex_);
    const std::uint64_t generation = generation_;
    if (++arrived_ == count_) {
      arrived_ = 0;
      ++generation_;
      all_came_.notify_all();
      return;
    }
    all_came_.wait(lock, [&] { return generation_ != generation; });
  }

 private:
  std::mutex mutex_;
  std::condition_variable all_came_;
  const int count_;
  int arrived_ = 0;
  std::uint64_t generation_ = 0;
};

}  // namespace

double rounding_margin(const Aabb& bounds, double reach) {
  return 1e-5 * (1.0 + std::max({max_abs(bounds.min), max_abs(bounds.max), reach}));
}

double footprint_margin(const SceneObject& object, const SunGrid& grid) {
  double margin = rounding_margin(object_bounds(object), grid_reach(grid));
  if (object.type == SceneObject::Type::Mesh && object.model) {
    // Embree tests the rays in the model's own float coordinates: its
    // rounding grows with those, however the model is placed.
    const glm::dvec3& s = object.mesh_scale;
    const double scale = std::max({std::abs(s.x), std::abs(s.y), std::abs(s.z)});
    margin = std::max(margin, 1e-5 * (1.0 + object.model->bounds.reach()) * scale);
  }
  return margin;
}

Aabb reachable_bounds(const Aabb& bounds, double plane_y, double reach) {
  if (bounds.empty()) return bounds;
  const double margin = rounding_margin(bounds, reach);
  Aabb grown;
  grown.min = bounds.min - glm::dvec3(margin);
  grown.max = bounds.max + glm::dvec3(margin);
  if (grown.max.y < plane_y) return Aabb{};
  grown.min.y = std::max(grown.min.y, plane_y);
  return grown;
}

namespace {

constexpr int kMaxShadowPoints = 128;
// A footprint of fewer cells than this is walked with a proof per point:
// its core's hull (up to a hundred points sorted) would cost more.
constexpr double kCoreCells = 64.0;
// A core narrower than this many cells (across x or z) is not drawn: its
// hull each sample costs more than the proofs it spares (200 thin poles'
// year: 21.0 s with cores from 3 cells, 16.6 s from 6; the city's 4.8 s).
constexpr double kCoreWidthCells = 6.0;
// A core's shadow narrower than this (cells per row, on average) spares
// fewer proofs than its rows' crossings cost (a pole thinner than a cell).
constexpr double kCoreCellsPerRow = 4.0;

// The shadow on the grid's plane of the convex hull of some points: each
// point slid down the sun's direction to the plane, and the hull of those.
// Rows and columns are found as SunGrid::point places them (origin + index
// x spacing), with a slack far above every step's rounding.
class PlaneShadow {
 public:
  // n <= kMaxShadowPoints; direction.y > 0.
  PlaneShadow(const glm::dvec3* points, int n, const glm::dvec3& direction, const SunGrid& grid)
      : origin_(grid.origin()), spacing_(grid.spacing), columns_(grid.columns) {
    Point2 slid[kMaxShadowPoints];
    // The largest magnitude any step below works with: a point's
    // coordinates, its slide, the grid's origin.
    extent_ = std::max({1.0, std::abs(origin_.x), std::abs(origin_.z)});
    for (int i = 0; i < n; ++i) {
      const glm::dvec3& c = points[i];
      const double t = (c.y - grid.center.y) / direction.y;
      slid[i] = {c.x - t * direction.x, c.z - t * direction.z};
      extent_ = std::max({extent_, std::abs(c.x), std::abs(c.z), std::abs(t * direction.x), std::abs(t * direction.z)});
    }
    Point2 hull[kMaxShadowPoints + 1];
    m_ = convex_hull(slid, n, hull);
    hull_.assign(hull, hull + m_);
    length_.resize(std::size_t(m_));
    slope_.resize(std::size_t(m_));
    flat_.resize(std::size_t(m_));
    for (int i = 0; i < m_; ++i) {
      const Point2& a = hull_[i];
      const Point2& b = hull_[(i + 1) % m_];
      length_[i] = std::hypot(b.x - a.x, b.z - a.z);
      // Once here, not per row: a division per edge and row was most of a
      // row's cost.
      slope_[i] = a.z == b.z ? 0.0 : (b.x - a.x) / (b.z - a.z);
      // An edge so near a row that its slope overflows is taken as along
      // it (both its ends, for the outer spans).
      flat_[i] = a.z == b.z || !std::isfinite(slope_[i]);
    }
    z_low_ = z_high_ = hull_[0].z;
    for (int i = 1; i < m_; ++i) z_low_ = std::min(z_low_, hull_[i].z), z_high_ = std::max(z_high_, hull_[i].z);
    // Every point within `slack` of the hull is taken by the outer spans
    // and every point taken by the inner spans lies that far inside: each
    // step's rounding (a point's slide, a row's crossing, a grid point's
    // own coordinates) is a few 1e-16 of `extent`, a millionth of the slack.
    // (One spare cell each side stood for it before: beside poles thinner
    // than a cell it was most of the footprint, every pair of it a ray cast.)
    slack_ = 1e-9 * extent_;
  }

  // Grid rows [first, last] that the shadow, grown by the slack, may cross;
  // false if none of [first_row, last_row).
  bool rows(int first_row, int last_row, int row_step, int& first, int& last) const {
    const double row_low = std::ceil((z_low_ - slack_ - origin_.z) / spacing_),
                 row_high = std::floor((z_high_ + slack_ - origin_.z) / spacing_);
    // Clamped in double before any int: a footprint far from a fine grid
    // lies billions of rows away.
    const double from = std::max<double>(first_row, row_low), to = std::min<double>(last_row - 1, row_high);
    if (!(from <= to)) return false;
    last = int(to);
    first = int(std::ceil(from / row_step)) * row_step;
    return first <= last;
  }

  // The columns of row r within the slack of the shadow.
  bool outer_columns(int r, int& c0, int& c1) const {
    // The hull within the band of z a slack either side of the row: each
    // edge that reaches into it, from where it enters the band to where it
    // leaves (or ends). An edge nearly along the row is taken over the
    // band's width, which its crossing's rounding (large for such an edge)
    // stays well inside; any other edge's is far below the slack.
    const double z = row_z(r), band_low = z - slack_, band_high = z + slack_;
    double x_low = 1e300, x_high = -1e300;
    for (int i = 0; i < m_; ++i) {
      const Point2& a = hull_[i];
      const Point2& b = hull_[(i + 1) % m_];
      const double edge_low = std::min(a.z, b.z), edge_high = std::max(a.z, b.z);
      if (edge_high < band_low || edge_low > band_high) continue;
      for (const double at : {std::max(band_low, edge_low), std::min(band_high, edge_high)}) {
        const double x = flat_[i] ? a.x : a.x + (at - a.z) * slope_[i];
        x_low = std::min(x_low, x);
        x_high = std::max(x_high, x);
      }
      if (flat_[i]) x_low = std::min(x_low, b.x), x_high = std::max(x_high, b.x);
    }
    if (m_ == 1) x_low = x_high = hull_[0].x;
    if (x_low > x_high) return false;
    const double first = std::max(0.0, std::ceil((x_low - slack_ - origin_.x) / spacing_));
    const double last = std::min(double(columns_ - 1), std::floor((x_high + slack_ - origin_.x) / spacing_));
    if (!(first <= last)) return false;
    c0 = int(first), c1 = int(last);
    return true;
  }

  // The columns of row r whose points lie inside the shadow by the slack:
  // a guess from the edges' crossings, kept only where its two end points
  // pass the inside test (the points between, on the segment joining them,
  // then lie inside too: the shadow is convex).
  bool inner_columns(int r, int& c0, int& c1) const {
    if (m_ < 3) return false;
    const double z = row_z(r);
    double low_a, high_a, low_b, high_b;
    if (!crossing(z - slack_, low_a, high_a) || !crossing(z + slack_, low_b, high_b)) return false;
    const double x_low = std::max(low_a, low_b) + slack_, x_high = std::min(high_a, high_b) - slack_;
    const double first = std::max(0.0, std::ceil((x_low - origin_.x) / spacing_));
    const double last = std::min(double(columns_ - 1), std::floor((x_high - origin_.x) / spacing_));
    if (!(first <= last)) return false;
    c0 = int(first), c1 = int(last);
    return inside({origin_.x + c0 * spacing_, z}) && inside({origin_.x + c1 * spacing_, z});
  }

  // Grid cells the shadow covers (its area in cells), and per row it
  // crosses: what its inner spans could spare against what they cost.
  double cells() const {
    double twice_area = 0.0;
    for (int i = 0; i < m_; ++i) {
      const Point2& a = hull_[i];
      const Point2& b = hull_[(i + 1) % m_];
      twice_area += a.x * b.z - b.x * a.z;
    }
    return 0.5 * std::abs(twice_area) / (spacing_ * spacing_);
  }
  double cells_per_row() const { return cells() / ((z_high_ - z_low_) / spacing_ + 1.0); }

 private:
  double row_z(int r) const { return origin_.z + r * spacing_; }

  // Where the line at height z crosses the hull (a guess: its rounding is
  // checked by `inside`).
  bool crossing(double z, double& x_low, double& x_high) const {
    if (z < z_low_ || z > z_high_) return false;
    x_low = 1e300, x_high = -1e300;
    for (int i = 0; i < m_; ++i) {
      const Point2& a = hull_[i];
      const Point2& b = hull_[(i + 1) % m_];
      if (z < std::min(a.z, b.z) || z > std::max(a.z, b.z)) continue;
      const double x =
          flat_[i] ? a.x : std::clamp(a.x + (z - a.z) * slope_[i], std::min(a.x, b.x), std::max(a.x, b.x));
      x_low = std::min(x_low, x);
      x_high = std::max(x_high, x);
    }
    return x_low <= x_high;
  }

  // Whether p lies to the left of every edge of the (counter-clockwise)
  // hull by more than the slack. The cross product's rounding is at most
  // a few tens of ulps of extent^2; 64 of them are added to the bar.
  bool inside(const Point2& p) const {
    const double rounding = 64.0 * 2.2e-16 * extent_ * extent_;
    for (int i = 0; i < m_; ++i) {
      const Point2& a = hull_[i];
      const Point2& b = hull_[(i + 1) % m_];
      if (!(cross(a, b, p) > slack_ * length_[i] + rounding)) return false;
    }
    return true;
  }

  glm::dvec3 origin_;
  double spacing_;
  int columns_;
  std::vector<Point2> hull_;
  std::vector<double> length_;  // of edge i (hull_[i] to the next)
  std::vector<double> slope_;   // of edge i: dx / dz (0 along a row)
  std::vector<char> flat_;      // edge i runs along a row
  int m_ = 0;
  double z_low_ = 0.0, z_high_ = 0.0, extent_ = 1.0, slack_ = 0.0;
};


}  // namespace

void footprint_spans(const Aabb& bounds, const glm::dvec3& direction, const SunGrid& grid, int first_row,
                     int last_row, const std::function<void(int, int, int)>& row_span, int row_step) {
  if (bounds.empty() || !(direction.y > 0.0)) return;
  // Each corner slides down the sun's direction to the plane: the points
  // whose rays pass through it. The bounds are convex, so the footprint is
  // the hull of the eight.
  const std::vector<glm::dvec3> corners = bounds.corners();
  const PlaneShadow shadow(corners.data(), 8, direction, grid);
  int r0, r1, c0, c1;
  if (!shadow.rows(first_row, last_row, row_step, r0, r1)) return;
  for (int r = r0; r <= r1; r += row_step)
    if (shadow.outer_columns(r, c0, c1)) row_span(r, c0, c1);
}

namespace {

// A box of a mesh's model space in the world (turned, stretched: a
// parallelepiped), cut to y >= cut: its corners there, and where its edges
// cross that height. Their hull is the cut solid.
std::vector<glm::dvec3> world_box_above(const Aabb& box, const glm::dmat4& to_world, double cut) {
  std::vector<glm::dvec3> c = box.corners();  // corners i and i | bit share an edge
  for (glm::dvec3& corner : c) corner = glm::dvec3(to_world * glm::dvec4(corner, 1.0));
  std::vector<glm::dvec3> points;
  for (int i = 0; i < 8; ++i)
    if (c[i].y >= cut) points.push_back(c[i]);
  for (int i = 0; i < 8; ++i)
    for (const int bit : {1, 2, 4}) {
      if (i & bit) continue;
      const glm::dvec3 &a = c[i], &b = c[i | bit];
      if ((a.y >= cut) == (b.y >= cut)) continue;
      glm::dvec3 p = a + (cut - a.y) / (b.y - a.y) * (b - a);
      p.y = cut;
      points.push_back(p);
    }
  return points;
}

double smallest_scale(const SceneObject& mesh) {
  return std::min({std::abs(mesh.mesh_scale.x), std::abs(mesh.mesh_scale.y), std::abs(mesh.mesh_scale.z)});
}

// A mesh's cores from its model's shell cores (model space, clear of the
// triangles by at least margin / smallest_scale there).
std::vector<SolidCore> mesh_cores(const SceneObject& mesh, const std::vector<Aabb>& model_cores, double plane_y,
                                  double margin) {
  std::vector<SolidCore> cores;
  const glm::dmat4 to_world = mesh_transform(mesh);
  for (const Aabb& box : model_cores) {
    SolidCore core;
    core.model_box = box;
    core.points = world_box_above(box, to_world, plane_y + margin);
    if (core.points.size() >= 4) cores.push_back(std::move(core));
  }
  return cores;
}

}  // namespace

std::vector<SolidCore> solid_cores(const SceneObject& object, double plane_y, double margin) {
  std::vector<SolidCore> cores;
  const ShapeKind& kind = shape_kind(object.type);
  if (kind.points_inside && kind.surely_meets) {
    SolidCore core;
    core.points = kind.points_inside(object, margin, plane_y + margin, std::numeric_limits<double>::infinity());
    if (core.points.size() >= 4 && core.points.size() <= std::size_t(kMaxShadowPoints)) cores.push_back(std::move(core));
    return cores;
  }
  // A model: each shell that closes up's core (shell_cores), clear of its
  // triangles by the margin in model space, which is at least the margin
  // in the world.
  if (object.type != SceneObject::Type::Mesh || !object.model || !(smallest_scale(object) > 0.0)) return cores;
  return mesh_cores(object, shell_cores(*object.model, margin / smallest_scale(object)), plane_y, margin);
}

void core_spans(const SolidCore& core, const glm::dvec3& direction, const SunGrid& grid, int first_row, int last_row,
                const std::function<void(int, int, int)>& row_span) {
  if (core.points.empty() || !(direction.y > 0.0)) return;
  const PlaneShadow shadow(core.points.data(), int(core.points.size()), direction, grid);
  int r0, r1, c0, c1;
  if (!shadow.rows(first_row, last_row, 1, r0, r1)) return;
  for (int r = r0; r <= r1; ++r)
    if (shadow.inner_columns(r, c0, c1)) row_span(r, c0, c1);
}

namespace {

// How many boxes a mesh's footprints are drawn from (shell_clusters):
// each is a hull and its rows per sample, against the rays a single box
// around a round or scattered model would leave to the query. At least 32
// (a teapot's parts, split), a building each up to 1024.
constexpr int kFewestMeshClusters = 32, kMostMeshClusters = 1024;
// The most footprints and cores a request's objects draw each sample.
constexpr int kMostDrawn = 65536;
// The most triangles of the instances whose mesh shadows a request draws
// (each instance holds its model's corners' heights, about half as many,
// 9 bytes each, and its nodes' and memories' state): past it, the
// instances beyond draw their clusters' footprints instead.
constexpr std::size_t kMostShadowTriangles = std::size_t(8) << 20;
// The most bytes the models' mesh shadows kept between requests hold.
constexpr std::size_t kKeptShadowBytes = std::size_t(256) << 20;
// At most about this many bytes of the mesh shadows' memories in one walk
// (MeshGridShadow::draw's slots: a year's draws keep one per time of day).
constexpr std::size_t kMeshMemoryBytes = std::size_t(256) << 20;
// The largest model given a mesh shadow (about 100 bytes a triangle and
// 0.7 s a million to find, in the plan, before any budget): larger open
// models draw their clusters' footprints, their pairs there ray cast.
constexpr std::size_t kMostShadowModelTriangles = std::size_t(1) << 20;

// One object as the footprints see it: the convex solids its footprints
// are drawn from (its bounds; a mesh's clusters of triangles), each cut to
// the plane's upper side, and its proofs of dark.
struct Caster {
  std::vector<std::vector<glm::dvec3>> hulls;  // each the points of one
  Aabb bounds;                                 // the object's own
  const SceneObject* object = nullptr;
  const ShapeKind* kind = nullptr;
  double margin = 0.0;
  std::vector<SolidCore> cores;
  std::vector<std::size_t> drawn_cores;  // those wide enough to draw each sample
  // A mesh's: world to model space, and the margin there.
  glm::dmat4 to_model{1.0};
  double model_margin = 0.0;
  // A model with open surfaces: its exact shadow each sample
  // (MeshGridShadow: dark, unsure and lit spans), drawn instead of hulls
  // and cores.
  std::shared_ptr<const MeshGridShadow> mesh_shadow;
};

// What a model's instances share, found once per request: its clusters,
// and its shells' cores clear by the largest margin any instance needs.
struct KeptFacts {
  std::vector<Aabb> clusters;
  std::vector<Aabb> cores;
  // Set when some shell has no core (an open surface: no core proves its
  // rays dark): the model as its exact shadows need it.
  std::shared_ptr<const MeshShadowModel> shadow;
};
struct ModelFacts {
  std::shared_ptr<const TriangleModel> model;
  KeptFacts kept;
  double core_margin = 0.0;
  // Every instance keeps up up (turned about y only, not flipped): a ray
  // that rises in the world rises in the model too, so shells open only
  // at their floor have cores (shell_cores' open_floors).
  bool upright = true;
};

// A model's clusters, cores and shadow model, kept for the next request on
// it (and for the walk after its plan: both draw the same casters):
// finding them is a few passes over the model's triangles, about 0.3 s for
// a million. Held by the model's weak pointer, so a model dropped from the
// store is dropped here; at most kKept, and shadow models of at most
// kKeptShadowBytes in all, the least recently used going first.
class ModelFactsCache {
 public:
  // The clusters and cores of `model` for `margin` and `open_floors`;
  // false if they were not kept (then `find` computes them).
  template <class Find>
  bool get(const std::shared_ptr<const TriangleModel>& model, double margin, bool open_floors, KeptFacts& facts,
           Find&& find) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (Entry& e : entries_)
        if (e.margin == margin && e.open_floors == open_floors && !e.model.owner_before(model) &&
            !model.owner_before(e.model) && !e.model.expired()) {
          e.used = ++clock_;
          facts = e.facts;
          return true;
        }
    }
    find(facts);
    std::lock_guard<std::mutex> lock(mutex_);
    entries_.erase(std::remove_if(entries_.begin(), entries_.end(), [](const Entry& e) { return e.model.expired(); }),
                   entries_.end());
    const auto oldest = [&] {
      return std::min_element(entries_.begin(), entries_.end(),
                              [](const Entry& a, const Entry& b) { return a.used < b.used; });
    };
    if (entries_.size() >= kKept) entries_.erase(oldest());
    const auto shadow_bytes = [](const KeptFacts& f) { return f.shadow ? mesh_shadow_model_bytes(*f.shadow) : 0; };
    std::size_t bytes = shadow_bytes(facts);
    for (const Entry& e : entries_) bytes += shadow_bytes(e.facts);
    while (bytes > kKeptShadowBytes && !entries_.empty()) {
      const auto gone = oldest();
      bytes -= shadow_bytes(gone->facts);
      entries_.erase(gone);
    }
    if (shadow_bytes(facts) <= kKeptShadowBytes) entries_.push_back({model, margin, open_floors, facts, ++clock_});
    return false;
  }

 private:
  static constexpr std::size_t kKept = 32;
  struct Entry {
    std::weak_ptr<const TriangleModel> model;
    double margin;
    bool open_floors;
    KeptFacts facts;
    std::uint64_t used;
  };
  std::mutex mutex_;
  std::vector<Entry> entries_;
  std::uint64_t clock_ = 0;
};

ModelFactsCache& model_facts_cache() {
  static ModelFactsCache cache;
  return cache;
}

// Whether a mesh's model-space y rises with world y and with nothing else:
// the row of its inverse transform that gives model y is (0, +, 0).
bool keeps_up(const SceneObject& mesh) {
  const glm::dmat4 to_model = glm::inverse(mesh_transform(mesh));
  return to_model[0][1] == 0.0 && to_model[2][1] == 0.0 && to_model[1][1] > 0.0;
}

// `slots`: the memories each mesh shadow keeps (MeshGridShadow::draw).
std::vector<Caster> casters_of(const Scene& scene, const SunGrid& grid, double* model_triangles = nullptr,
                               int slots = 0) {
  const double reach = grid_reach(grid);
  // Each model once, however many instances: the margin its cores need.
  std::map<const TriangleModel*, ModelFacts> models;
  for (const SceneObject& o : scene.objects)
    if (o.type == SceneObject::Type::Mesh && o.model && smallest_scale(o) > 0.0) {
      ModelFacts& facts = models[o.model.get()];
      facts.model = o.model;
      facts.core_margin = std::max(facts.core_margin, footprint_margin(o, grid) / smallest_scale(o));
      facts.upright = facts.upright && keeps_up(o);
    }
  for (auto& entry : models) {
    const TriangleModel* model = entry.first;
    ModelFacts& facts = entry.second;
    const bool kept = model_facts_cache().get(
        facts.model, facts.core_margin, facts.upright, facts.kept, [&](KeptFacts& found) {
          std::uint32_t shells = 0;
          const std::vector<std::uint32_t> shell_of = triangle_shells(*model, shells);
          found.clusters = shell_clusters(*model, shell_of, shells, kFewestMeshClusters, kMostMeshClusters);
          found.cores = shell_cores(*model, facts.core_margin, /*open_floors=*/facts.upright);
          if (found.cores.size() < shells && model->triangle_count() <= kMostShadowModelTriangles)
            found.shadow = mesh_shadow_model(*model);
        });
    // Priced only where found now (the plan finds them; its walk, and the
    // next request on the same model, take them kept).
    // A shadow model costs about as much again as the rest (the teapot's
    // 102,400 triangles: about 70 ms against 6 ms for its shells and
    // clusters, and a closed model's cores up to 0.3 s a million).
    if (model_triangles && !kept)
      *model_triangles += double(model->triangle_count()) * (facts.kept.shadow ? 2.0 : 1.0);
  }
  // Every instance draws its model's clusters and cores each sample: past
  // kMostDrawn in all (a thousand instances of a model of thousands of
  // buildings), each model is one box again, without cores, so that the
  // plan and the walk stay bounded (and exact: only slower).
  double drawn = 0.0;
  for (const SceneObject& o : scene.objects) {
    const auto facts = o.model ? models.find(o.model.get()) : models.end();
    drawn += facts == models.end() || facts->second.kept.shadow
                 ? 2.0
                 : double(facts->second.kept.clusters.size() + facts->second.kept.cores.size());
  }
  if (drawn > double(kMostDrawn))
    for (auto& [model, facts] : models) {
      facts.kept.clusters = {model->bounds};
      facts.kept.cores.clear();
    }
  std::size_t shadow_triangles = 0;
  std::vector<std::pair<MeshGridShadow*, std::size_t>> budgeted;  // each mesh shadow, its triangles
  std::vector<Caster> casters;
  for (const SceneObject& o : scene.objects) {
    Caster caster;
    caster.object = &o;
    caster.kind = &shape_kind(o.type);
    caster.bounds = object_bounds(o);
    caster.margin = footprint_margin(o, grid);
    const auto facts = o.model ? models.find(o.model.get()) : models.end();
    if (o.type == SceneObject::Type::Mesh && facts != models.end()) {
      // Each cluster's box grown by the margin in model space (at least
      // the margin in the world), in the world, cut to the plane's side.
      caster.to_model = glm::inverse(mesh_transform(o));
      caster.model_margin = caster.margin / smallest_scale(o);
      const glm::dmat4 to_world = mesh_transform(o);
      const std::shared_ptr<const MeshShadowModel>& shadow = facts->second.kept.shadow;
      if (shadow && shadow_triangles + mesh_shadow_model_triangles(*shadow) <= kMostShadowTriangles) {
        shadow_triangles += mesh_shadow_model_triangles(*shadow);
        auto mesh_shadow = std::make_shared<MeshGridShadow>(shadow, to_world, grid.center.y, caster.margin, slots);
        budgeted.emplace_back(mesh_shadow.get(), mesh_shadow_model_triangles(*shadow));
        caster.mesh_shadow = std::move(mesh_shadow);
        if (!caster.mesh_shadow->reach().empty()) casters.push_back(std::move(caster));
        continue;
      }
      for (Aabb box : facts->second.kept.clusters) {
        box.min -= glm::dvec3(caster.model_margin);
        box.max += glm::dvec3(caster.model_margin);
        std::vector<glm::dvec3> points = world_box_above(box, to_world, grid.center.y);
        if (points.size() >= 4) caster.hulls.push_back(std::move(points));
      }
      caster.cores = mesh_cores(o, facts->second.kept.cores, grid.center.y, caster.margin);
    } else {
      // The points around the object (a turned box's own corners, a
      // pole's prism), else its bounds (none above the plane either way):
      // the margin covers the pure query's rounding in both.
      std::vector<glm::dvec3> around;
      if (caster.kind->points_around) around = caster.kind->points_around(o, caster.margin, grid.center.y);
      if (!around.empty() && around.size() <= std::size_t(kMaxShadowPoints)) {
        caster.hulls.push_back(std::move(around));
      } else {
        const Aabb reachable = reachable_bounds(caster.bounds, grid.center.y, reach);
        if (!reachable.empty()) caster.hulls.push_back(reachable.corners());
      }
      caster.cores = solid_cores(o, grid.center.y, caster.margin);
    }
    if (caster.hulls.empty()) continue;
    // A core thinner than a few cells holds few points of a row: its hull
    // each sample would cost more than the proofs of an analytic solid it
    // spares (a model's cores are always drawn: without them its pairs
    // are rays). A core not drawn still settles the points inside it
    // (mark_inside).
    for (std::size_t i = 0; i < caster.cores.size(); ++i) {
      Aabb b;
      for (const glm::dvec3& p : caster.cores[i].points) b.extend(p);
      if (!caster.kind->surely_meets || std::min(b.extent().x, b.extent().z) >= kCoreWidthCells * grid.spacing)
        caster.drawn_cores.push_back(i);
    }
    casters.push_back(std::move(caster));
  }
  // The memories' bytes, shared by the mesh shadows as their triangles.
  for (const auto& [mesh_shadow, triangles] : budgeted)
    mesh_shadow->set_memory_budget(std::max<std::size_t>(
        1, std::size_t(double(kMeshMemoryBytes) * double(triangles) / double(std::max<std::size_t>(1, shadow_triangles)))));
  return casters;
}

// Whether a core's shadow spares more than its rows' crossings cost: an
// analytic solid's spares proofs, so only a shadow wide enough (a model's
// spares rays, always).
bool pays(const Caster& caster, const PlaneShadow& core) {
  return !caster.kind->surely_meets || (core.cells() >= kCoreCells && core.cells_per_row() >= kCoreCellsPerRow);
}

// Calls mark(row, column) for the grid points (every stride-th row and
// column) inside a solid by twice its margin: every ray from them, in any
// direction, surely meets it (ShapeKind::contains), so they see no sun at
// any sample. A closed mesh's points are those inside a shell's core by
// twice the margin (in model space): every ray from them leaves the shell
// (every rising one, for a shell closed by its floor: the sun's are, at
// every sample it is up). The core cut does not matter here: the whole
// box is inside.
void mark_inside(const std::vector<Caster>& casters, const SunGrid& grid, int stride,
                 const std::function<void(int, int)>& mark) {
  const glm::dvec3 origin = grid.origin();
  const auto scan = [&](const Aabb& b, const std::function<bool(const glm::dvec3&)>& contains) {
    if (!(grid.center.y > b.min.y && grid.center.y < b.max.y)) return;
    // In double first: bounds far from a fine grid lie billions of cells away.
    const double x0 = std::max(0.0, std::ceil((b.min.x - origin.x) / grid.spacing / stride) * stride);
    const double x1 = std::min(double(grid.columns - 1), std::floor((b.max.x - origin.x) / grid.spacing));
    const double z0 = std::max(0.0, std::ceil((b.min.z - origin.z) / grid.spacing / stride) * stride);
    const double z1 = std::min(double(grid.rows - 1), std::floor((b.max.z - origin.z) / grid.spacing));
    if (!(x0 <= x1 && z0 <= z1)) return;
    for (int r = int(z0); r <= int(z1); r += stride)
      for (int c = int(x0); c <= int(x1); c += stride)
        if (contains(grid.point(std::size_t(r) * std::size_t(grid.columns) + std::size_t(c)))) mark(r, c);
  };
  for (const Caster& o : casters) {
    if (o.kind->contains) {
      scan(o.bounds, [&](const glm::dvec3& p) { return o.kind->contains(*o.object, p, 2.0 * o.margin); });
      continue;
    }
    const glm::dmat4 to_world = mesh_transform(*o.object);
    for (const SolidCore& core : o.cores) {
      if (core.model_box.empty()) continue;
      Aabb world;
      for (const glm::dvec3& corner : core.model_box.corners()) world.extend(glm::dvec3(to_world * glm::dvec4(corner, 1.0)));
      const Aabb& box = core.model_box;
      const double m = 2.0 * o.model_margin;
      scan(world, [&](const glm::dvec3& p) {
        const glm::dvec3 q(o.to_model * glm::dvec4(p, 1.0));
        return q.x > box.min.x + m && q.x < box.max.x - m && q.y > box.min.y + m && q.y < box.max.y - m &&
               q.z > box.min.z + m && q.z < box.max.z - m;
      });
    }
  }
}

}  // namespace

FootprintShares footprint_shares(const Scene& scene, const SunGrid& grid, const std::vector<glm::dvec3>& directions) {
  FootprintShares out;
  if (directions.empty() || grid.points() == 0) return out;
  const std::vector<Caster> casters = casters_of(scene, grid, &out.model_triangles);
  for (const Caster& o : casters) out.hulls += double(o.hulls.size() + o.drawn_cores.size() + (o.mesh_shadow ? 1 : 0));
  // A lattice of at most about 128 x 128 of the grid's points (every
  // stride-th row and column), judged as footprint_sun_hours judges them:
  // inside a footprint, and then settled by a proof of dark or left to the
  // query. Indexed by lattice cell, so the plan's memory and time do not
  // grow with the grid.
  const int stride = std::max(1, int(std::ceil(std::max(grid.columns, grid.rows) / 128.0)));
  const int lattice_columns = (grid.columns + stride - 1) / stride, lattice_rows = (grid.rows + stride - 1) / stride;
  const std::size_t lattice = std::size_t(lattice_columns) * std::size_t(lattice_rows);
  const auto cell = [&](int r, int c) { return std::size_t(r / stride) * std::size_t(lattice_columns) + std::size_t(c / stride); };
  std::vector<int> seen(lattice, -1), cored(lattice, -1);
  std::vector<std::uint8_t> inside(lattice, 0);
  mark_inside(casters, grid, stride, [&](int r, int c) { inside[cell(r, c)] = 1; });
  // Directions in turn until about kMaxWork: a thousand objects over the
  // whole grid are 16 M visits a direction, and the plan runs before any
  // budget. A proof (a turned box's trigonometry) weighs 16 visits.
  constexpr double kMaxWork = 16.0e6, kWorkPerProof = 16.0, kWorkPerHull = 64.0;
  double work = 0.0;
  double candidates = 0.0, queried = 0.0, visits = 0.0, tests = 0.0, queried_tests = 0.0, core_rows = 0.0,
         mesh_visits = 0.0, mesh_shadow_work = 0.0;
  // Each mesh shadow's for the direction judged.
  std::vector<GridShadow> mesh_shadows(casters.size());
  std::vector<std::uint16_t> depth(lattice, 0);
  std::vector<std::int64_t> last_visit(lattice, -1);
  std::vector<std::uint8_t> dark(lattice, 0), left(lattice, 0), proofs(lattice, 0);
  std::vector<std::size_t> touched;
  // The directions in van der Corput order (first, middle, quarters, ...):
  // where the work runs out, those judged still spread over the period.
  std::vector<std::size_t> order;
  std::size_t span = 1;
  while (span < directions.size()) span *= 2;
  for (std::size_t m = 0; m < span; ++m) {
    std::size_t reversed = 0;
    for (std::size_t bit = 1, out_bit = span / 2; bit < span; bit *= 2, out_bit /= 2)
      if (m & bit) reversed |= out_bit;
    if (reversed < directions.size()) order.push_back(reversed);
  }
  std::size_t judged_directions = 0;
  for (std::size_t n = 0; n < order.size() && work < kMaxWork; ++n, ++judged_directions) {
    const glm::dvec3& d = directions[order[n]];
    if (!(d.y > 0.0)) continue;
    // A hull (its points slid and sorted) weighs about kWorkPerHull visits.
    work += kWorkPerHull * out.hulls;
    // As footprint_sun_hours: first the cores' shadows, dark without a
    // proof each.
    for (std::size_t index = 0; index < casters.size(); ++index) {
      const Caster& o = casters[index];
      if (!o.mesh_shadow) continue;
      GridShadow& mesh = mesh_shadows[index];
      o.mesh_shadow->draw(d, grid, stride, mesh);
      work += mesh.work;
      mesh_shadow_work += mesh.work;
      for (int r = mesh.first_row; r <= mesh.last_row; r += stride) {
        std::size_t count;
        const ColumnSpan* spans = mesh.dark_of(r, count);
        core_rows += count > 0 ? double(stride) : 0.0;
        for (std::size_t k = 0; k < count; ++k)
          for (int c = (spans[k].first + stride - 1) / stride * stride; c <= spans[k].last; c += stride) {
            work += 1.0;
            cored[cell(r, c)] = int(n);
          }
      }
    }
    for (const Caster& o : casters)
      for (const std::size_t c : o.drawn_cores) {
        const SolidCore& solid = o.cores[c];
        const PlaneShadow core(solid.points.data(), int(solid.points.size()), d, grid);
        int first_row, last_row, c0, c1;
        if (!pays(o, core)) continue;
        if (!core.rows(0, grid.rows, stride, first_row, last_row)) continue;
        for (int r = first_row; r <= last_row; r += stride) {
          if (!core.inner_columns(r, c0, c1)) continue;
          core_rows += double(stride);
          for (int c = (c0 + stride - 1) / stride * stride; c <= c1; c += stride) {
            work += 1.0;
            cored[cell(r, c)] = int(n);
          }
        }
      }
    // A lattice point in object `index`'s footprint (or a mesh's unsure span).
    const auto judge = [&](std::size_t index, int r, int c) {
      const Caster& o = casters[index];
      const std::size_t i = cell(r, c);
      const bool in_core = cored[i] == int(n);
      visits += in_core ? 0.0 : 1.0;
      work += 1.0;
      if (depth[i] == 0) touched.push_back(i);
      // Once per object, however many of its boxes hold the point.
      const std::int64_t visit = std::int64_t(n) * std::int64_t(casters.size()) + std::int64_t(index);
      if (last_visit[i] != visit && depth[i] < 65535) ++depth[i];
      if (last_visit[i] != visit && !o.kind->intersect) mesh_visits += 1.0;
      last_visit[i] = visit;
      if (inside[i]) return;
      const glm::dvec3 p = grid.point(std::size_t(r) * std::size_t(grid.columns) + std::size_t(c));
      // At most a few proofs a point: a thousand identical boxes
      // that none proves would be a thousand.
      const bool ask = !in_core && !dark[i] && o.kind->surely_meets && proofs[i] < 4;
      proofs[i] += ask ? 1 : 0;
      work += ask ? kWorkPerProof : 0.0;
      const bool sure = in_core || (ask && o.kind->surely_meets(*o.object, p, d, o.margin));
      dark[i] |= sure;
      // As footprint_sun_hours: the first footprint holding the
      // point judges it, and the query settles what it cannot.
      if (seen[i] == int(n)) return;
      seen[i] = int(n);
      candidates += in_core ? 0.0 : 1.0;
      if (!sure) {
        queried += 1.0;
        left[i] = 1;
      }
    };
    for (std::size_t index = 0; index < casters.size(); ++index) {
      const Caster& o = casters[index];
      if (o.mesh_shadow) {
        const GridShadow& mesh = mesh_shadows[index];
        for (int r = mesh.first_row; r <= mesh.last_row; r += stride) {
          std::size_t count;
          const ColumnSpan* spans = mesh.unsure_of(r, count);
          for (std::size_t k = 0; k < count; ++k)
            for (int c = (spans[k].first + stride - 1) / stride * stride; c <= spans[k].last; c += stride)
              judge(index, r, c);
        }
        continue;
      }
      for (const std::vector<glm::dvec3>& hull : o.hulls) {
        const PlaneShadow footprint(hull.data(), int(hull.size()), d, grid);
        int first_row, last_row, c0, c1;
        if (!footprint.rows(0, grid.rows, stride, first_row, last_row)) continue;
        for (int r = first_row; r <= last_row; r += stride) {
          if (!footprint.outer_columns(r, c0, c1)) continue;
          for (int c = (c0 + stride - 1) / stride * stride; c <= c1; c += stride) judge(index, r, c);
        }
      }
    }
    // The objects a ray is tested against besides the tree's levels and
    // the one the cost model prices every ray with: none where some object
    // surely meets it (its first hit ends a shadow ray), else every other
    // object whose bounds it passes.
    for (const std::size_t i : touched) {
      const double t = dark[i] || inside[i] ? 0.0 : double(depth[i]) - 1.0;
      tests += t;
      if (left[i]) queried_tests += t;
      depth[i] = 0, dark[i] = 0, left[i] = 0, proofs[i] = 0;
    }
    touched.clear();
  }
  const double judged = double(judged_directions) * double(lattice);
  out.queried = queried / judged;
  out.candidates = candidates / judged;
  out.depth = visits / judged;
  out.core_rows = core_rows / double(judged_directions);
  out.mesh_depth = mesh_visits / judged;
  out.mesh_shadow_work = mesh_shadow_work / double(judged_directions);
  out.tests = tests / judged;
  out.queried_tests = queried > 0.0 ? queried_tests / queried : 0.0;
  return out;
}

std::size_t mesh_memory_day_slots(double step_seconds, std::size_t samples) {
  if (!(step_seconds > kMeshMemoryMostStepSeconds)) return 0;
  const double per_day = 86400.0 / step_seconds;
  if (per_day < 32.0 || std::abs(per_day - std::round(per_day)) > 1e-6 || double(samples) <= per_day) return 0;
  return std::size_t(std::round(per_day));
}

void footprint_sun_hours(const RayScene& rays, const Scene& scene, const SunGrid& grid,
                         const std::vector<SunSample>& samples, SunHoursResult& result,
                         const std::function<bool()>& stop_requested, std::atomic<std::uint64_t>* pairs_done) {
  const std::size_t points = grid.points();
  const std::vector<Stretch> stretches = daylight_stretches(samples);
  std::size_t up = 0;
  for (const Stretch& s : stretches) up += s.end - s.first;
  result.samples_up = up;
  result.pairs = std::uint64_t(points) * up;
  result.tally.assign(points, PointTally{});

  // Samples go in blocks: first all threads draw the block's shadows (each
  // once, however many threads walk it), then each walks its own rows
  // through the block's samples in order. Rows are dealt in stripes of
  // kStripe, in turn, so that a scene whose shadows gather in one part of
  // the grid keeps every thread busy.
  constexpr int kStripe = 4;
  const int threads = int(std::max(1u, std::min<unsigned>(std::thread::hardware_concurrency(),
                                                          unsigned((grid.rows + kStripe - 1) / kStripe))));
  // A mesh's shadows are drawn in runs of consecutive samples, each run
  // by one thread with a memory of its own (MeshGridShadow::draw): at most
  // kMeshRuns a mesh and block (each run's first draw starts its memory
  // afresh; `runs` below), claimed by whichever thread is free (meshes'
  // draws differ in cost: ten teapots on sixteen threads left six idle
  // while each drew a block alone).
  constexpr int kMeshRuns = 8;
  // A year's samples, ten minutes apart, draw in a memory per time of day
  // instead: slots kMeshRuns + k mod day_slots (at least a block's).
  const double step_seconds = samples.size() >= 2 ? samples[1].utc_unix_s - samples[0].utc_unix_s : 0.0;
  const std::size_t day_slots = samples.size() >= 2 ? mesh_memory_day_slots(step_seconds, samples.size()) : 0;
  // Samples near each other: a run's next draws are near its first, which
  // starts the run's memory at once (else a run's first draw, far from the
  // slot's last, would draw fresh and its second start).
  const bool close_steps = samples.size() >= 2 && step_seconds <= kMeshMemoryMostStepSeconds;

  // Each object that a ray from the plane can reach: the solids of its
  // footprints, and the proof of a hit its kind offers
  // (ShapeKind::surely_meets).
  const std::vector<Caster> casters = casters_of(scene, grid, nullptr, kMeshRuns + int(day_slots));

  // Per point, in one place (the walk visits millions of points a
  // sample, each a cache miss per array it touches): the sample it was last
  // tested at (each is tested once a sample however many footprints hold
  // it), its last dark sample and the stretch that was in, its dark count
  // and its longest lit run. Samples are fewer than 2^31
  // (SunHoursLimits::kMaxSamples).
  struct PointState {
    std::int32_t tested = -1;
    std::int32_t last_dark = -1;
    std::int32_t dark_stretch = -1;
    std::uint32_t dark = 0;
    std::uint32_t longest = 0;
    // In a core's shadow since this sample, without a break (-1: not):
    // its dark samples since are counted when it leaves (CoreRuns).
    std::int32_t core_since = -1;
  };
  // A point inside a solid (a box's, a sphere's, a model's closed shell's
  // core) by twice the margin sees no sun at any sample (mark_inside):
  // settled once, for the whole period, by a `tested` past every sample,
  // so one test (tested >= k) skips it and a point already tested.
  constexpr std::int32_t kInside = std::numeric_limits<std::int32_t>::max();
  static_assert(SunHoursLimits::kMaxSamples < std::size_t(kInside));
  std::vector<PointState> state(points);
  mark_inside(casters, grid, 1, [&](int r, int c) { state[std::size_t(r) * std::size_t(grid.columns) + std::size_t(c)].tested = kInside; });

  // The samples with the sun up, in order, each with its stretch.
  struct Up {
    std::size_t k, stretch;
    bool last;  // of its stretch
  };
  std::vector<Up> ups;
  for (std::size_t j = 0; j < stretches.size(); ++j)
    for (std::size_t k = stretches[j].first; k < stretches[j].end; ++k) ups.push_back({k, j, k + 1 == stretches[j].end});
  // What each sample draws, in order: every core's shadow (dark), then
  // every footprint.
  struct Drawn {
    const Caster* caster;
    const std::vector<glm::dvec3>* points;  // null for a mesh shadow
    bool core;
    Aabb box;  // of the points
    std::size_t mesh = 0;  // a mesh shadow's slot among a sample's
  };
  std::vector<Drawn> drawn;
  const auto box_of = [](const std::vector<glm::dvec3>& points) {
    Aabb box;
    for (const glm::dvec3& p : points) box.extend(p);
    return box;
  };
  for (const Caster& o : casters)
    for (const std::size_t c : o.drawn_cores) drawn.push_back({&o, &o.cores[c].points, true, box_of(o.cores[c].points)});
  for (const Caster& o : casters)
    for (const std::vector<glm::dvec3>& hull : o.hulls) drawn.push_back({&o, &hull, false, box_of(hull)});
  std::size_t meshes = 0;
  for (const Caster& o : casters)
    if (o.mesh_shadow) drawn.push_back({&o, nullptr, false, o.mesh_shadow->reach(), meshes++});
  const Drawn* const mesh_drawn = drawn.data() + (drawn.size() - meshes);  // slot m is mesh_drawn[m]
  // The grid's rectangle, a cell wider each way and a millionth of the
  // magnitudes met (a thousand times PlaneShadow's slack): a shadow whose
  // box lies outside it holds no point (a site's objects far from a
  // garden's grid cost a hull each sample otherwise).
  const glm::dvec3 grid_low = grid.origin(),
                   grid_high = grid.origin() + glm::dvec3(grid.columns * grid.spacing, 0.0, grid.rows * grid.spacing);
  const double grid_magnitude = std::max(max_abs(grid_low), max_abs(grid_high));
  const auto misses_grid = [&](const Aabb& box, const glm::dvec3& d) {
    // Each corner slid down the sun onto the plane: x - (y - y0) dx / dy,
    // whose extremes over the box are at its corners.
    const double t_low = (box.min.y - grid.center.y) / d.y, t_high = (box.max.y - grid.center.y) / d.y;
    const double x0 = std::min(box.min.x - t_low * d.x, box.min.x - t_high * d.x),
                 x1 = std::max(box.max.x - t_low * d.x, box.max.x - t_high * d.x),
                 z0 = std::min(box.min.z - t_low * d.z, box.min.z - t_high * d.z),
                 z1 = std::max(box.max.z - t_low * d.z, box.max.z - t_high * d.z);
    const double slack =
        grid.spacing +
        1e-6 * (1.0 + std::max({std::abs(x0), std::abs(x1), std::abs(z0), std::abs(z1), grid_magnitude}));
    return x1 < grid_low.x - slack || x0 > grid_high.x + slack || z1 < grid_low.z - slack || z0 > grid_high.z + slack;
  };
  // Blocks of up to 32 samples, or 128 where meshes draw from memories of
  // consecutive samples (fewer memory starts, finer runs to deal); a
  // memory per time of day needs a block within a day.
  const std::size_t block = std::clamp<std::size_t>(16384 / std::max<std::size_t>(1, drawn.size()), 1,
                                                    meshes > 0 && day_slots == 0 ? 128 : 32);
  // The runs a mesh's block is cut into: those that end soonest when dealt
  // to the threads, a run's first draw costing about 3.3 of the others
  // (it starts its memory afresh: the teapot's 1.0 ms against 0.3; none
  // does in a memory per time of day).
  const double start_cost = day_slots > 0 ? 0.0 : 2.3;
  std::size_t runs = 1;
  double soonest = 1e300;
  for (std::size_t r = 1; r <= std::size_t(kMeshRuns) && meshes > 0; ++r) {
    const double rounds = std::ceil(double(meshes * r) / double(threads));
    const double end = rounds * (start_cost + double(block) / double(r));
    if (end < soonest * (1.0 - 1e-9)) soonest = end, runs = r;
  }
  // A block's mesh shadows are held at once: each draw gathers at most its
  // share of about 256 MB (16 bytes an entry; a fallback past it, see
  // MeshGridShadow::draw), at least 65,536 entries.
  const std::size_t most_gathered =
      std::max<std::size_t>(65536, (std::size_t(256) << 20) / 16 / std::max<std::size_t>(1, block * meshes));
  std::vector<std::optional<PlaneShadow>> shadows(block * drawn.size());
  std::vector<GridShadow> mesh_shadows(block * meshes);
  const auto owned_rows = [&](int t, int first, int last, const auto& visit) {
    // The first row of t's stripes at or after `first`.
    int stripe = first / kStripe;
    stripe += ((t - stripe % threads) % threads + threads) % threads;
    for (int r = std::max(first, stripe * kStripe); r <= last;) {
      visit(r);
      ++r;
      if (r % kStripe == 0) r += (threads - 1) * kStripe;
    }
  };
  // Per block, the mesh runs claimed so far.
  std::vector<std::atomic<std::uint32_t>> claimed((ups.size() + block - 1) / block);
  Barrier barrier(threads);
  std::atomic<std::uint64_t> cast{0};
  StopPoll poll(stop_requested);
  // Per row, the columns in some core's shadow at the row's last sample
  // (merged, in order), and this sample's as the cores are drawn: a row's
  // points are touched only where they enter or leave a core's shadow,
  // not at every sample they stay in it (a city's long shadows were most
  // of the walk). Each row is its owner thread's alone.
  std::vector<std::vector<ColumnSpan>> core_dark(std::size_t(grid.rows)), core_now(std::size_t(grid.rows));
  const auto worker = [&](int t) {
    std::uint64_t casts = 0, since = 0;
    for (std::size_t first = 0; first < ups.size(); first += block) {
      const std::size_t count = std::min(block, ups.size() - first);
      // The block's shadows, dealt among the threads. A sun on the horizon
      // draws none: no footprint reaches the plane.
      if (!poll.ask())
        for (std::size_t i = std::size_t(t); i < count * drawn.size(); i += std::size_t(threads)) {
          std::optional<PlaneShadow>& shadow = shadows[i];
          shadow.reset();
          const glm::dvec3& d = samples[ups[first + i / drawn.size()].k].direction;
          const Drawn& w = drawn[i % drawn.size()];
          if (w.caster->mesh_shadow) continue;
          if (!(d.y > 0.0) || misses_grid(w.box, d)) continue;
          shadow.emplace(w.points->data(), int(w.points->size()), d, grid);
          // An analytic solid's core's shadow only where it spares more
          // proofs than its rows' crossings cost (a model's spares rays).
          if (w.core && !pays(*w.caster, *shadow)) shadow.reset();
        }
      // The meshes' shadows: run j of mesh m is the j-th of `runs` stretches
      // of the block's samples, drawn in order in memory slot j, or each in
      // its time of day's where the block spans less than a day (no two of
      // its samples share one: a slot is one thread's at a time).
      const bool by_day = day_slots > 0 && ups[first + count - 1].k - ups[first].k < day_slots;
      if (!poll.stopped())
        for (std::size_t item; (item = claimed[first / block].fetch_add(1, std::memory_order_relaxed)) < meshes * runs;) {
          const std::size_t m = item / runs, j = item % runs;
          const Drawn& w = mesh_drawn[m];
          for (std::size_t e = count * j / runs; e < count * (j + 1) / runs; ++e) {
            const glm::dvec3& d = samples[ups[first + e].k].direction;
            GridShadow& mesh = mesh_shadows[e * meshes + m];
            mesh.first_row = 0, mesh.last_row = -1;
            if (d.y > 0.0 && !misses_grid(w.box, d))
              w.caster->mesh_shadow->draw(d, grid, 1, mesh,
                                          by_day ? kMeshRuns + int(ups[first + e].k % day_slots) : int(j),
                                          most_gathered, by_day || close_steps);
            if (poll.after(since, std::uint64_t(mesh.work))) break;
          }
        }
      barrier.wait();
      for (std::size_t e = 0; e < count && !poll.stopped(); ++e) {
        const Up& up = ups[first + e];
        const std::size_t k = up.k, j = up.stretch;
        const Stretch& stretch = stretches[j];
        const glm::dvec3& d = samples[k].direction;
        const std::int32_t now = std::int32_t(k);
        // Dark: the run since the point's last dark sample in this
        // stretch (or the stretch's start) ends here.
        const auto dark = [&](PointState& point) {
          const std::size_t start =
              point.dark_stretch == std::int32_t(j) ? std::size_t(point.last_dark + 1) : stretch.first;
          point.longest = std::max<std::uint32_t>(point.longest, std::uint32_t(k - start));
          point.last_dark = std::int32_t(k);
          point.dark_stretch = std::int32_t(j);
          ++point.dark;
        };
        // A point whose core run ends: dark from core_since (counted when
        // it entered) to the sample before `until`, the rest counted now.
        const auto leave_core = [&](PointState& point, std::size_t until) {
          point.dark += std::uint32_t(until - std::size_t(point.core_since) - 1);
          point.last_dark = std::int32_t(until - 1);
          point.core_since = -1;
        };
        // A ray through a solid's core surely meets it (SolidCore): each
        // row's stretch there is dark, proved for the row at once.
        for (std::size_t w = 0; w < drawn.size() && !poll.stopped(); ++w) {
          if (drawn[w].caster->mesh_shadow) {
            // A mesh's dark spans, as a core's.
            const GridShadow& mesh = mesh_shadows[e * meshes + drawn[w].mesh];
            if (mesh.empty()) continue;
            owned_rows(t, mesh.first_row, mesh.last_row, [&](int r) {
              std::size_t count;
              const ColumnSpan* spans = mesh.dark_of(r, count);
              core_now[std::size_t(r)].insert(core_now[std::size_t(r)].end(), spans, spans + count);
            });
            continue;
          }
          const std::optional<PlaneShadow>& shadow = shadows[e * drawn.size() + w];
          int first_row, last_row;
          if (!drawn[w].core || !shadow || !shadow->rows(0, grid.rows, 1, first_row, last_row)) continue;
          owned_rows(t, first_row, last_row, [&](int r) {
            int c0, c1;
            if (shadow->inner_columns(r, c0, c1)) core_now[std::size_t(r)].push_back({c0, c1});
          });
        }
        // Each row's points that enter a core's shadow turn dark (and stay
        // so, uncounted, while in it); those that leave it are counted.
        owned_rows(t, 0, grid.rows - 1, [&](int r) {
          std::vector<ColumnSpan>& was = core_dark[std::size_t(r)];
          std::vector<ColumnSpan>& is = core_now[std::size_t(r)];
          if (was.empty() && is.empty()) return;
          merge_spans(is);
          PointState* row = &state[std::size_t(r) * std::size_t(grid.columns)];
          std::uint64_t touched = 0;
          for_each_difference(is, was, [&](int c0, int c1) {
            touched += std::uint64_t(c1 - c0 + 1);
            for (int c = c0; c <= c1; ++c)
              if (row[c].tested != kInside) dark(row[c]), row[c].core_since = now;
          });
          for_each_difference(was, is, [&](int c0, int c1) {
            touched += std::uint64_t(c1 - c0 + 1);
            for (int c = c0; c <= c1; ++c)
              if (row[c].core_since >= 0) leave_core(row[c], k);
          });
          poll.after(since, touched);
          was.swap(is);
          is.clear();
        });
        // A point in a footprint, not settled yet this sample: dark for
        // certain when the ray passes well inside the object whose
        // footprint holds it (the pure ray cast's query would find that
        // hit: ShapeKind::surely_meets), else settled by the query itself.
        const auto judge = [&](const Caster& object, int r, int c0, int c1) {
          for (int c = c0; c <= c1; ++c) {
            const std::size_t i = std::size_t(r) * std::size_t(grid.columns) + std::size_t(c);
            PointState& point = state[i];
            if (point.tested >= now) continue;
            point.tested = now;
            const glm::dvec3 p = grid.point(i);
            const bool surely_dark =
                object.kind->surely_meets && object.kind->surely_meets(*object.object, p, d, object.margin);
            if (!surely_dark) {
              ++casts;
              const bool lit = sees_sun(rays, p, d);
              poll.after(since, 16);  // a query weighs about as much as 16 visits
              if (lit) continue;
            }
            dark(point);
          }
        };
        for (std::size_t w = 0; w < drawn.size() && !poll.stopped(); ++w) {
          const Caster& object = *drawn[w].caster;
          if (object.mesh_shadow) {
            // A mesh's unsure spans (its dark ones are the cores' now, the
            // rest lit as far as it goes).
            const GridShadow& mesh = mesh_shadows[e * meshes + drawn[w].mesh];
            if (mesh.empty()) continue;
            owned_rows(t, mesh.first_row, mesh.last_row, [&](int r) {
              std::size_t count;
              const ColumnSpan* spans = mesh.unsure_of(r, count);
              for_each_difference(spans, count, core_dark[std::size_t(r)], [&](int c0, int c1) {
                poll.after(since, std::uint64_t(c1 - c0 + 1));
                judge(object, r, c0, c1);
              });
            });
            continue;
          }
          const std::optional<PlaneShadow>& shadow = shadows[e * drawn.size() + w];
          if (!shadow || drawn[w].core) continue;
          int first_row, last_row;
          if (!shadow->rows(0, grid.rows, 1, first_row, last_row)) continue;
          // A footprint: its points not settled yet (outside the cores'
          // shadows).
          owned_rows(t, first_row, last_row, [&](int r) {
            int outer0, outer1;
            if (!shadow->outer_columns(r, outer0, outer1) || poll.after(since, std::uint64_t(outer1 - outer0 + 1)))
              return;
            const ColumnSpan outer{outer0, outer1};
            for_each_difference(&outer, 1, core_dark[std::size_t(r)],
                                [&](int c0, int c1) { judge(object, r, c0, c1); });
          });
        }
        if (!up.last || poll.stopped()) continue;
        // The stretch ends: each point's last run in it, and the runs in
        // the cores' shadows (the sun sets on them).
        owned_rows(t, 0, grid.rows - 1, [&](int r) {
          core_dark[std::size_t(r)].clear();
          for (int c = 0; c < grid.columns; ++c) {
            PointState& point = state[std::size_t(r) * std::size_t(grid.columns) + std::size_t(c)];
            if (point.tested == kInside) continue;
            if (point.core_since >= 0) leave_core(point, stretch.end);
            const std::size_t start =
                point.dark_stretch == std::int32_t(j) ? std::size_t(point.last_dark + 1) : stretch.first;
            point.longest = std::max<std::uint32_t>(point.longest, std::uint32_t(stretch.end - start));
          }
        });
      }
      barrier.wait();
      if (t == 0 && pairs_done && !poll.stopped()) pairs_done->fetch_add(std::uint64_t(count) * std::uint64_t(points));
    }
    cast.fetch_add(casts);
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(worker, t);
  worker(0);
  for (auto& thread : pool) thread.join();
  if (poll.stopped()) throw CastStopped();
  for (std::size_t i = 0; i < points; ++i) {
    const PointState& point = state[i];
    PointTally& t = result.tally[i];
    t.lit = point.tested == kInside ? 0 : std::uint32_t(up) - point.dark;
    t.longest = point.tested == kInside ? 0 : point.longest;
    t.run = 0;
  }
  result.pairs_ray_cast = cast.load();
  result.pairs_by_maps = result.pairs - result.pairs_ray_cast;
  result.path = "footprints";
}

}  // namespace umbra
