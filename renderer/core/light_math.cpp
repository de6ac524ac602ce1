#include "core/light_math.hpp"

#include "core/shader_facts.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <glm/trigonometric.hpp>

#include "core/lights/light_kind.hpp"
#include "core/lights/view_fitting.hpp"

namespace umbra {

glm::dvec3 orbit_light_position(const Light& light, double time) {
  return light.target + rotate_y(light.position - light.target, std::fmod(time * light.orbit_deg_per_s, 360.0));
}

glm::dvec3 sun_direction(double azimuth_deg, double elevation_deg, double north_deg) {
  // Azimuth A from a north turned clockwise by N is azimuth A + N from -Z
  // towards +X (clockwise seen from above, +Y up).
  const double azimuth = glm::radians(azimuth_deg + north_deg);
  const double elevation = glm::radians(elevation_deg);
  return {std::cos(elevation) * std::sin(azimuth), std::sin(elevation), -std::cos(elevation) * std::cos(azimuth)};
}

// Each kind places itself (core/lights/).
LightState light_at(const Light& light, double time) { return light_kind(light).place(light, time); }

double sun_disc_tan_radius(const Light& light) { return std::tan(glm::radians(0.5 * light.size)); }

glm::dmat4 stable_look_at(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up) {
  const glm::dvec3 forward = glm::normalize(target - eye);
  glm::dvec3 chosen_up = glm::normalize(up);
  // Within ~0.06 degrees of parallel the basis would spin wildly with tiny
  // changes of direction (and at exactly parallel be NaN): substitute.
  if (glm::length(glm::cross(forward, chosen_up)) < 1e-3) {
    if (std::abs(forward.y) > 0.5)
      chosen_up = glm::dvec3(0.0, 0.0, forward.y < 0.0 ? -1.0 : 1.0);
    else
      chosen_up = glm::dvec3(0.0, 1.0, 0.0);
  }
  return glm::lookAt(eye, target, chosen_up);
}

glm::dmat4 cube_face_view(const glm::dvec3& position, int face) {
  glm::dvec3 axis(0.0);
  axis[cube_face_axis(face)] = cube_face_negative(face) ? -1.0 : 1.0;
  return stable_look_at(position, position + axis, glm::dvec3(0.0, 1.0, 0.0));
}

CameraMatrices camera_matrices(const Camera& camera, int width, int height) {
  CameraMatrices m;
  m.view = stable_look_at(camera.position, camera.target, camera.up);
  m.projection = glm::perspective(glm::radians(camera.fov_y_deg), double(width) / double(height),
                                  camera.near_plane, camera.far_plane);
  return m;
}

std::optional<ScreenBounds> screen_bounds_of(const Aabb& box, const glm::dmat4& view_projection, double nearest_w) {
  ScreenBounds b{glm::dvec2(1e300), glm::dvec2(-1e300)};
  for (int k = 0; k < 8; ++k) {
    const glm::dvec3 corner{k & 1 ? box.max.x : box.min.x, k & 2 ? box.max.y : box.min.y,
                            k & 4 ? box.max.z : box.min.z};
    const glm::dvec4 clip = view_projection * glm::dvec4(corner, 1.0);
    if (!(clip.w > nearest_w)) return std::nullopt;
    b.low = glm::min(b.low, glm::dvec2(clip) / clip.w);
    b.high = glm::max(b.high, glm::dvec2(clip) / clip.w);
  }
  return b;
}

double screen_pixels_of(const Aabb& box, const Camera& camera, int width, int height) {
  const double whole = double(width) * double(height);
  if (box.empty()) return 0.0;
  const CameraMatrices m = camera_matrices(camera, width, height);
  const std::optional<ScreenBounds> b = screen_bounds_of(box, m.projection * m.view, 0.0);
  if (!b) return whole;
  const glm::dvec2 low = glm::clamp(b->low, -1.0, 1.0), high = glm::clamp(b->high, -1.0, 1.0);
  return (high.x - low.x) * 0.5 * width * (high.y - low.y) * 0.5 * height;
}

std::vector<bool> objects_split_by_the_light(const Mesh& mesh, const Camera& camera, int width, int height) {
  std::vector<bool> split(mesh.bounds.size(), false);
  for (const ObjectRange& r : mesh.object_ranges)
    if (r.first_index < mesh.closed_index_count && r.index_count > 0)
      split[r.object] = screen_pixels_of(mesh.bounds[r.object], camera, width, height) >= 4.0 * (r.index_count / 3);
  return split;
}

glm::dmat4 reversed_depth_projection(const Camera& camera, int width, int height) {
  // glm::perspective's x, y and w; z_clip = n (f - d) / (f - n) for a point
  // at depth d, so z_clip / w = n (f - d) / (d (f - n)): 1 at d = n, 0 at d = f.
  glm::dmat4 p = glm::perspective(glm::radians(camera.fov_y_deg), double(width) / double(height),
                                  camera.near_plane, camera.far_plane);
  const double n = camera.near_plane, f = camera.far_plane;
  p[2][2] = n / (f - n);
  p[3][2] = f * n / (f - n);
  return p;
}

int filter_reach_texels(const ShadowSettings& shadow) {
  switch (shadow.filter) {
    case ShadowFilter::Hard: return 1;
    case ShadowFilter::Pcf: return shadow.pcf_radius + 1;
    case ShadowFilter::Pcss: return kPcssSearchTexels + 1;  // the blocker search's reach
    // The certificate reads the texels a point's footprint (at most 1.5
    // texels wide) and the texel centres around it meet.
    case ShadowFilter::Exact: return 2;
  }
  return 1;
}

int filter_read_texels(const ShadowSettings& shadow) {
  switch (shadow.filter) {
    case ShadowFilter::Hard: return 1;
    // Bilinear taps R texels out read one texel further, rounded up.
    case ShadowFilter::Pcf: return shadow.pcf_radius + 2;
    case ShadowFilter::Pcss: return std::max(kPcssSearchTexels, kPcssMaxPenumbraTexels) + 1;
    case ShadowFilter::Exact: return 2;
  }
  return 1;
}

namespace {

// Grows `r` (texel units, unrounded) by the image in `view`'s layer of the
// part of `box` that the view draws.
void add_box_texels(const glm::dmat4& to_clip, double size, const Aabb& box, TexelRect& r) {
  if (box.empty()) return;
  const auto add = [&](const glm::dvec4& clip) {
    const glm::dvec2 texel = (glm::dvec2(clip) / clip.w * 0.5 + 0.5) * size;
    r.min = glm::min(r.min, texel);
    r.max = glm::max(r.max, texel);
  };
  std::array<glm::dvec4, 8> clips;
  // Corners inside the layer's sides and in front of the eye; corners
  // beyond each side (x < -w, x > w, y < -w, y > w) or at or behind it.
  bool inside = true;
  std::array<int, 5> beyond{};
  const std::vector<glm::dvec3> corners = box.corners();
  for (std::size_t i = 0; i < 8; ++i) {
    const glm::dvec4 c = to_clip * glm::dvec4(corners[i], 1.0);
    clips[i] = c;
    inside = inside && c.w > 0.0 && std::abs(c.x) <= c.w && std::abs(c.y) <= c.w;
    beyond[0] += c.x < -c.w, beyond[1] += c.x > c.w, beyond[2] += c.y < -c.w, beyond[3] += c.y > c.w;
    beyond[4] += c.w <= 0.0;
  }
  // A box wholly in front of the eye projects within its corners' image.
  // One wholly beyond a side, or behind the eye, draws nothing here. One
  // that straddles a side or reaches behind a point light's eye is cut to
  // the view's frustum first: only that part is drawn.
  if (inside) {
    for (const glm::dvec4& c : clips) add(c);
  } else if (std::find(beyond.begin(), beyond.end(), 8) == beyond.end()) {
    for (const glm::dvec3& p : frustum_box_intersection(to_clip, box)) add(to_clip * glm::dvec4(p, 1.0));
  }
}

constexpr TexelRect kNoTexels{glm::dvec2(1e300), glm::dvec2(-1e300)};

// Whole texels, one more on each side for rounding, within the layer.
TexelRect rounded_out(TexelRect r, double size) {
  if (!(r.min.x <= r.max.x && r.min.y <= r.max.y)) return TexelRect{};
  r.min = glm::clamp(glm::floor(r.min) - 1.0, 0.0, size);
  r.max = glm::clamp(glm::ceil(r.max) + 1.0, 0.0, size);
  return r;
}

// The bounding rectangle of the non-empty `rects`; empty if none is.
TexelRect bounding_rect(const std::vector<TexelRect>& rects) {
  TexelRect all = kNoTexels;
  for (const TexelRect& r : rects) {
    if (r.empty()) continue;
    all.min = glm::min(all.min, r.min);
    all.max = glm::max(all.max, r.max);
  }
  return all.min.x <= all.max.x ? all : TexelRect{};
}

}  // namespace

TexelRect caster_texels(const ShadowView& view, int layer_size, const std::vector<Aabb>& casters) {
  const glm::dmat4 to_clip = view.view_projection();
  TexelRect r = kNoTexels;
  for (const Aabb& box : casters) add_box_texels(to_clip, double(layer_size), box, r);
  return rounded_out(r, double(layer_size));
}

CasterTexels caster_texels_by_view(const ShadowPlan& plan, const std::vector<Aabb>& bounds,
                                   const std::vector<bool>& drawn) {
  const double size = double(plan.layer_size);
  CasterTexels table;
  for (const ShadowView& view : plan.views) {
    const glm::dmat4 to_clip = view.view_projection();
    std::vector<TexelRect>& row = table.by_object.emplace_back(bounds.size());
    // An empty view's layer is neither cleared nor drawn: nothing there.
    for (std::size_t i = 0; i < bounds.size() && !view.empty; ++i) {
      if (!drawn[i]) continue;
      TexelRect r = kNoTexels;
      add_box_texels(to_clip, size, bounds[i], r);
      row[i] = rounded_out(r, size);
    }
    table.by_view.push_back(bounding_rect(row));
  }
  return table;
}

// ---------------------------------------------------------------------------
// Convex geometry: a frustum against a box.

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// The six planes (a, b, c, d), inside where a x + b y + c z + d >= 0, of the
// clip volume of a view-projection matrix (Gribb & Hartmann), normalised so
// the value is a distance.
std::array<glm::dvec4, 6> clip_planes(const glm::dmat4& m) {
  const glm::dvec4 row0(m[0][0], m[1][0], m[2][0], m[3][0]);
  const glm::dvec4 row1(m[0][1], m[1][1], m[2][1], m[3][1]);
  const glm::dvec4 row2(m[0][2], m[1][2], m[2][2], m[3][2]);
  const glm::dvec4 row3(m[0][3], m[1][3], m[2][3], m[3][3]);
  std::array<glm::dvec4, 6> planes = {row3 + row0, row3 - row0, row3 + row1, row3 - row1, row3 + row2, row3 - row2};
  for (auto& p : planes) p /= glm::length(glm::dvec3(p));
  return planes;
}

std::array<glm::dvec3, 8> clip_corners(const glm::dmat4& m) {
  const glm::dmat4 inverse = glm::inverse(m);
  std::array<glm::dvec3, 8> corners;
  for (int i = 0; i < 8; ++i) {
    const glm::dvec4 p = inverse * glm::dvec4(i & 1 ? 1.0 : -1.0, i & 2 ? 1.0 : -1.0, i & 4 ? 1.0 : -1.0, 1.0);
    corners[i] = glm::dvec3(p) / p.w;
  }
  return corners;
}

// The 12 edges of a box-like set of 8 corners indexed by bits (x, y, z).
constexpr std::array<std::array<int, 2>, 12> kEdges = {{{0, 1}, {2, 3}, {4, 5}, {6, 7},
                                                        {0, 2}, {1, 3}, {4, 6}, {5, 7},
                                                        {0, 4}, {1, 5}, {2, 6}, {3, 7}}};

}  // namespace

std::vector<glm::dvec3> frustum_box_intersection(const glm::dmat4& view_projection, const Aabb& box) {
  std::vector<glm::dvec3> out;
  if (box.empty()) return out;
  const auto planes = clip_planes(view_projection);
  const auto frustum = clip_corners(view_projection);
  std::array<glm::dvec3, 8> box_corners;
  for (int i = 0; i < 8; ++i)
    box_corners[i] = {i & 1 ? box.max.x : box.min.x, i & 2 ? box.max.y : box.min.y, i & 4 ? box.max.z : box.min.z};

  // Tolerances relative to the sizes involved, so that a flat box (a plane)
  // and points computed on a face still count as inside.
  double scale = glm::length(box.extent()) + glm::length(box.center());
  for (const auto& c : frustum) scale = std::max(scale, glm::length(c));
  const double eps = 1e-9 * scale;
  auto in_frustum = [&](const glm::dvec3& p) {
    for (const auto& plane : planes)
      if (glm::dot(glm::dvec3(plane), p) + plane.w < -eps) return false;
    return true;
  };
  auto in_box = [&](const glm::dvec3& p) {
    return glm::all(glm::greaterThanEqual(p, box.min - eps)) && glm::all(glm::lessThanEqual(p, box.max + eps));
  };

  // The intersection of two convex solids is spanned by each one's corners
  // inside the other and the points where each one's edges cross the
  // other's faces.
  for (const auto& c : box_corners)
    if (in_frustum(c)) out.push_back(c);
  for (const auto& c : frustum)
    if (in_box(c)) out.push_back(c);
  for (const auto& edge : kEdges) {
    const glm::dvec3 a = box_corners[edge[0]], b = box_corners[edge[1]];
    for (const auto& plane : planes) {
      const double da = glm::dot(glm::dvec3(plane), a) + plane.w, db = glm::dot(glm::dvec3(plane), b) + plane.w;
      if ((da < 0.0) == (db < 0.0)) continue;
      const glm::dvec3 p = a + (b - a) * (da / (da - db));
      if (in_frustum(p)) out.push_back(p);
    }
  }
  for (const auto& edge : kEdges) {
    const glm::dvec3 a = frustum[edge[0]], b = frustum[edge[1]];
    for (int axis = 0; axis < 3; ++axis) {
      for (double face : {box.min[axis], box.max[axis]}) {
        const double da = a[axis] - face, db = b[axis] - face;
        if ((da < 0.0) == (db < 0.0)) continue;
        const glm::dvec3 p = a + (b - a) * (da / (da - db));
        if (in_box(p)) out.push_back(p);
      }
    }
  }
  return out;
}

// ---------------------------------------------------------------------------
// Fitting. Each light kind fits its own views (core/lights/: cascades for
// a directional light or the sun, a cone or a cube for a point light); the
// helpers below are shared with them (core/lights/view_fitting.hpp).

namespace {

// Boxes below named `Extent` hold light view-space points; `Aabb` world ones.
using Extent = Aabb;

}  // namespace

// Fraction of a map's side kept free for `texels` texels on each side (at
// most half the side, for tiny maps and wide kernels).
double spare_fraction(int texels, int size) { return std::min(2.0 * texels, 0.5 * size) / size; }

glm::dvec3 transform(const glm::dmat4& m, const glm::dvec3& p) { return glm::dvec3(m * glm::dvec4(p, 1.0)); }

std::vector<Aabb> bounds_of(const Scene& scene) {
  std::vector<Aabb> boxes;
  boxes.reserve(scene.objects.size());
  for (const auto& o : scene.objects) boxes.push_back(object_bounds(o));
  return boxes;
}

// Texel size of a view, read from its projection: ortho x scale = 2 / width,
// perspective y scale = 1 / tan(half fov).
void set_texel_size(ShadowView& v, bool perspective, int size) {
  if (perspective) {
    v.tan_half = 1.0 / v.projection[1][1];
    v.texel_size = glm::dvec2(2.0 * v.tan_half / size);
  } else {
    v.tan_half = 0.0;
    v.texel_size = glm::dvec2(2.0 / v.projection[0][0] / size, 2.0 / v.projection[1][1] / size);
  }
}

ShadowPlan plan_shadow(const RenderRequest& request) {
  const Light& light = request.light;
  const ShadowSettings& shadow = request.shadow;
  ShadowPlan plan;
  plan.perspective = light.projection == LightProjection::Perspective;
  const LightState placed = light_at(light, request.time);
  plan.position = placed.position;
  plan.direct_light = placed.direct;
  plan.direction = glm::normalize(light.target - plan.position);
  plan.layer_size = shadow.map_size;
  const glm::dmat4 light_view = stable_look_at(plan.position, light.target, glm::dvec3(0.0, 1.0, 0.0));

  if (shadow.fit == FrustumFit::Fixed) {
    ShadowView v;
    v.view = light_view;
    v.near_plane = shadow.near_plane;
    v.far_plane = shadow.far_plane;
    if (plan.perspective) {
      v.projection = glm::perspective(glm::radians(light.fov_y_deg), 1.0, v.near_plane, v.far_plane);
    } else {
      const double h = shadow.ortho_half_size;
      v.projection = glm::ortho(-h, h, -h, h, v.near_plane, v.far_plane);
    }
    set_texel_size(v, plan.perspective, plan.layer_size);
    plan.views = {v};
    return plan;
  }
  if (request.scene.objects.empty()) {
    // Nothing casts or receives: any valid view will do.
    ShadowView v;
    v.view = light_view;
    v.near_plane = plan.perspective ? 0.1 : -1.0;
    v.far_plane = 1.0;
    v.projection = plan.perspective ? glm::perspective(glm::radians(90.0), 1.0, 0.1, 1.0)
                                    : glm::ortho(-1.0, 1.0, -1.0, 1.0, -1.0, 1.0);
    v.empty = true;
    set_texel_size(v, plan.perspective, plan.layer_size);
    plan.views = {v};
    return plan;
  }
  light_kind(light).fit_views(plan, request, light_view);
  return plan;
}

namespace {

// An orthographic view's box in its own view space: x/y from the projection,
// z as [-far, -near].
Aabb ortho_box(const ShadowView& v) {
  const glm::dmat4 inverse = glm::inverse(v.projection);
  Aabb box;
  box.extend(glm::dvec3(inverse * glm::dvec4(-1.0, -1.0, -1.0, 1.0)));
  box.extend(glm::dvec3(inverse * glm::dvec4(1.0, 1.0, 1.0, 1.0)));
  return box;
}

bool view_covers(const ShadowView& have, const ShadowView& want, bool perspective) {
  if (have.view != want.view) return false;
  if (perspective) return have.projection == want.projection && have.empty == want.empty;
  if (have.empty && !want.empty) return false;
  // Texels no larger (a hair of rounding allowed), and want's box inside have's.
  const double tolerance = 1.0 + 1e-9;
  if (have.texel_size.x > want.texel_size.x * tolerance || have.texel_size.y > want.texel_size.y * tolerance)
    return false;
  const Aabb h = ortho_box(have), w = ortho_box(want);
  const double slack = 1e-9 * std::max(glm::length(h.extent()), 1e-300);
  for (int i = 0; i < 3; ++i)
    if (w.min[i] < h.min[i] - slack || w.max[i] > h.max[i] + slack) return false;
  return true;
}

// Whether orthographic view `v` holds world point p with `reach` texels of
// its `size`^2 layer to spare on every side, as choose_view in scene.frag
// asks, with room for the shader's float rounding: one texel across, and
// in depth 1e-3 of the range (a cascade's far plane lies 1e-3 of its
// range past its receivers) plus what float loses on eye depths as large
// as the near and far planes' (the eye space is centred on the light, not
// on the cascade).
bool holds_with_reach(const ShadowView& v, int size, int reach, const glm::dvec3& p) {
  const glm::dvec3 ndc = transform(v.view_projection(), p);  // orthographic: w = 1
  const double xy_limit = 1.0 - 2.0 * double(reach + 1) / size;
  const double range = std::max(v.far_plane - v.near_plane, 1e-300);
  const double z_limit = 1.0 - 1e-3 - 4e-6 * std::max(std::abs(v.near_plane), std::abs(v.far_plane)) / range;
  return std::abs(ndc.x) <= xy_limit && std::abs(ndc.y) <= xy_limit && std::abs(ndc.z) <= z_limit;
}

// Whether every point that `object` can darken through view `k` lies in
// an earlier view (see drop_casters_held_by_earlier_cascades).
bool held_by_earlier_cascades(const ShadowPlan& plan, std::size_t k, const Extent& object,
                              const std::vector<Extent>& extents, const std::vector<Aabb>& bounds,
                              double prism_far, int read) {
  const ShadowView& view = plan.views[k];
  // The object's shadow prism: its rectangle grown by what the filter reads
  // in view k (one texel more for rounding), from its nearest point away
  // from the light to `prism_far`, past the deepest point of the scene.
  const glm::dvec2 grow = double(read + 1) * view.texel_size;
  const glm::dvec2 lo = glm::dvec2(object.min) - grow, hi = glm::dvec2(object.max) + grow;
  const glm::dmat4 prism = glm::ortho(lo.x, hi.x, lo.y, hi.y, -object.max.z, prism_far) * view.view;
  for (std::size_t b = 0; b < bounds.size(); ++b) {
    const Extent& e = extents[b];
    if (e.empty() || e.max.x < lo.x || e.min.x > hi.x || e.max.y < lo.y || e.min.y > hi.y || e.min.z > object.max.z)
      continue;
    const std::vector<glm::dvec3> piece = frustum_box_intersection(prism, bounds[b]);
    if (piece.empty()) continue;
    // The piece is convex, as is what a view holds: all its corners in one
    // earlier view put all of it there.
    bool held = false;
    for (std::size_t j = 0; j < k && !held; ++j) {
      if (plan.views[j].empty) continue;
      held = std::all_of(piece.begin(), piece.end(), [&](const glm::dvec3& p) {
        return holds_with_reach(plan.views[j], plan.layer_size, read, p);
      });
    }
    if (!held) return false;
  }
  return true;
}

}  // namespace

bool drop_casters_held_by_earlier_cascades(const ShadowPlan& plan, const std::vector<Aabb>& bounds,
                                           const std::vector<bool>& candidates, const ShadowSettings& shadow,
                                           CasterTexels& table) {
  if (plan.layout != ShadowLayout::Cascades || plan.views.size() < 2 || !shadow.bias.automatic) return false;
  const int read = filter_read_texels(shadow);
  const glm::dmat4& light_view = plan.views[0].view;
  std::vector<Extent> extents(bounds.size());
  Extent scene;  // all of it, in light eye space
  for (std::size_t b = 0; b < bounds.size(); ++b) {
    if (bounds[b].empty()) continue;
    for (const glm::dvec3& corner : bounds[b].corners()) extents[b].extend(transform(light_view, corner));
    scene.extend(extents[b]);
  }
  if (scene.empty()) return false;
  // The prism's far face lies past the deepest point of the scene by a
  // margin, so that it cuts no box and never meets the near face.
  const double prism_far = -scene.min.z + 1e-3 * std::max(glm::length(scene.extent()), 1e-300);
  bool dropped = false;
  for (std::size_t i = 0; i < bounds.size() && i < candidates.size(); ++i) {
    if (!candidates[i] || extents[i].empty()) continue;
    for (std::size_t k = 1; k < plan.views.size() && k < table.by_object.size(); ++k) {
      TexelRect& rect = table.by_object[k][i];
      if (rect.empty() || plan.views[k].empty) continue;
      if (held_by_earlier_cascades(plan, k, extents[i], extents, bounds, prism_far, read)) {
        rect = TexelRect{};
        dropped = true;
      }
    }
  }
  for (std::size_t k = 0; k < table.by_object.size() && k < table.by_view.size(); ++k)
    table.by_view[k] = bounding_rect(table.by_object[k]);
  return dropped;
}

bool plane_can_shadow(const PlaneRange& plane, const ShadowPlan& plan) {
  // > 0: the light is above the plane, whose shadow falls below it.
  const double light_above = plan.perspective ? plan.position.y - plane.height : -plan.direction.y;
  if (light_above > 0.0) return plane.lowest_other < plane.height;
  if (light_above < 0.0) return plane.highest_other > plane.height;
  return false;
}

bool plan_covers(const ShadowPlan& have, const ShadowPlan& want) {
  if (have.perspective != want.perspective || have.layout != want.layout || have.layer_size != want.layer_size ||
      have.position != want.position || have.direction != want.direction || have.views.size() != want.views.size())
    return false;
  for (std::size_t i = 0; i < have.views.size(); ++i)
    if (!view_covers(have.views[i], want.views[i], have.perspective)) return false;
  return true;
}

}  // namespace umbra
