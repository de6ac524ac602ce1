// Filter "exact": the pixels to ray cast, listed by the GPU, so that a
// GPU's frame reads back a list instead of every pixel's certificate.
// Exactly reference/certified_frame.cpp's pixels_to_ray_cast (a test holds
// the two to each other): the pixels within u_ring (Chebyshev) of a pixel
// whose surface differs from a 4-neighbour's or that lies on the image's
// border, and the uncertain and the sliver-marked pixels. Three passes
// (CAST_PASS), each one dispatch over the display's pixels:
//   CAST_EDGES  u_cast_out = beside a change, or on the border;
//   CAST_ROWS   u_cast_out = u_cast_in's OR over [x - r, x + r];
//   CAST_LIST   the OR of u_cast_in over [y - r, y + r], the uncertain and
//               the marked pixels, each appended to CastList.
// GL's rows run bottom up; a listed index counts rows from the top, as
// PixelCertificates' do.
layout(local_size_x = 16, local_size_y = 16) in;

layout(binding = TEXTURE_UNIT_CERTIFICATES) uniform usampler2D u_certificates;
layout(location = UNIFORM_LOCATION_CAST_RING) uniform int u_ring;  // the dilation: pixels_to_ray_cast's ring - 1

uint surface(ivec2 p) { return texelFetch(u_certificates, p, 0).r >> CERTIFICATE_SURFACE_SHIFT; }

#if CAST_PASS == CAST_EDGES
layout(binding = IMAGE_UNIT_CAST_OUT, r8ui) uniform writeonly uimage2D u_cast_out;
#elif CAST_PASS == CAST_ROWS
layout(binding = IMAGE_UNIT_CAST_IN, r8ui) uniform readonly uimage2D u_cast_in;
layout(binding = IMAGE_UNIT_CAST_OUT, r8ui) uniform writeonly uimage2D u_cast_out;
#else
layout(binding = IMAGE_UNIT_CAST_IN, r8ui) uniform readonly uimage2D u_cast_in;
layout(binding = TEXTURE_UNIT_SLIVERS) uniform usampler2D u_slivers;
#if CAST_UNLIT
layout(binding = TEXTURE_UNIT_UNLIT) uniform sampler2D u_unlit;
#endif
layout(std430, binding = STORAGE_BUFFER_CAST_LIST) buffer CastList {
  uint header[CAST_LIST_HEADER_WORDS];  // [0]: how many pixels are listed
  uvec2 listed[];                       // ListedPixel: index, unlit
};
#endif

void main() {
  const ivec2 size = textureSize(u_certificates, 0);
  const ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= size.x || p.y >= size.y) return;
#if CAST_PASS == CAST_EDGES
  bool edge = p.x == 0 || p.y == 0 || p.x == size.x - 1 || p.y == size.y - 1;
  if (!edge) {
    const uint s = surface(p);
    edge = surface(p + ivec2(1, 0)) != s || surface(p - ivec2(1, 0)) != s || surface(p + ivec2(0, 1)) != s ||
           surface(p - ivec2(0, 1)) != s;
  }
  imageStore(u_cast_out, p, uvec4(edge ? 1u : 0u));
#elif CAST_PASS == CAST_ROWS
  uint near_edge = 0u;
  for (int x = max(p.x - u_ring, 0); x <= min(p.x + u_ring, size.x - 1); ++x) near_edge |= imageLoad(u_cast_in, ivec2(x, p.y)).r;
  imageStore(u_cast_out, p, uvec4(near_edge));
#else
  uint to_cast = 0u;
  for (int y = max(p.y - u_ring, 0); y <= min(p.y + u_ring, size.y - 1); ++y) to_cast |= imageLoad(u_cast_in, ivec2(p.x, y)).r;
  if ((texelFetch(u_certificates, p, 0).r & CERTIFICATE_VERDICT_MASK) == CERTIFICATE_UNCERTAIN) to_cast = 1u;
  if (texelFetch(u_slivers, p, 0).r != 0u) to_cast = 1u;
  if (to_cast == 0u) return;
  uint unlit = 0u;
#if CAST_UNLIT
  const uvec3 rgb = uvec3(round(texelFetch(u_unlit, p, 0).rgb * 255.0));
  unlit = rgb.r | (rgb.g << 8) | (rgb.b << 16);
#endif
  const uint at = atomicAdd(header[0], 1u);
  listed[at] = uvec2(uint(size.y - 1 - p.y) * uint(size.x) + uint(p.x), unlit);
#endif
}
