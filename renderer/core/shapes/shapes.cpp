// The table of shape kinds: one row per SceneObject::Type, each defined in
// its own file here.
#include <cstddef>

#include "core/shapes/shape.hpp"

namespace umbra {

extern const ShapeKind kPlaneShape, kBoxShape, kSphereShape, kMeshShape;

const std::vector<const ShapeKind*>& shape_kinds() {
  // In SceneObject::Type order (test_shapes checks it): shape_kind indexes it.
  static const std::vector<const ShapeKind*> kinds = {&kPlaneShape, &kBoxShape, &kSphereShape, &kMeshShape};
  return kinds;
}

const ShapeKind& shape_kind(SceneObject::Type type) { return *shape_kinds()[std::size_t(type)]; }

const ShapeKind* find_shape_kind(std::string_view name) {
  for (const ShapeKind* kind : shape_kinds())
    if (name == kind->name) return kind;
  return nullptr;
}

}  // namespace umbra
