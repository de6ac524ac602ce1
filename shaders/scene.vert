// Main pass: the scene from the camera.
layout(location = 0) in vec3 a_position;  // relative to the mesh origin
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec3 a_color;

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
}
