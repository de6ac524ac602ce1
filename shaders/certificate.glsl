// What filter "exact"'s shaders share (docs/certified-shadows.md): whose a
// triangle is. The owner of a triangle is what may be left out when the
// maps are asked whether anything else lies in front of a point:
// - an analytic shape (plane, box, sphere, cylinder) is convex, so no part
//   of it lies between a point of its surface that faces the light and
//   the light: all its triangles have one owner, the object;
// - a model need not be convex: a triangle that turns its outward side to
//   the light is owned by its convex patch (core/convex_patches.hpp: every
//   other triangle of the patch lies behind its plane, so none lies between
//   its points and the light), any other triangle by itself alone (a flat
//   triangle cannot lie in front of its own points).
// Per triangle: r its object, g its owner when it turns to the light
// (light_facing_owners in plan/conservative_maps.hpp; a shape's: its object).
layout(binding = TEXTURE_UNIT_TRIANGLE_OBJECTS) uniform usamplerBuffer u_triangle_objects;
// Per object: x its tessellation's distance from the true surface, y the
// angle of its normals from the true ones (radians), z flags
// (OBJECT_FLAG_MODEL, OBJECT_FLAG_CLOSED), w the largest |coordinate| of its
// bounds relative to the mesh origin.
layout(binding = TEXTURE_UNIT_OBJECT_FACTS) uniform samplerBuffer u_object_facts;

uint object_of(int triangle) { return texelFetch(u_triangle_objects, triangle).r; }

// The triangle's object and its owner when it turns to the light.
uvec2 triangle_ids(int triangle) { return texelFetch(u_triangle_objects, triangle).rg; }

vec4 object_facts(uint object) { return texelFetch(u_object_facts, int(object)); }

bool has_flag(vec4 facts, int flag) { return (int(facts.z) & flag) != 0; }

// `ids` and `facts`: the triangle's (the caller has fetched them already).
// `by_patch`: the patch's argument holds: the triangle turns its outward
// side to the light (certify.geom), or the point is seen from outside and
// faces the light (scene.frag); else a model's triangle owns itself.
uint owner_of(int triangle, uvec2 ids, vec4 facts, bool by_patch) {
  return has_flag(facts, OBJECT_FLAG_MODEL) && !by_patch ? (uint(triangle) | CERTIFICATE_TRIANGLE_OWNER) : ids.y;
}

// How far (world units) a float view matrix relative to the mesh origin may
// move a point whose coordinates there reach `extent`: about 1e-6 of the
// coordinates involved, the view's `translation` among them
// (light_view_rounding in core/light_math.hpp).
float light_view_rounding(float extent, float translation) { return 1e-6 * (extent + translation); }
