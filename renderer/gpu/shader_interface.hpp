// The interface between the renderer and its shaders, written once, in C++.
//
// The GLSL side is generated from this file when a program is built: the
// uniform block below becomes a `layout(std140) uniform FrameBlock` with
// the same members, and the constants, the bindings and the variant
// switches become `#define`s (see glsl_prelude). The shader files therefore
// declare no block members, and use no number of their own for a location,
// a binding or a shared constant; a program whose block layout or bindings
// differ from C++'s refuses to build (gl::check_block_layout,
// gl::check_bindings). No GL here.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "core/light_math.hpp"
#include "core/request.hpp"
#include "plan/shader_variants.hpp"
#include "core/scene.hpp"
#include "core/shader_facts.hpp"

namespace umbra {

// ---------------------------------------------------------------------------
// Constants the shaders share with C++ (injected as #defines of the same
// name): those the light math needs too (kMaxViews, the PCSS reach and
// samples, the cube-face order, the preview grid) are in core/shader_facts.hpp;
// the GL bindings are here. In the shaders each is the #define in brackets.

static_assert(kMaxCascades <= kMaxViews, "the shaders must hold every cascade");

/// Vertex attribute locations (ATTRIB_POSITION, ATTRIB_NORMAL, ATTRIB_COLOR):
/// a_position, a_normal, a_color, each a vec3 read from a Vertex.
inline constexpr int kAttribPosition = 0;
inline constexpr int kAttribNormal = 1;
inline constexpr int kAttribColor = 2;
/// Each attribute with its GLSL name and where it lies in a Vertex: what a
/// vertex array describes, one entry per attribute.
struct VertexAttribute {
  const char* glsl_name;
  int location;
  std::size_t offset;  // bytes into Vertex; 3 floats each
};
inline constexpr VertexAttribute kVertexAttributes[] = {
    {"a_position", kAttribPosition, offsetof(Vertex, position)},
    {"a_normal", kAttribNormal, offsetof(Vertex, normal)},
    {"a_color", kAttribColor, offsetof(Vertex, color)},
};
/// The colour output's location (FRAG_OUTPUT_COLOR): o_color.
inline constexpr int kFragOutputColor = 0;
/// The texture unit of the light's depth map array (TEXTURE_UNIT_SHADOW_MAP):
/// u_shadow_map, in the main pass and the depth preview.
inline constexpr int kTextureUnitShadowMap = 0;
/// The uniform location of u_layer (UNIFORM_LOCATION_LAYER): the view
/// (map layer) a shadow-pass draw fills, set per layer.
inline constexpr int kUniformLocationLayer = 0;
/// The uniform buffer binding of FrameBlock (UNIFORM_BUFFER_FRAME_BLOCK).
inline constexpr int kUniformBufferFrameBlock = 0;

// Filter "exact" (docs/certified-shadows.md).
/// The main pass's certificate output (FRAG_OUTPUT_CERTIFICATE): o_certificate,
/// a uint (PixelCertificates::codes); and the pixel shaded with
/// visibility 0 (FRAG_OUTPUT_UNLIT): o_unlit.
inline constexpr int kFragOutputCertificate = 1;
inline constexpr int kFragOutputUnlit = 2;
/// u_triangle_base's location (UNIFORM_LOCATION_TRIANGLE_BASE): the first
/// triangle of a draw (its first index / 3), so that first +
/// gl_PrimitiveID names a triangle of the scene's index buffer.
inline constexpr int kUniformLocationTriangleBase = 1;
/// A proved plane part's program (DisplayVariant::proof): u_proof_object
/// (UNIFORM_LOCATION_PROOF_OBJECT), the plane's scene object, and
/// u_proof_margin (UNIFORM_LOCATION_PROOF_MARGIN), the reach in world units
/// its proof allows for (DisplayPassPlan::proof_margin), and
/// u_proof_rounding (UNIFORM_LOCATION_PROOF_ROUNDING), the part of a
/// pixel's reach that the plan bounds (DisplayStep::proof_rounding).
inline constexpr int kUniformLocationProofObject = 2;
inline constexpr int kUniformLocationProofMargin = 3;
inline constexpr int kUniformLocationProofRounding = 4;
/// The sliver pass's u_cull_back (UNIFORM_LOCATION_CULL_BACK): 1 where the
/// main pass culled closed meshes' back faces (DisplayPassPlan::
/// sliver_skips_closed_back): their edges are drawn by the front faces.
inline constexpr int kUniformLocationCullBack = 5;
/// cast_list.comp's u_ring (UNIFORM_LOCATION_CAST_RING): how far its rows
/// and columns passes reach, pixels_to_ray_cast's ring - 1.
inline constexpr int kUniformLocationCastRing = 6;
inline constexpr int kTextureUnitCertifyNearest = 1;
inline constexpr int kTextureUnitCertifyNearestOwner = 2;
inline constexpr int kTextureUnitCertifyOthers = 3;
inline constexpr int kTextureUnitCertifyCentreTriangle = 4;
inline constexpr int kTextureUnitTriangleObjects = 5;
inline constexpr int kTextureUnitObjectFacts = 6;
inline constexpr int kTextureUnitCertificates = 7;
inline constexpr int kTextureUnitCertifyCover = 8;
inline constexpr int kTextureUnitSlivers = 9;
inline constexpr int kTextureUnitUnlit = 10;
/// Every texture unit a shader binds, with its sampler's GLSL name and
/// the #define that carries it.
struct TextureUnit {
  const char* glsl_name;
  const char* define;
  int unit;
};
inline constexpr TextureUnit kTextureUnits[] = {
    {"u_shadow_map", "TEXTURE_UNIT_SHADOW_MAP", kTextureUnitShadowMap},
    // The conservative maps (certify.frag): nearest depth and its owner,
    // the others' nearest depth, the triangle at each texel centre.
    {"u_nearest", "TEXTURE_UNIT_CERTIFY_NEAREST", kTextureUnitCertifyNearest},
    {"u_nearest_owner", "TEXTURE_UNIT_CERTIFY_NEAREST_OWNER", kTextureUnitCertifyNearestOwner},
    {"u_others", "TEXTURE_UNIT_CERTIFY_OTHERS", kTextureUnitCertifyOthers},
    {"u_centre_triangle", "TEXTURE_UNIT_CERTIFY_CENTRE_TRIANGLE", kTextureUnitCertifyCentreTriangle},
    // The cover map (ConservativeBand::cover_depth; far where not drawn).
    {"u_cover", "TEXTURE_UNIT_CERTIFY_COVER", kTextureUnitCertifyCover},
    // Buffer textures of the scene: each triangle's object, each object's facts.
    {"u_triangle_objects", "TEXTURE_UNIT_TRIANGLE_OBJECTS", kTextureUnitTriangleObjects},
    {"u_object_facts", "TEXTURE_UNIT_OBJECT_FACTS", kTextureUnitObjectFacts},
    // The main pass's certificates, read by the sliver pass (sliver.frag).
    {"u_certificates", "TEXTURE_UNIT_CERTIFICATES", kTextureUnitCertificates},
    // The sliver pass's marks and the unlit colours, read where the GPU
    // lists the pixels to ray cast (cast_list.comp).
    {"u_slivers", "TEXTURE_UNIT_SLIVERS", kTextureUnitSlivers},
    {"u_unlit", "TEXTURE_UNIT_UNLIT", kTextureUnitUnlit},
};
/// cast_list.comp's images (R8UI, the display's size): each pass reads the
/// last one's marks from u_cast_in (IMAGE_UNIT_CAST_IN) and writes its own
/// to u_cast_out (IMAGE_UNIT_CAST_OUT).
inline constexpr TextureUnit kImageUnits[] = {
    {"u_cast_in", "IMAGE_UNIT_CAST_IN", 0},
    {"u_cast_out", "IMAGE_UNIT_CAST_OUT", 1},
};
/// cast_list.comp's output, the shader storage block CastList
/// (STORAGE_BUFFER_CAST_LIST): a count, three words of padding, then per
/// pixel listed a ListedPixel (core/render_result.hpp: uvec2 index, unlit).
inline constexpr int kStorageBufferCastList = 0;
inline constexpr std::size_t kCastListHeaderBytes = 16;
static_assert(kCastListHeaderBytes % 8 == 0, "the list's entries (8 bytes) are read with its header");
/// cast_list.comp's passes (CAST_PASS): the pixels beside a change of
/// surface, those within the ring along rows, and the list (columns, the
/// uncertain and the marked pixels).
enum class CastPass { Edges = 0, Rows = 1, List = 2 };
/// The widest dilation the GPU lists (pixels_to_ray_cast's ring - 1): a
/// loop of 2r + 1 reads a pixel per pass. Wider rings (a curved shape seen
/// from very close) are found on the CPU from the read-back certificates.
inline constexpr int kMostListedRing = 32;
/// certificate.glsl's object facts: flags in z (OBJECT_FLAG_MODEL, OBJECT_FLAG_CLOSED).
inline constexpr int kObjectFlagModel = 1;
inline constexpr int kObjectFlagClosed = 2;
/// certify.frag's passes (CERTIFY_PASS: CERTIFY_CENTRE, _NEAREST, _OTHERS).
enum class CertifyPass { Centre = 0, Nearest = 1, Others = 2 };
/// CULL_CLOSED_BACK: the conservative passes leave out the faces of closed
/// shapes that clearly turn from the light (ShadowPassPlan::cull_closed_back).
std::string variant_defines(CertifyPass pass, bool perspective, bool cull_closed_back);
/// Per object of `scene`, certificate.glsl's facts (4 floats each), for
/// positions relative to `origin`.
std::vector<glm::vec4> object_facts(const Scene& scene, const glm::dvec3& origin);

// ---------------------------------------------------------------------------
// The uniform block, one per frame, shared by every program (binding
// kUniformBufferFrameBlock).
//
// std140 puts each member at an offset that GL reports; the C++ struct must
// agree. Members are mat4, vec4, vec2, float or int, and arrays only of mat4
// and vec4 (std140 strides other arrays to 16 bytes). Positions are relative
// to the mesh origin (see Mesh::origin), lengths in world units.
//
// UMBRA_FRAME_BLOCK(MEMBER, ARRAY) lists them: MEMBER(type, name),
// ARRAY(type, name, count).
#define UMBRA_FRAME_BLOCK(MEMBER, ARRAY)                                                            \
  /* The camera: origin-relative view-projection (reversed depth, see */                         \
  /* reversed_depth_projection), and its position. */                                             \
  MEMBER(mat4, camera_view_projection)                                                             \
  MEMBER(vec4, camera_position)                                                                    \
  /* The light: position (a point light's), unit direction of travel */                           \
  /* (position -> target), linear RGB colour with the ambient fraction in w. */                   \
  MEMBER(vec4, light_position)                                                                     \
  MEMBER(vec4, light_direction)                                                                    \
  MEMBER(vec4, light_color_ambient)                                                                \
  /* One entry per view of the light (layer of the map). All views but */                        \
  /* cube faces share light_view[0]. */                                                           \
  ARRAY(mat4, light_view, kMaxViews)                                                               \
  ARRAY(mat4, light_projection, kMaxViews)                                                    \
  /* x, y: near and far planes, world units along the view's axis. */                             \
  /* z, w: orthographic: world size of one texel along light x and y; */                          \
  /*       perspective: z = that size per unit of distance, w = tan(half fov). */                 \
  ARRAY(vec4, view_depth_texel, kMaxViews)                                                         \
  /* xy, zw: the texel rectangle (min, max) of the view's layer that the */                       \
  /* shadow pass drew anything into (caster_texels); none: 1e30, -1e30. */                        \
  ARRAY(vec4, view_casters, kMaxViews)                                                             \
  /* The seeds' explicit bias (BIAS_AUTO 0): constant and slope in window */                      \
  /* depth, normal offset in texels. */                                                           \
  MEMBER(float, bias_constant)                                                                     \
  MEMBER(float, bias_slope)                                                                        \
  MEMBER(float, bias_normal_offset)                                                                \
  /* PCSS: orthographic: tan(half the angular diameter); perspective: radius. */                  \
  MEMBER(float, light_size)                                                                        \
  /* Shadow map texels per side. */                                                               \
  MEMBER(float, map_size)                                                                          \
  /* Filter "exact": the conservative maps' texels per side (certified_map_size). */             \
  MEMBER(float, certified_map_size)                                                                \
  /* A point light: Mesh::smooth_normal_span, which LIGHT_SIDE's facing */                        \
  /* test allows for (scene.vert); 0 for a directional light. */                                  \
  MEMBER(float, smooth_normal_span)                                                                \
  /* Depth preview: the preview's side in pixels, and tiles per row */                            \
  /* (preview_tiles_per_row). */                                                                  \
  MEMBER(float, preview_size)                                                                      \
  MEMBER(int, preview_grid)                                                                        \
  /* Filter "exact": the camera's unit view direction with its near plane */                      \
  /* in w, its far plane, and the mesh origin in world units (positions */                        \
  /* are relative to it; the reference's offsets grow with the world's). */                       \
  MEMBER(vec4, camera_axis_near)                                                                   \
  MEMBER(vec4, mesh_origin_far)                                                                    \
  /* The image's width and height, pixels (the sliver pass). */                                   \
  MEMBER(vec2, image_size)

namespace std140 {
// The GLSL type names used above, as C++ types of the same std140 size.
using glm::mat4;
using glm::vec2;
using glm::vec4;
// std140 base alignment of each of them.
template <class T> inline constexpr std::size_t alignment = 16;
template <> inline constexpr std::size_t alignment<vec2> = 8;
template <> inline constexpr std::size_t alignment<float> = 4;
template <> inline constexpr std::size_t alignment<int> = 4;

struct FrameBlock {
#define UMBRA_CXX_MEMBER(type, name) alignas(alignment<type>) type name{};
#define UMBRA_CXX_ARRAY(type, name, count) alignas(16) type name[count]{};
  UMBRA_FRAME_BLOCK(UMBRA_CXX_MEMBER, UMBRA_CXX_ARRAY)
#undef UMBRA_CXX_MEMBER
#undef UMBRA_CXX_ARRAY
};
}  // namespace std140
using std140::FrameBlock;

/// One member of FrameBlock as GL names it, with its C++ offset.
struct BlockMember {
  const char* gl_name;  // e.g. "FrameBlock.light_view[0]"
  std::size_t offset;
  std::size_t array_stride;  // 0 for a single member
};
/// Every member of FrameBlock, in order, for gl::check_block_layout.
const BlockMember* frame_block_members(std::size_t& count);

// ---------------------------------------------------------------------------
// Variants (plan/shader_variants.hpp decides them): each switch becomes a
// compile-time #define here.

/// The #define lines that select `v`.
std::string variant_defines(const DisplayVariant& v);
std::string variant_defines(const PreviewVariant& v);

/// The block's contents for `request` drawn with the light's views in
/// `plan`, positions relative to mesh.origin; `casters`: one per view, where
/// its layer holds anything (caster_texels).
FrameBlock frame_block(const RenderRequest& request, const ShadowPlan& plan, const Mesh& mesh,
                       const std::vector<TexelRect>& casters);

/// What every program's source starts with: the GLSL version, the shared
/// constants and bindings, `extra_defines`, and the FrameBlock declaration.
std::string glsl_prelude(const std::string& extra_defines);

}  // namespace umbra
