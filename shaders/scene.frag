#version 450 core
// Main pass: Blinn-Phong lighting with a shadow-mapped direct term.
//
//   colour = (ambient + visibility * (diffuse + specular)) * albedo
//
// Ambient is never shadowed (it stands for light scattered around the
// scene); `visibility` in [0, 1] is the fraction of the light's direct light
// that reaches the surface, and is also what the "shadow" output shows.
in vec3 v_position;  // relative to the mesh origin
in vec3 v_normal;
in vec3 v_color;

layout(location = 0) out vec4 o_color;

// ---- light (positions relative to the mesh origin) ----
uniform bool u_light_perspective;  // false: directional light, true: point light
uniform vec3 u_light_position;
uniform vec3 u_light_direction;    // unit direction of travel, position -> target
uniform vec3 u_light_color;        // linear RGB
uniform float u_ambient;           // fraction of the light that is ambient
uniform vec3 u_camera_position;

// ---- shadow map: one layer per view of the light ----
// A light has one view, or several: cascades (a directional light, nearest
// camera depths first) or cube faces (a point light). Each point uses the
// first view whose map holds it with its filter kernel.
const int kMaxViews = 6;
uniform bool u_shadows_enabled;
uniform sampler2DArray u_shadow_map;  // window depth in [0,1], nearest, no compare
uniform int u_view_count;
uniform int u_filter_reach;           // texels a filter reads around its own
uniform mat4 u_light_view[kMaxViews];
uniform mat4 u_light_view_projection[kMaxViews];
uniform float u_light_near[kMaxViews];  // clip planes, world units along the view's axis
uniform float u_light_far[kMaxViews];
// Orthographic: world size of one texel in light x and y.
// Perspective: x = y = world size of one texel per unit of distance, and
// u_tan_half the tangent of half the field of view.
uniform vec2 u_texel_size[kMaxViews];
uniform float u_tan_half[kMaxViews];
uniform int u_filter;              // 0 hard, 1 pcf, 2 pcss
uniform int u_pcf_radius;          // pcf: (2r+1)^2 bilinear taps
uniform bool u_bias_auto;
uniform float u_bias_constant;     // explicit bias, window-depth units (the seeds')
uniform float u_bias_slope;        // explicit bias, window-depth units * (1 - N.L)
uniform float u_bias_normal_offset;// explicit bias, texels along the normal
// pcss: orthographic: tan(half the angular diameter); perspective: radius.
uniform float u_light_size;

uniform int u_output;              // 0: lit colour, 1: visibility as grey

// The view chosen for the point being shaded (see choose_view).
int g_layer = 0;
float g_near = 1.0;
float g_far = 2.0;
vec2 g_texel_size = vec2(0.0);
float g_tan_half = 0.0;

// ---------------------------------------------------------------------------
// Depth conversions between the depth buffer's window depth and linear depth
// (world units along the light's axis).
float linear_from_window(float z) {
  float n = g_near, f = g_far;
  return u_light_perspective ? n * f / (f - z * (f - n)) : n + z * (f - n);
}

float window_from_linear(float d) {
  float n = g_near, f = g_far;
  return u_light_perspective ? f * (d - n) / (d * (f - n)) : (d - n) / (f - n);
}

// ---------------------------------------------------------------------------
// The receiver: the surface point being shaded, as the shadow map sees it.
//
// Instead of one depth with a guessed bias, the receiver's own plane (from
// the triangle's true normal) gives its exact depth along the light ray
// through any texel centre: each texel is compared with the receiver where
// that texel actually looks. This removes acne on planar surfaces at any
// slope without the large slope bias that causes peter panning, and it keeps
// PCF kernels of any radius correct on tilted receivers.
struct Receiver {
  vec2 texel;        // position in texel units (uv * map size)
  float depth;       // linear depth of the point itself
  vec3 view_point;   // the point in light view space
  vec3 view_normal;  // its plane's normal in light view space
  float window_ref;  // explicit bias only: the seeds' window-depth reference
};

float receiver_depth_at(Receiver r, vec2 texel_center) {
  if (!u_bias_auto) return linear_from_window(r.window_ref);
  vec3 n = r.view_normal;
  if (u_light_perspective) {
    // The ray through the texel centre is depth * (a, b, -1); it meets the
    // plane n.(x - p) = 0 at depth = n.p / (n.(a, b, -1)). Rays nearly
    // parallel to the plane are kept from running off to infinity.
    vec3 ray = vec3(texel_center * g_texel_size - vec2(g_tan_half), -1.0);
    float denominator = dot(n, ray);
    float limit = 0.02 * length(ray);
    if (abs(denominator) < limit) denominator = denominator < 0.0 ? -limit : limit;
    float depth = dot(n, r.view_point) / denominator;
    return depth > 0.0 ? depth : r.depth;
  }
  // Orthographic: depth is affine in the texel position. Grazing planes
  // (n.z -> 0) are kept from extrapolating to infinity.
  float nz = n.z < 0.0 ? min(n.z, -0.02) : max(n.z, 0.02);
  vec2 offset = (texel_center - r.texel) * g_texel_size;
  return r.depth + dot(n.xy, offset) / nz;
}

// Depth stored in texel t (linear); outside the map counts as the far plane,
// which is what CLAMP_TO_BORDER with border depth 1 gives a sampler.
float stored_depth(ivec2 t) {
  ivec2 size = textureSize(u_shadow_map, 0).xy;
  if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, size))) return g_far;
  return linear_from_window(texelFetch(u_shadow_map, ivec3(t, g_layer), 0).r);
}

// The bias that remains once each texel is compared with the receiver's own
// plane: float precision of the depth buffer and of interpolated positions.
float remaining_bias(Receiver r) {
  float texel_world = u_light_perspective ? g_texel_size.x * r.depth : max(g_texel_size.x, g_texel_size.y);
  float precision_bias = u_light_perspective
      ? 4.0 * 6e-8 * r.depth * r.depth / g_near   // window-depth ulp near z = 1, linearised
      : 4.0 * 6e-8 * (g_far - g_near);
  return 0.05 * texel_world + precision_bias + 1e-6 * abs(r.depth);
}

// 1 where texel t does not occlude the receiver, 0 where it does.
float lit_by_texel(Receiver r, ivec2 t, float bias) {
  float reference = receiver_depth_at(r, vec2(t) + 0.5) - bias;
  return stored_depth(t) < reference ? 0.0 : 1.0;
}

// Bilinearly weighted percentage-closer filter: (2r+1)^2 bilinear taps one
// texel apart are the same as a tent-weighted sum over (2r+2)^2 texels.
float pcf(Receiver r, int radius, float bias) {
  vec2 base = r.texel - 0.5;
  ivec2 origin = ivec2(floor(base));
  vec2 f = base - floor(base);
  float sum = 0.0;
  for (int j = -radius; j <= radius + 1; ++j) {
    float wy = j == -radius ? 1.0 - f.y : (j == radius + 1 ? f.y : 1.0);
    for (int i = -radius; i <= radius + 1; ++i) {
      float wx = i == -radius ? 1.0 - f.x : (i == radius + 1 ? f.x : 1.0);
      sum += wx * wy * lit_by_texel(r, origin + ivec2(i, j), bias);
    }
  }
  float taps = float(2 * radius + 1);
  return sum / (taps * taps);
}

// A well-spread disk of sample points (Vogel spiral), rotated per pixel so
// that too few samples show as fine grain rather than as banding.
vec2 disk_sample(int i, int count, float rotation) {
  float radius = sqrt((float(i) + 0.5) / float(count));
  float angle = float(i) * 2.39996323 + rotation;
  return radius * vec2(cos(angle), sin(angle));
}

float pixel_rotation() {
  return 6.2831853 * fract(52.9829189 * fract(dot(gl_FragCoord.xy, vec2(0.06711056, 0.00583715))));
}

// Radius, in texels, of the region of the map through which the light's disc
// is seen from the receiver, at linear depth d of the map (d < receiver).
vec2 light_footprint_texels(Receiver r, float d) {
  if (u_light_perspective) {
    float angular = u_light_size * (r.depth - d) / (r.depth * max(d, g_near));
    return vec2(angular / g_texel_size.x);
  }
  return vec2((r.depth - d) * u_light_size) / g_texel_size;
}

// Percentage-closer soft shadows: find the average blocker depth, then
// filter over the region the light's disc covers at that depth.
float pcss(Receiver r, float bias) {
  const int kBlockerSamples = 16;
  const int kFilterSamples = 32;
  float rotation = pixel_rotation();
  vec2 search = min(light_footprint_texels(r, g_near), vec2(32.0));
  float blocker_sum = 0.0;
  int blockers = 0;
  for (int i = 0; i < kBlockerSamples; ++i) {
    vec2 p = r.texel + disk_sample(i, kBlockerSamples, rotation) * search;
    ivec2 t = ivec2(floor(p));
    float stored = stored_depth(t);
    if (stored < receiver_depth_at(r, vec2(t) + 0.5) - bias) {
      blocker_sum += stored;
      ++blockers;
    }
  }
  if (blockers == 0) return 1.0;
  vec2 penumbra = min(light_footprint_texels(r, blocker_sum / float(blockers)), vec2(64.0));
  if (max(penumbra.x, penumbra.y) < 1.0) return pcf(r, 0, bias);
  float sum = 0.0;
  for (int i = 0; i < kFilterSamples; ++i) {
    vec2 p = r.texel + disk_sample(i, kFilterSamples, rotation) * penumbra;
    sum += lit_by_texel(r, ivec2(floor(p)), bias);
  }
  return sum / float(kFilterSamples);
}

// The first view whose map holds p with the filter's reach to spare; else
// the first that holds p at all; -1 if none does.
int choose_view(vec3 p) {
  vec2 map_size = vec2(textureSize(u_shadow_map, 0).xy);
  vec2 reach = vec2(float(u_filter_reach));
  int fallback = -1;
  for (int i = 0; i < u_view_count; ++i) {
    vec4 clip = u_light_view_projection[i] * vec4(p, 1.0);
    if (clip.w <= 0.0) continue;  // behind a point light's view
    vec3 ndc = clip.xyz / clip.w;
    if (any(greaterThan(abs(ndc), vec3(1.0)))) continue;
    vec2 texel = (ndc.xy * 0.5 + 0.5) * map_size;
    if (all(greaterThanEqual(texel, reach)) && all(lessThanEqual(texel, map_size - reach))) return i;
    if (fallback < 0) fallback = i;
  }
  return fallback;
}

// Fraction of the direct light reaching point p (1 lit, 0 shadowed).
float shadow_visibility(vec3 p, vec3 geometric_normal, float n_dot_l) {
  if (!u_shadows_enabled) return 1.0;
  // Outside every view (beside the light's frustum, before near, beyond
  // far): nothing in the map can shadow the point, so it is lit (the seeds'
  // far-plane fix).
  int layer = choose_view(p);
  if (layer < 0) return 1.0;
  g_layer = layer;
  g_near = u_light_near[layer];
  g_far = u_light_far[layer];
  g_texel_size = u_texel_size[layer];
  g_tan_half = u_tan_half[layer];

  vec2 map_size = vec2(textureSize(u_shadow_map, 0).xy);
  Receiver r;
  r.view_point = (u_light_view[layer] * vec4(p, 1.0)).xyz;
  r.view_normal = normalize(mat3(u_light_view[layer]) * geometric_normal);
  r.depth = -r.view_point.z;
  r.window_ref = 0.0;
  vec3 lookup_point = p;
  if (!u_bias_auto) {
    // The seeds' bias: move the receiver along its normal, then compare in
    // window depth with max(slope * (1 - N.L), constant) subtracted.
    float texel_world = u_light_perspective ? g_texel_size.x * r.depth : max(g_texel_size.x, g_texel_size.y);
    lookup_point = p + geometric_normal * (u_bias_normal_offset * texel_world);
  }
  vec4 clip = u_light_view_projection[layer] * vec4(lookup_point, 1.0);
  if (clip.w <= 0.0) return 1.0;
  vec3 ndc = clip.xyz / clip.w;
  if (any(greaterThan(abs(ndc), vec3(1.0)))) return 1.0;
  r.texel = (ndc.xy * 0.5 + 0.5) * map_size;
  float bias = 0.0;
  if (u_bias_auto) {
    bias = remaining_bias(r);
  } else {
    r.window_ref = (ndc.z * 0.5 + 0.5) - max(u_bias_slope * (1.0 - n_dot_l), u_bias_constant);
  }
  if (u_filter == 0) return lit_by_texel(r, ivec2(floor(r.texel)), bias);
  if (u_filter == 2 && u_light_size > 0.0) return pcss(r, bias);
  return pcf(r, u_pcf_radius, bias);
}

void main() {
  vec3 albedo = v_color;
  vec3 normal = normalize(v_normal);
  if (!gl_FrontFacing) normal = -normal;  // planes are seen from both sides
  // The triangle's true plane, for the shadow lookup (a sphere's interpolated
  // normal is not the plane the shadow pass rasterised).
  vec3 geometric_normal = normalize(cross(dFdx(v_position), dFdy(v_position)));
  if (dot(geometric_normal, normal) < 0.0) geometric_normal = -geometric_normal;

  vec3 to_light = u_light_perspective ? normalize(u_light_position - v_position) : -u_light_direction;
  float n_dot_l = dot(normal, to_light);
  // Surfaces facing away from the light get no direct light at all.
  float visibility = n_dot_l > 0.0 ? shadow_visibility(v_position, geometric_normal, n_dot_l) : 0.0;

  if (u_output == 1) {
    o_color = vec4(vec3(visibility), 1.0);
    return;
  }
  vec3 to_camera = normalize(u_camera_position - v_position);
  vec3 halfway = normalize(to_light + to_camera);
  float direct = 1.0 - u_ambient;
  vec3 ambient = u_ambient * u_light_color;
  vec3 diffuse = direct * max(n_dot_l, 0.0) * u_light_color;
  vec3 specular = n_dot_l > 0.0 ? direct * 0.25 * pow(max(dot(normal, halfway), 0.0), 64.0) * u_light_color : vec3(0.0);
  vec3 lighting = (ambient + visibility * (diffuse + specular)) * albedo;
  o_color = vec4(clamp(lighting, 0.0, 1.0), 1.0);
}
