// What filter "exact"'s shaders share (docs/certified-shadows.md): whose a
// triangle is. The owner of a triangle is what may be left out when the
// maps are asked whether anything else lies in front of a point:
// - an analytic shape (plane, box, sphere, cylinder) is convex, so no part
//   of it lies between a point of its surface that faces the light and
//   the light: all its triangles have one owner, the object;
// - a model need not be convex: each of its triangles is its own owner
//   (a flat triangle cannot lie in front of its own points).
layout(binding = TEXTURE_UNIT_TRIANGLE_OBJECTS) uniform usamplerBuffer u_triangle_objects;
// Per object: x its tessellation's distance from the true surface, y the
// angle of its normals from the true ones (radians), z flags
// (OBJECT_FLAG_MODEL, OBJECT_FLAG_CLOSED), w the largest |coordinate| of its
// bounds relative to the mesh origin.
layout(binding = TEXTURE_UNIT_OBJECT_FACTS) uniform samplerBuffer u_object_facts;

uint object_of(int triangle) { return texelFetch(u_triangle_objects, triangle).r; }

vec4 object_facts(uint object) { return texelFetch(u_object_facts, int(object)); }

bool has_flag(vec4 facts, int flag) { return (int(facts.z) & flag) != 0; }

// `object` and `facts`: the triangle's object and its facts (the caller
// has fetched them already).
uint owner_of(int triangle, uint object, vec4 facts) {
  return has_flag(facts, OBJECT_FLAG_MODEL) ? (uint(triangle) | 0x80000000u) : object;
}
