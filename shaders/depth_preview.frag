#version 450 core
// The light's depth map as a readable grey image: near = black, far = white.
// A perspective light stores depth non-linearly (most of [0,1] is crowded
// near the far plane), so it is linearised first.
layout(location = 0) out vec4 o_color;

uniform sampler2D u_shadow_map;
uniform bool u_light_perspective;
uniform float u_light_near;
uniform float u_light_far;

void main() {
  float z = texelFetch(u_shadow_map, ivec2(gl_FragCoord.xy), 0).r;
  float grey = z;
  if (u_light_perspective) {
    float n = u_light_near, f = u_light_far;
    float linear = n * f / (f - z * (f - n));
    grey = (linear - n) / (f - n);
  }
  o_color = vec4(vec3(clamp(grey, 0.0, 1.0)), 1.0);
}
