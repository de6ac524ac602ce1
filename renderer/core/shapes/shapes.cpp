// The table of shape kinds: one row per SceneObject::Type, each defined in
// its own file here and listed in shape_list.hpp.
#include <cstddef>

#include "core/shapes/shape.hpp"

namespace umbra {

#define UMBRA_SHAPE_ROW_DECLARATION(value, row) extern const ShapeKind row;
UMBRA_SHAPE_KINDS(UMBRA_SHAPE_ROW_DECLARATION)
#undef UMBRA_SHAPE_ROW_DECLARATION

const std::vector<const ShapeKind*>& shape_kinds() {
  // In SceneObject::Type order (test_shapes checks it): shape_kind indexes it.
#define UMBRA_SHAPE_ROW_ADDRESS(value, row) &row,
  static const std::vector<const ShapeKind*> kinds = {UMBRA_SHAPE_KINDS(UMBRA_SHAPE_ROW_ADDRESS)};
#undef UMBRA_SHAPE_ROW_ADDRESS
  return kinds;
}

const ShapeKind& shape_kind(SceneObject::Type type) { return *shape_kinds()[std::size_t(type)]; }

TessellationError tessellation_error(const SceneObject& object) {
  const ShapeKind& kind = shape_kind(object.type);
  return kind.tessellation_error ? kind.tessellation_error(object) : TessellationError{};
}

const ShapeKind* find_shape_kind(std::string_view name) {
  for (const ShapeKind* kind : shape_kinds())
    if (name == kind->name) return kind;
  return nullptr;
}

}  // namespace umbra
