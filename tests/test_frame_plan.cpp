// What a frame draws (plan/frame_plan.hpp), decided without a GL context:
// which planes and meshes each layer of the shadow pass draws and how it is
// cleared, when the kept map serves, the main pass's steps and stencil
// protocol, the depth preview and the read-back.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/light_math.hpp"
#include "core/render_result.hpp"
#include "core/request.hpp"
#include "core/scene.hpp"
#include "scene_support.hpp"
#include "plan/frame_plan.hpp"
#include "request_parser.hpp"

namespace umbra {
namespace {

// The plan of `r`'s frame with nothing kept in the shadow map.
FramePlan fresh_plan(const RenderRequest& r) { return plan_frame(r, tessellate(r.scene), "scene", KeptShadowMap{}); }

// Whether `draws` draw any of object `object`'s triangles.
bool draws_object(const std::vector<DrawRange>& draws, const Mesh& mesh, std::size_t object) {
  for (const ObjectRange& o : mesh.object_ranges) {
    if (o.object != object || o.index_count == 0) continue;
    for (const DrawRange& d : draws)
      if (d.first < std::size_t(o.first_index) + o.index_count && o.first_index < d.first + d.count) return true;
  }
  return false;
}

std::size_t first_of_type(const Scene& scene, SceneObject::Type type) {
  for (std::size_t i = 0; i < scene.objects.size(); ++i)
    if (scene.objects[i].type == type) return i;
  ADD_FAILURE() << "no such object";
  return 0;
}

TEST(FramePlan, ACameraOnlyChangeReusesTheMap) {
  RenderRequest r = test::builtin_request("three-cubes");
  r.light.projection = LightProjection::Perspective;  // its views do not follow the camera
  const Mesh mesh = tessellate(r.scene);
  const FramePlan first = plan_frame(r, mesh, "scene", KeptShadowMap{});
  ASSERT_TRUE(first.shadow.needed);
  EXPECT_FALSE(first.shadow.reused);
  EXPECT_FALSE(first.shadow.layers.empty());
  const KeptShadowMap kept = first.shadow.kept_after;
  EXPECT_TRUE(kept.holds_plan);

  RenderRequest moved = r;
  moved.camera.position += glm::dvec3(0.3, -0.2, 0.1);
  const FramePlan second = plan_frame(moved, mesh, "scene", kept);
  EXPECT_TRUE(second.shadow.reused);
  EXPECT_TRUE(second.shadow.layers.empty()) << "no shadow pass";
  EXPECT_EQ(second.light.views.size(), kept.plan.views.size());
  EXPECT_EQ(second.shadow_views, first.shadow_views);

  // What the map depends on changed: drawn again.
  EXPECT_FALSE(plan_frame(moved, mesh, "another scene", kept).shadow.reused);
  RenderRequest culled = moved;
  culled.shadow.cull = CullMode::Back;
  EXPECT_FALSE(plan_frame(culled, mesh, "scene", kept).shadow.reused);
  RenderRequest lit_elsewhere = moved;
  lit_elsewhere.light.position += glm::dvec3(1.0, 0.0, 0.0);
  EXPECT_FALSE(plan_frame(lit_elsewhere, mesh, "scene", kept).shadow.reused);
  // A wider filter reads past the rectangles the map was cleared around.
  RenderRequest wider = moved;
  wider.shadow.pcf_radius = 6;
  EXPECT_FALSE(plan_frame(wider, mesh, "scene", kept).shadow.reused);
  // The depth output shows whole layers; this map was cleared in rectangles.
  RenderRequest depth = moved;
  depth.output = Output::Depth;
  EXPECT_FALSE(plan_frame(depth, mesh, "scene", kept).shadow.reused);
  KeptShadowMap cut_short = kept;
  cut_short.holds_plan = false;
  EXPECT_FALSE(plan_frame(moved, mesh, "scene", cut_short).shadow.reused);
}

TEST(FramePlan, APlaneThatCanShadowNothingIsLeftOutOfTheShadowPass) {
  const RenderRequest r = test::builtin_request("three-cubes");  // lit from above: the floor hides nothing
  const Mesh mesh = tessellate(r.scene);
  const std::size_t floor = first_of_type(r.scene, SceneObject::Type::Plane);
  const FramePlan plan = fresh_plan(r);
  ASSERT_EQ(plan.casting_planes.size(), 1u);
  EXPECT_FALSE(plan.casting_planes[0]);
  ASSERT_FALSE(plan.shadow.layers.empty());
  for (const ShadowLayerDraw& layer : plan.shadow.layers) {
    EXPECT_FALSE(draws_object(layer.draws, mesh, floor)) << "layer " << layer.layer;
    EXPECT_TRUE(draws_object(layer.draws, mesh, 1) || draws_object(layer.draws, mesh, 2) ||
                draws_object(layer.draws, mesh, 3))
        << "a layer drawn holds a box";
  }
  // Lit from below, the floor hides the boxes: it casts.
  RenderRequest below = r;
  below.light.position = {-2.0, -4.0, -1.0};
  EXPECT_TRUE(fresh_plan(below).casting_planes[0]);
}

TEST(FramePlan, TheDepthOutputClearsWholeLayersAndDrawsEveryPlane) {
  RenderRequest r = test::builtin_request("three-cubes");
  r.output = Output::Depth;
  const Mesh mesh = tessellate(r.scene);
  const FramePlan plan = fresh_plan(r);
  EXPECT_TRUE(plan.depth_output);
  ASSERT_TRUE(plan.shadow.needed);
  EXPECT_EQ(plan.casting_planes, std::vector<bool>{true});
  std::size_t non_empty = 0;
  for (const ShadowView& view : plan.light.views) non_empty += !view.empty;
  EXPECT_EQ(plan.shadow.layers.size(), non_empty);
  for (const ShadowLayerDraw& layer : plan.shadow.layers) {
    EXPECT_TRUE(layer.clear_whole) << "layer " << layer.layer;
    EXPECT_TRUE(draws_object(layer.draws, mesh, 0)) << "the floor, in layer " << layer.layer;
  }
  EXPECT_TRUE(plan.shadow.kept_after.whole_layers);
  EXPECT_TRUE(plan.display.steps.empty()) << "no main pass";
  EXPECT_EQ(plan.preview.size, r.shadow.map_size);
  EXPECT_EQ(plan.preview.view_count, int(plan.light.views.size()));

  // The colour output clears only around the casters where they are small
  // in the layer.
  RenderRequest color = r;
  color.output = Output::Color;
  color.shadow.map_size = 4096;
  const FramePlan colour_plan = fresh_plan(color);
  bool some_rectangle = false;
  for (const ShadowLayerDraw& layer : colour_plan.shadow.layers) {
    if (layer.clear_whole) continue;
    some_rectangle = true;
    EXPECT_LT(layer.x0, layer.x1);
    EXPECT_LT(layer.y0, layer.y1);
    EXPECT_GE(layer.x0, 0);
    EXPECT_LE(layer.x1, colour_plan.light.layer_size);
  }
  EXPECT_TRUE(some_rectangle);
}

TEST(FramePlan, ReadBack) {
  RenderRequest r = test::builtin_request("three-cubes");
  r.width = 320;
  r.height = 200;
  const ReadBack colour = fresh_plan(r).read_back;
  EXPECT_FALSE(colour.depth_preview);
  EXPECT_EQ(colour.width, 320);
  EXPECT_EQ(colour.height, 200);
  EXPECT_EQ(colour.channels, 3);
  EXPECT_EQ(colour.bit_depth, 8);
  r.output = Output::Shadow;
  EXPECT_EQ(fresh_plan(r).read_back.channels, 1);
  EXPECT_EQ(fresh_plan(r).display.clear_color, glm::vec4(1.0f)) << "shadow output: nothing blocks the light";
  r.output = Output::Depth;
  r.shadow.map_size = 512;
  r.depth_bits = 16;
  const ReadBack depth = fresh_plan(r).read_back;
  EXPECT_TRUE(depth.depth_preview);
  EXPECT_EQ(depth.width, 512);
  EXPECT_EQ(depth.height, 512);
  EXPECT_EQ(depth.channels, 1);
  EXPECT_EQ(depth.bit_depth, 16);
  r.depth_bits = 8;
  EXPECT_EQ(fresh_plan(r).read_back.bit_depth, 8);
}

TEST(FramePlan, AHeavyMeshIsLeftOutOfACascadeItShadowsNothingIn) {
  int dropped = 0;
  for (double time = 0.0; time < 18.0; time += 1.5) {
    RenderRequest r = test::builtin_request("teapot");
    r.time = time;
    const Mesh mesh = tessellate(r.scene);
    const std::size_t teapot = first_of_type(r.scene, SceneObject::Type::Mesh);
    const FramePlan plan = plan_frame(r, mesh, "scene", KeptShadowMap{});
    if (plan.light.layout != ShadowLayout::Cascades) continue;
    const CasterTexels all = caster_texels_by_view(plan.light, mesh.bounds, drawn_objects(mesh, plan.casting_planes));
    for (std::size_t k = 0; k < plan.light.views.size(); ++k) {
      const bool reaches = !all.by_object[k][teapot].empty();
      // A layer left with nothing to draw is not drawn at all.
      bool drawn = false;
      for (const ShadowLayerDraw& layer : plan.shadow.layers)
        drawn = drawn || (layer.layer == int(k) && draws_object(layer.draws, mesh, teapot));
      EXPECT_EQ(drawn, !plan.casters.by_object[k][teapot].empty()) << "t=" << time;
      if (k == 0) {
        EXPECT_EQ(drawn, reaches) << "the first cascade keeps all";
      }
      dropped += reaches && !drawn;
    }
    // The depth output shows whole layers: nothing is left out.
    r.output = Output::Depth;
    const FramePlan depth = plan_frame(r, mesh, "scene", KeptShadowMap{});
    for (const ShadowLayerDraw& layer : depth.shadow.layers)
      EXPECT_EQ(draws_object(layer.draws, mesh, teapot), !all.by_object[layer.layer][teapot].empty()) << "t=" << time;
  }
  EXPECT_GT(dropped, 0) << "the teapot is left out of some cascade";
}

TEST(FramePlan, ScatteredObjectsAreDrawnInOneRangeOfTheirKind) {
  // A floor and 40 boxes in a row, every other one drawn.
  Scene scene;
  SceneObject floor;
  floor.type = SceneObject::Type::Plane;
  floor.size = {100, 0, 100};
  scene.objects.push_back(floor);
  for (int i = 0; i < 40; ++i) {
    SceneObject box;
    box.center = {double(i) * 2.0 - 40.0, 0.5, 0.0};
    scene.objects.push_back(box);
  }
  const Mesh mesh = tessellate(scene);
  const auto every_other = [&](int boxes) {
    std::vector<bool> drawn(scene.objects.size(), false);
    for (int i = 0; i < boxes; ++i) drawn[1 + 2 * i] = true;
    return drawn;
  };
  // 10 runs: a range each, culled as asked.
  const std::vector<DrawRange> few = scene_draw_ranges(mesh, CullMode::Front, every_other(10));
  ASSERT_EQ(few.size(), 10u);
  for (const DrawRange& d : few) {
    EXPECT_EQ(d.count, 36u);
    EXPECT_EQ(d.cull, CullMode::Front);
  }
  // 20 runs (past kMaxRuns): all closed meshes in one range.
  const std::vector<DrawRange> many = scene_draw_ranges(mesh, CullMode::Front, every_other(20));
  ASSERT_EQ(many.size(), 1u);
  EXPECT_EQ(many[0].first, 0u);
  EXPECT_EQ(many[0].count, mesh.closed_index_count);
  // Planes exactly as marked, two-sided, after the closed meshes.
  std::vector<bool> with_floor = every_other(3);
  with_floor[0] = true;
  const std::vector<DrawRange> floor_too = scene_draw_ranges(mesh, CullMode::Back, with_floor);
  ASSERT_EQ(floor_too.size(), 4u);
  EXPECT_TRUE(draws_object({floor_too.back()}, mesh, 0));
  EXPECT_EQ(floor_too.back().cull, CullMode::None);
  EXPECT_FALSE(draws_object(scene_draw_ranges(mesh, CullMode::Back, every_other(20)), mesh, 0));
  // Only the closed part.
  EXPECT_EQ(scene_draw_ranges(mesh, CullMode::Back, with_floor, MeshPart::Closed).size(), 3u);
}

// LightSplit's scene (test_light_math.cpp): a floor, a box, a sphere near
// the camera and one far off (too small on screen to be worth splitting).
RenderRequest split_scene() {
  RenderRequest r;
  SceneObject plane;
  plane.type = SceneObject::Type::Plane;
  plane.size = {20, 1, 20};
  SceneObject box;
  box.type = SceneObject::Type::Box;
  box.center = {0, 0.5, 0};
  SceneObject near_sphere;
  near_sphere.type = SceneObject::Type::Sphere;
  near_sphere.center = {0, 1, 3};
  near_sphere.radius = 1.0;
  SceneObject far_sphere = near_sphere;
  far_sphere.center = {0, 1, -40};
  r.scene.objects = {plane, box, near_sphere, far_sphere};
  r.camera.position = {0, 2, 8};
  r.camera.target = {0, 1, 0};
  r.width = 640;
  r.height = 360;
  return r;
}

TEST(FramePlan, ClosedMeshesAreDrawnInTwoPartsByLightSide) {
  const RenderRequest r = split_scene();
  const Mesh mesh = tessellate(r.scene);
  const FramePlan plan = fresh_plan(r);
  const std::vector<DisplayStep>& steps = plan.display.steps;
  ASSERT_GE(steps.size(), 3u);
  EXPECT_EQ(steps[0].kind, DisplayStep::Kind::ClosedFacingLight);
  EXPECT_EQ(steps[0].program, DisplayProgram::LightFacing);
  EXPECT_EQ(steps[1].kind, DisplayStep::Kind::ClosedAwayFromLight);
  EXPECT_EQ(steps[1].program, DisplayProgram::LightAway);
  EXPECT_EQ(steps[2].kind, DisplayStep::Kind::Objects);
  EXPECT_EQ(steps[2].program, DisplayProgram::Frame);
  for (int i : {0, 1}) {
    EXPECT_TRUE(steps[i].clip_by_light_side);
    EXPECT_FALSE(steps[i].cells);
    EXPECT_TRUE(draws_object(steps[i].draws, mesh, 1)) << "the box";
    EXPECT_TRUE(draws_object(steps[i].draws, mesh, 2)) << "the near sphere";
    EXPECT_FALSE(draws_object(steps[i].draws, mesh, 3)) << "the far sphere";
    EXPECT_FALSE(draws_object(steps[i].draws, mesh, 0)) << "the floor";
    for (const DrawRange& d : steps[i].draws) EXPECT_EQ(d.cull, CullMode::Back) << "seen from outside";
  }
  EXPECT_FALSE(steps[2].clip_by_light_side);
  EXPECT_FALSE(draws_object(steps[2].draws, mesh, 1));
  EXPECT_FALSE(draws_object(steps[2].draws, mesh, 2));
  EXPECT_TRUE(draws_object(steps[2].draws, mesh, 3));

  // Without the shadow lookup there is nothing to spare: one step draws all.
  RenderRequest unshadowed = r;
  unshadowed.shadow.enabled = false;
  const FramePlan flat = fresh_plan(unshadowed);
  ASSERT_EQ(flat.display.steps.size(), 1u);
  EXPECT_EQ(flat.display.steps[0].kind, DisplayStep::Kind::Objects);
  for (std::size_t object = 0; object < 4; ++object)
    EXPECT_TRUE(draws_object(flat.display.steps[0].draws, mesh, object)) << object;
  EXPECT_FALSE(flat.shadow.needed);
  EXPECT_TRUE(flat.shadow_views.empty());

  // From inside the box its back faces are what the camera sees: no
  // culling, and so no split.
  RenderRequest inside = r;
  inside.camera.position = {0.1, 0.5, 0.2};
  for (const DisplayStep& step : fresh_plan(inside).display.steps) {
    EXPECT_NE(step.kind, DisplayStep::Kind::ClosedFacingLight);
    for (const DrawRange& d : step.draws) EXPECT_EQ(d.cull, CullMode::None);
  }
}

TEST(FramePlan, TheFloorsCellsFollowTheStencilStepsInOrder) {
  // three-cubes' floor under a light of no size (umbras, shadows of the
  // boxes' bounds, shadowable cells and others), and a second floor beside
  // it at the same height (neither hides anything from the light).
  RenderRequest r = test::builtin_request("three-cubes");
  SceneObject second_floor = r.scene.objects[0];
  second_floor.center = {40.0, -0.5, 0.0};
  second_floor.size = {20.0, 0.0, 20.0};
  r.scene.objects.push_back(second_floor);
  const Mesh mesh = tessellate(r.scene);
  const FramePlan plan = fresh_plan(r);
  const DisplayPassPlan& display = plan.display;
  EXPECT_GT(display.umbras, 0u);
  std::vector<DisplayStep> cells;
  for (const DisplayStep& step : display.steps)
    if (step.cells) cells.push_back(step);
    else EXPECT_TRUE(cells.empty()) << "the scene's objects first, then the cells";
  ASSERT_FALSE(cells.empty());
  using Kind = DisplayStep::Kind;
  using Test = StencilStep::Test;
  for (const DisplayStep& step : display.steps) {
    if (step.kind == Kind::Objects) {
      EXPECT_FALSE(draws_object(step.draws, mesh, 0)) << "the floor is drawn in cells";
    }
  }
  std::size_t last_plane = 0;
  int last_kind = -1;
  for (const DisplayStep& step : cells) {
    // Plane by plane, each in the order of the protocol.
    if (step.plane != last_plane) last_kind = -1;
    EXPECT_GE(step.plane, last_plane);
    EXPECT_GT(int(step.kind), last_kind) << "plane " << step.plane;
    last_plane = step.plane, last_kind = int(step.kind);
    for (const DrawRange& d : step.draws) {
      EXPECT_GT(d.count, 0u);
      EXPECT_LE(d.first + d.count, display.cell_indices.size());
    }
    const int dark_mark = 2 * int(step.plane) + 2, near_mark = dark_mark + 1;
    const StencilStep& s = step.stencil;
    EXPECT_TRUE(s.enabled);
    switch (step.kind) {
      case Kind::BoundsMarks:
        EXPECT_EQ(step.program, DisplayProgram::Dark);
        EXPECT_TRUE(s.marks_only && s.replace);
        EXPECT_EQ(s.test, Test::Always);
        EXPECT_EQ(s.ref, near_mark);
        break;
      case Kind::DarkUmbras:
        EXPECT_EQ(step.program, DisplayProgram::Dark);
        EXPECT_TRUE(s.replace && !s.marks_only);
        EXPECT_EQ(s.test, Test::Always);
        EXPECT_EQ(s.ref, dark_mark);
        break;
      case Kind::ShadowableLookup:
        EXPECT_EQ(step.program, DisplayProgram::Frame);
        EXPECT_FALSE(s.replace);
        EXPECT_EQ(s.test, Test::Equal) << "the lookup only where near";
        EXPECT_EQ(s.ref, near_mark);
        EXPECT_EQ(s.mask, 0xFF);
        break;
      case Kind::ShadowableLit:
        EXPECT_EQ(step.program, DisplayProgram::Lit);
        EXPECT_EQ(s.test, Test::NotEqual);
        EXPECT_EQ(s.ref, dark_mark);
        EXPECT_EQ(s.mask, 0xFE) << "neither mark";
        break;
      case Kind::UnshadowableCells:
        EXPECT_EQ(step.program, DisplayProgram::Lit);
        EXPECT_EQ(s.test, Test::NotEqual);
        EXPECT_EQ(s.ref, dark_mark);
        EXPECT_EQ(s.mask, 0xFF);
        break;
      default:
        ADD_FAILURE() << "a scene step among the cells";
    }
  }
  // The first floor has every kind of step.
  std::vector<Kind> first_floor;
  for (const DisplayStep& step : cells)
    if (step.plane == 0) first_floor.push_back(step.kind);
  EXPECT_EQ(first_floor, (std::vector<Kind>{Kind::BoundsMarks, Kind::DarkUmbras, Kind::ShadowableLookup,
                                            Kind::ShadowableLit, Kind::UnshadowableCells}));
  EXPECT_TRUE(std::any_of(cells.begin(), cells.end(), [](const DisplayStep& s) { return s.plane == 1; }));

  // The seeds' bias draws every plane whole: no cells.
  RenderRequest seeds_bias = r;
  seeds_bias.shadow.bias.automatic = false;
  const FramePlan whole = fresh_plan(seeds_bias);
  EXPECT_TRUE(whole.display.cell_indices.empty());
  for (const DisplayStep& step : whole.display.steps) EXPECT_FALSE(step.cells);
  // A light with a size has no umbras drawn dark.
  RenderRequest soft = r;
  soft.light.size = 0.2;
  for (const DisplayStep& step : fresh_plan(soft).display.steps) EXPECT_NE(step.kind, Kind::DarkUmbras);
}

// The frame's shader variant is the plan's decision: the GL side builds the
// programs it names and decides nothing.
TEST(FramePlan, TheDisplayVariantIsDecidedInThePlan) {
  RenderRequest shadowed = test::builtin_request("three-cubes");
  RenderRequest off = shadowed;
  off.shadow.enabled = false;
  RenderRequest shadow_output = shadowed;
  shadow_output.output = Output::Shadow;
  RenderRequest point = shadowed;
  point.light.projection = LightProjection::Perspective;
  for (const RenderRequest& r : {shadowed, off, shadow_output, point}) {
    const FramePlan plan = fresh_plan(r);
    const DisplayVariant expected = display_variant(r, plan.light);
    EXPECT_EQ(plan.display.variant.shadows, expected.shadows);
    EXPECT_EQ(plan.display.variant.shadow_output, expected.shadow_output);
    EXPECT_EQ(plan.display.variant.perspective, expected.perspective);
    EXPECT_EQ(plan.display.variant.view_count, expected.view_count);
    EXPECT_EQ(plan.display.variant.pcf_radius, expected.pcf_radius);
  }
  EXPECT_TRUE(fresh_plan(shadowed).display.variant.shadows);
  EXPECT_FALSE(fresh_plan(off).display.variant.shadows);
  EXPECT_TRUE(fresh_plan(shadow_output).display.variant.shadow_output);
  EXPECT_TRUE(fresh_plan(point).display.variant.perspective);
}

TEST(FramePlan, EachStepsProgramDerivesFromTheFramesVariant) {
  const DisplayVariant frame = fresh_plan(test::builtin_request("three-cubes")).display.variant;
  ASSERT_TRUE(frame.shadows);
  const DisplayVariant lit = program_variant(frame, DisplayProgram::Lit);
  EXPECT_FALSE(lit.shadows);
  EXPECT_TRUE(lit.direct_light);
  const DisplayVariant dark = program_variant(frame, DisplayProgram::Dark);
  EXPECT_FALSE(dark.shadows);
  EXPECT_FALSE(dark.direct_light) << "an umbra is drawn with ambient light only";
  const DisplayVariant facing = program_variant(frame, DisplayProgram::LightFacing);
  EXPECT_TRUE(facing.shadows) << "the part that may face the light keeps the lookup";
  EXPECT_EQ(facing.light_side, 1);
  const DisplayVariant away = program_variant(frame, DisplayProgram::LightAway);
  EXPECT_FALSE(away.shadows);
  EXPECT_EQ(away.light_side, -1);
  EXPECT_EQ(program_variant(frame, DisplayProgram::Frame).light_side, 0);
  EXPECT_EQ(program_variant(frame, DisplayProgram::Frame).filter, frame.filter);
}

// Filter "exact": the certified maps of every view that holds a caster,
// cleared where the certificate may read them (kCertifiedReadTexels around
// the casters), every object reaching into it but the planes that shadow
// nothing, no face culled; one main-pass step with the certificates read
// back; nothing reused or kept. A fixed frustum: every object into every
// layer, cleared whole.
// Filter "exact" draws a plane the maps leave out in parts: the objects'
// bounds' shadows marked `near` and certified there by the maps (the
// frame's program on the plane's own triangles), the umbras proved dark,
// the rest proved lit (the proof programs, which keep the direct light for
// the uncertain pixels they leave).
TEST(FramePlan, ACertifiedFrameProvesTheFloorLitOrDarkAwayFromTheShadowsOfBounds) {
  RenderRequest r = test::builtin_request("three-cubes");
  r.shadow.filter = ShadowFilter::Exact;
  const Mesh mesh = tessellate(r.scene);
  const FramePlan plan = plan_frame(r, mesh, "scene", KeptShadowMap{});
  const DisplayPassPlan& pass = plan.display;
  using Kind = DisplayStep::Kind;
  std::vector<Kind> kinds;
  for (const DisplayStep& step : pass.steps) kinds.push_back(step.kind);
  // The cubes (closed, seen from outside) in two parts, as in any frame
  // with maps: where they may face the light, and where none of them can
  // (the facing rule settles those without a map: scene.frag).
  ASSERT_EQ(kinds, (std::vector<Kind>{Kind::ClosedFacingLight, Kind::ClosedAwayFromLight, Kind::Objects,
                                      Kind::BoundsMarks, Kind::DarkUmbras, Kind::CertifiedNear, Kind::ProvedLit}));
  const std::size_t floor = mesh.planes.at(0).object;
  for (std::size_t i = 0; i < 2; ++i) {
    std::size_t drawn = 0;
    for (const DrawRange& draw : pass.steps[i].draws) drawn += draw.count;
    EXPECT_EQ(drawn, mesh.closed_index_count);
    EXPECT_TRUE(pass.steps[i].clip_by_light_side);
    const DisplayVariant v = program_variant(pass.variant, pass.steps[i].program);
    EXPECT_TRUE(v.certificates);
    EXPECT_EQ(v.shadows, i == 0);  // the part turned from the light reads no map
  }
  // The floor is not among the objects drawn whole, nor the cubes now.
  std::size_t drawn = 0;
  for (const DrawRange& draw : pass.steps[2].draws) drawn += draw.count;
  EXPECT_EQ(drawn, 0u);
  EXPECT_EQ(pass.umbras, 3u);  // one per cube
  EXPECT_GT(pass.proof_margin, 0.0f);
  EXPECT_LT(pass.proof_margin, 0.1f);
  EXPECT_FALSE(pass.cell_indices.empty());
  for (std::size_t i = 3; i < pass.steps.size(); ++i) {
    const DisplayStep& step = pass.steps[i];
    SCOPED_TRACE(i);
    EXPECT_EQ(step.object, floor);
    EXPECT_GT(step.proof_rounding, 0.0f);
    EXPECT_LT(step.proof_rounding, 1e-3f);
    EXPECT_TRUE(step.stencil.enabled);
    // The marks and umbras come from the cells' buffers; the plane's own
    // triangles from the scene's.
    EXPECT_EQ(step.cells, step.kind == Kind::BoundsMarks || step.kind == Kind::DarkUmbras);
    const DisplayVariant v = program_variant(pass.variant, step.program);
    if (step.kind == Kind::CertifiedNear) {
      EXPECT_EQ(step.program, DisplayProgram::Frame);
      EXPECT_EQ(v.filter, ShadowFilter::Exact);
      EXPECT_EQ(step.stencil.test, StencilStep::Test::Equal);
    } else {
      EXPECT_EQ(v.proof, step.kind == Kind::ProvedLit ? 1 : -1);
      EXPECT_TRUE(v.certificates);
      EXPECT_TRUE(v.direct_light);  // uncertain pixels are drawn lit
      EXPECT_FALSE(v.shadows);
    }
  }
  EXPECT_TRUE(pass.steps[3].stencil.marks_only);
  EXPECT_EQ(pass.steps[6].stencil.test, StencilStep::Test::NotEqual);
  EXPECT_EQ(pass.steps[6].stencil.mask, 0xFE);  // neither of the plane's marks
  // A floor 10^5 wide: its polygons' float corners round by up to
  // 2^-24 of 5 10^4, and the shadow of the bounds is grown by that too.
  const ParsedRequest parsed = parse_render_request(R"({"scene": {"objects": [{"type": "plane", "center": [0, 0, 0], "size": [100000, 100000]},
      {"type": "box", "center": [0, 0.5, 0], "size": [1, 1, 1]}]}, "light": {"position": [0, 10, 0], "target": [0, 0, 0]},
      "camera": {"position": [0, 3, 3], "target": [0, 0, 0]}, "shadow": {"filter": "exact"}})",
                                                     Route::Render, {});
  ASSERT_TRUE(parsed.ok()) << parsed.error.message;
  const RenderRequest& huge = *parsed.request;
  const Mesh huge_mesh = tessellate(huge.scene);
  const FramePlan huge_plan = plan_frame(huge, huge_mesh, "scene", KeptShadowMap{});
  const auto marks_step = std::find_if(huge_plan.display.steps.begin(), huge_plan.display.steps.end(),
                                       [](const DisplayStep& step) { return step.kind == Kind::BoundsMarks; });
  ASSERT_NE(marks_step, huge_plan.display.steps.end());
  const DisplayStep& marks = *marks_step;
  double lowest_x = 1e300;
  for (std::size_t i = marks.draws[0].first; i < marks.draws[0].first + marks.draws[0].count; ++i)
    lowest_x = std::min(lowest_x, double(huge_plan.display.cell_vertices[huge_plan.display.cell_indices[i]].position[0]) +
                                      huge_mesh.origin.x);
  EXPECT_LT(lowest_x, -0.5 - 3.0 * double(huge_plan.display.proof_margin) - 5e4 * std::ldexp(1.0, -24));
  EXPECT_GT(lowest_x, -0.5 - 3.0 * double(huge_plan.display.proof_margin) - 0.02);
  // The other filters' Lit and Dark programs prove nothing.
  RenderRequest pcf = r;
  pcf.shadow.filter = ShadowFilter::Pcf;
  const DisplayVariant frame = plan_frame(pcf, mesh, "scene", KeptShadowMap{}).display.variant;
  EXPECT_EQ(program_variant(frame, DisplayProgram::Lit).proof, 0);
  EXPECT_EQ(program_variant(frame, DisplayProgram::Dark).proof, 0);
  EXPECT_FALSE(program_variant(frame, DisplayProgram::Dark).direct_light);
  // A point light inside a cube's bounds: the floor's shadows cannot be
  // bounded, and it is drawn whole, certified by the maps.
  RenderRequest inside = r;
  inside.light.projection = LightProjection::Perspective;
  inside.light.position = r.scene.objects[1].center;
  const FramePlan whole = plan_frame(inside, mesh, "scene", KeptShadowMap{});
  ASSERT_EQ(whole.display.steps.size(), 3u);  // the cubes split by the light, then every other object
  EXPECT_EQ(whole.display.steps[2].kind, Kind::Objects);
  EXPECT_TRUE(whole.display.cell_indices.empty());
}

// A layer where an object's corners move by more than kMostRoundingTexels
// (a 5 mm box 10^4 from the scene's centre, texels of 10^-5) draws no
// conservative maps: they would prove nothing at a swollen box's cost per
// triangle. Built-in scenes' layers all draw theirs.
TEST(FramePlan, ACertifiedLayerWhoseObjectsTheLightViewMovesByTexelsProvesNothing) {
  // A 2 cm box at the centre, 5 mm boxes 10^4 away on both sides, seen
  // from 2 cm, under a light at `light`.
  const auto far_boxes = [](const std::string& light) {
    const ParsedRequest parsed = parse_render_request(R"({"width": 640, "height": 360, "scene": {"objects": [
        {"type": "box", "center": [0, 0, 0], "size": [0.02, 0.002, 0.02]},
        {"type": "box", "center": [9534.6, 2860.3, 953.4], "size": [0.005, 0.005, 0.005]},
        {"type": "box", "center": [-9534.6, -2860.3, -953.4], "size": [0.005, 0.005, 0.005]}]},
      "light": {"position": [)" + light + R"(], "target": [0, 0, 0]},
      "camera": {"position": [0.0, 0.017, 0.012], "target": [0, 0.001, 0], "near": 0.0001, "far": 0.1},
      "shadow": {"filter": "exact", "map_size": 2048}})",
                                                       Route::Render, {});
    EXPECT_TRUE(parsed.ok()) << parsed.error.message;
    return parsed.ok() ? *parsed.request : RenderRequest{};
  };
  const RenderRequest far = far_boxes("19069.2, 5720.7, 1906.9");
  const Mesh far_mesh = tessellate(far.scene);
  const FramePlan far_plan = plan_frame(far, far_mesh, "far", KeptShadowMap{}, CertifiedPath::Maps);
  ASSERT_FALSE(far_plan.shadow.layers.empty());
  for (const ShadowLayerDraw& layer : far_plan.shadow.layers) EXPECT_TRUE(layer.proves_nothing) << layer.layer;
  for (const char* name : {"three-cubes", "torus-knot", "cube-on-plane"}) {
    RenderRequest r = test::builtin_request(name);
    r.shadow.filter = ShadowFilter::Exact;
    const Mesh mesh = tessellate(r.scene);
    const FramePlan plan = plan_frame(r, mesh, name, KeptShadowMap{}, CertifiedPath::Maps);
    for (const ShadowLayerDraw& layer : plan.shadow.layers) EXPECT_FALSE(layer.proves_nothing) << name << " " << layer.layer;
  }
  // Only the objects a layer draws count: the same far boxes, with the
  // light's view near the scene's centre (a sun over the small box) and
  // out of the camera's cascades, leave them alone.
  const RenderRequest aside = far_boxes("0.01, 0.03, 0.02");
  const Mesh aside_mesh = tessellate(aside.scene);
  const FramePlan aside_plan = plan_frame(aside, aside_mesh, "aside", KeptShadowMap{}, CertifiedPath::Maps);
  ASSERT_FALSE(aside_plan.shadow.layers.empty());
  for (const ShadowLayerDraw& layer : aside_plan.shadow.layers) {
    bool draws_far = false;
    for (const DrawRange& d : layer.draws)
      for (const ObjectRange& r : aside_mesh.object_ranges)
        if (r.object != 0 && r.first_index < d.first + d.count && d.first < r.first_index + r.index_count) draws_far = true;
    EXPECT_EQ(layer.proves_nothing, draws_far) << layer.layer;
  }
}

// The two paths without maps (CertifiedPath): proofs keep the floor's
// proved parts and the sliver pass; the ray cast keeps neither, and an
// undrawn pixel (the sky) is uncertain too: nothing else would find an
// object the raster missed there.
TEST(FramePlan, ACertifiedFrameWithoutMapsProvesTheFloorOrCastsEveryPixel) {
  RenderRequest r = test::builtin_request("three-cubes");
  r.shadow.filter = ShadowFilter::Exact;
  const Mesh mesh = tessellate(r.scene);
  const FramePlan maps = plan_frame(r, mesh, "scene", KeptShadowMap{}, CertifiedPath::Maps);
  const FramePlan proofs = plan_frame(r, mesh, "scene", KeptShadowMap{}, CertifiedPath::Proofs);
  const FramePlan cast = plan_frame(r, mesh, "scene", KeptShadowMap{}, CertifiedPath::RayCast);
  EXPECT_TRUE(maps.shadow.needed);
  EXPECT_EQ(maps.certified_path, CertifiedPath::Maps);
  for (const FramePlan* plan : {&proofs, &cast}) {
    EXPECT_FALSE(plan->shadow.needed);
    EXPECT_TRUE(plan->shadow.layers.empty());
    EXPECT_TRUE(plan->shadow_views.empty());
    EXPECT_TRUE(plan->display.certificates);
    EXPECT_FALSE(plan->display.variant.shadows);  // the frame's program marks its pixels uncertain
    EXPECT_TRUE(plan->display.variant.direct_light);
    EXPECT_TRUE(plan->read_back.certificates);
  }
  EXPECT_EQ(proofs.certified_path, CertifiedPath::Proofs);
  // The same steps but the split of closed meshes by the light, which
  // only a frame with maps has (without them no pixel reads a map).
  EXPECT_EQ(proofs.display.steps.size() + 2, maps.display.steps.size());
  EXPECT_EQ(maps.display.steps[1].kind, DisplayStep::Kind::ClosedAwayFromLight);
  EXPECT_EQ(proofs.display.steps[0].kind, DisplayStep::Kind::Objects);
  EXPECT_EQ(proofs.display.umbras, 3u);
  EXPECT_FALSE(proofs.display.sliver_draws.empty());
  EXPECT_EQ(proofs.display.background_certificate, 0u);
  EXPECT_EQ(program_variant(proofs.display.variant, DisplayProgram::Lit).proof, 1);
  EXPECT_EQ(cast.certified_path, CertifiedPath::RayCast);
  ASSERT_EQ(cast.display.steps.size(), 1u);
  EXPECT_TRUE(cast.display.cell_indices.empty());
  EXPECT_TRUE(cast.display.sliver_draws.empty());
  EXPECT_EQ(cast.display.background_certificate, PixelCertificates::kUncertain);
}

TEST(FramePlan, ACertifiedFrameDrawsItsMapsWholeAndReadsItsCertificates) {
  RenderRequest r = test::builtin_request("three-cubes");
  r.shadow.filter = ShadowFilter::Exact;
  const Mesh mesh = tessellate(r.scene);
  const FramePlan plan = plan_frame(r, mesh, "scene", KeptShadowMap{});
  EXPECT_TRUE(plan.shadow.certify);
  EXPECT_FALSE(plan.shadow.reused);
  EXPECT_FALSE(plan.shadow.kept_after.holds_plan);
  ASSERT_FALSE(plan.shadow.layers.empty());
  for (const ShadowLayerDraw& layer : plan.shadow.layers) {
    const TexelRect& c = plan.casters.by_view[std::size_t(layer.layer)];
    ASSERT_FALSE(c.empty());
    if (!layer.clear_whole) {
      EXPECT_LE(layer.x0, std::max(0, int(c.min.x) - kCertifiedReadTexels));
      EXPECT_LE(layer.y0, std::max(0, int(c.min.y) - kCertifiedReadTexels));
      EXPECT_GE(layer.x1, std::min(plan.light.layer_size, int(c.max.x) + kCertifiedReadTexels));
      EXPECT_GE(layer.y1, std::min(plan.light.layer_size, int(c.max.y) + kCertifiedReadTexels));
    }
    // Closed meshes' faces turned from the light are culled (the centre
    // map; the conservative passes' quads all face the light, and their
    // geometry shader drops those faces itself).
    for (const DrawRange& draw : layer.draws)
      EXPECT_EQ(draw.cull, draw.first < mesh.closed_index_count ? CullMode::Back : CullMode::None);
  }
  EXPECT_TRUE(plan.shadow.cull_closed_back);
  // ... unless a point light is inside a closed object's bounds.
  RenderRequest inside = r;
  inside.light.projection = LightProjection::Perspective;
  inside.light.position = r.scene.objects[1].center;
  const FramePlan lit_inside = plan_frame(inside, mesh, "scene", KeptShadowMap{});
  EXPECT_FALSE(lit_inside.shadow.cull_closed_back);
  for (const ShadowLayerDraw& layer : lit_inside.shadow.layers)
    for (const DrawRange& draw : layer.draws) EXPECT_EQ(draw.cull, CullMode::None);
  RenderRequest fixed = r;
  fixed.shadow.fit = FrustumFit::Fixed;
  const FramePlan fixed_plan = plan_frame(fixed, mesh, "scene", KeptShadowMap{});
  EXPECT_EQ(fixed_plan.shadow.layers.size(), fixed_plan.light.views.size());
  for (const ShadowLayerDraw& layer : fixed_plan.shadow.layers) EXPECT_TRUE(layer.clear_whole);
  EXPECT_TRUE(plan.display.certificates);
  ASSERT_GE(plan.display.steps.size(), 3u);
  EXPECT_EQ(plan.display.steps[0].kind, DisplayStep::Kind::ClosedFacingLight);
  EXPECT_EQ(plan.display.steps[1].kind, DisplayStep::Kind::ClosedAwayFromLight);
  EXPECT_EQ(plan.display.steps[2].kind, DisplayStep::Kind::Objects);
  EXPECT_EQ(plan.display.variant.filter, ShadowFilter::Exact);
  EXPECT_TRUE(plan.read_back.certificates);
  EXPECT_TRUE(plan.read_back.unlit);
  // The floor shadows nothing (every cube stands on it): left out.
  std::size_t drawn = 0;
  for (const DrawRange& draw : plan.shadow.layers[0].draws) drawn += draw.count;
  EXPECT_LT(drawn, mesh.closed_index_count + mesh.open_index_count);
  // The shadow output reads no unlit colours; the depth output and a frame
  // without shadows are not certified.
  r.output = Output::Shadow;
  EXPECT_FALSE(plan_frame(r, mesh, "scene", KeptShadowMap{}).read_back.unlit);
  r.output = Output::Depth;
  EXPECT_FALSE(plan_frame(r, mesh, "scene", KeptShadowMap{}).shadow.certify);
  r.output = Output::Color;
  r.shadow.enabled = false;
  EXPECT_FALSE(plan_frame(r, mesh, "scene", KeptShadowMap{}).display.certificates);
}

TEST(FramePlan, ACameraOnlyChangeReusesTheCertifiedMaps) {
  RenderRequest r = test::builtin_request("three-cubes");
  r.shadow.filter = ShadowFilter::Exact;
  r.light.projection = LightProjection::Perspective;  // its views do not follow the camera
  const Mesh mesh = tessellate(r.scene);
  const FramePlan first = plan_frame(r, mesh, "scene", KeptShadowMap{});
  ASSERT_TRUE(first.shadow.certify);
  ASSERT_FALSE(first.shadow.layers.empty());
  const KeptCertifiedMaps kept = first.shadow.certified_kept_after;
  EXPECT_TRUE(kept.holds_plan);
  EXPECT_FALSE(first.shadow.kept_after.holds_plan) << "the shadow map is not drawn";

  RenderRequest moved = r;
  moved.camera.position += glm::dvec3(0.3, -0.2, 0.1);
  moved.output = Output::Shadow;
  const FramePlan second = plan_frame(moved, mesh, "scene", KeptShadowMap{}, CertifiedPath::Maps, kept);
  EXPECT_TRUE(second.shadow.certify);
  EXPECT_TRUE(second.shadow.reused);
  EXPECT_TRUE(second.shadow.layers.empty()) << "no shadow pass";
  EXPECT_EQ(second.shadow_views, first.shadow_views);
  EXPECT_TRUE(second.display.certificates);
  // The certificate reads the maps around the same casters they were drawn
  // around.
  ASSERT_EQ(second.casters.by_view.size(), first.casters.by_view.size());
  for (std::size_t v = 0; v < first.casters.by_view.size(); ++v) {
    EXPECT_EQ(second.casters.by_view[v].min, first.casters.by_view[v].min);
    EXPECT_EQ(second.casters.by_view[v].max, first.casters.by_view[v].max);
  }

  // What the maps depend on changed: drawn again.
  const auto reused = [&](const RenderRequest& q, const std::string& key, const KeptCertifiedMaps& k,
                          CertifiedPath path = CertifiedPath::Maps) {
    return plan_frame(q, mesh, key, KeptShadowMap{}, path, k).shadow.reused;
  };
  EXPECT_FALSE(reused(moved, "another scene", kept));
  RenderRequest lit_elsewhere = moved;
  lit_elsewhere.light.position += glm::dvec3(1.0, 0.0, 0.0);
  EXPECT_FALSE(reused(lit_elsewhere, "scene", kept));
  RenderRequest fixed = moved;
  fixed.shadow.fit = FrustumFit::Fixed;
  EXPECT_FALSE(reused(fixed, "scene", kept));
  // Maps of a fixed frustum are cleared and drawn whole, a fitted one's
  // around its casters: the same views drawn for the other fit do not serve.
  KeptCertifiedMaps other_fit = kept;
  other_fit.fit = FrustumFit::Fixed;
  EXPECT_FALSE(reused(moved, "scene", other_fit));
  KeptCertifiedMaps other_planes = kept;
  other_planes.planes.assign(other_planes.planes.size(), true);
  if (other_planes.planes != kept.planes) {
    EXPECT_FALSE(reused(moved, "scene", other_planes));
  }
  KeptCertifiedMaps cut_short = kept;
  cut_short.holds_plan = false;
  EXPECT_FALSE(reused(moved, "scene", cut_short));
  // Frames that read no maps reuse none.
  EXPECT_FALSE(reused(moved, "scene", kept, CertifiedPath::Proofs));
  EXPECT_TRUE(plan_frame(moved, mesh, "scene", KeptShadowMap{}, CertifiedPath::Proofs, kept).shadow.layers.empty());
  RenderRequest pcf = moved;
  pcf.shadow.filter = ShadowFilter::Pcf;
  const FramePlan pcf_plan = plan_frame(pcf, mesh, "scene", KeptShadowMap{}, CertifiedPath::Maps, kept);
  EXPECT_FALSE(pcf_plan.shadow.reused);
  EXPECT_FALSE(pcf_plan.shadow.certify);
}

}  // namespace
}  // namespace umbra
