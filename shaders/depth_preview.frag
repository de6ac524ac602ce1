#version 450 core
// The light's depth map as a readable grey image: near = black, far = white.
// A perspective light stores depth non-linearly (most of [0,1] is crowded
// near the far plane), so it is linearised first. With several layers
// (cascades, cube faces) the image is a grid of tiles, layer 0 top left,
// row by row, each layer scaled down to its tile.
layout(location = 0) out vec4 o_color;

const int kMaxViews = 6;
uniform sampler2DArray u_shadow_map;
uniform int u_view_count;
uniform int u_grid;                // tiles per row and per column
uniform float u_image_size;        // the preview's side, pixels
uniform bool u_light_perspective;
uniform float u_light_near[kMaxViews];
uniform float u_light_far[kMaxViews];

void main() {
  // Row 0 of the read-back image is the top: count tile rows from the top.
  vec2 cell = gl_FragCoord.xy / u_image_size * float(u_grid);
  ivec2 tile = ivec2(floor(vec2(cell.x, float(u_grid) - cell.y)));
  int layer = tile.y * u_grid + tile.x;
  if (layer >= u_view_count) {
    o_color = vec4(vec3(0.5), 1.0);  // an unused tile
    return;
  }
  ivec2 texel = ivec2(fract(cell) * vec2(textureSize(u_shadow_map, 0).xy));
  float z = texelFetch(u_shadow_map, ivec3(texel, layer), 0).r;
  float grey = z;
  if (u_light_perspective) {
    float n = u_light_near[layer], f = u_light_far[layer];
    float linear = n * f / (f - z * (f - n));
    grey = (linear - n) / (f - n);
  }
  o_color = vec4(vec3(clamp(grey, 0.0, 1.0)), 1.0);
}
