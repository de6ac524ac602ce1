// Every shape kind, once: SceneObject::Type's values and the shape table
// (shapes.cpp) are both made from this list, in this order. A new kind is
// one line here and one file in this folder defining its row (shape.hpp).
//
// UMBRA_SHAPE_KINDS(X) calls X(Type value, its ShapeKind row) per kind.
// New kinds go last: a value's number is its place in the table.
#pragma once

#define UMBRA_SHAPE_KINDS(X) \
  X(Plane, kPlaneShape)      \
  X(Box, kBoxShape)          \
  X(Sphere, kSphereShape)    \
  X(Mesh, kMeshShape)        \
  X(Cylinder, kCylinderShape)
