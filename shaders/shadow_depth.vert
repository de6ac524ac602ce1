// Shadow pass: positions into the clip space of the light's view being drawn.
layout(location = ATTRIB_POSITION) in vec3 a_position;  // relative to the mesh origin

layout(location = UNIFORM_LOCATION_LAYER) uniform int u_layer;  // the view (map layer) this draw fills; set per layer

void main() {
  gl_Position = u.light_projection[u_layer] * (u.light_view[u_layer] * vec4(a_position, 1.0));
}
