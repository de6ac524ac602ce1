// The C++ side of the shader interface: variants and the uniform block's
// contents. No GL (the block's layout against GL is checked in
// test_render.cpp, where a context exists).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <regex>
#include <sstream>

#include "core/light_math.hpp"
#include "core/render_result.hpp"
#include "core/shader_facts.hpp"
#include "gpu/embedded_shaders.hpp"
#include "plan/conservative_maps.hpp"
#include "gpu/shader_interface.hpp"
#include "plan/frame_plan.hpp"

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
  const std::string d = variant_defines(v);
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
  EXPECT_EQ(variant_defines(display_variant(a, plan_shadow(a))), variant_defines(display_variant(b, plan_shadow(b))));
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
    EXPECT_EQ(variant_defines(lit), variant_defines(display_variant(off, plan_shadow(off))));
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


// Magnum's GenericGL_Test, for Umbra: each fact the shaders share with C++
// is a #define of the prelude with the C++ constant's value.
TEST(FramePrelude, DefinesEachSharedFactAsTheCxxConstant) {
  const std::string prelude = glsl_prelude("");
  const std::pair<const char*, int> facts[] = {
      {"kMaxViews", kMaxViews},
      {"kPcssSearchTexels", kPcssSearchTexels},
      {"kPcssMaxPenumbraTexels", kPcssMaxPenumbraTexels},
      {"kPcssBlockerSamples", kPcssBlockerSamples},
      {"kPcssFilterSamples", kPcssFilterSamples},
      {"ATTRIB_POSITION", kAttribPosition},
      {"ATTRIB_NORMAL", kAttribNormal},
      {"ATTRIB_COLOR", kAttribColor},
      {"FRAG_OUTPUT_COLOR", kFragOutputColor},
      {"TEXTURE_UNIT_SHADOW_MAP", kTextureUnitShadowMap},
      {"UNIFORM_LOCATION_LAYER", kUniformLocationLayer},
      {"UNIFORM_LOCATION_TRIANGLE_BASE", kUniformLocationTriangleBase},
      {"UNIFORM_LOCATION_PROOF_OBJECT", kUniformLocationProofObject},
      {"UNIFORM_LOCATION_PROOF_MARGIN", kUniformLocationProofMargin},
      {"UNIFORM_LOCATION_PROOF_ROUNDING", kUniformLocationProofRounding},
      {"UNIFORM_LOCATION_CULL_BACK", kUniformLocationCullBack},
      {"UNIFORM_LOCATION_CAST_RING", kUniformLocationCastRing},
      {"UNIFORM_BUFFER_FRAME_BLOCK", kUniformBufferFrameBlock},
      {"CERTIFICATE_OBJECT_SHIFT", int(PixelCertificates::kObjectShift)},
      {"CERTIFICATE_SURFACE_SHIFT", int(PixelCertificates::kSurfaceShift)},
      {"STORAGE_BUFFER_CAST_LIST", kStorageBufferCastList},
      {"CAST_LIST_HEADER_WORDS", int(kCastListHeaderBytes / 4)},
      {"CAST_EDGES", int(CastPass::Edges)},
      {"CAST_ROWS", int(CastPass::Rows)},
      {"CAST_LIST", int(CastPass::List)},
  };
  for (const auto& [name, value] : facts)
    EXPECT_NE(prelude.find(std::string("#define ") + name + " " + std::to_string(value) + "\n"), std::string::npos)
        << name << " is not " << value << " in:\n" << prelude;
  for (const TextureUnit& unit : kTextureUnits)
    EXPECT_NE(prelude.find(std::string("#define ") + unit.define + " " + std::to_string(unit.unit) + "\n"), std::string::npos)
        << unit.define;
  for (const TextureUnit& unit : kImageUnits)
    EXPECT_NE(prelude.find(std::string("#define ") + unit.define + " " + std::to_string(unit.unit) + "\n"), std::string::npos)
        << unit.define;
  EXPECT_NE(prelude.find("#define CERTIFICATE_VERDICT_MASK " + std::to_string(PixelCertificates::kVerdictMask) + "u\n"),
            std::string::npos);
  // A ListedPixel is the list's uvec2: two words, index first.
  static_assert(sizeof(PixelCertificates::ListedPixel) == 8 && offsetof(PixelCertificates::ListedPixel, unlit) == 4);
  // The owner of a model's triangle alone, as the CPU's maps name it.
  EXPECT_NE(prelude.find("#define CERTIFICATE_TRIANGLE_OWNER " + std::to_string(kModelTriangleOwner) + "u\n"),
            std::string::npos);
  EXPECT_NE(prelude.find("layout(std140, binding = UNIFORM_BUFFER_FRAME_BLOCK) uniform FrameBlock"), std::string::npos);
  // The block comes after the #define it names.
  EXPECT_LT(prelude.find("#define UNIFORM_BUFFER_FRAME_BLOCK"), prelude.find("uniform FrameBlock"));
}

TEST(FramePrelude, CubeFaceIsTheLayerThatCxxDrawsEachFaceInto) {
  const std::string prelude = glsl_prelude("");
  const std::string head = "#define CUBE_FACE(axis, negative) (";
  const std::size_t at = prelude.find(head);
  ASSERT_NE(at, std::string::npos) << prelude;
  // The macro's body, evaluated as GLSL would: per_axis * axis + (negative ? minus : plus).
  int per_axis = -1, minus = -1, plus = -1;
  ASSERT_EQ(std::sscanf(prelude.c_str() + at + head.size(), "%d * (axis) + ((negative) ? %d : %d))", &per_axis, &minus,
                        &plus),
            3)
      << prelude.substr(at, 80);
  for (int face = 0; face < kCubeFaceCount; ++face) {
    const int axis = cube_face_axis(face);
    const bool negative = cube_face_negative(face);
    EXPECT_EQ(per_axis * axis + (negative ? minus : plus), face) << "face " << face;
    EXPECT_EQ(cube_face(axis, negative), face);
    // The face's name is its direction, and cube_face_view looks along it.
    EXPECT_EQ(std::string(kCubeFaceNames[face]), std::string(negative ? "-" : "+") + "XYZ"[axis]);
    const glm::dvec3 light(1.0, 2.0, 3.0);
    glm::dvec3 along(0.0);
    along[axis] = negative ? -1.0 : 1.0;
    const glm::dvec4 eye = cube_face_view(light, face) * glm::dvec4(light + 2.0 * along, 1.0);
    EXPECT_NEAR(eye.x, 0.0, 1e-12) << kCubeFaceNames[face];
    EXPECT_NEAR(eye.y, 0.0, 1e-12) << kCubeFaceNames[face];
    EXPECT_NEAR(eye.z, -2.0, 1e-12) << kCubeFaceNames[face];
  }
}

TEST(FramePrelude, ThePreviewGridIsTheSmallestSquareThatHoldsEveryView) {
  EXPECT_EQ(preview_tiles_per_row(1), 1);
  EXPECT_EQ(preview_tiles_per_row(2), 2);
  EXPECT_EQ(preview_tiles_per_row(4), 2);
  EXPECT_EQ(preview_tiles_per_row(5), 3);
  EXPECT_EQ(preview_tiles_per_row(kCubeFaceCount), 3);
  EXPECT_EQ(preview_tiles_per_row(9), 3);
  RenderRequest r = default_frame();
  r.shadow.cascades = 3;
  const ShadowPlan plan = plan_shadow(r);
  ASSERT_EQ(plan.views.size(), 3u);
  EXPECT_EQ(frame_block(r, plan, Mesh{}, std::vector<TexelRect>(3)).preview_grid, 2);
  // What the panel is told of it: the grid, and for a cube which face each tile is.
  EXPECT_EQ(preview_tiles_parameters(plan), "; grid=2");
  ShadowPlan cube;
  cube.layout = ShadowLayout::Cube;
  cube.views.resize(kCubeFaceCount);
  EXPECT_EQ(preview_tiles_parameters(cube), "; grid=3; faces=+X,-X,+Y,-Y,+Z,-Z");
}

// The shaders take every location and binding from the prelude: a number
// of their own would be a second copy of a fact C++ holds.
TEST(ShaderFiles, NameNoNumberOfTheirOwnForALocationOrBinding) {
  const std::regex numbered(R"(layout\s*\([^)]*\b(location|binding)\s*=\s*[0-9])");
  // A declaration that C++ binds by number: a vertex shader's input, a
  // fragment shader's output, any uniform outside the block.
  const std::regex bound_by_cxx(R"(^\s*(layout\s*\(([^)]*)\)\s*)?(uniform|in|out)\s+\w+\s+\w+\s*;)");
  ASSERT_FALSE(shader_source_names().empty());
  int declarations = 0;
  for (const std::string_view name : shader_source_names()) {
    const bool vertex = name.size() > 5 && name.substr(name.size() - 5) == ".vert";
    std::istringstream lines{std::string(shader_source(name))};
    std::string line;
    for (int number = 1; std::getline(lines, line); ++number) {
      const std::string code = line.substr(0, line.find("//"));
      EXPECT_FALSE(std::regex_search(code, numbered)) << name << ":" << number << ": " << line;
      std::smatch m;
      if (!std::regex_search(code, m, bound_by_cxx)) continue;
      const std::string qualifier = m[3];
      const bool by_cxx = qualifier == "uniform" || (vertex ? qualifier == "in" : qualifier == "out");
      if (!by_cxx) continue;  // a varying: matched by name between the stages
      ++declarations;
      EXPECT_TRUE(m[1].matched) << name << ":" << number << " leaves its number to GL: " << line;
    }
  }
  // a_position twice, a_normal, a_color, o_color twice, u_layer, u_shadow_map twice; filter "exact"'s:
  // certificate.glsl's two buffer textures, certify.geom's u_layer and u_triangle_base, certify.frag's
  // u_triangle_base, o_triangle, u_layer, o_owner and u_nearest_owner, scene.frag's o_certificate,
  // o_unlit, u_triangle_base, u_proof_object, u_proof_margin, u_proof_rounding and five maps; the sliver
  // pass's a_position, a_normal, u_triangle_base, u_cull_back, u_certificates and o_sliver; the
  // cast list's u_certificates, u_ring, u_slivers and u_unlit (its images name two words before theirs).
  EXPECT_EQ(declarations, 39);
}

}  // namespace
}  // namespace umbra
