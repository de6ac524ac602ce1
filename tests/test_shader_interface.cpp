// The C++ side of the shader interface: variants and the uniform block's
// contents. No GL (the block's layout against GL is checked in
// test_render.cpp, where a context exists).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "core/light_math.hpp"
#include "gpu/shader_interface.hpp"

namespace umbra {
namespace {

RenderRequest default_frame() {
  RenderRequest r;
  r.scene.objects.push_back({});  // one unit box at the origin
  return r;
}

TEST(DisplayVariant, TheDefaultFrameIsAnOrthographicPcfR1WithTheReceiverPlane) {
  const RenderRequest r = default_frame();
  const ShadowPlan plan = plan_shadow(r);
  const DisplayVariant v = display_variant(r, plan);
  EXPECT_TRUE(v.shadows);
  EXPECT_FALSE(v.shadow_output);
  EXPECT_FALSE(v.perspective);
  EXPECT_FALSE(v.cube);
  EXPECT_EQ(v.view_count, int(plan.views.size()));
  EXPECT_EQ(v.filter, ShadowFilter::Pcf);
  EXPECT_EQ(v.pcf_radius, 1);
  EXPECT_TRUE(v.bias_auto);
  EXPECT_EQ(v.filter_reach, filter_reach_texels(r.shadow));
  const std::string d = v.defines();
  EXPECT_NE(d.find("#define FILTER 1\n"), std::string::npos) << d;
  EXPECT_NE(d.find("#define PCF_RADIUS 1\n"), std::string::npos) << d;
  EXPECT_NE(d.find("#define VIEW_COUNT " + std::to_string(plan.views.size()) + "\n"), std::string::npos) << d;
}

TEST(DisplayVariant, SwitchesThatCannotMatterDoNotMakeANewProgram) {
  RenderRequest a = default_frame(), b = default_frame();
  a.shadow.enabled = b.shadow.enabled = false;
  b.shadow.filter = ShadowFilter::Hard;
  b.shadow.pcf_radius = 7;
  b.shadow.bias.automatic = false;
  EXPECT_EQ(display_variant(a, plan_shadow(a)).defines(), display_variant(b, plan_shadow(b)).defines());
  // PCSS needs an area light; with an ideal one it is PCF, as the API says.
  RenderRequest pcss = default_frame();
  pcss.shadow.filter = ShadowFilter::Pcss;
  pcss.shadow.pcf_radius = 2;
  EXPECT_EQ(display_variant(pcss, plan_shadow(pcss)).filter, ShadowFilter::Pcf);
  EXPECT_EQ(display_variant(pcss, plan_shadow(pcss)).pcf_radius, 2);
  pcss.light.size = 1.0;
  EXPECT_EQ(display_variant(pcss, plan_shadow(pcss)).filter, ShadowFilter::Pcss);
  EXPECT_EQ(display_variant(pcss, plan_shadow(pcss)).filter_reach, kPcssSearchTexels + 1);
}

TEST(DisplayVariant, CellsNoShadowCanFallOnUseTheProgramOfAFrameWithoutShadows) {
  for (const bool shadow_output : {false, true}) {
    RenderRequest frame = default_frame(), off = default_frame();
    frame.shadow.filter = ShadowFilter::Pcss;
    frame.light.size = 1.0;
    frame.light.projection = off.light.projection = LightProjection::Perspective;
    off.shadow.enabled = false;
    if (shadow_output) frame.output = off.output = Output::Shadow;
    const DisplayVariant lit = without_shadows(display_variant(frame, plan_shadow(frame)));
    EXPECT_FALSE(lit.shadows);
    EXPECT_EQ(lit.shadow_output, shadow_output);
    EXPECT_TRUE(lit.perspective);
    EXPECT_EQ(lit.defines(), display_variant(off, plan_shadow(off)).defines());
  }
}

TEST(DisplayVariant, APointLightAllAroundItsObjectsUsesTheCube) {
  RenderRequest r = default_frame();
  r.light.projection = LightProjection::Perspective;
  r.light.position = {0.0, 0.0, 0.0};
  r.light.target = {0.0, -1.0, 0.0};
  r.scene.objects.front().center = {0.0, 0.0, 0.0};
  r.scene.objects.front().size = {4.0, 4.0, 4.0};  // the light sits inside the box
  const ShadowPlan plan = plan_shadow(r);
  ASSERT_EQ(plan.layout, ShadowLayout::Cube);
  const DisplayVariant v = display_variant(r, plan);
  EXPECT_TRUE(v.perspective);
  EXPECT_TRUE(v.cube);
  EXPECT_EQ(v.view_count, 6);
}

TEST(FrameBlock, HoldsEachViewRelativeToTheOrigin) {
  RenderRequest r = default_frame();
  r.width = 640;
  r.height = 360;
  r.light.size = 2.0;  // degrees
  r.light.ambient = 0.25;
  const ShadowPlan plan = plan_shadow(r);
  const glm::dvec3 origin(10.0, -2.0, 3.0);
  Mesh mesh;
  mesh.origin = origin;
  mesh.smooth_normal_span = 0.5;
  std::vector<TexelRect> casters(plan.views.size());  // nothing drawn
  // No rectangle: one that no filter, however far it reaches, can meet.
  EXPECT_EQ(frame_block(r, plan, mesh, casters).view_casters[0], glm::vec4(1e30f, 1e30f, -1e30f, -1e30f));
  casters[0] = {{3.0, 4.0}, {50.0, 60.0}};
  const FrameBlock b = frame_block(r, plan, mesh, casters);
  EXPECT_EQ(b.view_casters[0], glm::vec4(3.0f, 4.0f, 50.0f, 60.0f));
  EXPECT_EQ(b.map_size, float(plan.layer_size));
  EXPECT_EQ(b.smooth_normal_span, 0.0f) << "a directional light's facing test is exact";
  casters.pop_back();
  EXPECT_THROW(frame_block(r, plan, mesh, casters), std::out_of_range);
  EXPECT_FLOAT_EQ(b.light_color_ambient.w, 0.25f);
  EXPECT_NEAR(b.light_size, std::tan(1.0 * M_PI / 180.0), 1e-7);
  EXPECT_NEAR(b.camera_position.x, r.camera.position.x - origin.x, 1e-6);
  for (std::size_t i = 0; i < plan.views.size(); ++i) {
    const ShadowView& v = plan.views[i];
    EXPECT_FLOAT_EQ(b.view_depth_texel[i].x, float(v.near_plane));
    EXPECT_FLOAT_EQ(b.view_depth_texel[i].y, float(v.far_plane));
    EXPECT_FLOAT_EQ(b.view_depth_texel[i].z, float(v.texel_size.x));
    // A point relative to the origin lands where the world point does.
    const glm::dvec3 world(0.3, 0.2, -0.1);
    const glm::dvec4 expected = v.view_projection() * glm::dvec4(world, 1.0);
    const glm::vec4 got = b.light_projection[i] * (b.light_view[i] * glm::vec4(glm::vec3(world - origin), 1.0f));
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(got[k], expected[k], 1e-4) << "view " << i << " component " << k;
  }
  r.light.projection = LightProjection::Perspective;
  const ShadowPlan point = plan_shadow(r);
  EXPECT_EQ(frame_block(r, point, mesh, std::vector<TexelRect>(point.views.size())).smooth_normal_span, 0.5f);
}

TEST(FramePrelude, DeclaresEveryBlockMemberAndTheSharedConstants) {
  const std::string prelude = glsl_prelude("#define SOMETHING 1\n");
  EXPECT_EQ(prelude.rfind("#version 450 core\n", 0), 0u);
  EXPECT_NE(prelude.find("#define kMaxViews " + std::to_string(kMaxViews) + "\n"), std::string::npos);
  EXPECT_NE(prelude.find("#define kPcssSearchTexels " + std::to_string(kPcssSearchTexels) + "\n"), std::string::npos);
  EXPECT_NE(prelude.find("#define SOMETHING 1\n"), std::string::npos);
  std::size_t count = 0;
  const BlockMember* members = frame_block_members(count);
  ASSERT_GT(count, 10u);
  std::size_t last_offset = 0;
  for (std::size_t i = 0; i < count; ++i) {
    std::string name = std::string(members[i].gl_name).substr(std::strlen("FrameBlock."));
    name = name.substr(0, name.find('['));
    EXPECT_NE(prelude.find(" " + name + (members[i].array_stride ? "[" : ";")), std::string::npos) << name;
    if (i > 0) {
      EXPECT_GT(members[i].offset, last_offset) << name;
    }
    last_offset = members[i].offset;
  }
  EXPECT_EQ(sizeof(FrameBlock) % 16, 0u);
}

}  // namespace
}  // namespace umbra
