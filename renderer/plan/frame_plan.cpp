#include "plan/frame_plan.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <utility>

#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/vector_relational.hpp>

#include "core/render_result.hpp"
#include "core/shader_facts.hpp"
#include "plan/draw_cost.hpp"
#include "plan/receiver_cells.hpp"
#include "plan/umbras.hpp"

namespace umbra {

namespace {

// The main pass's planes: drawn whole (one flag per Mesh::planes entry),
// or in parts whose indices are in the cells' index buffer: per plane, its
// umbras drawn dark, the shadows of its objects' bounds (only marked in
// the stencil), its shadowable cells and its other cells.
struct IndexRange {
  std::size_t first = 0, count = 0;
};
struct PlaneDraw {
  std::size_t plane = 0;  // in Mesh::planes
  IndexRange dark, bounds, shadowable, unshadowable;
  // The shadows of the objects' bounds were found (`bounds`, perhaps
  // none): the shadowable cells need the lookup only inside them.
  bool lookup_only_near = false;
};
struct CellDraws {
  std::vector<bool> whole_planes;
  std::vector<PlaneDraw> planes;  // at most 8: each marks the stencil with its own pair of values
  std::size_t umbras = 0;         // polygons drawn dark
  std::vector<Vertex> vertices;
  std::vector<std::uint32_t> indices;
};

// `cells`' index lists into one buffer of `draws`, each plane's ranges
// moved to where their list lands in it: every plane's umbras, then the
// shadows of the objects' bounds, then the shadowable cells, then the
// others (the last two empty for proved plane parts).
void pack_cells(CellTriangles& cells, CellDraws& draws) {
  if (draws.planes.empty()) return;
  std::vector<std::uint32_t> indices = std::move(cells.dark);
  for (std::vector<std::uint32_t>* part : {&cells.bounds, &cells.shadowable, &cells.unshadowable}) {
    for (PlaneDraw& draw : draws.planes) {
      IndexRange& range = part == &cells.bounds ? draw.bounds : part == &cells.shadowable ? draw.shadowable : draw.unshadowable;
      range.first += indices.size();
    }
    indices.insert(indices.end(), part->begin(), part->end());
  }
  draws.vertices = std::move(cells.vertices);
  draws.indices = std::move(indices);
}

// The cells of the planes the shadow pass leaves out (planes[i] false).
CellDraws plane_cells_of(const RenderRequest& request, const ShadowPlan& light, const Mesh& mesh,
                         const std::vector<bool>& planes, const CasterTexels& casters) {
  CellDraws draws;
  draws.whole_planes.assign(mesh.planes.size(), true);
  // The seeds' bias moves the point along its normal before it is looked
  // up: such frames draw every plane whole. So do scenes of many planes,
  // whose regions would cost more to find than they save.
  if (!request.shadow.bias.automatic || mesh.planes.size() > kMaxPlanesInCells) return draws;
  const double margin = double(filter_read_texels(request.shadow)) + 1.0;
  // One region per view and caster, or past that many pairs one per view
  // around all its casters (looser, and as cheap for a thousand casters).
  constexpr std::size_t kMaxRegionPairs = 128;
  std::size_t pairs = 0;
  for (const std::vector<TexelRect>& row : casters.by_object)
    pairs += std::size_t(std::count_if(row.begin(), row.end(), [](const TexelRect& r) { return !r.empty(); }));
  const bool per_caster = pairs <= kMaxRegionPairs;
  // Under a light of no size, the umbras of boxes and spheres are drawn
  // dark without the lookup (umbras.hpp).
  const bool umbras = request.light.size == 0.0;
  CellTriangles cells;
  std::map<double, std::vector<PlanePolygon>> regions_at;  // by plane height
  for (std::size_t i = 0; i < mesh.planes.size(); ++i) {
    const PlaneRange& plane = mesh.planes[i];
    // A plane in the map is a caster: all of it can be shadowed.
    if (planes[i]) continue;
    const Aabb& bounds = mesh.bounds[plane.object];
    PlaneDraw draw;
    draw.plane = i;
    draw.dark.first = cells.dark.size();
    draw.bounds.first = cells.bounds.size();
    draw.shadowable.first = cells.shadowable.size();
    draw.unshadowable.first = cells.unshadowable.size();
    if (umbras) {
      const std::vector<PlanePolygon> dark = umbras_on_plane(bounds, light, request.scene.objects, margin);
      append_dark_triangles(dark, plane.height, plane.color, mesh.origin, cells);
      draws.umbras += dark.size();
    }
    if (const std::optional<std::vector<PlanePolygon>> shadows =
            shadow_bounds_on_plane(bounds, plane.object, light, mesh.bounds, margin)) {
      append_polygon_triangles(*shadows, plane.height, plane.color, mesh.origin, cells, cells.bounds);
      draw.lookup_only_near = true;
    }
    auto at = regions_at.find(plane.height);
    if (at == regions_at.end())
      at = regions_at
               .emplace(plane.height, per_caster ? shadowable_regions(plane.height, light, casters.by_object, margin)
                                                 : view_regions(plane.height, light, casters.by_view, margin))
               .first;
    append_cell_triangles(plane_cells(bounds, at->second), plane.height, plane.color, mesh.origin, cells);
    draw.dark.count = cells.dark.size() - draw.dark.first;
    draw.bounds.count = cells.bounds.size() - draw.bounds.first;
    draw.shadowable.count = cells.shadowable.size() - draw.shadowable.first;
    draw.unshadowable.count = cells.unshadowable.size() - draw.unshadowable.first;
    draws.planes.push_back(draw);
    draws.whole_planes[i] = false;
  }
  pack_cells(cells, draws);
  return draws;
}

DisplayStep cell_step(DisplayStep::Kind kind, DisplayProgram program, const IndexRange& range, std::size_t plane,
                      const StencilStep& stencil) {
  DisplayStep step;
  step.kind = kind;
  step.program = program;
  step.cells = true;
  step.draws.push_back({range.first, range.count, CullMode::None});
  step.stencil = stencil;
  step.plane = plane;
  return step;
}

StencilStep stencil(StencilStep::Test test, int ref, int mask, bool replace, bool marks_only = false) {
  StencilStep s;
  s.enabled = true;
  s.test = test;
  s.ref = ref;
  s.mask = mask;
  s.replace = replace;
  s.marks_only = marks_only;
  return s;
}

// Plane by plane, with the stencil (llvmpipe skips the shader for a block
// of pixels that the early stencil test rejects, not for lanes that a
// branch masks off):
// 1. the shadows of its objects' bounds, marked `near` and not drawn;
// 2. its umbras, with the program of a light that reaches no surface,
//    marked `dark` instead;
// 3. its shadowable cells with the lookup where marked `near`, then lit
//    where marked neither;
// 4. its other cells lit where not dark (an umbra never reaches them).
// The lookup's pixels are drawn from the cells' triangles, as without the
// marks, so it interpolates the same positions. The two marks differ in
// their lowest bit only, and each plane has its own pair: coplanar parts
// of different planes would not mark each other. Without the shadows of
// the bounds (a point light whose foot is inside an object's bounds), the
// lookup runs on every shadowable cell but the umbras.
void append_cell_steps(const std::vector<PlaneDraw>& planes, std::vector<DisplayStep>& steps) {
  using Kind = DisplayStep::Kind;
  using Test = StencilStep::Test;
  static_assert(2 * kMaxPlanesInCells + 1 <= 0xFF, "each plane's two marks fit in the 8-bit stencil");
  int plane_marks = 0;
  for (const PlaneDraw& draw : planes) {
    plane_marks += 2;
    const int dark_mark = plane_marks, near_mark = plane_marks + 1;
    const bool marked_near = draw.lookup_only_near;
    // Marked whatever is in front: only this plane's draws below read the
    // mark, and they test depth themselves. (With the depth test, a plane
    // coplanar with one drawn before would be marked where its polygons
    // lose to that plane by a rounding and drawn lit where its cells win.)
    if (draw.bounds.count > 0)
      steps.push_back(cell_step(Kind::BoundsMarks, DisplayProgram::Dark, draw.bounds, draw.plane,
                                stencil(Test::Always, near_mark, 0xFF, true, true)));
    if (draw.dark.count > 0)
      steps.push_back(cell_step(Kind::DarkUmbras, DisplayProgram::Dark, draw.dark, draw.plane,
                                stencil(Test::Always, dark_mark, 0xFF, true)));
    if (draw.shadowable.count > 0) {
      steps.push_back(cell_step(Kind::ShadowableLookup, DisplayProgram::Frame, draw.shadowable, draw.plane,
                                marked_near ? stencil(Test::Equal, near_mark, 0xFF, false)
                                            : stencil(Test::NotEqual, dark_mark, 0xFF, false)));
      if (marked_near)  // neither mark
        steps.push_back(cell_step(Kind::ShadowableLit, DisplayProgram::Lit, draw.shadowable, draw.plane,
                                  stencil(Test::NotEqual, dark_mark, 0xFE, false)));
    }
    if (draw.unshadowable.count > 0)
      steps.push_back(cell_step(Kind::UnshadowableCells, DisplayProgram::Lit, draw.unshadowable, draw.plane,
                                stencil(Test::NotEqual, dark_mark, 0xFF, false)));
  }
}

// Filter "exact": the planes the maps leave out, in parts that geometry
// settles (docs/certified-shadows.md, "Proved plane parts"): for each, the
// umbras of boxes and spheres shrunk by 3 `margin` (proved dark) and the
// shadows of every other object's bounds grown by 3 `margin` (outside
// them, proved lit), and by their corners' float rounding; found as the
// other filters' cells find theirs, but in world units and asking no view
// (umbras.hpp). A plane whose shadows cannot be bounded (a point light's
// foot under an object, too many objects) stays whole.
CellDraws proved_planes_of(const RenderRequest& request, const ShadowPlan& light, const Mesh& mesh,
                           const std::vector<bool>& planes, double margin) {
  CellDraws draws;
  draws.whole_planes.assign(mesh.planes.size(), true);
  if (mesh.planes.size() > kMaxPlanesInCells || !(margin > 0.0) || !std::isfinite(margin)) return draws;
  CellTriangles cells;
  for (std::size_t i = 0; i < mesh.planes.size(); ++i) {
    const PlaneRange& plane = mesh.planes[i];
    if (planes[i]) continue;  // in the maps: a caster, certified by them
    const Aabb& bounds = mesh.bounds[plane.object];
    // The polygons are drawn with float corners relative to the mesh
    // origin, each moved by up to 2^-24 of its largest coordinate there
    // (all lie on the plane, a hair past its edge at most): their edges
    // move as far, and the proofs are taken that much wider.
    const double far = std::max({std::abs(bounds.min.x - mesh.origin.x), std::abs(bounds.max.x - mesh.origin.x),
                                 std::abs(bounds.min.z - mesh.origin.z), std::abs(bounds.max.z - mesh.origin.z)});
    const double grow = 3.0 * margin + 2e-7 * 1.01 * far;
    const std::optional<std::vector<PlanePolygon>> shadows =
        shadow_bounds_on_plane(bounds, plane.object, light, mesh.bounds, 0.0, grow);
    if (!shadows) continue;
    PlaneDraw draw;
    draw.plane = i;
    draw.dark.first = cells.dark.size();
    draw.bounds.first = cells.bounds.size();
    const std::vector<PlanePolygon> dark = umbras_on_plane(bounds, light, request.scene.objects, 0.0, grow);
    append_dark_triangles(dark, plane.height, plane.color, mesh.origin, cells);
    draws.umbras += dark.size();
    append_polygon_triangles(*shadows, plane.height, plane.color, mesh.origin, cells, cells.bounds);
    draw.dark.count = cells.dark.size() - draw.dark.first;
    draw.bounds.count = cells.bounds.size() - draw.bounds.first;
    draws.planes.push_back(draw);
    draws.whole_planes[i] = false;
  }
  pack_cells(cells, draws);
  return draws;
}

// The reach a proved part's pixel may have (world units): a texel of the
// light's coarsest view where it meets the planes (a point light's at the
// farthest corner of a plane left out of the maps). A pixel whose exact
// point may lie further would be left uncertain by the maps too, whose
// certificate takes half a texel at most.
double proof_margin_of(const ShadowPlan& light, const Mesh& mesh, const std::vector<bool>& planes) {
  double texel = 0.0;
  for (const ShadowView& view : light.views) texel = std::max({texel, view.texel_size.x, view.texel_size.y});
  if (!light.perspective) return texel;
  double farthest = 0.0;
  for (std::size_t i = 0; i < mesh.planes.size(); ++i)
    if (!planes[i])
      for (const glm::dvec3& corner : mesh.bounds[mesh.planes[i].object].corners())
        farthest = std::max(farthest, glm::distance(corner, light.position));
  return texel * farthest;
}

// scene.frag's seen_here reach of a point of `plane` (world bounds) but for
// the pixel's footprint, bounded over the plane: 1e-6 of its largest
// coordinate relative to the mesh origin, of its distances from that
// origin and from the camera, and the reference's offset off an analytic
// surface, 2e-9 (1 + its distance from the world's origin); twice that
// for the shader's own rounding of the sum.
double proof_rounding(const Aabb& plane, const glm::dvec3& origin, const glm::dvec3& camera) {
  double extent = 0.0, from_origin = 0.0, from_camera = 0.0, from_world = 0.0;
  for (const glm::dvec3& corner : plane.corners()) {
    const glm::dvec3 relative = corner - origin;
    extent = std::max({extent, std::abs(relative.x), std::abs(relative.y), std::abs(relative.z)});
    from_origin = std::max(from_origin, glm::length(relative));
    from_camera = std::max(from_camera, glm::distance(corner, camera));
    from_world = std::max(from_world, glm::length(corner));
  }
  return 2.0 * (1e-6 * (extent + from_origin + from_camera) + 2e-9 * (1.0 + from_world));
}

// Per plane drawn in proved parts, with the stencil as append_cell_steps
// marks it (each plane its own pair of marks):
// 1. the shadows of the objects' bounds, marked `near` and not drawn;
// 2. its umbras, proved dark (program Dark: the proof's), marked `dark`;
// 3. its own triangles where marked `near`, certified by the maps (the
//    frame's program: the triangles are the scene's, whose owner the maps
//    know);
// 4. the same where marked neither, proved lit (program Lit: the proof's).
void append_proved_plane_steps(const std::vector<PlaneDraw>& planes, const Mesh& mesh, const glm::dvec3& camera,
                               std::vector<DisplayStep>& steps) {
  using Kind = DisplayStep::Kind;
  using Test = StencilStep::Test;
  int plane_marks = 0;
  for (const PlaneDraw& draw : planes) {
    plane_marks += 2;
    const int dark_mark = plane_marks, near_mark = plane_marks + 1;
    const std::size_t object = mesh.planes[draw.plane].object;
    const float rounding = float(proof_rounding(mesh.bounds[object], mesh.origin, camera));
    const auto with_object = [object, rounding](DisplayStep step) {
      step.object = object;
      step.proof_rounding = rounding;
      return step;
    };
    if (draw.bounds.count > 0)
      steps.push_back(with_object(cell_step(Kind::BoundsMarks, DisplayProgram::Dark, draw.bounds, draw.plane,
                                            stencil(Test::Always, near_mark, 0xFF, true, true))));
    if (draw.dark.count > 0)
      steps.push_back(with_object(cell_step(Kind::DarkUmbras, DisplayProgram::Dark, draw.dark, draw.plane,
                                            stencil(Test::Always, dark_mark, 0xFF, true))));
    std::vector<bool> only(mesh.bounds.size(), false);
    only[object] = true;
    const auto own_triangles = [&](Kind kind, DisplayProgram program, const StencilStep& test) {
      DisplayStep step;
      step.kind = kind;
      step.program = program;
      step.draws = scene_draw_ranges(mesh, CullMode::None, only);
      step.stencil = test;
      step.plane = draw.plane;
      return with_object(std::move(step));
    };
    if (draw.bounds.count > 0)
      steps.push_back(own_triangles(Kind::CertifiedNear, DisplayProgram::Frame, stencil(Test::Equal, near_mark, 0xFF, false)));
    steps.push_back(own_triangles(Kind::ProvedLit, DisplayProgram::Lit, stencil(Test::NotEqual, dark_mark, 0xFE, false)));
  }
}

// Per scene object, its draw's estimated ms in the light's views (the
// most over them), by which a shadow pass chunks long draws.
std::vector<double> shadow_object_draw_ms(const RenderRequest& request, const ShadowPlan& light) {
  std::vector<glm::dmat4> views;
  for (const ShadowView& view : light.views)
    if (!view.empty) views.push_back(view.projection * view.view);
  return object_draw_ms(request.scene, views, double(light.layer_size), double(light.layer_size));
}

// The shadow pass of a frame that draws one.
ShadowPassPlan plan_shadow_pass(const RenderRequest& request, const ShadowPlan& light, const std::vector<bool>& planes,
                                const CasterTexels& casters, const Mesh& mesh, const std::string& scene_key) {
  ShadowPassPlan pass;
  pass.needed = true;
  pass.object_draw_ms = shadow_object_draw_ms(request, light);
  // The depth output shows whole layers. A frame's main pass reads a layer
  // only for points whose filter (FILTER_READ texels around them) meets the
  // casters' rectangle, so only within twice that of it: only that much is
  // cleared, unless the rectangle is most of the layer. On llvmpipe,
  // clearing a 2048^2 layer costs ~2 ms, most of what a layer of a few
  // objects costs once the floor is left out.
  const bool whole_layers = request.output == Output::Depth;
  const int margin = clear_margin_texels(request.shadow);
  for (std::size_t layer = 0; layer < light.views.size(); ++layer) {
    // An empty view (no object reaches into it) holds no receiver either,
    // so the main pass never reads its layer: it is not even cleared (the
    // depth preview clears it before showing it). Nor is a layer that no
    // drawn object reaches: the main pass sees its rectangle empty.
    if (light.views[layer].empty || (!whole_layers && casters.by_view[layer].empty())) continue;
    ShadowLayerDraw draw;
    draw.layer = int(layer);
    draw.clear_whole = whole_layers || clears_whole_layer(casters.by_view[layer], light.layer_size);
    if (!draw.clear_whole) {
      const TexelRect& c = casters.by_view[layer];
      draw.x0 = std::max(0, int(c.min.x) - margin), draw.y0 = std::max(0, int(c.min.y) - margin);
      draw.x1 = std::min(light.layer_size, int(c.max.x) + margin);
      draw.y1 = std::min(light.layer_size, int(c.max.y) + margin);
    }
    // Culling front faces stores the far side of closed objects: their lit
    // faces then sit well in front of the stored depth, so no bias is needed
    // against self-shadowing there, and the bias stays small elsewhere (less
    // peter panning). See ShadowSettings::cull for why planes are exempt.
    // Only what reaches into this view: a sphere beside a point light is
    // in one or two of its six faces, and each face it is drawn into
    // shades all its vertices.
    std::vector<bool> in_view;
    for (const TexelRect& object : casters.by_object[layer]) in_view.push_back(!object.empty());
    draw.draws = scene_draw_ranges(mesh, request.shadow.cull, in_view);
    pass.layers.push_back(std::move(draw));
  }
  KeptShadowMap& kept = pass.kept_after;
  kept.holds_plan = true;
  kept.plan = light;
  kept.scene_key = scene_key;
  kept.cull = request.shadow.cull;
  kept.planes = planes;
  kept.whole_layers = whole_layers;
  kept.clear_margin = margin;
  kept.automatic_bias = request.shadow.bias.automatic;
  return pass;
}

// Filter "exact": where the certified maps hold anything, by view, for the
// certificate's shortcut (a point whose texels lie beyond it is lit). The
// maps hold every drawn object in every view, so none is dropped from a
// cascade (as caster_table may drop a heavy mesh); and a fixed frustum's
// conservative maps hold casters beyond its near and far planes too (only
// a fitted view holds all it draws), so there the rectangle is the layer's
// and beyond.
CasterTexels certified_caster_table(const RenderRequest& request, const ShadowPlan& light, const Mesh& mesh,
                                    const std::vector<bool>& planes) {
  RenderRequest every_object = request;
  every_object.output = Output::Depth;  // the depth output draws every object into every layer
  CasterTexels casters = caster_table(every_object, light, mesh, planes);
  if (request.shadow.fit == FrustumFit::Fixed) {
    for (TexelRect& rect : casters.by_view) {
      rect.min = glm::dvec2(-1e9);
      rect.max = glm::dvec2(1e9);
    }
  }
  return casters;
}

// Filter "exact": the certified maps (ShadowPassPlan::certify). The
// conservative maps must hold, in each texel, the nearest of whatever may
// lie in front of a point the certificate reads them for: of a closed
// shape, the faces turned to the light are enough (where a ray leaves it
// last), unless the light is inside it (cull_closed_back).
ShadowPassPlan plan_certified_shadow_pass(const RenderRequest& request, const ShadowPlan& light, const Mesh& mesh,
                                          const std::vector<bool>& planes, const CasterTexels& casters,
                                          const std::string& scene_key) {
  ShadowPassPlan pass;
  pass.needed = true;
  pass.certify = true;
  pass.object_draw_ms = shadow_object_draw_ms(request, light);
  // A fixed frustum's maps hold what lies beyond its near and far planes
  // too: every object goes into every layer, cleared whole. A fitted
  // view's objects all lie inside it, and the certificate reads a layer
  // only within kCertifiedReadTexels of its casters' rectangle: only that
  // much is cleared (unless it is most of the layer), only the objects
  // reaching into it are drawn, and a layer nothing reaches is left alone.
  const bool fixed = request.shadow.fit == FrustumFit::Fixed;
  const std::vector<bool> drawn = drawn_objects(mesh, planes);
  // A closed shape between a point and the light crosses the point's ray
  // last (nearest the light) on a face turned to the light, unless the
  // light is inside it.
  pass.cull_closed_back = true;
  if (light.perspective)
    for (const ObjectRange& r : mesh.object_ranges)
      if (r.first_index < mesh.closed_index_count) {
        const Aabb& b = mesh.bounds[r.object];
        const glm::dvec3 hair = 1e-6 * (b.extent() + 1.0);
        if (glm::all(glm::greaterThanEqual(light.position, b.min - hair)) &&
            glm::all(glm::lessThanEqual(light.position, b.max + hair)))
          pass.cull_closed_back = false;
      }
  const CullMode closed_cull = pass.cull_closed_back ? CullMode::Back : CullMode::None;
  for (std::size_t layer = 0; layer < light.views.size(); ++layer) {
    ShadowLayerDraw draw;
    draw.layer = int(layer);
    // The objects the layer draws (or fewer: past kMaxRuns scene_draw_ranges
    // draws some more in one range; their triangles are swollen by their own
    // rounding in the maps all the same, and a far object cannot reach a
    // view its rounding is not even a texel of).
    std::vector<bool> layer_objects;
    if (fixed) {
      draw.clear_whole = true;
      draw.draws = scene_draw_ranges(mesh, closed_cull, drawn);
      layer_objects = drawn;
    } else {
      const TexelRect& c = casters.by_view[layer];
      if (light.views[layer].empty || c.empty()) continue;
      const int margin = kCertifiedReadTexels;
      draw.clear_whole = clears_whole_layer(c, light.layer_size);
      draw.x0 = std::max(0, int(c.min.x) - margin), draw.y0 = std::max(0, int(c.min.y) - margin);
      draw.x1 = std::min(light.layer_size, int(c.max.x) + margin);
      draw.y1 = std::min(light.layer_size, int(c.max.y) + margin);
      std::vector<bool> in_view;
      for (const TexelRect& object : casters.by_object[layer]) in_view.push_back(!object.empty());
      draw.draws = scene_draw_ranges(mesh, closed_cull, in_view);
      layer_objects = std::move(in_view);
    }
    // The GL's view of this layer, relative to the mesh origin (FrameBlock),
    // and the size of the conservative maps' texels (a point light's where
    // they are smallest, at its near plane).
    const ShadowView& v = light.views[layer];
    const double translation = glm::length(glm::dvec3((v.view * glm::translate(glm::dmat4(1.0), mesh.origin))[3]));
    const double coarse = double(light.layer_size) / double(certified_map_size(light.layer_size));
    const double texel = certified_texel_world(light.perspective, v.texel_size, v.tan_half, coarse, v.near_plane);
    for (const ObjectRange& r : mesh.object_ranges)
      if (r.object < layer_objects.size() && layer_objects[r.object] &&
          light_view_rounding(largest_coordinate(mesh.bounds.at(r.object), mesh.origin), translation) >
              kMostRoundingTexels * texel)
        draw.proves_nothing = true;
    pass.layers.push_back(std::move(draw));
  }
  pass.kept_after.holds_plan = false;
  KeptCertifiedMaps& kept = pass.certified_kept_after;
  kept.holds_plan = true;
  kept.plan = light;
  kept.scene_key = scene_key;
  kept.planes = planes;
  kept.fit = request.shadow.fit;
  return pass;
}

// The faces of a closed mesh that turn from the light get no direct light
// (and, in a certified frame, no proof from the maps: the facing rule
// settles them), yet llvmpipe would run the whole lookup for each of their
// pixels (it runs both sides of a branch): `contact-line`'s box face fills a
// third of the frame. So closed meshes are drawn in two parts (LIGHT_SIDE,
// scene.vert): with the lookup where a point may face the light, without
// it where none can. Their front faces only: a back face's normal would be
// turned to the camera in scene.frag. `objects` loses those split.
void split_closed_by_the_light(const RenderRequest& request, const Mesh& mesh, CullMode closed_cull,
                               std::vector<bool>& objects, std::vector<DisplayStep>& steps) {
  std::vector<bool> split;
  if (closed_cull == CullMode::Back) split = objects_split_by_the_light(mesh, request.camera, request.width, request.height);
  std::size_t split_count = 0, unsplit_closed = 0;
  for (const ObjectRange& r : mesh.object_ranges) {
    if (r.first_index >= mesh.closed_index_count || !objects[r.object] || split.empty()) continue;
    split[r.object] ? ++split_count : ++unsplit_closed;
  }
  // Past kMaxRuns the closed meshes are drawn in one range: the split would
  // then draw the unsplit ones too, or the last draw the split ones again.
  // Counting objects, not runs, errs towards fewer draws.
  if (split_count > kMaxRuns && unsplit_closed > 0) {
    for (const ObjectRange& r : mesh.object_ranges)
      if (r.first_index < mesh.closed_index_count) split[r.object] = true;
  } else if (unsplit_closed > kMaxRuns) {
    split.clear();
  }
  if (std::find(split.begin(), split.end(), true) != split.end()) {
    for (std::size_t i = 0; i < split.size(); ++i) {
      split[i] = split[i] && objects[i];
      objects[i] = objects[i] && !split[i];
    }
    for (const auto& [kind, program] : {std::pair{DisplayStep::Kind::ClosedFacingLight, DisplayProgram::LightFacing},
                                        std::pair{DisplayStep::Kind::ClosedAwayFromLight, DisplayProgram::LightAway}}) {
      DisplayStep step;
      step.kind = kind;
      step.program = program;
      step.draws = scene_draw_ranges(mesh, closed_cull, split, MeshPart::Closed);
      step.clip_by_light_side = true;
      steps.push_back(std::move(step));
    }
  }
}

// What every main pass has: its size, clear colour, variant and the
// objects' draw costs in the camera's view.
DisplayPassPlan display_pass_of(const RenderRequest& request, const ShadowPlan& light) {
  DisplayPassPlan pass;
  pass.width = request.width;
  pass.height = request.height;
  // Shadow output: no geometry, nothing blocks the light.
  pass.clear_color = request.output == Output::Shadow ? glm::vec4(1.0f, 1.0f, 1.0f, 1.0f)
                                                      : glm::vec4(0.11f, 0.12f, 0.14f, 1.0f);
  pass.variant = display_variant(request, light);
  const CameraMatrices camera = camera_matrices(request.camera, request.width, request.height);
  pass.object_draw_ms =
      object_draw_ms(request.scene, {camera.projection * camera.view}, double(request.width), double(request.height));
  return pass;
}

// Closed meshes' faces culled in the main pass: back faces where the
// camera sees every closed mesh from outside, else none.
CullMode closed_cull_of(const RenderRequest& request, const Mesh& mesh) {
  return closed_meshes_seen_from_outside(mesh, request.camera, double(request.width) / request.height) ? CullMode::Back
                                                                                                       : CullMode::None;
}

DisplayPassPlan plan_certified_display_pass(const RenderRequest& request, const ShadowPlan& light, const Mesh& mesh,
                                            const std::vector<bool>& planes, CertifiedPath path) {
  DisplayPassPlan pass = display_pass_of(request, light);
  pass.certificates = true;
  // Without maps, the frame's program has no lookup: every pixel it draws
  // is left to the ray cast (scene.frag, CERTIFICATES without SHADOWS).
  if (path != CertifiedPath::Maps) pass.variant = without_shadows(pass.variant);
  CellDraws proved;
  if (pass.variant.direct_light && path != CertifiedPath::RayCast) {
    pass.proof_margin = float(proof_margin_of(light, mesh, planes));
    proved = proved_planes_of(request, light, mesh, planes, double(pass.proof_margin));
  }
  pass.umbras = proved.umbras;
  pass.cell_vertices = std::move(proved.vertices);
  pass.cell_indices = std::move(proved.indices);
  // Back faces culled only where the camera sees every closed mesh from
  // outside, as in any frame: then no back face is the nearest surface of
  // a camera ray, for the raster or for the reference.
  const CullMode closed_cull = closed_cull_of(request, mesh);
  std::vector<bool> objects = drawn_objects(mesh, proved.whole_planes);
  if (pass.variant.shadows) split_closed_by_the_light(request, mesh, closed_cull, objects, pass.steps);
  DisplayStep all;
  all.kind = DisplayStep::Kind::Objects;
  all.program = DisplayProgram::Frame;
  all.draws = scene_draw_ranges(mesh, closed_cull, objects);
  pass.steps.push_back(std::move(all));
  append_proved_plane_steps(proved.planes, mesh, request.camera.position, pass.steps);
  // The sliver pass finds pixels to ray cast where the raster missed an
  // object thinner than a pixel: with every pixel ray cast, the sky's
  // included, there are none to find.
  if (path == CertifiedPath::RayCast)
    pass.background_certificate = PixelCertificates::kUncertain;
  else
    pass.sliver_draws = scene_draw_ranges(mesh, CullMode::None, {});
  pass.sliver_skips_closed_back = closed_cull == CullMode::Back;
  return pass;
}

DisplayPassPlan plan_display_pass(const RenderRequest& request, const ShadowPlan& light, const Mesh& mesh,
                                  const std::vector<bool>& planes, const CasterTexels& casters) {
  DisplayPassPlan pass = display_pass_of(request, light);
  CellDraws cells;
  if (pass.variant.shadows) cells = plane_cells_of(request, light, mesh, planes, casters);
  pass.umbras = cells.umbras;
  pass.cell_vertices = std::move(cells.vertices);
  pass.cell_indices = std::move(cells.indices);
  // A box's far faces, drawn before its near ones, would be shaded in full
  // and then drawn over: with the camera outside every closed mesh they
  // are culled (about a sixth of a box scene's main pass on llvmpipe).
  const CullMode closed_cull = closed_cull_of(request, mesh);
  std::vector<bool> objects = drawn_objects(mesh, cells.whole_planes);
  if (pass.variant.shadows) split_closed_by_the_light(request, mesh, closed_cull, objects, pass.steps);
  DisplayStep all;
  all.kind = DisplayStep::Kind::Objects;
  all.program = DisplayProgram::Frame;
  all.draws = scene_draw_ranges(mesh, closed_cull, objects);
  pass.steps.push_back(std::move(all));
  append_cell_steps(cells.planes, pass.steps);
  return pass;
}

std::string describe_views(const ShadowPlan& light) {
  const char* layout = light.layout == ShadowLayout::Cascades ? "cascades"
                       : light.layout == ShadowLayout::Cube   ? "cube"
                                                              : "single";
  return std::string(layout) + "; views=" + std::to_string(light.views.size()) +
         "; size=" + std::to_string(light.layer_size);
}

}  // namespace

std::string preview_tiles_parameters(const ShadowPlan& plan) {
  std::string p = "; grid=" + std::to_string(preview_tiles_per_row(int(plan.views.size())));
  if (plan.layout == ShadowLayout::Cube) {
    p += "; faces=";
    for (int face = 0; face < kCubeFaceCount; ++face) p += std::string(face ? "," : "") + kCubeFaceNames[face];
  }
  return p;
}

DisplayVariant program_variant(const DisplayVariant& frame, DisplayProgram which) {
  DisplayVariant v = which == DisplayProgram::Frame || which == DisplayProgram::LightFacing ? frame : without_shadows(frame);
  if (frame.certificates && frame.direct_light && (which == DisplayProgram::Lit || which == DisplayProgram::Dark)) {
    // A proof's program keeps the direct light: an uncertain pixel is drawn
    // lit for the CPU to pick from.
    v.proof = which == DisplayProgram::Lit ? 1 : -1;
    return v;
  }
  if (which == DisplayProgram::Dark) v.direct_light = false;
  if (which == DisplayProgram::LightFacing) v.light_side = 1;
  if (which == DisplayProgram::LightAway) v.light_side = -1;
  return v;
}

int certified_map_size(int layer_size) { return std::max(64, layer_size / 2); }

bool certified_frame(const RenderRequest& request, const ShadowPlan& light) {
  return request.output != Output::Depth && display_variant(request, light).certificates;
}

bool needs_shadow_map(const RenderRequest& request, const ShadowPlan& light) {
  return (request.shadow.enabled && light.direct_light) || request.output == Output::Depth;
}

std::vector<bool> drawn_objects(const Mesh& mesh, const std::vector<bool>& planes) {
  std::vector<bool> drawn(mesh.bounds.size(), true);
  for (std::size_t i = 0; i < mesh.planes.size(); ++i)
    if (!planes.empty() && !planes[i]) drawn[mesh.planes[i].object] = false;
  return drawn;
}

std::vector<bool> casting_planes(const RenderRequest& request, const ShadowPlan& light, const Mesh& mesh) {
  std::vector<bool> planes;
  for (const PlaneRange& plane : mesh.planes)
    planes.push_back(request.output == Output::Depth || plane_can_shadow(plane, light));
  return planes;
}

CasterTexels caster_table(const RenderRequest& request, const ShadowPlan& light, const Mesh& mesh,
                          const std::vector<bool>& planes) {
  CasterTexels table = caster_texels_by_view(light, mesh.bounds, drawn_objects(mesh, planes));
  if (request.output == Output::Depth || light.layout != ShadowLayout::Cascades) return table;
  // Only meshes whose triangles cost more to draw again than the test
  // costs (a few microseconds per box near them), and at most kMaxRuns of
  // them (scene_draw_ranges may draw more in one range, dropped or not).
  std::vector<bool> heavy(mesh.bounds.size(), false);
  std::size_t count = 0;
  for (const ObjectRange& r : mesh.object_ranges)
    if (r.index_count / 3 >= kHeavyTriangles) heavy[r.object] = true, ++count;
  if (count == 0 || count > kMaxRuns) return table;
  drop_casters_held_by_earlier_cascades(light, mesh.bounds, heavy, request.shadow, table);
  return table;
}

int clear_margin_texels(const ShadowSettings& shadow) { return 2 * filter_read_texels(shadow) + 1; }

// On llvmpipe, glClear of the whole attachment is done tile by tile by the
// rasteriser threads as they draw, so a tile's depths are written and then
// drawn over while in cache, whereas glClearTexSubImage writes the
// rectangle to memory on the GL thread and the draw reads it back.
// Measured per layer (clear and draw, 960x540): `point-close`'s -Y face,
// over 90 % of the layer, 7.7 -> 4.5 ms cleared whole; a face of 30 %,
// about even; of 17 %, 1.4 -> 2.1 ms. A GPU clears whole attachments
// fastest too.
bool clears_whole_layer(const TexelRect& rect, int layer_size) {
  const glm::dvec2 size = rect.max - rect.min;
  return size.x * size.y > 0.4 * double(layer_size) * double(layer_size);
}

bool certified_maps_serve(const KeptCertifiedMaps& kept, const RenderRequest& request, const ShadowPlan& light,
                          const std::vector<bool>& planes, const std::string& scene_key) {
  return kept.holds_plan && kept.scene_key == scene_key && kept.planes == planes && kept.fit == request.shadow.fit &&
         plan_covers(kept.plan, light);
}

bool shadow_map_serves(const KeptShadowMap& kept, const RenderRequest& request, const ShadowPlan& light,
                       const std::vector<bool>& planes, const std::string& scene_key) {
  // A map cleared only around its casters serves frames whose filter
  // reads no further than the one it was cleared for, and no depth output.
  const bool cleared_enough =
      kept.whole_layers ||
      (request.output != Output::Depth && clear_margin_texels(request.shadow) <= kept.clear_margin);
  // The depth output draws every object into every layer; a map drawn
  // with the automatic bias may lack some (caster_table).
  const bool drawn_for_lookups_like_these = kept.whole_layers || !kept.automatic_bias || request.shadow.bias.automatic;
  return kept.holds_plan && kept.scene_key == scene_key && kept.cull == request.shadow.cull &&
         kept.planes == planes && cleared_enough && drawn_for_lookups_like_these && plan_covers(kept.plan, light);
}

std::vector<DrawRange> scene_draw_ranges(const Mesh& mesh, CullMode closed_cull, const std::vector<bool>& objects,
                                         MeshPart part) {
  // Runs of consecutive objects to draw, one range each: closed meshes,
  // open models and planes apart (in that order in the index buffer).
  using Run = std::pair<std::uint32_t, std::uint32_t>;  // first index, count
  std::vector<bool> is_plane(mesh.bounds.size(), false);
  for (const PlaneRange& plane : mesh.planes) is_plane[plane.object] = true;
  std::vector<Run> closed, open_models, planes;
  for (const ObjectRange& r : mesh.object_ranges) {
    if ((!objects.empty() && !objects[r.object]) || r.index_count == 0) continue;
    std::vector<Run>& runs = r.first_index < mesh.closed_index_count ? closed : is_plane[r.object] ? planes : open_models;
    if (!runs.empty() && runs.back().first + runs.back().second == r.first_index)
      runs.back().second += r.index_count;
    else
      runs.emplace_back(r.first_index, r.index_count);
  }
  // Many scattered objects (a thousand spheres, some in the view): one call
  // for all of their kind costs less than hundreds; those outside the view
  // draw nothing. Planes keep their flags: a plane left out of the shadow
  // pass must stay out, and there are few of them.
  if (closed.size() > kMaxRuns) closed = {Run{0, mesh.closed_index_count}};
  if (open_models.size() > kMaxRuns) {
    const std::uint32_t end = open_models.back().first + open_models.back().second;
    open_models = {Run{open_models.front().first, end - open_models.front().first}};  // no plane lies between
  }
  if (part == MeshPart::Closed) open_models.clear(), planes.clear();
  std::vector<DrawRange> draws;
  for (const Run& run : closed) draws.push_back({run.first, run.second, closed_cull});
  // A plane or an open model has one side: culling it could drop it from
  // the pass entirely.
  for (const Run& run : open_models) draws.push_back({run.first, run.second, CullMode::None});
  for (const Run& run : planes) draws.push_back({run.first, run.second, CullMode::None});
  return draws;
}

std::vector<double> object_draw_ms(const Scene& scene, const std::vector<glm::dmat4>& view_projections,
                                   double width, double height) {
  std::vector<double> ms(scene.objects.size(), 0.0);
  for (std::size_t i = 0; i < scene.objects.size(); ++i)
    for (const glm::dmat4& view_projection : view_projections)
      ms[i] = std::max(ms[i], mesh_draw_ms(scene.objects[i], view_projection, width, height));
  return ms;
}

const char* to_string(CertifiedPath path) {
  switch (path) {
    case CertifiedPath::Maps: return "maps";
    case CertifiedPath::Proofs: return "proofs";
    case CertifiedPath::RayCast: return "ray-cast";
  }
  return "maps";
}

FramePlan plan_frame(const RenderRequest& request, const Mesh& mesh, const std::string& scene_key,
                     const KeptShadowMap& kept, CertifiedPath path, const KeptCertifiedMaps& kept_certified) {
  FramePlan plan;
  plan.light = plan_shadow(request);
  plan.depth_output = request.output == Output::Depth;
  plan.shadow.needed = needs_shadow_map(request, plan.light);
  plan.casting_planes = casting_planes(request, plan.light, mesh);
  if (certified_frame(request, plan.light)) {
    // A plane that can shadow nothing (plane_can_shadow: every other object
    // lies on its light's side) is left out of the maps, as from any
    // frame's: it lies in front of no point but its own. A sun below the
    // horizon: no map, every surface dark (CERTIFICATES without a lookup).
    // A sun below the horizon needs no map whatever the path.
    plan.certified_path = plan.shadow.needed ? path : CertifiedPath::Maps;
    const bool maps = plan.certified_path == CertifiedPath::Maps && plan.shadow.needed;
    // Only the camera moved (or the output changed): the kept certified
    // maps serve, read with the views they were drawn for.
    const bool reused =
        maps && certified_maps_serve(kept_certified, request, plan.light, plan.casting_planes, scene_key);
    if (reused) plan.light = kept_certified.plan;
    plan.casters = certified_caster_table(request, plan.light, mesh, plan.casting_planes);
    if (!maps) {
      if (plan.certified_path != CertifiedPath::Maps) plan.shadow = ShadowPassPlan{};
    } else {
      if (reused) {
        plan.shadow.certify = true;
        plan.shadow.reused = true;
      } else {
        plan.shadow =
            plan_certified_shadow_pass(request, plan.light, mesh, plan.casting_planes, plan.casters, scene_key);
      }
      plan.shadow_views = describe_views(plan.light);
    }
    plan.display = plan_certified_display_pass(request, plan.light, mesh, plan.casting_planes, plan.certified_path);
    plan.read_back = {false, request.width, request.height, request.output == Output::Shadow ? 1 : 3, 8};
    plan.read_back.certificates = true;
    plan.read_back.unlit = request.output != Output::Shadow;
    return plan;
  }
  if (plan.shadow.needed && shadow_map_serves(kept, request, plan.light, plan.casting_planes, scene_key)) {
    // Nothing the map depends on changed (typically only the camera
    // moved): draw with the views it was made for.
    plan.light = kept.plan;
    plan.shadow.reused = true;
  }
  plan.casters = caster_table(request, plan.light, mesh, plan.casting_planes);
  if (plan.shadow.needed) {
    if (!plan.shadow.reused)
      plan.shadow = plan_shadow_pass(request, plan.light, plan.casting_planes, plan.casters, mesh, scene_key);
    plan.shadow_views = describe_views(plan.light) + (plan.depth_output ? preview_tiles_parameters(plan.light) : "");
  }
  if (plan.depth_output) {
    plan.preview.size = request.shadow.map_size;
    plan.preview.bits = request.depth_bits;
    plan.preview.perspective = plan.light.perspective;
    plan.preview.view_count = int(plan.light.views.size());
    // The shadow pass leaves empty views' layers as they were: show them as
    // cleared, far everywhere.
    for (std::size_t layer = 0; layer < plan.light.views.size(); ++layer)
      if (plan.light.views[layer].empty) plan.preview.empty_layers.push_back(int(layer));
    plan.read_back = {true, plan.preview.size, plan.preview.size, 1, plan.preview.bits};
  } else {
    plan.display = plan_display_pass(request, plan.light, mesh, plan.casting_planes, plan.casters);
    plan.read_back = {false, request.width, request.height, request.output == Output::Shadow ? 1 : 3, 8};
  }
  return plan;
}

}  // namespace umbra
