// Filter "exact"'s sliver pass: the camera's view of every triangle's
// edges, each drawn as a quad kSliverPixels wide on each side.
//
// The rasteriser snaps a triangle's corners to 1/256 pixel before it
// decides which pixel centres the triangle covers. An object thinner than
// a pixel whose edge passes that close to a row of centres can be met by
// the reference's camera rays there and missed by the raster at every
// centre: no neighbour sees another object, so the certificates' ring does
// not catch it. A centre the true triangle covers but the snapped one does
// not lies within the snap of an edge: these quads reach every such centre,
// and sliver.frag marks it where an object other than the one the main
// pass drew there reaches in front (docs/certified-shadows.md).
#include "certificate.glsl"
layout(triangles) in;
layout(triangle_strip, max_vertices = 12) out;

layout(location = UNIFORM_LOCATION_TRIANGLE_BASE) uniform int u_triangle_base;
layout(location = UNIFORM_LOCATION_CULL_BACK) uniform int u_cull_back;

in vec3 v_normal[];

flat out uint g_object;
// 1 for a model's edge, or a flat face's (a crease, where N.L may jump):
// marked over the object itself too (sliver.frag).
flat out uint g_over_itself;

// Far above the snap (1/512 pixel), far below a pixel.
const float kSliverPixels = 1.0 / 32.0;

void main() {
  // Written again before each EmitVertex, after which outputs are undefined.
  const uint object = object_of(u_triangle_base + gl_PrimitiveIDIn);
  const vec4 facts = object_facts(object);
  // A face whose corners' normals are one (a box's, a cylinder's cap, a
  // flat-shaded model's) meets its neighbours at creases: which side the
  // raster shows at a centre within the snap of the edge matters there
  // even where both sides are the object's (plan/sliver_marks.hpp, Edge::
  // crease: the CPU's marks find creases exactly). A smooth shape's faces
  // share their corners' normals: no crease.
  const bool flat_face = v_normal[0] == v_normal[1] && v_normal[1] == v_normal[2];
  const uint over_itself = has_flag(facts, OBJECT_FLAG_MODEL) || flat_face ? 1u : 0u;
  // An edge's part nearer the camera than half its near plane is clipped
  // away: the main pass and the reference both start at the near plane.
  float w_min = 0.5 * u.camera_axis_near.w;
  // A closed mesh's face turned from the camera, where the main pass culls
  // such faces (the camera outside every closed mesh): each of its edges
  // is either an edge of a face turned to the camera too (the outline),
  // drawn there, or lies behind a face of its own mesh turned to the camera
  // (a ray from outside reaches a face turned away only from inside), so
  // no other object is drawn in front of the face yet behind the edge.
  // Only a face clearly clockwise on the screen (fan area below its float
  // rounding, as certify.geom judges faces for the light) with every corner
  // in front of the camera.
  if (u_cull_back != 0 && has_flag(facts, OBJECT_FLAG_CLOSED) && gl_in[0].gl_Position.w > w_min &&
      gl_in[1].gl_Position.w > w_min && gl_in[2].gl_Position.w > w_min) {
    vec2 s[3];
    for (int i = 0; i < 3; ++i) s[i] = (gl_in[i].gl_Position.xy / gl_in[i].gl_Position.w * 0.5 + 0.5) * u.image_size;
    vec2 e1 = s[1] - s[0], e2 = s[2] - s[0];
    float perimeter = length(e1) + length(e2) + length(s[2] - s[1]);
    float extent = max(max(max(abs(s[0].x), abs(s[0].y)), max(abs(s[1].x), abs(s[1].y))), max(abs(s[2].x), abs(s[2].y)));
    float rounding = 4e-6 * max(1.0, extent) * perimeter + 1e-6 * perimeter * perimeter;
    if (e1.x * e2.y - e1.y * e2.x < -rounding) return;
  }
  for (int i = 0; i < 3; ++i) {
    vec4 a = gl_in[i].gl_Position, b = gl_in[(i + 1) % 3].gl_Position;
    if (a.w < w_min && b.w < w_min) continue;
    if (a.w < w_min) a = mix(a, b, (w_min - a.w) / (b.w - a.w));
    if (b.w < w_min) b = mix(b, a, (w_min - b.w) / (a.w - b.w));
    // Pixels, and normalized depth (affine along a line on the screen).
    vec3 na = a.xyz / a.w, nb = b.xyz / b.w;
    vec2 pa = (na.xy * 0.5 + 0.5) * u.image_size, pb = (nb.xy * 0.5 + 0.5) * u.image_size;
    vec2 along = pb - pa;
    float length_pixels = length(along);
    vec2 d = length_pixels > 1e-6 ? along / length_pixels : vec2(1.0, 0.0);
    vec2 n = vec2(-d.y, d.x);
    vec2 e = d * kSliverPixels, f = n * kSliverPixels;
    vec2 corners[4] = vec2[4](pa - e - f, pa - e + f, pb + e - f, pb + e + f);
    float depths[4] = float[4](na.z, na.z, nb.z, nb.z);
    for (int k = 0; k < 4; ++k) {
      g_object = object;
      g_over_itself = over_itself;
      gl_Position = vec4(corners[k] / u.image_size * 2.0 - 1.0, depths[k], 1.0);
      EmitVertex();
    }
    EndPrimitive();
  }
}
