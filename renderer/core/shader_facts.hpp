// Facts that the light math and the shaders both depend on, written once.
//
// The shaders get each of these as a #define of the same name from
// glsl_prelude (gpu/shader_interface.cpp), and tests/test_shader_interface.cpp
// holds the two to each other, as Magnum's Shaders/generic.glsl and
// GenericGL_Test do. Pure: no GL, nothing but constants and constexpr
// functions, so that core/ can use them without including the GPU layer.
#pragma once

namespace umbra {

/// Views of one light that the shaders hold: up to kMaxCascades cascades
/// (core/light_math.hpp), or the kCubeFaceCount cube faces.
inline constexpr int kMaxViews = 6;

/// PCSS: how far the blocker search reaches, texels; and the widest
/// penumbra it filters, texels. A view must hold a point with the search's
/// reach to spare (see filter_reach_texels), and the texels around a point
/// that the filter reads are bounded by both (filter_read_texels).
inline constexpr int kPcssSearchTexels = 32;
inline constexpr int kPcssMaxPenumbraTexels = 64;
/// PCSS: samples of the blocker search and of the filter (scene.frag's
/// loops; the cost model counts them too).
inline constexpr int kPcssBlockerSamples = 16;
inline constexpr int kPcssFilterSamples = 32;

/// A point light's cube faces, one map layer each, in this order: +X, -X,
/// +Y, -Y, +Z, -Z. Face (axis, negative) is layer 2 * axis + negative, so
/// that cube_face_view (light_math) draws each face into the layer that
/// scene.frag's pick by major axis reads (CUBE_FACE in GLSL).
inline constexpr int kCubeFaceCount = 6;
constexpr int cube_face(int axis, bool negative) { return 2 * axis + (negative ? 1 : 0); }
/// The axis (0 x, 1 y, 2 z) a face looks along, and whether towards minus.
constexpr int cube_face_axis(int face) { return face / 2; }
constexpr bool cube_face_negative(int face) { return face % 2 != 0; }
/// Each face's name, in layer order, as the depth preview's tiles are labelled.
inline constexpr const char* kCubeFaceNames[kCubeFaceCount] = {"+X", "-X", "+Y", "-Y", "+Z", "-Z"};

/// The depth preview shows `views` layers as a square grid of tiles, layer
/// 0 top left, row by row: this many tiles per row (and rows at most),
/// the smallest n with n * n >= views (depth_preview.frag reads it from the
/// frame block; the response header Umbra-Shadow-Views carries it to the
/// panel).
constexpr int preview_tiles_per_row(int views) {
  int n = 1;
  while (n * n < views) ++n;
  return n;
}

static_assert(kCubeFaceCount <= kMaxViews, "the shaders must hold every cube face");

}  // namespace umbra
