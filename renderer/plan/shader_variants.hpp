// The shader variants a frame draws with: the main pass's switches and the
// depth preview's, decided from the request and the light's views. Pure: the
// GLSL text they become is gpu/shader_interface.hpp's.
#pragma once

#include <string>

#include "core/light_math.hpp"
#include "core/request.hpp"

namespace umbra {

// ---------------------------------------------------------------------------
// Variants: each switch is a compile-time #define (gpu/shader_interface.hpp's
// variant_defines), so the shader has no branch on a uniform (a software
// rasteriser runs both sides of a branch it cannot prove uniform, and
// cannot fold it away) and every loop has a constant trip count. Which
// variant a frame draws with is the frame plan's decision, made here
// without GL.

/// The main pass's variant for one frame.
struct DisplayVariant {
  bool shadows = true;          // SHADOWS: 0 draws no shadow term at all
  bool direct_light = true;     // DIRECT_LIGHT: 0 (a sun below the horizon): ambient only, visibility 0
  bool shadow_output = false;   // OUTPUT_SHADOW: visibility as grey, not colour
  bool perspective = false;     // LIGHT_PERSPECTIVE: point light
  bool cube = false;            // LIGHT_CUBE: six faces, picked by major axis
  int view_count = 1;           // VIEW_COUNT: 1..kMaxViews
  ShadowFilter filter = ShadowFilter::Pcf;  // FILTER: FILTER_HARD / _PCF / _PCSS
  int pcf_radius = 1;           // PCF_RADIUS: 0..8
  bool bias_auto = true;        // BIAS_AUTO: receiver plane vs the seeds' bias
  int filter_reach = 2;         // FILTER_REACH: see filter_reach_texels
  int filter_read = 3;          // FILTER_READ: see filter_read_texels
  /// LIGHT_SIDE: closed meshes are drawn in two parts, split where their
  /// points may start to face the light (scene.vert): 1 the part that may
  /// face it, -1 the part that cannot (lit by ambient only, visibility 0),
  /// 0 whole (everything else).
  int light_side = 0;
  /// CERTIFICATES: filter "exact" (shadows on, not the depth output): the
  /// main pass also writes each pixel's verdict and unlit colour
  /// (PixelCertificates), with the lookup (FILTER_EXACT) or, under a sun
  /// below the horizon, without one (everything dark).
  bool certificates = false;
  /// PROOF: with certificates and no lookup, a plane's part that the frame
  /// plan proved lit (1) or dark (-1) by geometry alone; 0 none.
  int proof = 0;
};

/// The main pass's variant for `request` drawn with the light's views in
/// `plan`. Switches that cannot matter are left at their defaults (no shadow
/// pass: no filter), so equal frames share one program.
DisplayVariant display_variant(const RenderRequest& request, const ShadowPlan& plan);

/// `v` with no shadow term (and the shadow switches at their defaults, as
/// display_variant leaves them): the program for points no caster can
/// shadow, the same one a frame without shadows uses.
DisplayVariant without_shadows(const DisplayVariant& v);

/// The depth preview's variant.
struct PreviewVariant {
  bool perspective = false;  // LIGHT_PERSPECTIVE: linearise the stored depth
  int view_count = 1;        // VIEW_COUNT: tiles drawn
};

}  // namespace umbra
