// The light's depth map as a readable grey image: near = black, far = white.
// A perspective light stores depth non-linearly (most of [0,1] is crowded
// near the far plane), so it is linearised first. With several layers
// (cascades, cube faces) the image is a grid of tiles, layer 0 top left,
// row by row, each layer scaled down to its tile.
// Variant (PreviewVariant): LIGHT_PERSPECTIVE, VIEW_COUNT.
layout(location = FRAG_OUTPUT_COLOR) out vec4 o_color;

layout(binding = TEXTURE_UNIT_SHADOW_MAP) uniform sampler2DArray u_shadow_map;

void main() {
  // Row 0 of the read-back image is the top: count tile rows from the top.
  float grid = float(u.preview_grid);
  vec2 cell = gl_FragCoord.xy / u.preview_size * grid;
  ivec2 tile = ivec2(floor(vec2(cell.x, grid - cell.y)));
  int layer = tile.y * u.preview_grid + tile.x;
  if (layer >= VIEW_COUNT) {
    o_color = vec4(vec3(0.5), 1.0);  // an unused tile
    return;
  }
  ivec2 texel = ivec2(fract(cell) * u.map_size);
  float z = texelFetch(u_shadow_map, ivec3(texel, layer), 0).r;
  float grey = z;
#if LIGHT_PERSPECTIVE
  float n = u.view_depth_texel[layer].x, f = u.view_depth_texel[layer].y;
  float linear = n * f / (f - z * (f - n));
  grey = (linear - n) / (f - n);
#endif
  o_color = vec4(vec3(clamp(grey, 0.0, 1.0)), 1.0);
}
