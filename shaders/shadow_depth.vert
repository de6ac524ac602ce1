#version 450 core
// Shadow pass: positions into the light's clip space, nothing else.
layout(location = 0) in vec3 a_position;  // relative to the mesh origin

uniform mat4 u_light_view_projection;     // origin-relative

void main() {
  gl_Position = u_light_view_projection * vec4(a_position, 1.0);
}
