// Main pass: Blinn-Phong lighting with a shadow-mapped direct term.
//
//   colour = (ambient + visibility * (diffuse + specular)) * albedo
//
// Ambient is never shadowed (it stands for light scattered around the
// scene); `visibility` in [0, 1] is the fraction of the light's direct light
// that reaches the surface, and is also what the "shadow" output shows.
//
// Built once per variant (DisplayVariant in renderer/gpu/shader_interface.hpp,
// which also declares the FrameBlock `u`): SHADOWS, DIRECT_LIGHT, OUTPUT_SHADOW,
// LIGHT_PERSPECTIVE, LIGHT_CUBE, VIEW_COUNT, FILTER, PCF_RADIUS,
// FILTER_REACH, FILTER_READ, BIAS_AUTO, LIGHT_SIDE, CERTIFICATES and PROOF are #defines, so nothing below
// branches on a uniform and every loop has a constant trip count.
in vec3 v_position;  // relative to the mesh origin
in vec3 v_normal;
in vec3 v_color;

layout(location = FRAG_OUTPUT_COLOR) out vec4 o_color;

#if CERTIFICATES
// Filter "exact": each pixel's verdict, and its colour with visibility 0,
// for the CPU to settle (PixelCertificates).
#include "certificate.glsl"
layout(location = FRAG_OUTPUT_CERTIFICATE) out uint o_certificate;
layout(location = FRAG_OUTPUT_UNLIT) out vec4 o_unlit;
layout(location = UNIFORM_LOCATION_TRIANGLE_BASE) uniform int u_triangle_base;

// What the camera sees at this pixel, and how far the exact surface along
// the same camera ray may lie from the rasterised point.
struct Seen {
  vec3 p;                 // the rasterised point (relative to the mesh origin)
  vec3 geometric_normal;  // its triangle's plane, facing the camera
  int triangle;
  uint object;
  uint facing_owner;      // the triangle's owner where it turns to the light (triangle_ids)
  vec4 facts;             // object_facts
  float reach;            // world units: the exact point lies within this of p
  float n_dot_l_rate;     // |d(N.L)/dx| + |d(N.L)/dy| across the pixel
  float cos_view;         // |cos| of the camera ray's angle to the face
  bool clipped;           // the camera's near or far plane passes within reach
};

// The pixel's Seen: v_position on `triangle` of `object`. Called outside
// any branch (derivatives).
Seen seen_here(int triangle, uvec2 ids, vec3 geometric_normal, float n_dot_l) {
  Seen seen;
  seen.p = v_position;
  vec3 to_eye = u.camera_position.xyz - v_position;
  seen.geometric_normal = dot(geometric_normal, to_eye) < 0.0 ? -geometric_normal : geometric_normal;
  seen.triangle = triangle;
  seen.object = ids.x;
  seen.facing_owner = ids.y;
  seen.facts = object_facts(ids.x);
  seen.n_dot_l_rate = fwidth(n_dot_l);
  // The exact surface along this pixel's camera ray: within the shape's
  // tessellation distance of the face (further along a ray that meets the
  // face obliquely; a curved shape seen at a grazing angle is left to the
  // ray cast), and within rounding: 1/50 of the pixel's footprint on the
  // surface (the rasteriser snaps vertices to 1/256 pixel) and float
  // rounding: about 10 ulps of the coordinates involved (the object's
  // extent, the point's and the camera's), and for a model more than the
  // reference's offset off its surface (256 ulps of its extent,
  // offset_off_surface).
  seen.cos_view = abs(dot(normalize(to_eye), seen.geometric_normal));
  float rounding = has_flag(seen.facts, OBJECT_FLAG_MODEL) ? 3e-5 : 1e-6;
  // The reference moves a shadow ray's start off an analytic surface by
  // 1e-9 (1 + |point|) in world units: far from the world's origin that is
  // more than the rounding near the mesh origin.
  float world_offset = 2e-9 * (1.0 + length(v_position + u.mesh_origin_far.xyz));
  seen.reach = seen.facts.x / max(seen.cos_view, 0.2) + 0.02 * (length(dFdx(v_position)) + length(dFdy(v_position))) +
               rounding * seen.facts.w + 1e-6 * (length(v_position) + length(to_eye)) + world_offset;
  // The camera's near and far planes cut the true surface where they cut
  // its faces only within the reach: there the reference's camera ray may
  // start past the surface the raster shows (ray_cast.cpp starts it at the
  // near plane), so such points are left to the ray cast.
  float along_axis = dot(-to_eye, u.camera_axis_near.xyz);
  seen.clipped = along_axis - u.camera_axis_near.w < 2.0 * seen.reach ||
                 u.mesh_origin_far.w - along_axis < 2.0 * seen.reach;
  return seen;
}

// What no map is needed for: a point seen near the camera's near or far
// plane, or a curved shape seen at a grazing angle, is uncertain.
bool left_to_the_ray_cast(Seen s) { return (s.facts.x > 0.0 && s.cos_view < 0.2) || s.clipped; }

// The verdict of the point's facing alone: dark where it faces away from
// the light, uncertain where it nearly grazes it, else CERTIFICATE_LIT:
// it faces the light with margin, and what lies in front of it decides.
// n_dot_l is the GL's (interpolated normal), which the reference computes
// the same way for a model and exactly for a shape.
uint verdict_by_facing(Seen s, float n_dot_l, vec3 to_light) {
  // The shape's normal error, float rounding, and how fast N.L changes
  // across the pixel (s.n_dot_l_rate): the rasteriser's snap moves where
  // the interpolated normal is read by a fraction of a pixel (on a tiny
  // triangle of a model whose normals turn fast, that flipped N.L's sign).
  float normal_slack = sin(s.facts.y) + 1e-4 + 0.05 * s.n_dot_l_rate;
  if (n_dot_l < -normal_slack) return CERTIFICATE_DARK;  // faces away: no direct light, here or exactly
  if (n_dot_l <= normal_slack) return CERTIFICATE_UNCERTAIN;
  // The own-owner rule holds where the point's plane faces the light, and
  // for a closed shape only from outside.
  if (dot(s.geometric_normal, to_light) <= normal_slack) return CERTIFICATE_UNCERTAIN;
  if (has_flag(s.facts, OBJECT_FLAG_CLOSED) && !gl_FrontFacing) return CERTIFICATE_UNCERTAIN;
  return CERTIFICATE_LIT;
}

#if PROOF != 0
// A part of a plane that the frame plan proved lit (PROOF 1: the segment
// to the light from every point within 2 u_proof_margin of it misses every
// other object's bounds) or dark (PROOF -1: it crosses a box or sphere
// at least u_proof_margin deep); docs/certified-shadows.md, "Proved plane
// parts". The plane is its own exact surface (no tessellation, exact
// normals) and holds no other object's triangles.
layout(location = UNIFORM_LOCATION_PROOF_OBJECT) uniform uint u_proof_object;
layout(location = UNIFORM_LOCATION_PROOF_MARGIN) uniform float u_proof_margin;
// seen_here's reach but for the pixel's footprint, bounded over the whole
// plane by the plan (ProvedPlane::rounding).
layout(location = UNIFORM_LOCATION_PROOF_ROUNDING) uniform float u_proof_rounding;

// The verdict on a pixel of a proved part: uncertain where its exact point
// may lie beyond the margin (seen_here's reach, its footprint's lengths
// bounded by their sums) or near the camera's near or far plane; a proved
// umbra is dark; a part proved lit is lit where the plane faces the light
// with margin (verdict_by_facing for a plane: its faces are its normal).
uint verdict_by_proof(float n_dot_l) {
  vec3 dx = abs(dFdx(v_position)), dy = abs(dFdy(v_position));
  float reach = 0.02 * (dx.x + dx.y + dx.z + dy.x + dy.y + dy.z) + u_proof_rounding;
  float along_axis = dot(v_position - u.camera_position.xyz, u.camera_axis_near.xyz);
  bool clipped = along_axis - u.camera_axis_near.w < 2.0 * reach || u.mesh_origin_far.w - along_axis < 2.0 * reach;
  float normal_slack = 1e-4 + 0.05 * fwidth(n_dot_l);
  if (reach > u_proof_margin || clipped) return CERTIFICATE_UNCERTAIN;
  if (PROOF < 0 || n_dot_l < -normal_slack) return CERTIFICATE_DARK;
  return n_dot_l <= normal_slack ? CERTIFICATE_UNCERTAIN : CERTIFICATE_LIT;
}
#endif
#endif

#if SHADOWS
// Window depth in [0, 1] per layer; nearest, no compare; outside the map
// the border reads 1 (far).
layout(binding = TEXTURE_UNIT_SHADOW_MAP) uniform sampler2DArray u_shadow_map;

// ---------------------------------------------------------------------------
// The view of the light that holds the point being shaded.
//
// A light has one view, or several: cascades (a directional light, nearest
// camera depths first) or cube faces (a point light). Views are read from
// the block with constant indices only: an index that differs from pixel to
// pixel would make a software rasteriser fetch each matrix lane by lane.
struct View {
  int layer;
  vec3 eye;       // the shaded point in this view's eye space
  vec3 ndc;       // ... and in its normalized device coordinates
  mat3 rotation;  // world -> eye space, for normals
  float near, far;  // world units along the view's axis
  vec2 texel;       // world size of a texel (perspective: per unit of distance)
  float tan_half;   // perspective: tangent of half the field of view
  vec4 casters;     // texels the shadow pass drew into: min xy, max zw
};

#if !LIGHT_CUBE
// All views but cube faces share one eye space: the vertex shader puts the
// point in it.
in vec3 v_light_eye;
#endif

// Clip coordinates in view i of a point in its eye space. An orthographic
// projection only scales and offsets each axis.
vec4 clip_in_view(int i, vec3 eye) {
  mat4 p = u.light_projection[i];
#if LIGHT_PERSPECTIVE
  return p * vec4(eye, 1.0);
#else
  return vec4(eye * vec3(p[0][0], p[1][1], p[2][2]) + p[3].xyz, 1.0);
#endif
}

// The same in the view `v` was chosen for. Every perspective view is
// glm::perspective with aspect 1, so it is rebuilt from near, far and
// tan_half rather than selected among the views' matrices per pixel.
vec4 clip_in_chosen_view(View v, vec3 eye) {
#if LIGHT_PERSPECTIVE
  float depth = -eye.z;
  float z = (v.far + v.near) / (v.far - v.near) * depth - 2.0 * v.far * v.near / (v.far - v.near);
  return vec4(eye.xy / v.tan_half, z, depth);
#else
  vec4 clip = clip_in_view(0, eye);
  for (int i = 1; i < VIEW_COUNT; ++i)
    if (v.layer == i) clip = clip_in_view(i, eye);
  return clip;
#endif
}

bool holds(vec4 clip, out vec3 ndc) {
  ndc = clip.xyz / clip.w;
  return clip.w > 0.0 && all(lessThanEqual(abs(ndc), vec3(1.0)));  // w <= 0: behind a point light
}

// Everything but the point's own coordinates, for view `layer`.
void set_view_constants(inout View v) {
  vec4 depth_texel = u.view_depth_texel[0];
  v.casters = u.view_casters[0];
  for (int i = 1; i < VIEW_COUNT; ++i) {
    if (v.layer == i) {
      depth_texel = u.view_depth_texel[i];
      v.casters = u.view_casters[i];
    }
  }
  v.near = depth_texel.x;
  v.far = depth_texel.y;
#if LIGHT_PERSPECTIVE
  v.texel = vec2(depth_texel.z);
  v.tan_half = depth_texel.w;
#else
  v.texel = depth_texel.zw;
  v.tan_half = 0.0;
#endif
}

#if LIGHT_CUBE
// Faces +X, -X, +Y, -Y, +Z, -Z (layer CUBE_FACE(axis, negative), the order
// of cube_face in renderer/core/shader_facts.hpp), each a little wider than
// 90 degrees so that the face of p's major axis holds p with its filter
// kernel. A face's
// rotation is a signed permutation (cube_face_view in
// renderer/core/light_math.hpp), built here from the axis and sign rather than
// selected among six matrices: that selection was about a third of a point
// light's main pass on llvmpipe. The projection is rebuilt from near, far
// and tan_half.
bool choose_view(vec3 p, out View v) {
  vec3 d = p - u.light_position.xyz;
  vec3 a = abs(d);
  int axis = a.x >= a.y && a.x >= a.z ? 0 : (a.y >= a.z ? 1 : 2);
  float s = d[axis] < 0.0 ? -1.0 : 1.0;
  v.layer = CUBE_FACE(axis, s < 0.0);
  // Columns: where the world axes go. Eye (s d.z, d.y, -s d.x) on +-X,
  // (d.x, s d.z, -s d.y) on +-Y, (-s d.x, d.y, -s d.z) on +-Z.
  vec3 x_to = axis == 0 ? vec3(0.0, 0.0, -s) : (axis == 1 ? vec3(1.0, 0.0, 0.0) : vec3(-s, 0.0, 0.0));
  vec3 y_to = axis == 1 ? vec3(0.0, 0.0, -s) : vec3(0.0, 1.0, 0.0);
  vec3 z_to = axis == 0 ? vec3(s, 0.0, 0.0) : (axis == 1 ? vec3(0.0, s, 0.0) : vec3(0.0, 0.0, -s));
  v.rotation = mat3(x_to, y_to, z_to);
  v.eye = v.rotation * d;
  set_view_constants(v);
  return holds(clip_in_chosen_view(v, v.eye), v.ndc);
}
#else
// The first view whose map holds the point with the filter's reach
// (FILTER_REACH texels) to spare; else the first that holds it at all;
// false if none does.
bool choose_view(vec3 p, out View v) {
  v.eye = v_light_eye;
  v.rotation = mat3(u.light_view[0]);
  int chosen = -1, fallback = -1;
  vec3 chosen_ndc = vec3(0.0), fallback_ndc = vec3(0.0);
  for (int i = 0; i < VIEW_COUNT; ++i) {
    vec3 ndc;
    bool inside = holds(clip_in_view(i, v.eye), ndc);
    vec2 texel = (ndc.xy * 0.5 + 0.5) * u.map_size;
    bool with_kernel = inside && all(greaterThanEqual(texel, vec2(FILTER_REACH))) &&
                       all(lessThanEqual(texel, vec2(u.map_size - FILTER_REACH)));
    if (chosen < 0 && with_kernel) {
      chosen = i;
      chosen_ndc = ndc;
    }
    if (fallback < 0 && inside) {
      fallback = i;
      fallback_ndc = ndc;
    }
  }
  v.layer = chosen >= 0 ? chosen : fallback;
  v.ndc = chosen >= 0 ? chosen_ndc : fallback_ndc;
  set_view_constants(v);
  return v.layer >= 0;
}
#endif

// Depth along the view's axis (world units) of window depth z.
float linear_from_window(View v, float z) {
#if LIGHT_PERSPECTIVE
  return v.near * v.far / (v.far - z * (v.far - v.near));
#else
  return v.near + z * (v.far - v.near);
#endif
}

// ---------------------------------------------------------------------------
// The receiver: the surface point being shaded, as the shadow map sees it.
//
// Instead of one depth with a guessed bias, the receiver's own plane (from
// the triangle's true normal) gives its depth along the light ray through
// any texel centre: each texel is compared with the receiver where that
// texel actually looks. This removes acne on planar surfaces at any slope
// without the large slope bias that causes peter panning, and it keeps PCF
// kernels of any radius correct on tilted receivers.
//
// On a plane, window depth is affine in the texel position for both kinds
// of light (orthographic: depth is affine and window depth is affine in
// depth; perspective: 1/depth is affine and window depth is affine in
// 1/depth). So the receiver is a reference depth at its own texel and a
// gradient, and each texel's comparison is one multiply-add in the map's
// own units, with no per-texel linearisation.
struct Receiver {
  vec2 texel;       // where the point falls, texel units (uv * map size)
  float reference;  // window depth compared with at `texel`, bias subtracted
  vec2 gradient;    // change of `reference` per texel
  float depth;      // linear depth of the point itself (PCSS)
};

// The bias that remains once each texel is compared with the receiver's own
// plane: float precision of the depth buffer and of interpolated positions,
// in world units.
float remaining_bias(View v, float depth) {
#if LIGHT_PERSPECTIVE
  float texel_world = v.texel.x * depth;
  float precision_bias = 4.0 * 6e-8 * depth * depth / v.near;  // window-depth ulp near z = 1, linearised
#else
  float texel_world = max(v.texel.x, v.texel.y);
  float precision_bias = 4.0 * 6e-8 * (v.far - v.near);
#endif
  return 0.05 * texel_world + precision_bias + 1e-6 * abs(depth);
}

// False if the (moved) point falls outside the view: nothing in the map can
// shadow it then.
bool make_receiver(View v, vec3 geometric_normal, float n_dot_l, out Receiver r) {
  r.depth = -v.eye.z;
  vec3 ndc = v.ndc;
#if !BIAS_AUTO
  // The seeds' bias: move the receiver along its normal, then compare in
  // window depth with max(slope * (1 - N.L), constant) subtracted.
#if LIGHT_PERSPECTIVE
  float texel_world = v.texel.x * r.depth;
#else
  float texel_world = max(v.texel.x, v.texel.y);
#endif
  vec3 moved = v.eye + v.rotation * geometric_normal * (u.bias_normal_offset * texel_world);
  if (!holds(clip_in_chosen_view(v, moved), ndc)) return false;
#endif
  r.texel = (ndc.xy * 0.5 + 0.5) * u.map_size;
#if BIAS_AUTO
  vec3 n = normalize(v.rotation * geometric_normal);
  float range = v.far - v.near;
#if LIGHT_PERSPECTIVE
  // The ray through texel t is depth * (t * texel - tan_half, -1); it meets
  // the plane n.(x - p) = 0 where 1/depth = n.ray(t) / n.p, and n.p =
  // depth_p * n.ray(t_p). Window depth = far / range - (near far / range) /
  // depth. Rays nearly parallel to the plane are kept from running off to
  // infinity.
  vec3 ray = vec3(r.texel * v.texel - vec2(v.tan_half), -1.0);
  float denominator = dot(n, ray);
  float limit = 0.02 * length(ray);
  if (abs(denominator) < limit) denominator = denominator < 0.0 ? -limit : limit;
  float b_over_depth = v.near * v.far / (range * r.depth);
  r.reference = v.far / range - b_over_depth;
  r.gradient = -b_over_depth * n.xy * v.texel / denominator;
  float window_per_world = b_over_depth / r.depth;
#else
  // Depth is affine in the texel position; grazing planes (n.z -> 0) are
  // kept from extrapolating to infinity.
  float nz = n.z < 0.0 ? min(n.z, -0.02) : max(n.z, 0.02);
  r.reference = (r.depth - v.near) / range;
  r.gradient = n.xy * v.texel / (nz * range);
  float window_per_world = 1.0 / range;
#endif
  r.reference -= remaining_bias(v, r.depth) * window_per_world;
#else
  r.reference = (ndc.z * 0.5 + 0.5) - max(u.bias_slope * (1.0 - n_dot_l), u.bias_constant);
  r.gradient = vec2(0.0);
#endif
  return true;
}

// The texel of a point lit without reading the map: off the layer.
const float kReadsNothing = -1.0e6;

// Whether the texels the filter reads around the receiver (FILTER_READ at
// most each way) meet the part of the layer that the shadow pass drew
// into. If not, nothing in the map can shadow the point, and the layer
// there was not even cleared: the point is lit without reading it. Most of
// a floor is lit this way, far from what stands on it.
bool near_casters(View v, Receiver r) {
  return all(greaterThan(r.texel + float(FILTER_READ), v.casters.xy)) &&
         all(lessThan(r.texel - float(FILTER_READ), v.casters.zw));
}

// The receiver's reference at a texel centre: its plane where that texel
// looks, but never deeper than the point itself. Only what lies in front of
// the point can shadow it, and capping the plane there keeps two things
// out:
// - a plane extended past its own edge: a box face lit at a shallow angle
//   runs, beyond its base, beneath the floor the box stands on, and the
//   floor's texels would grey the face along its base;
// - empty texels: a texel holding 1 (nothing drawn there within the view's
//   depth range) is never in front of a point inside the view, so a
//   receiver just inside a cascade's far plane is not darkened by the empty
//   texels beyond it (the seam a cascade boundary drew across the floor).
// A texel on the receiver's own surface is at its plane, so nearer texels
// keep the plane: no acne on sloped receivers.
float reference_at(Receiver r, vec2 texel_center) {
  return r.reference + min(dot(r.gradient, texel_center - r.texel), 0.0);
}

float stored_depth(View v, vec2 texel_center) {
  return textureLod(u_shadow_map, vec3(texel_center / u.map_size, float(v.layer)), 0.0).r;
}

// 1 where the texel at texel_center does not occlude the receiver, else 0.
float lit_by_texel(View v, Receiver r, vec2 texel_center) {
  return step(reference_at(r, texel_center), stored_depth(v, texel_center));
}

// Bilinearly weighted percentage-closer filter: (2R+1)^2 bilinear taps one
// texel apart are the same as a tent-weighted sum over (2R+2)^2 texels,
// read here four at a time with textureGather.
float pcf(View v, Receiver r, const int R) {
  vec2 base = r.texel - 0.5;
  vec2 origin = floor(base);  // the texel a bilinear tap at r.texel starts from
  vec2 f = base - origin;
  float sum = 0.0;
  for (int by = 0; by <= R; ++by) {
    for (int bx = 0; bx <= R; ++bx) {
      // This 2x2 block's lower-left texel, relative to `origin`.
      vec2 corner = vec2(2 * bx - R, 2 * by - R);
      vec4 stored = textureGather(u_shadow_map, vec3((origin + corner + 1.0) / u.map_size, float(v.layer)));
      // textureGather's order: (x0, y1), (x1, y1), (x1, y0), (x0, y0).
      // Each texel centre's offset from r.texel, and reference_at for all four.
      vec4 dx = corner.x + vec4(0.0, 1.0, 1.0, 0.0) - f.x;
      vec4 dy = corner.y + vec4(1.0, 1.0, 0.0, 0.0) - f.y;
      vec4 reference = r.reference + min(r.gradient.x * dx + r.gradient.y * dy, vec4(0.0));
      vec4 lit = step(reference, stored);
      // The tent's edge columns and rows weigh by the tap's fraction.
      vec4 wx = vec4(1.0), wy = vec4(1.0);
      if (bx == 0) wx.xw = vec2(1.0 - f.x);
      if (bx == R) wx.yz = vec2(f.x);
      if (by == 0) wy.zw = vec2(1.0 - f.y);
      if (by == R) wy.xy = vec2(f.y);
      sum += dot(lit, wx * wy);
    }
  }
  float taps = float(2 * R + 1);
  return sum / (taps * taps);
}

#if FILTER == FILTER_PCSS
// A well-spread disk of sample points (Vogel spiral), turned per pixel by
// `turn` (cos, sin of the angle) so that too few samples show as fine grain
// rather than as banding. i and count are constants in every call, so the
// spiral itself folds to constants: a pixel pays one rotation per sample,
// not a sine, a cosine and a square root.
vec2 disk_sample(int i, int count, vec2 turn) {
  float radius = sqrt((float(i) + 0.5) / float(count));
  float angle = float(i) * 2.39996323;
  vec2 d = radius * vec2(cos(angle), sin(angle));
  return vec2(turn.x * d.x - turn.y * d.y, turn.y * d.x + turn.x * d.y);
}

vec2 pixel_turn() {
  float angle = 6.2831853 * fract(52.9829189 * fract(dot(gl_FragCoord.xy, vec2(0.06711056, 0.00583715))));
  return vec2(cos(angle), sin(angle));
}

// Radius, in texels, of the region of the map through which the light's disc
// is seen from the receiver, at linear depth d of the map (d < receiver).
vec2 light_footprint_texels(View v, Receiver r, float d) {
#if LIGHT_PERSPECTIVE
  float angular = u.light_size * (r.depth - d) / (r.depth * max(d, v.near));
  return vec2(angular / v.texel.x);
#else
  return vec2((r.depth - d) * u.light_size) / v.texel;
#endif
}

// Percentage-closer soft shadows: find the average blocker depth, then
// filter over the region the light's disc covers at that depth.
float pcss(View v, Receiver r) {
  vec2 turn = pixel_turn();
  vec2 search = min(light_footprint_texels(v, r, v.near), vec2(kPcssSearchTexels));
  float blocker_sum = 0.0;
  int blockers = 0;
  for (int i = 0; i < kPcssBlockerSamples; ++i) {
    vec2 t = floor(r.texel + disk_sample(i, kPcssBlockerSamples, turn) * search) + 0.5;
    float stored = stored_depth(v, t);
    if (stored < reference_at(r, t)) {
      blocker_sum += linear_from_window(v, stored);
      ++blockers;
    }
  }
  if (blockers == 0) return 1.0;
  vec2 penumbra = min(light_footprint_texels(v, r, blocker_sum / float(blockers)), vec2(kPcssMaxPenumbraTexels));
  if (max(penumbra.x, penumbra.y) < 1.0) return pcf(v, r, 0);
  float sum = 0.0;
  for (int i = 0; i < kPcssFilterSamples; ++i)
    sum += lit_by_texel(v, r, floor(r.texel + disk_sample(i, kPcssFilterSamples, turn) * penumbra) + 0.5);
  return sum / float(kPcssFilterSamples);
}
#endif

#if FILTER == FILTER_EXACT
// ---------------------------------------------------------------------------
// Filter "exact": a verdict per pixel instead of a filtered guess. The maps
// (certify.frag) prove a point lit or shadowed, or the pixel is left to the
// CPU's ray cast (reference/certified_frame.hpp). Why each rule is sound:
// docs/certified-shadows.md.
layout(binding = TEXTURE_UNIT_CERTIFY_NEAREST) uniform sampler2DArray u_nearest;
layout(binding = TEXTURE_UNIT_CERTIFY_NEAREST_OWNER) uniform usampler2DArray u_nearest_owner;
layout(binding = TEXTURE_UNIT_CERTIFY_OTHERS) uniform sampler2DArray u_others;
layout(binding = TEXTURE_UNIT_CERTIFY_CENTRE_TRIANGLE) uniform usampler2DArray u_centre_triangle;
layout(binding = TEXTURE_UNIT_CERTIFY_COVER) uniform sampler2DArray u_cover;

// How far (world units) the light's float view matrix may move a point
// whose coordinates (relative to the mesh origin) reach `extent`: about
// 1e-6 of the coordinates involved, the view's translation among them
// (seen_here's rounding term, for the light; light_view_rounding,
// certificate.glsl, as the maps take it for their corners).
float light_rounding(float extent) {
#if LIGHT_CUBE
  float translation = length(u.light_position.xyz);
#else
  float translation = length(u.light_view[0][3].xyz);
#endif
  return light_view_rounding(extent, translation);
}

// The verdict on a point that faces the light with margin: the maps'
// proof of light or of shadow, or none.
uint verdict_by_maps(Seen s) {
  View v;
  if (!choose_view(s.p, v)) return CERTIFICATE_UNCERTAIN;
  // Where the maps see the point: off by the light view's rounding too.
  s.reach += light_rounding(length(s.p));
  float depth = -v.eye.z;
#if LIGHT_PERSPECTIVE
  float texel_world = v.texel.x * depth;
  float window_per_world = v.near * v.far / ((v.far - v.near) * depth * depth);
#else
  float texel_world = min(v.texel.x, v.texel.y);
  float window_per_world = 1.0 / (v.far - v.near);
#endif
  // Where the exact point's light ray can pass: a square of texels, and
  // a window depth, each widened by `reach`.
  float spread = s.reach / texel_world + 1e-3;
#if LIGHT_PERSPECTIVE
  // A shift along the view's axis moves an off-axis point's image too.
  spread *= 1.0 + (abs(v.ndc.x) + abs(v.ndc.y)) * v.tan_half;
#endif
  if (spread > 0.5) return CERTIFICATE_UNCERTAIN;
  vec2 t = (v.ndc.xy * 0.5 + 0.5) * u.map_size;
  vec2 lo = t - spread, hi = t + spread;
  float z = v.ndc.z * 0.5 + 0.5;
  float dz = s.reach * window_per_world + 2e-6;
  if (any(lessThan(lo, vec2(1.0))) || any(greaterThan(hi, vec2(u.map_size - 1.0))) || z - dz <= 0.0 || z + dz >= 1.0)
    return CERTIFICATE_UNCERTAIN;
  // Far from every caster's rectangle (the image of the bounds of what the
  // maps hold; a texel a triangle touches lies within a texel of it):
  // nothing lies in front of the point, and the maps are not even read.
  // Such lanes read texel 0 instead of their own (llvmpipe makes the masked
  // reads too, and scattered ones miss its cache: see shadow_visibility).
  bool near = all(greaterThan(hi + 2.0, v.casters.xy)) && all(lessThan(lo - 2.0, v.casters.zw));
  vec2 at = near ? t : vec2(1.5);
  lo = at - spread;
  hi = at + spread;
  if (!near) return CERTIFICATE_LIT;
  // A model's patch is the point's owner only seen from outside: seen from
  // within, the light lies on the inward side of the face, where the
  // patch's other triangles are (verdict_by_facing made it turn to the light).
  uint own = owner_of(s.triangle, uvec2(s.object, s.facing_owner), s.facts, gl_FrontFacing);
  // Lit: in every texel of the conservative maps (half as fine as the
  // layer: certified_map_size) that the ray can cross (at most 2 x 2, read
  // at once), everything but the point's own owner lies behind it
  // (conservative depths: nothing is nearer anywhere in the texel).
  // textureGather's order: (x0, y1), (x1, y1), (x1, y0), (x0, y0).
  float coarse = u.certified_map_size / u.map_size;
  vec2 first = floor(lo * coarse), last = floor(hi * coarse);
  vec3 block = vec3((first + 1.0) / u.certified_map_size, float(v.layer));
  vec4 nearest = textureGather(u_nearest, block);
  uvec4 owner = textureGather(u_nearest_owner, block);
  vec4 others = textureGather(u_others, block);
  vec4 behind = mix(nearest, others, vec4(equal(owner, uvec4(own))));
  // Texels of the block outside the square count as behind.
  float one_column = last.x == first.x ? 1.0 : 0.0, one_row = last.y == first.y ? 1.0 : 0.0;
  vec4 outside = vec4(one_row, max(one_row, one_column), one_column, 0.0);
  if (all(greaterThan(vec4(greaterThan(behind, vec4(z + dz))) + outside, vec4(0.5)))) return CERTIFICATE_LIT;
  // Shadowed, by the cover map: every light ray through each texel the
  // square meets crosses a triangle no farther than its cover depth, which
  // lies in front of the point by more than dz.
  vec4 cover = textureGather(u_cover, block);
  if (all(greaterThan(vec4(lessThan(cover, vec4(z - dz))) + outside, vec4(0.5)))) return CERTIFICATE_DARK;
  // Shadowed: one triangle holds the four texel centres around the square
  // (so, being convex, the square too) and lies in front of the point by
  // more than dz even at its farthest centre (a plane is affine between
  // them). A convex object's own triangles are no proof: they are its
  // tessellation, not the surface the reference sees.
  // The rasteriser snaps a triangle's corners to a fraction of a texel
  // (llvmpipe: 1/256) before it decides which centres it covers, so a
  // triangle that covers a centre truly holds only the points a little
  // inside: the square must keep kSnapTexels inside the centres' square.
  // The centre map is drawn at the conservative maps' size too (its pass
  // costs a quarter; only the band along shadow edges that it leaves to the
  // ray cast widens): the square and the snap in its texels.
  const float kSnapTexels = 1.0 / 32.0;
  vec2 centre_lo = lo * coarse, centre_hi = hi * coarse;
  vec2 c0 = floor(centre_lo - 0.5);
  if (any(lessThan(centre_lo, c0 + 0.5 + kSnapTexels)) || any(greaterThan(centre_hi, c0 + 1.5 - kSnapTexels)))
    return CERTIFICATE_UNCERTAIN;
  vec3 centres = vec3((c0 + 1.0) / u.certified_map_size, float(v.layer));
  uvec4 triangles = textureGather(u_centre_triangle, centres);
  vec4 depths = textureGather(u_shadow_map, centres);
  uint triangle = triangles.x;
  if (triangle == 0u || any(notEqual(triangles, uvec4(triangle)))) return CERTIFICATE_UNCERTAIN;
  bool model = has_flag(s.facts, OBJECT_FLAG_MODEL);
  uint occluder = object_of(int(triangle - 1u));
  if (!model && occluder == s.object) return CERTIFICATE_UNCERTAIN;
  // The snap moves the stored depths too: by the plane's slope over the
  // snap, which the four depths bound.
  float farthest = max(max(depths.x, depths.y), max(depths.z, depths.w));
  float nearest_centre = min(min(depths.x, depths.y), min(depths.z, depths.w));
  float snap_depth = 4.0 * kSnapTexels * (farthest - nearest_centre);
  // The light view's rounding moved the triangle as the map drew it: the
  // square must keep that much more inside the centres, and the depths
  // that much more in front, measured where the triangle is (its nearest
  // centre, for a point light: texels shrink towards the light).
  float occluder_rounding = light_rounding(sqrt(3.0) * object_facts(occluder).w);
#if LIGHT_PERSPECTIVE
  float occluder_depth = max(linear_from_window(v, nearest_centre), v.near);
  float occluder_texel = v.texel.x * occluder_depth / (1.0 + 2.0 * v.tan_half);
  float occluder_window = v.near * v.far / ((v.far - v.near) * occluder_depth * occluder_depth);
#else
  float occluder_texel = texel_world;
  float occluder_window = window_per_world;
#endif
  float moved = occluder_rounding * coarse / occluder_texel;
  if (any(lessThan(centre_lo, c0 + 0.5 + kSnapTexels + moved)) || any(greaterThan(centre_hi, c0 + 1.5 - kSnapTexels - moved)))
    return CERTIFICATE_UNCERTAIN;
  return farthest + snap_depth + occluder_rounding * occluder_window < z - dz ? CERTIFICATE_DARK : CERTIFICATE_UNCERTAIN;
}

// The pixel's verdict: the facing rules, then the maps'.
uint certify(Seen s, float n_dot_l, vec3 to_light) {
  uint facing = verdict_by_facing(s, n_dot_l, to_light);
  return facing == CERTIFICATE_LIT ? verdict_by_maps(s) : facing;
}
#else
// Fraction of the direct light reaching point p (1 lit, 0 shadowed).
float shadow_visibility(vec3 p, vec3 geometric_normal, float n_dot_l) {
  // Outside every view (beside the light's frustum, before near, beyond
  // far): nothing in the map can shadow the point, so it is lit (the seeds'
  // far-plane fix).
  View v;
  if (!choose_view(p, v)) return 1.0;
  Receiver r;
  if (!make_receiver(v, geometric_normal, n_dot_l, r)) return 1.0;
  // A point that no caster is near is lit, but it does not just return:
  // llvmpipe runs a branch for a whole block of pixels at once, and the
  // lanes that left it still make their texture reads (masked), each at its
  // own texel all over the layer: a quarter of the default frame's main
  // pass went to those cache misses. Pointed off the layer, they all fall
  // on the border (far). The branch tests the texel, not near_casters:
  // past a test of the flag the compiler knows it is true and drops the
  // select. (A GPU skips the rest for those pixels either way.)
  r.texel = near_casters(v, r) ? r.texel : vec2(kReadsNothing);
  if (r.texel.x == kReadsNothing) return 1.0;
#if FILTER == FILTER_HARD
  return lit_by_texel(v, r, floor(r.texel) + 0.5);
#elif FILTER == FILTER_PCSS
  return pcss(v, r);
#else
  return pcf(v, r, PCF_RADIUS);
#endif
}
#endif  // FILTER_EXACT
#endif  // SHADOWS

void main() {
  vec3 albedo = v_color;
  vec3 normal = normalize(v_normal);
  if (!gl_FrontFacing) normal = -normal;  // planes are seen from both sides
#if LIGHT_PERSPECTIVE
  vec3 to_light = normalize(u.light_position.xyz - v_position);
#else
  vec3 to_light = -u.light_direction.xyz;
#endif
  float n_dot_l = dot(normal, to_light);
#if LIGHT_SIDE < 0
  // Drawn only where no point faces the light (scene.vert).
  float visibility = 0.0;
#if CERTIFICATES
  // Filter "exact": the facing rule settles such a point, dark or (within
  // its slack, or where the exact point may lie elsewhere) uncertain, and
  // no map is read. Never lit here: a point that turned out to face the
  // light would need the maps' proof.
  vec3 geometric_normal = normalize(cross(dFdx(v_position), dFdy(v_position)));
  if (dot(geometric_normal, normal) < 0.0) geometric_normal = -geometric_normal;
  Seen seen = seen_here(u_triangle_base + gl_PrimitiveID, triangle_ids(u_triangle_base + gl_PrimitiveID), geometric_normal,
                        n_dot_l);
  uint facing = verdict_by_facing(seen, n_dot_l, to_light);
  uint verdict = left_to_the_ray_cast(seen) || facing == CERTIFICATE_LIT ? CERTIFICATE_UNCERTAIN : facing;
  o_certificate = ((seen.object + 1u) << CERTIFICATE_OBJECT_SHIFT) | (n_dot_l > 0.0 ? 4u : 0u) | verdict;
  visibility = verdict == CERTIFICATE_DARK ? 0.0 : 1.0;
#endif
#elif SHADOWS
  // The triangle's true plane, for the shadow lookup (a sphere's interpolated
  // normal is not the plane the shadow pass rasterised). Derivatives are
  // taken here, outside any branch.
  vec3 geometric_normal = normalize(cross(dFdx(v_position), dFdy(v_position)));
  if (dot(geometric_normal, normal) < 0.0) geometric_normal = -geometric_normal;
#if FILTER == FILTER_EXACT
  Seen seen = seen_here(u_triangle_base + gl_PrimitiveID, triangle_ids(u_triangle_base + gl_PrimitiveID), geometric_normal,
                        n_dot_l);
  uint verdict = left_to_the_ray_cast(seen) ? CERTIFICATE_UNCERTAIN : certify(seen, n_dot_l, to_light);
  // Which side of the light the surface turns to: the reference's camera
  // ray may meet the face beside a crease instead (the CPU casts where
  // this or the object changes between pixels).
  o_certificate = ((seen.object + 1u) << CERTIFICATE_OBJECT_SHIFT) | (n_dot_l > 0.0 ? 4u : 0u) | verdict;
  // The ray cast settles an uncertain pixel: drawn lit here, and unlit in
  // o_unlit, for the CPU to pick from.
  float visibility = verdict == CERTIFICATE_DARK ? 0.0 : 1.0;
#else
  // Surfaces facing away from the light get no direct light at all.
  float visibility = n_dot_l > 0.0 ? shadow_visibility(v_position, geometric_normal, n_dot_l) : 0.0;
#endif
#elif PROOF != 0
  // The plan proved this part of a plane lit or dark; the pixel adds what
  // only it knows: how it faces the camera and the light, and how far its
  // exact point may lie (within the margin the plan allowed for).
  uint verdict = verdict_by_proof(n_dot_l);
  o_certificate = ((u_proof_object + 1u) << CERTIFICATE_OBJECT_SHIFT) | (n_dot_l > 0.0 ? 4u : 0u) | verdict;
  float visibility = verdict == CERTIFICATE_DARK ? 0.0 : 1.0;
#elif DIRECT_LIGHT
  float visibility = n_dot_l > 0.0 ? 1.0 : 0.0;
#else
  // A sun below the horizon: no direct light reaches any surface.
  float visibility = 0.0;
#endif
#if CERTIFICATES && !SHADOWS && PROOF == 0 && LIGHT_SIDE >= 0
  // Certified without a lookup: a sun below the horizon lights nothing, so
  // every surface is dark; the CPU casts only around changes of object.
  // With the light up, a frame drawn without maps (DisplayPassPlan::
  // certificates, FramePlan: the ray cast is cheaper than the maps) leaves
  // every pixel but the proved plane parts' to the ray cast.
  o_certificate = ((object_of(u_triangle_base + gl_PrimitiveID) + 1u) << CERTIFICATE_OBJECT_SHIFT) |
                  (n_dot_l > 0.0 ? 4u : 0u) |
                  (DIRECT_LIGHT == 1 ? CERTIFICATE_UNCERTAIN : CERTIFICATE_DARK);
#endif

#if OUTPUT_SHADOW
  o_color = vec4(vec3(visibility), 1.0);
#else
  vec3 light_color = u.light_color_ambient.rgb;
  float ambient = u.light_color_ambient.a;
  vec3 to_camera = normalize(u.camera_position.xyz - v_position);
  vec3 halfway = normalize(to_light + to_camera);
  float direct = 1.0 - ambient;
  vec3 diffuse = direct * max(n_dot_l, 0.0) * light_color;
  vec3 specular = n_dot_l > 0.0 ? direct * 0.25 * pow(max(dot(normal, halfway), 0.0), 64.0) * light_color : vec3(0.0);
  vec3 lighting = (ambient * light_color + visibility * (diffuse + specular)) * albedo;
  o_color = vec4(clamp(lighting, 0.0, 1.0), 1.0);
#if CERTIFICATES
  o_unlit = vec4(clamp(ambient * light_color * albedo, 0.0, 1.0), 1.0);
#endif
#endif
#if OUTPUT_SHADOW && CERTIFICATES
  o_unlit = vec4(0.0, 0.0, 0.0, 1.0);
#endif
}
