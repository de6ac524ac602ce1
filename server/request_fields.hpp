// The render request's fields, one row each: the JSON path, the member the
// value fills, its type, range, choices and default, when it can change the
// output, and its doc line. Pure data (no GL, no parsing): the parser
// (request_parser.cpp) reads bodies through these rows, Umbra-Unused-Fields
// comes from their `used_when`, and tests/test_api_document.cpp holds
// docs/openapi.json to them row by row.
//
// A scene object's fields are rows too, one group per object type
// (shape_fields()): a new type is one more group and its rows.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include <glm/vec3.hpp>
#include <nlohmann/json.hpp>

#include "core/request.hpp"

namespace umbra {

/// How a field's JSON value is read (request_parser.cpp, read_value).
enum class FieldType {
  Integer,        ///< a whole number in `range`; or the row's `word` ("auto")
  IntegerChoice,  ///< one of `numbers` (depth_bits: 8 or 16)
  Number,         ///< a finite number in `range`
  Boolean,        ///< true or false
  Choice,         ///< one of the strings `choices`; FieldValue::choice is its position
  Vec3,           ///< [x, y, z], each in `range`
  Size2,          ///< [sx, sz], each in `range`: a plane's size, stored (sx, 0, sz)
  Color,          ///< [r, g, b] each in [0, 1], or "#rrggbb"
  NumberOrVec3,   ///< a number n (stored (n, n, n)) or [x, y, z], each in `range`
  Text,           ///< a string the parser interprets itself (light.sun.utc, a mesh's model)
  Animation,      ///< a mesh's animation: a name, an index, or {name | index, speed, loop}
  Object,         ///< the rows below this path; or the row's `word` ("auto")
  Scene,          ///< a built-in scene's name, or an object of the rows below (the parser's)
  ObjectList,     ///< an array of scene objects, each read by its type's group (shape_fields)
};

/// A numeric range: [min, max], either end open where it says so.
struct FieldRange {
  double min = 0.0;
  double max = 0.0;
  bool open_min = false;
  bool open_max = false;
};

/// A value as read from JSON: what a row's setter stores in its member.
struct FieldValue {
  bool flag = false;       ///< Boolean
  double number = 0.0;     ///< Integer, IntegerChoice, Number
  glm::dvec3 vec{0.0};     ///< Vec3, Size2 as (sx, 0, sz), Color, NumberOrVec3
  std::size_t choice = 0;  ///< Choice: the position in the row's `choices`
  bool word = false;       ///< the row's `word` was given instead of a value
  std::string text;        ///< Text, as written (a row's getter: a mesh's model id)
  nlohmann::json object;   ///< Animation, as the parser reads it back (a row's getter)
};

/// What decides whether a field can change the output asked for: the rows'
/// `used_when` read these, and Umbra-Unused-Fields lists every field sent
/// whose row says it is not used.
struct FieldUse {
  bool depth = false;          ///< the depth output (or POST /api/depth)
  bool sun = false;            ///< light.sun given
  bool sun_down = false;       ///< a sun below the horizon: no direct light, no shadow
  bool shadowed = false;       ///< shadows are drawn in the frame
  bool shadow_pass = false;    ///< a shadow map is rendered (shadowed, or the depth output)
  bool fixed = false;          ///< shadow.fit "fixed"
  bool perspective = false;    ///< a perspective light
  bool filtering = false;      ///< the frame samples a shadow map (shadowed, not depth)
  bool certified = false;      ///< ... with filter "exact": no bias, every face drawn
  bool pcf_used = false;       ///< the filter runs PCF (pcf, or pcss with an ideal light)
  bool camera_fitted = false;  ///< an orthographic light fitted to the scene: to what the camera sees
};
/// `sun_down`: whether a sun light is below the horizon at the request's time.
FieldUse field_use(const RenderRequest& request, bool sun_down);

/// One field. Target: RenderRequest for the body's fields, SceneObject for
/// an object's.
template <class Target>
struct FieldRow {
  using Setter = void (*)(Target&, const FieldValue&);
  /// Reads the member back for the JSON writer (write_object): false where
  /// the field is not written (a mesh's colour it does not override).
  using Getter = bool (*)(const Target&, FieldValue&);
  using RangeRule = FieldRange (*)(const Target&);
  using UseRule = bool (*)(const FieldUse&);

  /// Body fields: the dotted path from the body's root ("shadow.bias.slope").
  /// Object fields: the key inside the object ("size").
  std::string path;
  FieldType type = FieldType::Number;
  /// Stores a read value in the member it fills (Object rows: called before
  /// the rows below are read, with `word` set when the word was given).
  Setter set = nullptr;
  /// The setter's inverse, for the JSON writer; object fields have one each.
  Getter get = nullptr;
  /// Numbers, integers, and each component of a vector. The document's range.
  FieldRange range{};
  /// Set where the range depends on fields read before this one (light.size:
  /// at most 90 degrees for an orthographic light): replaces `range` then.
  RangeRule range_rule = nullptr;
  std::vector<std::string> choices;  ///< Choice
  std::vector<double> numbers;       ///< IntegerChoice
  /// A string also taken instead of a value ("auto": shadow.cascades, shadow.bias).
  std::string word;
  /// The API's default, as JSON, applied by the parser through the row's own
  /// reader; null where there is none or it depends on the scene.
  nlohmann::json default_value;
  /// Set: the message when the field is left out (it is required).
  std::string required;
  /// Object rows: absent unless sent (light.sun); the rows below get their
  /// defaults only when it is.
  bool optional_object = false;
  /// Object fields: read after the type's own fields (a shape's center and
  /// color): the order in which a body with several bad fields is refused.
  bool read_late = false;
  /// When the field can change the output; null: always.
  UseRule used_when = nullptr;
  /// Object rows: the component of docs/openapi.json that describes them.
  std::string schema;
  /// A phrase of the field's description in docs/openapi.json.
  std::string doc;

  /// The last part of the path: the field's JSON key.
  std::string key() const {
    const auto dot = path.rfind('.');
    return dot == std::string::npos ? path : path.substr(dot + 1);
  }
  /// The path of the object that holds it ("" for the body's root).
  std::string parent() const {
    const auto dot = path.rfind('.');
    return dot == std::string::npos ? "" : path.substr(0, dot);
  }
  bool used(const FieldUse& use) const { return used_when == nullptr || used_when(use); }
};

using RequestField = FieldRow<RenderRequest>;
using ObjectField = FieldRow<SceneObject>;

/// One scene object type: its "type" name and its rows (after "type", in the
/// order the API lists them).
struct ShapeFields {
  std::string type;  ///< the "type" value: "plane"
  SceneObject::Type kind;
  std::string schema;  ///< its component in docs/openapi.json: "PlaneObject"
  std::vector<ObjectField> rows;
};

/// The document's component for the body itself.
inline constexpr const char* kRequestSchema = "RenderRequest";

/// Every field of a body, each object's rows after its own row, in the order
/// the API lists them (the order of "unknown field (expected one of: ...)").
const std::vector<RequestField>& request_fields();
/// The rows directly inside the object at `parent` ("" for the root), in order.
const std::vector<const RequestField*>& request_fields_in(std::string_view parent);
/// The row at `path`; throws std::out_of_range if there is none.
const RequestField& request_field(std::string_view path);

/// The scene object types, in the order the API lists them.
const std::vector<ShapeFields>& shape_fields();
/// The group of `kind`; throws std::out_of_range if there is none.
const ShapeFields& shape_fields_of(SceneObject::Type kind);

/// `object` as the API writes it (GET /api/scenes): its "type" and every
/// field its rows read back, in the form the parser reads (a plane's size
/// as [sx, sz]). Parsing it gives the same object.
nlohmann::json write_object(const SceneObject& object);

}  // namespace umbra
