#include "plan/conservative_maps.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <thread>

#include "core/convex_patches.hpp"
#include "core/light_math.hpp"
#include "core/shapes/shape.hpp"

namespace umbra {

std::vector<ConservativeObject> conservative_objects(const Scene& scene, const glm::dvec3& mesh_origin) {
  std::vector<ConservativeObject> objects;
  objects.reserve(scene.objects.size());
  for (const SceneObject& o : scene.objects)
    objects.push_back({tessellation_error(o).distance, o.type == SceneObject::Type::Mesh, shape_kind(o.type).closed(o),
                       largest_coordinate(object_bounds(o), mesh_origin)});
  return objects;
}

double light_view_rounding(const ConservativeObject& object, const glm::mat4& view) {
  return light_view_rounding(object.extent, glm::length(glm::dvec3(view[3])));
}

std::vector<std::uint32_t> light_facing_owners(const Scene& scene, const Mesh& mesh) {
  std::size_t triangles = 0;
  for (const ObjectRange& r : mesh.object_ranges) triangles = std::max(triangles, std::size_t(r.first_index + r.index_count) / 3);
  std::vector<std::uint32_t> owners(triangles, 0);
  std::vector<std::pair<const TriangleModel*, std::vector<std::uint32_t>>> patches_of;  // per model, once
  for (const ObjectRange& r : mesh.object_ranges) {
    const SceneObject& o = scene.objects.at(r.object);
    const std::size_t first = r.first_index / 3, count = r.index_count / 3;
    if (o.type != SceneObject::Type::Mesh) {
      std::fill_n(owners.begin() + std::ptrdiff_t(first), count, std::uint32_t(r.object));
      continue;
    }
    for (std::size_t t = 0; t < count; ++t) owners[first + t] = std::uint32_t(first + t) | kModelTriangleOwner;
    if (!o.model || triangles >= kMostPatchOwnedTriangles) continue;
    auto known = std::find_if(patches_of.begin(), patches_of.end(), [&](const auto& k) { return k.first == o.model.get(); });
    if (known == patches_of.end()) known = patches_of.insert(patches_of.end(), {o.model.get(), convex_patches(*o.model)});
    const std::vector<std::uint32_t>& head = known->second;
    if (head.size() != count) continue;  // not this range's triangles: keep them their own
    // A patch of one keeps the triangle's own owner; the others name their
    // first triangle, as numbered in the scene.
    std::vector<std::uint8_t> shared(count, 0);
    for (std::size_t t = 0; t < count; ++t)
      if (head[t] != t) shared[t] = shared[head[t]] = 1;
    for (std::size_t t = 0; t < count; ++t)
      if (shared[t]) owners[first + t] = std::uint32_t(first + head[t]) | kModelPatchOwner;
  }
  return owners;
}

namespace {

// certify.geom's to_texels, in double.
glm::dvec3 to_texels(const glm::dvec4& clip, double size) {
  const glm::dvec3 ndc = glm::dvec3(clip) / clip.w;
  return {(ndc.x * 0.5 + 0.5) * size, (ndc.y * 0.5 + 0.5) * size, ndc.z * 0.5 + 0.5};
}

// certify.geom, step for step (its comments say why each step holds).
// `owner`: the triangle's own; `facing_owner`: its owner where it clearly
// turns its outward side to the light (a model's patch).
bool set_up(const glm::dvec4 in_clip[3], const ConservativeView& view, const ConservativeObject& object,
            std::uint32_t owner, std::uint32_t facing_owner, ConservativeMaps::Setup& s) {
  const double size = double(view.size);
  glm::dvec4 poly[4];
  int n = 0;
  if (view.perspective) {
    const double w_min = 0.5 * view.near_plane;
    for (int i = 0; i < 3; ++i) {
      const glm::dvec4 a = in_clip[i], b = in_clip[(i + 1) % 3];
      const bool a_in = a.w >= w_min, b_in = b.w >= w_min;
      if (a_in) poly[n++] = a;
      if (a_in != b_in) poly[n++] = a + (b - a) * ((w_min - a.w) / (b.w - a.w));
    }
    if (n < 3) return false;
  } else {
    for (int i = 0; i < 3; ++i) poly[i] = in_clip[i];
    n = 3;
  }
  glm::dvec3 p[4];
  glm::dvec2 lo(1e300), hi(-1e300);
  double min_depth = 1e300, max_depth = -1e300;
  for (int i = 0; i < n; ++i) {
    p[i] = to_texels(poly[i], size);
    lo = glm::min(lo, glm::dvec2(p[i]));
    hi = glm::max(hi, glm::dvec2(p[i]));
    min_depth = std::min(min_depth, p[i].z);
    max_depth = std::max(max_depth, p[i].z);
  }
  if (!(hi.x >= -1.0 && hi.y >= -1.0 && lo.x <= size + 1.0 && lo.y <= size + 1.0)) return false;
  double area = 0.0;
  for (int i = 0; i < n; ++i) {
    const glm::dvec2 a(p[i]), b(p[(i + 1) % n]);
    area += a.x * b.y - b.x * a.y;
  }
  const double extent = std::max(std::max(std::abs(lo.x), std::abs(lo.y)), std::max(std::abs(hi.x), std::abs(hi.y)));
  // Which way the face turns on the layer, where it is clear (certify.geom).
  const bool cull = view.cull_closed_back && object.closed && !object.model;
  bool turns_to_light = false;
  if (cull || facing_owner != owner) {
    double perimeter = 0.0, fan_area = 0.0;
    for (int i = 0; i < n; ++i) perimeter += glm::length(glm::dvec2(p[(i + 1) % n]) - glm::dvec2(p[i]));
    for (int i = 1; i + 1 < n; ++i) {
      const glm::dvec2 e1 = glm::dvec2(p[i]) - glm::dvec2(p[0]), e2 = glm::dvec2(p[i + 1]) - glm::dvec2(p[0]);
      fan_area += e1.x * e2.y - e1.y * e2.x;
    }
    const double fan_rounding = 4e-6 * std::max(1.0, extent) * perimeter + 1e-6 * perimeter * perimeter;
    if (cull && fan_area < -fan_rounding) return false;
    turns_to_light = fan_area > fan_rounding;
  }
  const bool has_area = std::abs(area) > 1e-4 * std::max(1.0, extent);
  s.edge_count = has_area ? n : 0;
  for (int i = 0; i < 4; ++i) {
    const int k = area >= 0.0 ? i : n - 1 - i;
    s.corner[i] = i < n ? glm::dvec2(p[k]) : glm::dvec2(0.0);
  }
  glm::dvec3 a = p[0], b = p[1], c = p[2];
  glm::dvec2 ab = glm::dvec2(b) - glm::dvec2(a), ac = glm::dvec2(c) - glm::dvec2(a);
  double det = ab.x * ac.y - ab.y * ac.x;
  if (n == 4) {
    const glm::dvec2 ad = glm::dvec2(p[3]) - glm::dvec2(a);
    const double det2 = ac.x * ad.y - ac.y * ad.x;
    if (std::abs(det2) > std::abs(det)) {
      b = p[2];
      c = p[3];
      ab = glm::dvec2(b) - glm::dvec2(a);
      ac = glm::dvec2(c) - glm::dvec2(a);
      det = det2;
    }
  }
  s.plane_valid = std::abs(det) > 1e-6 * std::max(1.0, glm::dot(ab, ab) + glm::dot(ac, ac));
  if (s.plane_valid) {
    const double dzb = b.z - a.z, dzc = c.z - a.z;
    s.plane = {(dzb * ac.y - dzc * ab.y) / det, (dzc * ab.x - dzb * ac.x) / det, a.z};
  } else {
    s.plane = {0.0, 0.0, a.z};
  }
  s.origin = glm::dvec2(a);
  s.min_depth = min_depth;
  s.max_depth = max_depth;
  s.owner = turns_to_light ? facing_owner : owner;
  const double coarse_texels = double(view.layer_size) / size;
  double nearest_w = 1e300;
  for (int i = 0; i < n; ++i) nearest_w = std::min(nearest_w, poly[i].w);
  const double texel_world =
      certified_texel_world(view.perspective, view.texel_size, view.tan_half, coarse_texels, nearest_w);
  const double window_per_world =
      view.perspective ? view.near_plane * view.far_plane / ((view.far_plane - view.near_plane) * nearest_w * nearest_w)
                       : 1.0 / (view.far_plane - view.near_plane);
  // The true surface reaches past the drawn triangle by the shape's
  // tessellation distance and the light view's rounding of its corners.
  const double rounding = light_view_rounding(object, view.view);
  s.rounding = rounding / texel_world;
  s.depth_rounding = rounding * window_per_world;
  s.swell = (object.swell + rounding) / texel_world;
  s.depth_swell = (object.swell + rounding) * window_per_world;
  const double margin = 0.5 + s.swell + 1.0 / 32.0 + 1e-6 * extent;
  s.lo = glm::clamp(lo - margin, glm::dvec2(-1.0), glm::dvec2(size + 1.0));
  s.hi = glm::clamp(hi + margin, glm::dvec2(-1.0), glm::dvec2(size + 1.0));
  return true;
}

// The texels whose centres (i + 0.5) lie in [lo, hi].
int first_centre(double lo) { return int(std::ceil(lo - 0.5)); }
int last_centre(double hi) { return int(std::floor(hi - 0.5)); }

// The float no greater than `d` (in [0, 1]): a depth rounded towards the
// light. Where float(d) rounded up, it is above d >= 0, so positive: the
// next float below is one less in its bits (std::nextafter's value, without
// a library call per texel).
float float_at_most(double d) {
  float f = float(d);
  if (double(f) > d) {
    std::uint32_t bits;
    std::memcpy(&bits, &f, sizeof bits);
    --bits;
    std::memcpy(&f, &bits, sizeof f);
  }
  return f;
}

}  // namespace

// A corner is shared by about six triangles and four edges: each is
// projected once per layer (the same double product each time).
struct ConservativeMaps::ClipCorners {
  const std::vector<glm::vec3>& positions;
  glm::dmat4 to_clip;
  std::vector<glm::dvec4> clip = std::vector<glm::dvec4>(positions.size());
  std::vector<std::uint8_t> projected = std::vector<std::uint8_t>(positions.size(), 0);

  const glm::dvec4& operator()(std::uint32_t v) {
    if (!projected.at(v)) {
      clip[v] = to_clip * glm::dvec4(glm::dvec3(positions[v]), 1.0);
      projected[v] = 1;
    }
    return clip[v];
  }
};

ConservativeMaps::ConservativeMaps(const std::vector<glm::vec3>& positions, const std::vector<std::uint32_t>& indices,
                                   const std::vector<ConservativeObject>& objects,
                                   const std::vector<std::uint32_t>& triangle_objects,
                                   const std::vector<DrawRange>& draws, const ConservativeView& view,
                                   const std::vector<std::uint32_t>& facing_owners, const SliverEdges* edges) {
  ClipCorners clip_of{positions, glm::dmat4(view.projection) * glm::dmat4(view.view)};
  // Which triangles the maps hold (their setups'), for the folds.
  std::vector<std::uint8_t> drawn(edges ? triangle_objects.size() : 0, 0);
  for (const DrawRange& draw : draws) {
    for (std::size_t i = draw.first; i + 2 < draw.first + draw.count; i += 3) {
      const std::size_t triangle = i / 3;
      const std::uint32_t object = triangle_objects.at(triangle);
      const ConservativeObject& facts = objects.at(object);
      glm::dvec4 clip[3];
      for (int k = 0; k < 3; ++k) clip[k] = clip_of(indices.at(i + std::size_t(k)));
      const std::uint32_t owner = facts.model ? (std::uint32_t(triangle) | kModelTriangleOwner) : object;
      const std::uint32_t facing_owner = facts.model && !facing_owners.empty() ? facing_owners.at(triangle) : owner;
      Setup s;
      if (set_up(clip, view, facts, owner, facing_owner, s)) {
        setups_.push_back(s);
        if (edges) drawn.at(triangle) = 1;
      }
    }
  }
  // The boxes' texels summed: past kMostTexelTouches passes over the
  // layer, the maps are not drawn but hold depth 0 (they prove nothing).
  double touches = 0.0;
  for (const Setup& s : setups_) touches += (s.hi.x - s.lo.x + 1.0) * (s.hi.y - s.lo.y + 1.0);
  if (touches > kMostTexelTouches * double(view.size) * double(view.size)) {
    too_much_ = true;
    return;
  }
  if (edges) find_folds(clip_of, *edges, drawn, objects, view);
}

// The cover map's argument (docs/certified-shadows.md, "The cover map"):
// how many of the drawn triangles a light ray meets changes, as the ray
// moves across the layer, only where it crosses an edge whose two
// triangles lie on one side of it there (the surface folds over, seen from
// the light), or an edge of a drawn triangle that no other drawn triangle
// shares. Every other edge is crossed from one triangle into the next.
void ConservativeMaps::find_folds(ClipCorners& clip_of, const SliverEdges& edges, const std::vector<std::uint8_t>& drawn,
                                  const std::vector<ConservativeObject>& objects, const ConservativeView& view) {
  cover_ = true;
  const double size = double(view.size);
  const double w_min = view.perspective ? 0.5 * view.near_plane : -1e300;
  const auto is_drawn = [&](std::uint32_t t) { return t != SliverEdges::kOpen && t < drawn.size() && drawn[t]; };
  for (const SliverEdges::Edge& e : edges.all()) {
    if (!is_drawn(e.first_triangle) && !is_drawn(e.second_triangle)) continue;
    glm::dvec4 a = clip_of(e.a), b = clip_of(e.b);
    if (a.w < w_min && b.w < w_min) continue;  // wholly behind half the near plane: off the layer
    bool fold = true;
    if (is_drawn(e.first_triangle) && is_drawn(e.second_triangle) && a.w >= w_min && b.w >= w_min) {
      const glm::dvec4 c = clip_of(e.first_third), d = clip_of(e.second_third);
      if (c.w >= w_min && d.w >= w_min) {
        const glm::dvec2 pa = glm::dvec2(to_texels(a, size)), pb = glm::dvec2(to_texels(b, size));
        const glm::dvec2 pc = glm::dvec2(to_texels(c, size)), pd = glm::dvec2(to_texels(d, size));
        const glm::dvec2 ab = pb - pa;
        // Each third corner's side, settled beyond the corners' rounding
        // (as the maps' edges allow it: 1e-3 texel and 1e-6 of the extent).
        const double eps = 1e-3 + 1e-6 * std::max({std::abs(pa.x), std::abs(pa.y), std::abs(pb.x), std::abs(pb.y), 1.0});
        const auto side = [&](const glm::dvec2& q) {
          const glm::dvec2 aq = q - pa;
          const double cross = ab.x * aq.y - ab.y * aq.x;
          const double bound = 2.0 * eps * (std::abs(ab.x) + std::abs(ab.y) + std::abs(aq.x) + std::abs(aq.y) +
                                            std::abs(q.x - pb.x) + std::abs(q.y - pb.y)) + 4.0 * eps * eps;
          return cross > bound ? 1 : cross < -bound ? -1 : 0;
        };
        const int sc = side(pc), sd = side(pd);
        fold = !(sc != 0 && sd != 0 && sc != sd);
      }
    }
    if (!fold) continue;
    // The part in front of half the near plane (the rest lies off the
    // layer, as every triangle's part there does).
    if (a.w < w_min) a = b + (a - b) * ((b.w - w_min) / (b.w - a.w));
    if (b.w < w_min) b = a + (b - a) * ((a.w - w_min) / (a.w - b.w));
    Fold f{glm::dvec2(to_texels(a, size)), glm::dvec2(to_texels(b, size))};
    // Clamped to a little beyond the layer: a fold's marks off it are not kept.
    const glm::dvec2 lo(-4.0), hi(size + 4.0);
    if (std::max(f.a.x, f.b.x) < lo.x || std::min(f.a.x, f.b.x) > hi.x || std::max(f.a.y, f.b.y) < lo.y ||
        std::min(f.a.y, f.b.y) > hi.y)
      continue;
    // Every texel whose square comes within the rounding of the fold: its
    // centre within half a diagonal of it, and 1/32 texel, 1e-3 texel and
    // 1e-6 of the corners' extent more (the maps' own margins).
    // And the light view's rounding of the corners, in texels where the
    // fold is nearest the light (set_up's texel size).
    const double extent = std::max({size, std::abs(f.a.x), std::abs(f.a.y), std::abs(f.b.x), std::abs(f.b.y)});
    const double coarse_texels = double(view.layer_size) / size;
    const double texel_world = certified_texel_world(view.perspective, view.texel_size, view.tan_half, coarse_texels,
                                                     std::max(std::min(a.w, b.w), w_min));
    const double rounding = e.object < objects.size() ? light_view_rounding(objects[e.object], view.view) : 0.0;
    f.reach = 0.5 * std::sqrt(2.0) + 1.0 / 32.0 + 1e-3 + 1e-6 * extent + rounding / texel_world;
    folds_.push_back(f);
  }
}

void ConservativeMaps::touched(int& x0, int& y0, int& x1, int& y1) const {
  if (too_much_) {  // every texel
    x0 = y0 = -1;
    x1 = y1 = std::numeric_limits<int>::max() / 2;
    return;
  }
  x0 = y0 = std::numeric_limits<int>::max();
  x1 = y1 = std::numeric_limits<int>::min();
  for (const Setup& s : setups_) {
    // Centres within the box, as draw() takes them.
    x0 = std::min(x0, first_centre(s.lo.x));
    y0 = std::min(y0, first_centre(s.lo.y));
    x1 = std::max(x1, last_centre(s.hi.x) + 1);
    y1 = std::max(y1, last_centre(s.hi.y) + 1);
  }
  if (setups_.empty()) x0 = y0 = x1 = y1 = 0;
}

// certify.frag over the band: each texel whose centre lies in a setup's box
// and on the inner side of each of its edges (grown as the shader grows
// them) takes the least depth of its plane over the texel's square; the
// nearest map keeps the least depth and its owner, the others map the
// least depth of every other owner.
void ConservativeMaps::draw(ConservativeBand& band) const {
  const std::size_t w = std::size_t(std::max(0, band.width())), h = std::size_t(std::max(0, band.height()));
  band.nearest_depth.assign(w * h, 1.0f);
  band.nearest_owner.assign(w * h, kNoOwner);
  band.others_depth.assign(w * h, 1.0f);
  // The cover map: each texel's farthest depth of the triangles touching
  // it (-infinity: none yet); scratch 1 where a triangle holds the texel's
  // centre, 2 where a fold passes near.
  band.cover_depth.assign(w * h, cover_ ? -std::numeric_limits<float>::infinity() : 1.0f);
  band.scratch.assign(cover_ ? w * h : 0, 0);
  if (w == 0 || h == 0) return;
  if (too_much_) {
    std::fill(band.nearest_depth.begin(), band.nearest_depth.end(), 0.0f);
    std::fill(band.nearest_owner.begin(), band.nearest_owner.end(), kEveryOwner);
    std::fill(band.others_depth.begin(), band.others_depth.end(), 0.0f);
    return;
  }
  struct Edge {
    double nx, ny, k;  // keeps nx * cx + ny * cy + k <= 0
  };
  for (const Setup& s : setups_) {
    // Centres within the box.
    const int i0 = std::max(band.x0, first_centre(s.lo.x)), i1 = std::min(band.x1 - 1, last_centre(s.hi.x));
    const int j0 = std::max(band.y0, first_centre(s.lo.y)), j1 = std::min(band.y1 - 1, last_centre(s.hi.y));
    if (i0 > i1 || j0 > j1) continue;
    // certify.frag drops a centre where dot(n, c - a) - (|n.x| + |n.y|) / 2
    // exceeds its rounding, (|n.x| + |n.y|) (1e-3 + 1e-6 (|d.x| + |d.y|)) +
    // swell |n|, the first two terms for float. Here |d| is taken as the
    // clamped box's size, which can be less than the shader's (a corner far
    // off the layer): still far above this double arithmetic's rounding, so
    // the 1e-3 texel alone would do.
    const double reach = (s.hi.x - s.lo.x) + (s.hi.y - s.lo.y) + 2.0;
    Edge edges[4];
    // For the cover map: the centres the polygon itself holds (no growth,
    // no swell: a curved shape's faces lie inside its true surface), kept
    // inside by the corners' rounding (1e-3 texel and 1e-6 of their extent).
    Edge inner[4];
    double corner_extent = 1.0;
    for (int e = 0; e < s.edge_count; ++e)
      corner_extent = std::max({corner_extent, std::abs(s.corner[e].x), std::abs(s.corner[e].y)});
    for (int e = 0; e < s.edge_count; ++e) {
      const glm::dvec2 a = s.corner[e], b = s.corner[(e + 1) % s.edge_count];
      const double nx = b.y - a.y, ny = a.x - b.x, l1 = std::abs(nx) + std::abs(ny);
      const double rounding = l1 * (1e-3 + 1e-6 * reach) + s.swell * std::sqrt(nx * nx + ny * ny);
      edges[e] = {nx, ny, -nx * a.x - ny * a.y - 0.5 * l1 - rounding};
      inner[e] = {nx, ny, -nx * a.x - ny * a.y + l1 * (1e-3 + 1e-6 * corner_extent) + s.rounding * std::sqrt(nx * nx + ny * ny)};
    }
    // The row's span of centres on the inner side of every edge of `of`.
    const auto span_of = [&](const Edge* of, double cy, double& from, double& to) {
      for (int e = 0; e < s.edge_count; ++e) {
        const Edge& g = of[e];
        const double k = g.ny * cy + g.k;
        if (g.nx > 0.0) {
          to = std::min(to, -k / g.nx + 1e-6);
        } else if (g.nx < 0.0) {
          from = std::max(from, -k / g.nx - 1e-6);
        } else if (k > 0.0) {
          return false;
        }
      }
      return from <= to;
    };
    const double slope = 0.5 * (std::abs(s.plane.x) + std::abs(s.plane.y));
    for (int j = j0; j <= j1; ++j) {
      const double cy = double(j) + 0.5;
      // The row's span of centres on the inner side of every edge, widened
      // by a millionth of a texel for this double arithmetic.
      double from = double(i0) + 0.5, to = double(i1) + 0.5;
      if (!span_of(edges, cy, from, to)) continue;
      const int a = std::max(i0, first_centre(from)), b = std::min(i1, last_centre(to));
      const std::size_t row = std::size_t(j - band.y0) * w;
      const double dy = cy - s.origin.y;
      if (cover_ && s.edge_count >= 3) {
        double in_from = from, in_to = to;
        if (span_of(inner, cy, in_from, in_to))
          for (int i = std::max(a, first_centre(in_from)); i <= std::min(b, last_centre(in_to)); ++i)
            band.scratch[row + std::size_t(i - band.x0)] = 1;
      }
      for (int i = a; i <= b; ++i) {
        double depth = s.min_depth, farthest = s.max_depth, rounding = 1e-6;
        if (s.plane_valid) {
          const double dx = double(i) + 0.5 - s.origin.x;
          const double centre = s.plane.z + s.plane.x * dx + s.plane.y * dy;
          depth = std::max(depth, centre - slope);
          farthest = std::min(farthest, centre + slope);
          rounding += 4e-7 * (std::abs(s.plane.x * dx) + std::abs(s.plane.y * dy) + slope + std::abs(s.plane.z));
        }
        const float d = float_at_most(std::clamp(depth - rounding - s.depth_swell, 0.0, 1.0));
        const std::size_t at = row + std::size_t(i - band.x0);
        // The cover map: the farthest depth of the plane over the texel's
        // square (never past the farthest corner) and its rounding, to the
        // nearest float here, a float step further in finish_cover.
        if (cover_) band.cover_depth[at] = std::max(band.cover_depth[at], float(farthest + rounding + s.depth_rounding));
        if (s.owner == band.nearest_owner[at]) {
          band.nearest_depth[at] = std::min(band.nearest_depth[at], d);
        } else if (d < band.nearest_depth[at]) {
          band.others_depth[at] = band.nearest_depth[at];
          band.nearest_depth[at] = d;
          band.nearest_owner[at] = s.owner;
        } else {
          band.others_depth[at] = std::min(band.others_depth[at], d);
        }
      }
    }
  }
  if (cover_) finish_cover(band);
}

// Marks the texels near each fold, and leaves the cover map far wherever
// a fold passes or no triangle holds the texel's centre.
void ConservativeMaps::finish_cover(ConservativeBand& band) const {
  const std::size_t w = std::size_t(band.width());
  // Solves lo <= c x + k <= hi for x, within [x_lo, x_hi].
  const auto clip = [](double c, double k, double lo, double hi, double& x_lo, double& x_hi) {
    if (std::abs(c) < 1e-12) {
      if (k < lo || k > hi) x_hi = x_lo - 1.0;
      return;
    }
    double p = (lo - k) / c, q = (hi - k) / c;
    if (p > q) std::swap(p, q);
    x_lo = std::max(x_lo, p);
    x_hi = std::min(x_hi, q);
  };
  for (const Fold& f : folds_) {
    const double r = f.reach;
    const int j0 = std::max(band.y0, first_centre(std::min(f.a.y, f.b.y) - r));
    const int j1 = std::min(band.y1 - 1, last_centre(std::max(f.a.y, f.b.y) + r));
    const glm::dvec2 d = f.b - f.a;
    const double length = glm::length(d);
    const glm::dvec2 u = length > 1e-12 ? d / length : glm::dvec2(1.0, 0.0), n(-u.y, u.x);
    for (int j = j0; j <= j1; ++j) {
      const double cy = double(j) + 0.5 - f.a.y;
      // The centres (x, cy) within r of the line and within r past its
      // ends along it: a rectangle around the segment, x relative to a.
      double x_lo = -1e300, x_hi = 1e300;
      clip(n.x, n.y * cy, -r, r, x_lo, x_hi);
      clip(u.x, u.y * cy, -r, length + r, x_lo, x_hi);
      if (x_lo > x_hi) continue;
      const int i0 = std::max(band.x0, first_centre(std::max(x_lo + f.a.x, -1e9)));
      const int i1 = std::min(band.x1 - 1, last_centre(std::min(x_hi + f.a.x, 1e9)));
      const std::size_t row = std::size_t(j - band.y0) * w;
      for (int i = i0; i <= i1; ++i) band.scratch[row + std::size_t(i - band.x0)] |= 2;
    }
  }
  // Kept: a step up from the nearest float of the farthest depth (at
  // least that depth), at most 1.
  // (The step in the bits, as float_at_most's: no library call per texel.)
  for (std::size_t at = 0; at < band.cover_depth.size(); ++at) {
    const float d = band.cover_depth[at];
    if (band.scratch[at] == 1 && d > 0.0f && d < 1.0f) {
      std::uint32_t bits;
      std::memcpy(&bits, &d, sizeof bits);
      ++bits;
      std::memcpy(&band.cover_depth[at], &bits, sizeof bits);
    } else {
      // Not proved, or at or before the light's near plane (depth <= 0:
      // nothing a fitted view holds; left far rather than stepped).
      band.cover_depth[at] = 1.0f;
    }
  }
}

bool ConservativeBand::others_all_far() const {
  return std::all_of(others_depth.begin(), others_depth.end(), [](float d) { return d == 1.0f; });
}

void draw_conservative_bands(const ConservativeMaps& maps, int x0, int y0, int x1, int y1, std::size_t band_bytes,
                             const std::function<void(const ConservativeBand&)>& take) {
  if (x1 <= x0 || y1 <= y0) return;
  const std::size_t row_bytes = std::size_t(x1 - x0) * (3 * sizeof(float) + sizeof(std::uint32_t) + 1);
  const int rows = int(std::clamp<std::size_t>(band_bytes / row_bytes, 1, std::size_t(y1 - y0)));
  const int threads = int(std::max(1u, std::thread::hardware_concurrency()));
  // Bands of about equal rows, at least one per thread where the rows allow.
  const int count = std::max((y1 - y0 + rows - 1) / rows, std::min(threads, y1 - y0));
  std::vector<ConservativeBand> bands(std::size_t(std::min(count, threads)));
  // Allocated here, not on the threads (draw() assigns within capacity).
  const std::size_t most = std::size_t(x1 - x0) * std::size_t((y1 - y0 + count - 1) / count + 1);
  for (ConservativeBand& band : bands) {
    band.nearest_depth.reserve(most);
    band.nearest_owner.reserve(most);
    band.others_depth.reserve(most);
    band.cover_depth.reserve(most);
    band.scratch.reserve(most);
  }
  for (int first = 0; first < count; first += int(bands.size())) {
    const int batch = std::min(int(bands.size()), count - first);
    for (int b = 0; b < batch; ++b) {
      ConservativeBand& band = bands[std::size_t(b)];
      band.x0 = x0;
      band.x1 = x1;
      band.y0 = y0 + int(std::int64_t(y1 - y0) * (first + b) / count);
      band.y1 = y0 + int(std::int64_t(y1 - y0) * (first + b + 1) / count);
    }
    std::vector<std::thread> pool;
    try {
      for (int b = 1; b < batch; ++b) pool.emplace_back([&maps, &bands, b] { maps.draw(bands[std::size_t(b)]); });
    } catch (...) {  // no thread to be had: those started are joined first
      for (std::thread& t : pool) t.join();
      throw;
    }
    maps.draw(bands[0]);
    for (std::thread& t : pool) t.join();
    for (int b = 0; b < batch; ++b) take(bands[std::size_t(b)]);
  }
}

}  // namespace umbra
