// Main pass: the scene from the camera.
layout(location = ATTRIB_POSITION) in vec3 a_position;  // relative to the mesh origin
layout(location = ATTRIB_NORMAL) in vec3 a_normal;
layout(location = ATTRIB_COLOR) in vec3 a_color;

out vec3 v_position;
out vec3 v_normal;
out vec3 v_color;
#if SHADOWS && !LIGHT_CUBE
out vec3 v_light_eye;  // the point in the light's eye space (shared by all its views)
#endif

// The floor's cells are drawn by two programs (with and without the shadow
// lookup) that share edges: GLSL only promises both compute the same
// position for the same vertex when it is invariant, and without that a
// crack could open along a shared edge.
invariant gl_Position;

void main() {
  v_position = a_position;
  v_normal = a_normal;
  v_color = a_color;
#if SHADOWS && !LIGHT_CUBE
  v_light_eye = (u.light_view[0] * vec4(a_position, 1.0)).xyz;
#endif
  gl_Position = u.camera_view_projection * vec4(a_position, 1.0);
#if LIGHT_SIDE != 0
  // A closed mesh seen from outside is drawn in two parts: where its points
  // may face the light, with the shadow lookup, and where none can, without
  // it (ShadowRenderer::run_display_pass). Clipping splits each triangle
  // where `toward`, interpolated from its vertices, crosses 0; both parts
  // use one `toward`, so the line is the same for both.
  //
  // scene.frag lights a point if dot(normal, light - p) > 0, with the normal
  // interpolated. Towards a directional light that is linear across a
  // triangle, so interpolating it from the vertices gives it exactly.
  // Towards a point light it differs from the interpolation by
  // sum_k w_k dot(n_k, p_k - p): no more than the triangle's longest edge
  // where its normals differ (u.smooth_normal_span), and 0 where they are
  // one. The 1e-4 terms are far above float rounding.
#if LIGHT_PERSPECTIVE
  vec3 to_light = u.light_position.xyz - a_position;
  float scale = length(to_light);
  float toward = dot(a_normal, to_light) + u.smooth_normal_span + 1e-4 * scale;
#else
  float scale = 1.0;
  float toward = dot(a_normal, -u.light_direction.xyz) + 1e-4;
#endif
#if LIGHT_SIDE > 0
  // More than its share: the two parts overlap rather than leave a crack
  // where their clipped edges snap apart (where both draw, both give
  // visibility 0). 1e-2 is a band a hundredth of a radius wide on a
  // sphere: far more than llvmpipe's 1/256-pixel snapping at any size on
  // screen that is split, and little more of it looked up.
  gl_ClipDistance[0] = toward + 1e-2 * scale;
#else
  gl_ClipDistance[0] = -toward;
#endif
#endif
}
