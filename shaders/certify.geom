// Conservative rasterisation of the light's view, for filter "exact"
// (docs/certified-shadows.md): every texel that a triangle touches
// anywhere, not only those whose centre it covers, gets a fragment, and
// certify.frag gives it the nearest depth the triangle reaches inside that
// texel. A needle thinner than a texel is therefore never missed.
//
// Each triangle becomes one quad: the bounding box of its projection,
// grown by half a texel and a margin for rounding, clamped to the layer.
// certify.frag drops the texels of the box that a separating edge shows
// the triangle does not touch. A point light's triangle is first clipped
// to the half-space in front of the light (w > 0): the part behind the
// light cannot lie between it and any point it lights.
#include "certificate.glsl"
layout(triangles) in;
layout(triangle_strip, max_vertices = 4) out;

layout(location = UNIFORM_LOCATION_LAYER) uniform int u_layer;
layout(location = UNIFORM_LOCATION_TRIANGLE_BASE) uniform int u_triangle_base;

// The polygon (the triangle, or the triangle clipped: up to 4 corners) in
// texel units of the layer, counter-clockwise; fewer than 3 distinct edges
// or no area: g_edge_count 0 (the box alone is tested).
flat out vec2 g_corner[4];
flat out int g_edge_count;
// Window depth over the layer where the triangle's plane is: depth =
// g_plane.z + g_plane.x * (x - g_origin.x) + g_plane.y * (y - g_origin.y),
// x, y in texels; g_plane_valid 0 where the projection has no area (a
// triangle seen edge-on).
flat out vec3 g_plane;
flat out vec2 g_origin;
flat out int g_plane_valid;
// The least window depth of the polygon's corners: no point of it is nearer.
flat out float g_min_depth;
// How far the shape's true surface may reach beyond this face (its
// tessellation distance), in texels sideways and in window depth towards
// the light: certify.frag swells the triangle by it.
flat out float g_swell;
flat out float g_depth_swell;
// The triangle's owner (certificate.glsl), found once per triangle here
// rather than per texel.
flat out uint g_owner;

// Texel units and window depth of a clip-space point.
vec3 to_texels(vec4 clip) {
  vec3 ndc = clip.xyz / clip.w;
  return vec3((ndc.xy * 0.5 + 0.5) * u.certified_map_size, ndc.z * 0.5 + 0.5);
}

void main() {
  // The polygon in clip space: clipped to w >= w_min (a point light) by one
  // Sutherland-Hodgman step; an orthographic view's w is 1 everywhere.
  vec4 in_clip[3] = vec4[3](gl_in[0].gl_Position, gl_in[1].gl_Position, gl_in[2].gl_Position);
  vec4 poly[4];
  int n = 0;
#if LIGHT_PERSPECTIVE
  // Half the view's near plane: a fitted view's near plane lies before
  // everything inside its frustum (lights/point.cpp), so no part of a
  // triangle nearer than this falls on the layer; the parser refuses
  // filter "exact" with a fixed frustum for a point light.
  float w_min = 0.5 * u.view_depth_texel[u_layer].x;
  for (int i = 0; i < 3; ++i) {
    vec4 a = in_clip[i], b = in_clip[(i + 1) % 3];
    bool a_in = a.w >= w_min, b_in = b.w >= w_min;
    if (a_in) poly[n++] = a;
    if (a_in != b_in) {
      float t = (w_min - a.w) / (b.w - a.w);
      poly[n++] = mix(a, b, t);
    }
  }
  if (n < 3) return;  // wholly behind the light
#else
  for (int i = 0; i < 3; ++i) poly[i] = in_clip[i];
  n = 3;
#endif
  vec3 p[4];
  vec2 lo = vec2(1e30), hi = vec2(-1e30);
  float min_depth = 1e30;
  for (int i = 0; i < n; ++i) {
    p[i] = to_texels(poly[i]);
    lo = min(lo, p[i].xy);
    hi = max(hi, p[i].xy);
    min_depth = min(min_depth, p[i].z);
  }
  // Off the layer: no texel to mark.
  if (hi.x < -1.0 || hi.y < -1.0 || lo.x > u.certified_map_size + 1.0 || lo.y > u.certified_map_size + 1.0) return;
  // Orientation, for outward edge normals.
  float area = 0.0;
  for (int i = 0; i < n; ++i) {
    vec2 a = p[i].xy, b = p[(i + 1) % n].xy;
    area += a.x * b.y - b.x * a.y;
  }
  float extent = max(max(abs(lo.x), abs(lo.y)), max(abs(hi.x), abs(hi.y)));
  int triangle = u_triangle_base + gl_PrimitiveIDIn;
  uvec2 ids = triangle_ids(triangle);
  vec4 facts = object_facts(ids.x);
  // Which way the face turns on the layer (counter-clockwise: its outward
  // side to the light), only where it is clear: its area taken from edge
  // vectors (a fan from the first corner, so that rounding scales with the
  // edges, not with the corners' distance from the layer's origin, as the
  // shoelace sum's products' does: a red-team pass saw a face turned to
  // the light come out clockwise that way), beyond its rounding: each
  // corner's texel coordinates off by up to about 4e-7 of the extent (the
  // projection's float steps) times the perimeter, and the products' own
  // rounding (2^-24 of the edges' lengths multiplied), both with tenfold
  // headroom.
  float perimeter = 0.0, fan_area = 0.0;
  for (int i = 0; i < n; ++i) perimeter += length(p[(i + 1) % n].xy - p[i].xy);
  for (int i = 1; i + 1 < n; ++i) {
    vec2 e1 = p[i].xy - p[0].xy, e2 = p[i + 1].xy - p[0].xy;
    fan_area += e1.x * e2.y - e1.y * e2.x;
  }
  float fan_rounding = 4e-6 * max(1.0, extent) * perimeter + 1e-6 * perimeter * perimeter;
#if CULL_CLOSED_BACK
  // A face of a closed shape (box, sphere, cylinder: convex) that turns
  // from the light: whatever of the shape lies on a point's ray to the
  // light, the ray leaves the shape last through a face turned to it, which
  // lies nearer the light in the same texel (the light is outside every
  // closed object: ShadowPassPlan::cull_closed_back).
  if (has_flag(facts, OBJECT_FLAG_CLOSED) && !has_flag(facts, OBJECT_FLAG_MODEL) && fan_area < -fan_rounding)
    return;
#endif
  // Below this the polygon is a sliver whose edge normals rounding can
  // turn around: only its box is trusted.
  bool has_area = abs(area) > 1e-4 * max(1.0, extent);
  g_edge_count = has_area ? n : 0;
  for (int i = 0; i < 4; ++i) {
    int k = area >= 0.0 ? i : n - 1 - i;  // counter-clockwise
    g_corner[i] = i < n ? p[k].xy : vec2(0.0);
  }
  // The plane through three of the polygon's corners (all in front of the
  // light; clipping keeps the triangle's plane): the best-conditioned triple.
  vec3 a = p[0], b = p[1], c = p[2];
  vec2 ab = b.xy - a.xy, ac = c.xy - a.xy;
  float det = ab.x * ac.y - ab.y * ac.x;
  if (n == 4) {
    vec2 ad = p[3].xy - a.xy;
    float det2 = ac.x * ad.y - ac.y * ad.x;
    if (abs(det2) > abs(det)) {
      b = p[2];
      c = p[3];
      ab = b.xy - a.xy;
      ac = c.xy - a.xy;
      det = det2;
    }
  }
  // A polygon that reaches past 2^16 texels (a triangle clipped next to a
  // point light: its cut corners land millions of texels off the layer)
  // has corners rounded by more than 1/128 texel in float, and a plane
  // through them is no bound on the layer (a red-team pass: an open
  // cylinder around a point light, 26 floor pixels proved lit; the CPU's
  // double held). Its nearest corner's depth alone is.
  g_plane_valid = abs(det) > 1e-6 * max(1.0, dot(ab, ab) + dot(ac, ac)) && extent <= 65536.0 ? 1 : 0;
  if (g_plane_valid == 1) {
    float dzb = b.z - a.z, dzc = c.z - a.z;
    g_plane = vec3((dzb * ac.y - dzc * ab.y) / det, (dzc * ab.x - dzb * ac.x) / det, a.z);
  } else {
    g_plane = vec3(0.0, 0.0, a.z);
  }
  g_origin = a.xy;
  g_min_depth = min_depth;
  // A model's face is its patch's only where it clearly turns to the light.
  g_owner = owner_of(triangle, ids, facts, fan_area > fan_rounding);
  // A curved shape's faces are chords: its true surface, which the
  // reference casts against, reaches up to its tessellation distance
  // beyond them (ShapeKind::tessellation_error). Measured where that is
  // most: a texel of this map at the polygon's nearest depth, window depth
  // where it changes fastest, and a point light's off-axis projection.
  // And the light view's rounding of its corners (about 1e-6 of the
  // coordinates involved: light_view_rounding).
  float swell_world = facts.x + light_view_rounding(sqrt(3.0) * facts.w, length(u.light_view[u_layer][3].xyz));
  vec4 view = u.view_depth_texel[u_layer];
  float coarse_texels = u.map_size / u.certified_map_size;
#if LIGHT_PERSPECTIVE
  float nearest_w = 1e30;
  for (int i = 0; i < n; ++i) nearest_w = min(nearest_w, poly[i].w);
  float texel_world = view.z * nearest_w * coarse_texels / (1.0 + 2.0 * view.w);
  float window_per_world = view.x * view.y / ((view.y - view.x) * nearest_w * nearest_w);
#else
  float texel_world = min(view.z, view.w) * coarse_texels;
  float window_per_world = 1.0 / (view.y - view.x);
#endif
  g_swell = swell_world / texel_world;
  g_depth_swell = swell_world * window_per_world;
  // The box, half a texel, the swell and a rounding margin wider, clamped
  // to the layer and a texel beyond it.
  // (The rasteriser snaps the box's corners to a fraction of a texel,
  // llvmpipe 1/256: the margin is well above it.)
  float margin = 0.5 + g_swell + 1.0 / 32.0 + 1e-6 * extent;
  lo = clamp(lo - margin, vec2(-1.0), vec2(u.certified_map_size + 1.0));
  hi = clamp(hi + margin, vec2(-1.0), vec2(u.certified_map_size + 1.0));
  vec2 corners[4] = vec2[4](lo, vec2(hi.x, lo.y), vec2(lo.x, hi.y), hi);
  // Outputs are undefined after EmitVertex (GLSL 4.50, 8.15): every vertex
  // writes the flat ones again, so that whichever vertex provokes them
  // carries them.
  vec2 corner[4] = g_corner;
  int edge_count = g_edge_count, plane_valid = g_plane_valid;
  vec3 plane = g_plane;
  vec2 origin = g_origin;
  float min_depth_here = g_min_depth, swell = g_swell, depth_swell = g_depth_swell;
  uint owner = g_owner;
  for (int i = 0; i < 4; ++i) {
    g_corner = corner;
    g_edge_count = edge_count;
    g_plane_valid = plane_valid;
    g_plane = plane;
    g_origin = origin;
    g_min_depth = min_depth_here;
    g_swell = swell;
    g_depth_swell = depth_swell;
    g_owner = owner;
    // Depth is written by the fragment shader; z 0 keeps the quad from
    // being clipped by the view's near and far planes.
    gl_Position = vec4(corners[i] / u.certified_map_size * 2.0 - 1.0, 0.0, 1.0);
    EmitVertex();
  }
  EndPrimitive();
}
