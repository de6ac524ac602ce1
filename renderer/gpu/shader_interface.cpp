#include "gpu/shader_interface.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include <glm/ext/matrix_transform.hpp>
#include <glm/geometric.hpp>

#include "core/render_result.hpp"
#include "core/shapes/shape.hpp"
#include "plan/conservative_maps.hpp"
#include "plan/frame_plan.hpp"

namespace umbra {

namespace {

// FrameBlock as GLSL text, from the same list that made the C++ struct.
#define UMBRA_GLSL_MEMBER(type, name) "  " #type " " #name ";\n"
#define UMBRA_GLSL_ARRAY(type, name, count) "  " #type " " #name "[" #count "];\n"
constexpr const char* kFrameBlockGlsl =
    "layout(std140, binding = UNIFORM_BUFFER_FRAME_BLOCK) uniform FrameBlock {\n" UMBRA_FRAME_BLOCK(
        UMBRA_GLSL_MEMBER, UMBRA_GLSL_ARRAY) "} u;\n";
#undef UMBRA_GLSL_MEMBER
#undef UMBRA_GLSL_ARRAY

#define UMBRA_MEMBER_ENTRY(type, name) {"FrameBlock." #name, offsetof(FrameBlock, name), 0},
#define UMBRA_ARRAY_ENTRY(type, name, count) \
  {"FrameBlock." #name "[0]", offsetof(FrameBlock, name), sizeof(FrameBlock::name[0])},
const BlockMember kFrameBlockMembers[] = {UMBRA_FRAME_BLOCK(UMBRA_MEMBER_ENTRY, UMBRA_ARRAY_ENTRY)};
#undef UMBRA_MEMBER_ENTRY
#undef UMBRA_ARRAY_ENTRY

int filter_code(ShadowFilter filter) {
  switch (filter) {
    case ShadowFilter::Hard: return 0;
    case ShadowFilter::Pcf: return 1;
    case ShadowFilter::Pcss: return 2;
    case ShadowFilter::Exact: return 3;
  }
  return 1;
}

// CUBE_FACE in the prelude is written from cube_face's values on the
// assumption that it is linear in the axis.
constexpr bool cube_face_is_linear() {
  for (int axis = 0; axis < 3; ++axis)
    for (bool negative : {false, true})
      if (cube_face(axis, negative) != cube_face(1, false) * axis + cube_face(0, negative)) return false;
  return true;
}
static_assert(cube_face_is_linear(), "CUBE_FACE cannot be written as GLSL from cube_face");

}  // namespace

const BlockMember* frame_block_members(std::size_t& count) {
  count = sizeof kFrameBlockMembers / sizeof kFrameBlockMembers[0];
  return kFrameBlockMembers;
}

std::string variant_defines(const DisplayVariant& v) {
  std::ostringstream d;
  d << "#define SHADOWS " << int(v.shadows) << "\n"
    << "#define DIRECT_LIGHT " << int(v.direct_light) << "\n"
    << "#define OUTPUT_SHADOW " << int(v.shadow_output) << "\n"
    << "#define LIGHT_PERSPECTIVE " << int(v.perspective) << "\n"
    << "#define LIGHT_CUBE " << int(v.cube) << "\n"
    << "#define VIEW_COUNT " << v.view_count << "\n"
    << "#define FILTER " << filter_code(v.filter) << "\n"
    << "#define PCF_RADIUS " << v.pcf_radius << "\n"
    << "#define BIAS_AUTO " << int(v.bias_auto) << "\n"
    << "#define FILTER_REACH " << v.filter_reach << "\n"
    << "#define FILTER_READ " << v.filter_read << "\n"
    << "#define LIGHT_SIDE " << v.light_side << "\n"
    << "#define CERTIFICATES " << int(v.certificates) << "\n"
    << "#define PROOF " << v.proof << "\n";
  return d.str();
}

FrameBlock frame_block(const RenderRequest& request, const ShadowPlan& plan, const Mesh& mesh,
                       const std::vector<TexelRect>& casters) {
  const glm::dvec3& origin = mesh.origin;
  // Origin-relative float matrices: the translation by the origin is folded
  // in while still in double precision.
  const glm::dmat4 from_origin = glm::translate(glm::dmat4(1.0), origin);
  const auto relative = [&](const glm::dmat4& m) { return glm::mat4(m * from_origin); };
  FrameBlock b;
  const CameraMatrices camera = camera_matrices(request.camera, request.width, request.height);
  b.camera_view_projection = relative(reversed_depth_projection(request.camera, request.width, request.height) *
                                      camera.view);
  b.camera_position = glm::vec4(glm::vec3(request.camera.position - origin), 1.0f);
  b.light_position = glm::vec4(glm::vec3(plan.position - origin), 1.0f);
  b.light_direction = glm::vec4(glm::vec3(plan.direction), 0.0f);
  b.light_color_ambient = glm::vec4(glm::vec3(request.light.color), float(request.light.ambient));
  if (plan.views.size() > std::size_t(kMaxViews))
    throw std::logic_error("a light with " + std::to_string(plan.views.size()) + " views; the shaders hold " +
                           std::to_string(kMaxViews));
  for (std::size_t i = 0; i < plan.views.size(); ++i) {
    const ShadowView& v = plan.views[i];
    b.light_view[i] = relative(v.view);
    b.light_projection[i] = glm::mat4(v.projection);
    b.view_depth_texel[i] = plan.perspective ? glm::vec4(v.near_plane, v.far_plane, v.texel_size.x, v.tan_half)
                                             : glm::vec4(v.near_plane, v.far_plane, v.texel_size.x, v.texel_size.y);
    const TexelRect& held = casters.at(i);
    // None: a rectangle that no filter's reach meets from anywhere.
    b.view_casters[i] = held.empty() ? glm::vec4(1e30f, 1e30f, -1e30f, -1e30f)
                                     : glm::vec4(held.min.x, held.min.y, held.max.x, held.max.y);
  }
  const DepthBias& bias = request.shadow.bias;
  b.bias_constant = float(bias.constant);
  b.bias_slope = float(bias.slope);
  b.bias_normal_offset = float(bias.normal_offset);
  // An area light: a point light's radius, or the tangent of half a
  // directional light's angular diameter.
  b.light_size = float(plan.perspective ? request.light.size : sun_disc_tan_radius(request.light));
  b.map_size = float(plan.layer_size);
  b.certified_map_size = float(certified_map_size(plan.layer_size));
  b.smooth_normal_span = plan.perspective ? float(mesh.smooth_normal_span) : 0.0f;
  b.preview_grid = preview_tiles_per_row(int(plan.views.size()));
  b.preview_size = float(request.shadow.map_size);
  const glm::dvec3 axis = glm::normalize(request.camera.target - request.camera.position);
  b.camera_axis_near = glm::vec4(glm::vec3(axis), float(request.camera.near_plane));
  b.mesh_origin_far = glm::vec4(glm::vec3(origin), float(request.camera.far_plane));
  b.image_size = glm::vec2(float(request.width), float(request.height));
  return b;
}

std::string variant_defines(CertifyPass pass, bool perspective, bool cull_closed_back) {
  return "#define CERTIFY_PASS " + std::to_string(int(pass)) + "\n#define LIGHT_PERSPECTIVE " +
         std::to_string(int(perspective)) + "\n#define CULL_CLOSED_BACK " + std::to_string(int(cull_closed_back)) + "\n";
}

std::vector<glm::vec4> object_facts(const Scene& scene, const glm::dvec3& origin) {
  std::vector<glm::vec4> facts;
  facts.reserve(scene.objects.size());
  for (const SceneObject& o : scene.objects) {
    const TessellationError error = tessellation_error(o);
    const double extent = largest_coordinate(object_bounds(o), origin);
    const bool model = o.type == SceneObject::Type::Mesh;
    const int flags = (model ? kObjectFlagModel : 0) | (shape_kind(o.type).closed(o) ? kObjectFlagClosed : 0);
    facts.emplace_back(float(error.distance), float(error.normal_angle), float(flags), float(extent));
  }
  return facts;
}

std::string variant_defines(const PreviewVariant& v) {
  std::ostringstream d;
  d << "#define LIGHT_PERSPECTIVE " << int(v.perspective) << "\n"
    << "#define VIEW_COUNT " << v.view_count << "\n";
  return d.str();
}

std::string glsl_prelude(const std::string& extra_defines) {
  std::ostringstream s;
  s << "#version 450 core\n"
    << "#define kMaxViews " << kMaxViews << "\n"
    << "#define kPcssSearchTexels " << kPcssSearchTexels << "\n"
    << "#define kPcssMaxPenumbraTexels " << kPcssMaxPenumbraTexels << "\n"
    << "#define kPcssBlockerSamples " << kPcssBlockerSamples << "\n"
    << "#define kPcssFilterSamples " << kPcssFilterSamples << "\n"
    << "#define FILTER_HARD " << filter_code(ShadowFilter::Hard) << "\n"
    << "#define FILTER_PCF " << filter_code(ShadowFilter::Pcf) << "\n"
    << "#define FILTER_PCSS " << filter_code(ShadowFilter::Pcss) << "\n"
    << "#define FILTER_EXACT " << filter_code(ShadowFilter::Exact) << "\n"
    // A cube face's layer from its axis (0 x, 1 y, 2 z) and whether it
    // looks towards minus: cube_face in core/shader_facts.hpp.
    << "#define CUBE_FACE(axis, negative) (" << cube_face(1, false) << " * (axis) + ((negative) ? "
    << cube_face(0, true) << " : " << cube_face(0, false) << "))\n"
    << "#define ATTRIB_POSITION " << kAttribPosition << "\n"
    << "#define ATTRIB_NORMAL " << kAttribNormal << "\n"
    << "#define ATTRIB_COLOR " << kAttribColor << "\n"
    << "#define FRAG_OUTPUT_COLOR " << kFragOutputColor << "\n"
    << "#define FRAG_OUTPUT_CERTIFICATE " << kFragOutputCertificate << "\n"
    << "#define FRAG_OUTPUT_UNLIT " << kFragOutputUnlit << "\n"
    << "#define UNIFORM_LOCATION_TRIANGLE_BASE " << kUniformLocationTriangleBase << "\n"
    << "#define UNIFORM_LOCATION_PROOF_OBJECT " << kUniformLocationProofObject << "\n"
    << "#define UNIFORM_LOCATION_PROOF_MARGIN " << kUniformLocationProofMargin << "\n"
    << "#define UNIFORM_LOCATION_PROOF_ROUNDING " << kUniformLocationProofRounding << "\n"
    << "#define UNIFORM_LOCATION_CULL_BACK " << kUniformLocationCullBack << "\n"
    << "#define UNIFORM_LOCATION_CAST_RING " << kUniformLocationCastRing << "\n"
    << "#define CERTIFICATE_LIT " << PixelCertificates::kCertainlyLit << "u\n"
    << "#define CERTIFICATE_DARK " << PixelCertificates::kCertainlyDark << "u\n"
    << "#define CERTIFICATE_UNCERTAIN " << PixelCertificates::kUncertain << "u\n"
    << "#define CERTIFICATE_OBJECT_SHIFT " << PixelCertificates::kObjectShift << "\n"
    << "#define CERTIFICATE_SURFACE_SHIFT " << PixelCertificates::kSurfaceShift << "\n"
    << "#define CERTIFICATE_VERDICT_MASK " << PixelCertificates::kVerdictMask << "u\n"
    << "#define CERTIFICATE_TRIANGLE_OWNER " << kModelTriangleOwner << "u\n"
    << "#define OBJECT_FLAG_MODEL " << kObjectFlagModel << "\n"
    << "#define OBJECT_FLAG_CLOSED " << kObjectFlagClosed << "\n"
    << "#define CERTIFY_CENTRE " << int(CertifyPass::Centre) << "\n"
    << "#define CERTIFY_NEAREST " << int(CertifyPass::Nearest) << "\n"
    << "#define CERTIFY_OTHERS " << int(CertifyPass::Others) << "\n";
  for (const TextureUnit& unit : kTextureUnits) s << "#define " << unit.define << " " << unit.unit << "\n";
  for (const TextureUnit& unit : kImageUnits) s << "#define " << unit.define << " " << unit.unit << "\n";
  s << "#define STORAGE_BUFFER_CAST_LIST " << kStorageBufferCastList << "\n"
    << "#define CAST_LIST_HEADER_WORDS " << kCastListHeaderBytes / 4 << "\n"
    << "#define CAST_EDGES " << int(CastPass::Edges) << "\n"
    << "#define CAST_ROWS " << int(CastPass::Rows) << "\n"
    << "#define CAST_LIST " << int(CastPass::List) << "\n";
  s
    << "#define UNIFORM_LOCATION_LAYER " << kUniformLocationLayer << "\n"
    << "#define UNIFORM_BUFFER_FRAME_BLOCK " << kUniformBufferFrameBlock << "\n"
    << extra_defines << kFrameBlockGlsl
    // Each file's own line numbers in compile errors.
    << "#line 1\n";
  return s.str();
}

}  // namespace umbra
