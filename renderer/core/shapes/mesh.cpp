// A mesh object: a triangle model placed in the scene (core/mesh_instance.hpp
// holds the work; this is its row). Closed or open as its model is. No
// exact intersection here: the reference layer casts its triangles through
// Embree (reference/mesh_ray_cast.hpp), and RayScene picks that path for
// any kind whose row has no `intersect`.
#include "core/mesh_instance.hpp"
#include "core/shapes/shape.hpp"

namespace umbra {

namespace {

void tessellate(const SceneObject& o, Mesh& mesh) { append_mesh_instance(o, mesh); }

}  // namespace

extern const ShapeKind kMeshShape;  // listed in shapes.cpp
const ShapeKind kMeshShape = {
    SceneObject::Type::Mesh, "mesh", mesh_bounds, mesh_surface_bounds, mesh_is_closed, /*horizontal_plane=*/false,
    tessellate, mesh_triangle_count, mesh_vertex_count, /*intersect=*/nullptr, /*points_inside=*/nullptr,
    /*tessellation_error=*/nullptr, /*surely_meets=*/nullptr, /*contains=*/nullptr,
};

}  // namespace umbra
