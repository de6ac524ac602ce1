// Filter "exact"'s sliver pass (sliver.geom): marks a pixel whose centre
// an edge of another object than the one the main pass drew there passes
// within the rasteriser's snap of, in front of what was drawn (the depth
// test against the main pass's depth, not written). The CPU casts it.
layout(binding = TEXTURE_UNIT_CERTIFICATES) uniform usampler2D u_certificates;

flat in uint g_object;

layout(location = FRAG_OUTPUT_COLOR) out uint o_sliver;

void main() {
  // PixelCertificates: (object + 1) << 3 | facing << 2 | verdict.
  uint drawn = texelFetch(u_certificates, ivec2(gl_FragCoord.xy), 0).r >> 3;
  if (drawn == g_object + 1u) discard;
  o_sliver = 1u;
}
