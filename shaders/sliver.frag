// Filter "exact"'s sliver pass (sliver.geom): marks a pixel whose centre
// an edge of another object than the one the main pass drew there passes
// within the rasteriser's snap of, in front of what was drawn (the depth
// test against the main pass's depth, not written). The CPU casts it.
layout(binding = TEXTURE_UNIT_CERTIFICATES) uniform usampler2D u_certificates;

flat in uint g_object;
flat in uint g_over_itself;

layout(location = FRAG_OUTPUT_COLOR) out uint o_sliver;

void main() {
  // PixelCertificates: (object + 1) << CERTIFICATE_OBJECT_SHIFT | facing << 2 | verdict.
  uint drawn = texelFetch(u_certificates, ivec2(gl_FragCoord.xy), 0).r >> CERTIFICATE_OBJECT_SHIFT;
  // A model need not be convex: its outline can pass in front of a
  // farther part of itself, which the raster may show where the
  // reference's ray meets the outline. A crease parts two faces whose N.L
  // may differ. Elsewhere an analytic shape is convex and smooth: where
  // the raster shows it, the reference's ray meets it too, as lit.
  if (drawn == g_object + 1u && g_over_itself == 0u) discard;
  o_sliver = 1u;
}
