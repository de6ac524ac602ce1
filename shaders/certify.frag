// Filter "exact"'s maps of the light's view (docs/certified-shadows.md),
// one program per CERTIFY_PASS:
// - CERTIFY_CENTRE: the map as the other filters draw it (depth at texel
//   centres), with the triangle seen at each centre (index + 1; 0 none);
// - CERTIFY_NEAREST: conservative (certify.geom): the nearest window depth
//   any triangle reaches anywhere in each texel, and that triangle's owner;
// - CERTIFY_OTHERS: the same, leaving out the owner CERTIFY_NEAREST found:
//   the nearest depth of everything else.
#if CERTIFY_PASS == CERTIFY_CENTRE
layout(location = UNIFORM_LOCATION_TRIANGLE_BASE) uniform int u_triangle_base;
layout(location = FRAG_OUTPUT_COLOR) out uint o_triangle;

void main() { o_triangle = uint(u_triangle_base + gl_PrimitiveID) + 1u; }

#else
layout(location = UNIFORM_LOCATION_LAYER) uniform int u_layer;

flat in vec2 g_corner[4];
flat in int g_edge_count;
flat in vec3 g_plane;
flat in vec2 g_origin;
flat in int g_plane_valid;
flat in float g_min_depth;
flat in float g_swell;
flat in float g_depth_swell;
flat in uint g_owner;

#if CERTIFY_PASS == CERTIFY_NEAREST
layout(location = FRAG_OUTPUT_COLOR) out uint o_owner;
#else
layout(binding = TEXTURE_UNIT_CERTIFY_NEAREST_OWNER) uniform usampler2DArray u_nearest_owner;
#endif

void main() {
  // This texel: the square of side 1 about its centre.
  vec2 c = gl_FragCoord.xy;
  // A polygon edge whose outside holds the whole square, beyond the swell,
  // separates them: the triangle, and the true surface it stands for, touch
  // no point of this texel.
  for (int i = 0; i < g_edge_count; ++i) {
    vec2 a = g_corner[i], b = g_corner[(i + 1) % g_edge_count];
    vec2 n = vec2(b.y - a.y, a.x - b.x);  // outward: the polygon turns counter-clockwise
    vec2 d = c - a;
    float rounding = (abs(n.x) + abs(n.y)) * (1e-3 + 1e-6 * (abs(d.x) + abs(d.y))) + g_swell * length(n);
    if (dot(n, d) - 0.5 * (abs(n.x) + abs(n.y)) > rounding) discard;
  }
  // The least depth of the triangle's plane over the square, never less
  // than its nearest corner; less a margin for float rounding.
  float depth = g_min_depth;
  float rounding = 1e-6;
  if (g_plane_valid == 1) {
    vec2 d = c - g_origin;
    float slope = 0.5 * (abs(g_plane.x) + abs(g_plane.y));
    depth = max(depth, g_plane.z + g_plane.x * d.x + g_plane.y * d.y - slope);
    rounding += 4e-7 * (abs(g_plane.x * d.x) + abs(g_plane.y * d.y) + slope + abs(g_plane.z));
  }
  gl_FragDepth = clamp(depth - rounding - g_depth_swell, 0.0, 1.0);
#if CERTIFY_PASS == CERTIFY_NEAREST
  o_owner = g_owner;
#else
  if (g_owner == texelFetch(u_nearest_owner, ivec3(ivec2(c), u_layer), 0).r) discard;
#endif
}
#endif
