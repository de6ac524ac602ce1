// Filter "exact"'s sliver pass (sliver.geom): positions into the camera's
// clip space, and the vertex normals, which tell a flat face.
layout(location = ATTRIB_POSITION) in vec3 a_position;  // relative to the mesh origin
layout(location = ATTRIB_NORMAL) in vec3 a_normal;

out vec3 v_normal;

void main() {
  gl_Position = u.camera_view_projection * vec4(a_position, 1.0);
  v_normal = a_normal;
}
