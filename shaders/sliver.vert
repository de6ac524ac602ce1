// Filter "exact"'s sliver pass (sliver.geom): positions into the camera's clip space.
layout(location = ATTRIB_POSITION) in vec3 a_position;  // relative to the mesh origin

void main() { gl_Position = u.camera_view_projection * vec4(a_position, 1.0); }
