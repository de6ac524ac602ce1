#include "request_fields.hpp"

#include <map>
#include <stdexcept>
#include <utility>

#include "request_parser.hpp"

namespace umbra {

FieldUse field_use(const RenderRequest& q, bool sun_down) {
  FieldUse u;
  u.depth = q.output == Output::Depth;
  u.sun = q.light.sun.has_value();
  // A sun below the horizon lights nothing directly: its frame draws no
  // shadow, as if shadows were off (the depth output still draws the map).
  // So fields may come and go from the list while Play crosses sunset.
  u.sun_down = u.sun && sun_down;
  u.shadowed = q.shadow.enabled && !u.sun_down;
  u.shadow_pass = u.shadowed || u.depth;
  u.fixed = q.shadow.fit == FrustumFit::Fixed;
  u.perspective = q.light.projection == LightProjection::Perspective;
  u.filtering = u.shadowed && !u.depth;
  // Filter "exact" reads no bias: its maps prove, or the ray cast decides.
  u.certified = u.filtering && q.shadow.filter == ShadowFilter::Exact;
  u.pcf_used = q.shadow.filter == ShadowFilter::Pcf || (q.shadow.filter == ShadowFilter::Pcss && q.light.size == 0.0);
  // An orthographic light fitted to the scene is fitted to what the camera
  // sees: then the camera and image size shape even the depth map.
  u.camera_fitted = !u.fixed && !u.perspective;
  return u;
}

namespace {

using json = nlohmann::json;
using L = RequestLimits;
using Q = RenderRequest;
using O = SceneObject;
using V = FieldValue;

// Builds a row: FieldRow's members, named where they are set.
template <class Target>
class Row {
 public:
  Row(const char* path, FieldType type, typename FieldRow<Target>::Setter set, const char* doc) {
    f_.path = path;
    f_.type = type;
    f_.set = set;
    f_.doc = doc;
  }
  Row& in(double min, double max, bool open_min = false, bool open_max = false) {
    f_.range = {min, max, open_min, open_max};
    return *this;
  }
  Row& range_rule(typename FieldRow<Target>::RangeRule rule) {
    f_.range_rule = rule;
    return *this;
  }
  Row& choices(std::vector<std::string> choices) {
    f_.choices = std::move(choices);
    return *this;
  }
  Row& numbers(std::vector<double> numbers) {
    f_.numbers = std::move(numbers);
    return *this;
  }
  Row& word(const char* word) {
    f_.word = word;
    return *this;
  }
  Row& by_default(json value) {
    f_.default_value = std::move(value);
    return *this;
  }
  Row& required(const char* message) {
    f_.required = message;
    return *this;
  }
  Row& optional_object() {
    f_.optional_object = true;
    return *this;
  }
  Row& read_late() {
    f_.read_late = true;
    return *this;
  }
  Row& used_when(typename FieldRow<Target>::UseRule rule) {
    f_.used_when = rule;
    return *this;
  }
  Row& written_by(typename FieldRow<Target>::Getter get) {
    f_.get = get;
    return *this;
  }
  Row& schema(const char* schema) {
    f_.schema = schema;
    return *this;
  }
  operator FieldRow<Target>() const { return f_; }

 private:
  FieldRow<Target> f_;
};

using R = Row<Q>;
using OR = Row<O>;

const json kOrigin = json::array({0, 0, 0});

// When a field can change the output (FieldUse).
bool sees_camera(const FieldUse& u) { return !u.depth || u.camera_fitted; }
bool lights_colour(const FieldUse& u) { return !u.depth; }
bool filters(const FieldUse& u) { return u.filtering; }
bool biases(const FieldUse& u) { return u.filtering && !u.certified; }
bool draws_map(const FieldUse& u) { return u.shadow_pass; }
bool fixed_map(const FieldUse& u) { return u.fixed && u.shadow_pass; }

std::vector<RequestField> make_request_fields() {
  const double kCoord = L::kMaxCoordinate;
  return {
      R("width", FieldType::Integer, [](Q& q, const V& v) { q.width = int(v.number); }, "Image width, pixels.")
          .in(16, 4096)
          .by_default(960)
          .used_when(sees_camera),
      R("height", FieldType::Integer, [](Q& q, const V& v) { q.height = int(v.number); }, "Image height, pixels.")
          .in(16, 4096)
          .by_default(540)
          .used_when(sees_camera),
      R("scene", FieldType::Scene, nullptr, "A built-in scene's name (`GET /api/scenes`), or a custom scene.")
          .by_default("cube-on-plane")
          .schema("CustomScene"),
      R("scene.objects", FieldType::ObjectList, nullptr, "At most 1000 objects.")
          .in(0, double(L::kMaxObjects))
          .required("is required for a custom scene"),
      R("camera", FieldType::Object, nullptr, "").schema("Camera").used_when(sees_camera),
      R("camera.position", FieldType::Vec3, [](Q& q, const V& v) { q.camera.position = v.vec; }, "Eye position.")
          .in(-kCoord, kCoord)
          .used_when(sees_camera),
      R("camera.target", FieldType::Vec3, [](Q& q, const V& v) { q.camera.target = v.vec; }, "Point looked at.")
          .in(-kCoord, kCoord)
          .used_when(sees_camera),
      R("camera.up", FieldType::Vec3, [](Q& q, const V& v) { q.camera.up = v.vec; }, "Up vector, non-zero.")
          .in(-kCoord, kCoord)
          .by_default(json::array({0, 1, 0}))
          .used_when(sees_camera),
      R("camera.fov_y_deg", FieldType::Number, [](Q& q, const V& v) { q.camera.fov_y_deg = v.number; },
        "Vertical field of view, degrees")
          .in(L::kMinFovDeg, 180.0, false, true)
          .by_default(45)
          .used_when(sees_camera),
      R("camera.near", FieldType::Number, [](Q& q, const V& v) { q.camera.near_plane = v.number; },
        "Near clip distance, world units, > 0.")
          .in(0.0, L::kMaxExtent, true)
          .by_default(0.1)
          .used_when(sees_camera),
      R("camera.far", FieldType::Number, [](Q& q, const V& v) { q.camera.far_plane = v.number; },
        "Far clip distance, world units, > near")
          .in(0.0, 1e9, true)
          .by_default(100)
          .used_when(sees_camera),
      R("light", FieldType::Object, nullptr, "").schema("Light"),
      R("light.position", FieldType::Vec3, [](Q& q, const V& v) { q.light.position = v.vec; },
        "Orthographic: a directional light, parallel rays travelling position -> target.")
          .in(-kCoord, kCoord)
          // A sun places the light: only the position's distance from the
          // target is kept, which fit "fixed" measures near and far from.
          .used_when([](const FieldUse& u) { return !u.sun || (u.fixed && u.shadow_pass); }),
      R("light.target", FieldType::Vec3, [](Q& q, const V& v) { q.light.target = v.vec; }, "Where the light points.")
          .in(-kCoord, kCoord)
          .by_default(kOrigin),
      R("light.color", FieldType::Color, [](Q& q, const V& v) { q.light.color = v.vec; },
        "A colour: `[r, g, b]` in 0..1 or `\"#rrggbb\"`.")
          .in(0.0, 1.0)
          .by_default(json::array({1, 1, 1}))
          .used_when(lights_colour),
      R("light.ambient", FieldType::Number, [](Q& q, const V& v) { q.light.ambient = v.number; },
        "Ambient fraction, never shadowed")
          .in(0.0, 1.0)
          .by_default(0.3)
          .used_when(lights_colour),
      R("light.projection", FieldType::Choice,
        [](Q& q, const V& v) {
          q.light.projection = v.choice == 0 ? LightProjection::Orthographic : LightProjection::Perspective;
        },
        "The light's shadow projection")
          .choices({"orthographic", "perspective"})
          .by_default("orthographic"),
      R("light.fov_y_deg", FieldType::Number, [](Q& q, const V& v) { q.light.fov_y_deg = v.number; },
        "A perspective light's shadow field of view with `shadow.fit` \"fixed\" only")
          .in(L::kMinFovDeg, 180.0, false, true)
          .by_default(90)
          .used_when([](const FieldUse& u) { return u.fixed && u.perspective; }),
      R("light.size", FieldType::Number, [](Q& q, const V& v) { q.light.size = v.number; },
        "0: an ideal light, hard-edged shadows.")
          .in(0.0, L::kMaxExtent)
          // An orthographic light's size is an angle (light.projection is read first).
          .range_rule([](const Q& q) {
            return FieldRange{0.0, q.light.projection == LightProjection::Perspective ? L::kMaxExtent
                                                                                       : L::kMaxLightAngularSize};
          })
          .by_default(0)
          .used_when(filters),
      R("light.orbit_deg_per_s", FieldType::Number, [](Q& q, const V& v) { q.light.orbit_deg_per_s = v.number; },
        "Orbit speed about +Y through `target`, degrees per second")
          .in(-L::kMaxOrbitSpeed, L::kMaxOrbitSpeed)
          .by_default(20)
          // A sun does not orbit.
          .used_when([](const FieldUse& u) { return !u.sun; }),
      R("light.sun", FieldType::Object, [](Q& q, const V&) { q.light.sun.emplace(); }, "")
          .schema("Sun")
          .optional_object(),
      R("light.sun.latitude", FieldType::Number, [](Q& q, const V& v) { q.light.sun->latitude_deg = v.number; },
        "Degrees, north positive.")
          .in(-90.0, 90.0)
          .required("is required for a sun light"),
      R("light.sun.longitude", FieldType::Number, [](Q& q, const V& v) { q.light.sun->longitude_deg = v.number; },
        "Degrees, east positive.")
          .in(-180.0, 180.0)
          .required("is required for a sun light"),
      // The parser reads the RFC 3339 text; the value is seconds since 1970 (UTC).
      R("light.sun.utc", FieldType::Text, [](Q& q, const V& v) { q.light.sun->utc_unix_s = v.number; },
        "The instant at time 0: an RFC 3339 date-time")
          .required("is required for a sun light"),
      R("light.sun.north_deg", FieldType::Number, [](Q& q, const V& v) { q.light.sun->north_deg = v.number; },
        "Where north is: -Z turned clockwise, seen from above, by this many degrees")
          .in(-360.0, 360.0)
          .by_default(0),
      R("time", FieldType::Number, [](Q& q, const V& v) { q.time = v.number; }, "Animation time, seconds")
          .in(-L::kMaxTime, L::kMaxTime)
          .by_default(0),
      R("shadow", FieldType::Object, nullptr, "").schema("Shadow"),
      R("shadow.enabled", FieldType::Boolean, [](Q& q, const V& v) { q.shadow.enabled = v.flag; },
        "false: no shadow pass; every surface facing the light is lit.")
          .by_default(true)
          // A sun below the horizon draws no shadow either way (but the depth map).
          .used_when([](const FieldUse& u) { return !(u.sun_down && !u.depth); }),
      R("shadow.map_size", FieldType::Integer, [](Q& q, const V& v) { q.shadow.map_size = int(v.number); },
        "Shadow map width = height, texels (per layer).")
          .in(64, 8192)
          .by_default(2048)
          .used_when(draws_map),
      R("shadow.filter", FieldType::Choice, [](Q& q, const V& v) { q.shadow.filter = ShadowFilter(v.choice); },
        "`hard`: one texel.")
          .choices({"hard", "pcf", "pcss", "exact"})
          .by_default("pcf")
          .used_when(filters),
      R("shadow.pcf_radius", FieldType::Integer, [](Q& q, const V& v) { q.shadow.pcf_radius = int(v.number); },
        "PCF kernel half-width r: (2r+1)^2 taps.")
          .in(0, 8)
          .by_default(1)
          .used_when([](const FieldUse& u) { return u.filtering && u.pcf_used; }),
      R("shadow.bias", FieldType::Object, [](Q& q, const V& v) { q.shadow.bias.automatic = v.word; }, "")
          .word("auto")
          .by_default("auto")
          .schema("BiasObject")
          .used_when(biases),
      R("shadow.bias.constant", FieldType::Number, [](Q& q, const V& v) { q.shadow.bias.constant = v.number; },
        "The smallest bias, depth-buffer units")
          .in(0.0, 1.0)
          .by_default(0.005)
          .used_when(biases),
      R("shadow.bias.slope", FieldType::Number, [](Q& q, const V& v) { q.shadow.bias.slope = v.number; },
        "The bias at grazing light is slope x (1 - N.L), depth-buffer units")
          .in(0.0, 1.0)
          .by_default(0.05)
          .used_when(biases),
      R("shadow.bias.normal_offset", FieldType::Number, [](Q& q, const V& v) { q.shadow.bias.normal_offset = v.number; },
        "Texels.")
          .in(0.0, 64.0)
          .by_default(0)
          .used_when(biases),
      R("shadow.cull", FieldType::Choice, [](Q& q, const V& v) { q.shadow.cull = CullMode(v.choice); },
        "Faces culled in the shadow pass")
          .choices({"front", "back", "none"})
          .by_default("front")
          .used_when([](const FieldUse& u) { return u.shadow_pass && !u.certified; }),
      R("shadow.fit", FieldType::Choice, [](Q& q, const V& v) { q.shadow.fit = FrustumFit(v.choice); },
        "`scene`: the light's views, near and far fitted to what the image needs")
          .choices({"scene", "fixed"})
          .by_default("scene")
          .used_when(draws_map),
      // "auto" is 0 (ShadowSettings::cascades); the most is kMaxCascades
      // (core/light_math.hpp, which the server does not see: a test holds them equal).
      R("shadow.cascades", FieldType::Integer,
        [](Q& q, const V& v) { q.shadow.cascades = v.word ? 0 : int(v.number); },
        "Orthographic light with fit \"scene\" only")
          .in(1, 4)
          .word("auto")
          .by_default("auto")
          .used_when([](const FieldUse& u) { return !u.fixed && !u.perspective && u.shadow_pass; }),
      R("shadow.ortho_half_size", FieldType::Number, [](Q& q, const V& v) { q.shadow.ortho_half_size = v.number; },
        "Fit \"fixed\", orthographic light: half the side of the light's square frustum, world units.")
          .in(L::kMinExtent, L::kMaxExtent)
          .by_default(10)
          .used_when([](const FieldUse& u) { return u.fixed && !u.perspective && u.shadow_pass; }),
      R("shadow.near", FieldType::Number, [](Q& q, const V& v) { q.shadow.near_plane = v.number; },
        "Fit \"fixed\": the light's near plane")
          .in(-L::kMaxExtent, L::kMaxExtent)
          .by_default(1.0)
          .used_when(fixed_map),
      R("shadow.far", FieldType::Number, [](Q& q, const V& v) { q.shadow.far_plane = v.number; },
        "Fit \"fixed\": the light's far plane, > near.")
          .in(-L::kMaxExtent, L::kMaxExtent)
          .by_default(7.5)
          .used_when(fixed_map),
      R("output", FieldType::Choice, [](Q& q, const V& v) { q.output = Output(v.choice); }, "`color`: the lit frame, RGB.")
          .choices({"color", "depth", "shadow", "exact", "error"})
          .by_default("color"),
      R("depth_bits", FieldType::IntegerChoice, [](Q& q, const V& v) { q.depth_bits = int(v.number); },
        "Bits per sample of the `depth` output's grey PNG")
          .numbers({8, 16})
          .by_default(8)
          .used_when([](const FieldUse& u) { return u.depth; }),
  };
}

// The rows every primitive shares: where it is and its colour, read after
// its own fields.
// Getters of the common kinds: the member as it is stored.
template <glm::dvec3 O::*member>
bool vector_of(const O& o, V& v) {
  v.vec = o.*member;
  return true;
}
template <double O::*member>
bool number_of(const O& o, V& v) {
  v.number = o.*member;
  return true;
}

ObjectField center_row() {
  return OR("center", FieldType::Vec3, [](O& o, const V& v) { o.center = v.vec; }, "Its centre.")
      .written_by(vector_of<&O::center>)
      .in(-L::kMaxCoordinate, L::kMaxCoordinate)
      .by_default(kOrigin)
      .read_late();
}
ObjectField color_row() {
  return OR("color", FieldType::Color, [](O& o, const V& v) { o.color = v.vec; },
            "A colour: `[r, g, b]` in 0..1 or `\"#rrggbb\"`.")
      .written_by(vector_of<&O::color>)
      .in(0.0, 1.0)
      .by_default(json::array({0.8, 0.8, 0.8}))
      .read_late();
}

std::vector<ShapeFields> make_shape_fields() {
  std::vector<ShapeFields> shapes;
  shapes.push_back({"plane", O::Type::Plane, "PlaneObject",
                    {center_row(),
                     OR("size", FieldType::Size2, [](O& o, const V& v) { o.size = v.vec; },
                        "[sx, sz], full edge lengths along X and Z.")
                         .written_by(vector_of<&O::size>)
                         .in(L::kMinExtent, L::kMaxExtent)
                         .by_default(json::array({10, 10})),
                     color_row()}});
  shapes.push_back({"box", O::Type::Box, "BoxObject",
                    {center_row(),
                     OR("size", FieldType::Vec3, [](O& o, const V& v) { o.size = v.vec; }, "[sx, sy, sz], full edge lengths.")
                         .written_by(vector_of<&O::size>)
                         .in(L::kMinExtent, L::kMaxExtent)
                         .by_default(json::array({1, 1, 1})),
                     OR("rotation_y_deg", FieldType::Number, [](O& o, const V& v) { o.rotation_y_deg = v.number; },
                        "Rotation about its own vertical axis, degrees, counter-clockwise seen from +Y.")
                         .written_by(number_of<&O::rotation_y_deg>)
                         .in(-36000.0, 36000.0)
                         .by_default(0),
                     color_row()}});
  shapes.push_back({"sphere", O::Type::Sphere, "SphereObject",
                    {center_row(),
                     OR("radius", FieldType::Number, [](O& o, const V& v) { o.radius = v.number; }, "Radius, world units.")
                         .written_by(number_of<&O::radius>)
                         .in(L::kMinExtent, L::kMaxExtent)
                         .by_default(0.5),
                     color_row()}});
  shapes.push_back(
      {"mesh", O::Type::Mesh, "MeshObject",
       {// Looked up by the parser among the server's and the built-in models.
        OR("model", FieldType::Text, nullptr, "A held model's id (`sha256:<hex>`) or name")
            .written_by([](const O& o, V& v) {
              v.text = o.model_id;
              return true;
            })
            .required("is required: a model's id or name; "),
        // Read by the parser after "model" (it names one of that model's animations).
        OR("animation", FieldType::Animation, nullptr,
           "One of the model's animations, played at the request's `time`: its name or index, or "
           "`{\"name\" | \"index\", \"speed\", \"loop\"}`")
            .written_by([](const O& o, V& v) {
              if (!o.animation) return false;
              v.object = json::object();
              if (!o.animation->name.empty())
                v.object["name"] = o.animation->name;
              else
                v.object["index"] = o.animation->index;
              v.object["speed"] = o.animation->speed;
              v.object["loop"] = o.animation->loop;
              return true;
            }),
        OR("position", FieldType::Vec3, [](O& o, const V& v) { o.center = v.vec; }, "Where the model-space origin goes.")
            .written_by(vector_of<&O::center>)
            .in(-L::kMaxCoordinate, L::kMaxCoordinate)
            .by_default(kOrigin),
        OR("rotation_deg", FieldType::Vec3, [](O& o, const V& v) { o.rotation_deg = v.vec; },
           "Rotations about X, Y and Z, degrees, right-handed; X applied first.")
            .written_by(vector_of<&O::rotation_deg>)
            .in(-36000.0, 36000.0)
            .by_default(kOrigin),
        OR("scale", FieldType::NumberOrVec3, [](O& o, const V& v) { o.mesh_scale = v.vec; }, "A number, or [sx, sy, sz].")
            .written_by(vector_of<&O::mesh_scale>)
            .in(L::kMinExtent, L::kMaxExtent)
            .by_default(1),
        // No default: the model's own base colours.
        OR("color", FieldType::Color,
           [](O& o, const V& v) {
             o.color = v.vec;
             o.mesh_color_override = true;
           },
           "Overrides every base colour of the model.")
            .written_by([](const O& o, V& v) {
              v.vec = o.color;
              return o.mesh_color_override;
            })
            .in(0.0, 1.0)}});
  // A vertical axis whose middle is `center`, capped (core/shapes/cylinder.cpp):
  // its height is stored as size.y, as a box's.
  shapes.push_back({"cylinder", O::Type::Cylinder, "CylinderObject",
                    {center_row(),
                     OR("radius", FieldType::Number, [](O& o, const V& v) { o.radius = v.number; }, "Radius, world units.")
                         .written_by(number_of<&O::radius>)
                         .in(L::kMinExtent, L::kMaxExtent)
                         .by_default(0.5),
                     OR("height", FieldType::Number, [](O& o, const V& v) { o.size.y = v.number; },
                        "Height along its vertical axis, world units; `center` is its middle.")
                         .written_by([](const O& o, V& v) {
                           v.number = o.size.y;
                           return true;
                         })
                         .in(L::kMinExtent, L::kMaxExtent)
                         .by_default(1),
                     color_row()}});
  return shapes;
}

}  // namespace

const std::vector<RequestField>& request_fields() {
  static const std::vector<RequestField> rows = make_request_fields();
  return rows;
}

const std::vector<const RequestField*>& request_fields_in(std::string_view parent) {
  static const std::map<std::string, std::vector<const RequestField*>, std::less<>> by_parent = [] {
    std::map<std::string, std::vector<const RequestField*>, std::less<>> m;
    for (const RequestField& row : request_fields()) m[row.parent()].push_back(&row);
    return m;
  }();
  static const std::vector<const RequestField*> none;
  const auto it = by_parent.find(parent);
  return it == by_parent.end() ? none : it->second;
}

const RequestField& request_field(std::string_view path) {
  for (const RequestField& row : request_fields())
    if (row.path == path) return row;
  throw std::out_of_range("no request field " + std::string(path));
}

const std::vector<ShapeFields>& shape_fields() {
  static const std::vector<ShapeFields> shapes = make_shape_fields();
  return shapes;
}

const ShapeFields& shape_fields_of(SceneObject::Type kind) {
  for (const ShapeFields& shape : shape_fields())
    if (shape.kind == kind) return shape;
  throw std::out_of_range("no fields for this object type");
}

namespace {

// A value as the parser reads it for `row`'s type.
json write_value(const ObjectField& row, const FieldValue& v) {
  switch (row.type) {
    case FieldType::Integer:
    case FieldType::IntegerChoice:
    case FieldType::Number: return v.number;
    case FieldType::Boolean: return v.flag;
    case FieldType::Choice: return row.choices.at(v.choice);
    case FieldType::Size2: return json::array({v.vec.x, v.vec.z});
    case FieldType::Vec3:
    case FieldType::Color:
    case FieldType::NumberOrVec3: return json::array({v.vec.x, v.vec.y, v.vec.z});
    case FieldType::Text: return v.text;
    case FieldType::Animation: return v.object;
    case FieldType::Object:
    case FieldType::Scene:
    case FieldType::ObjectList: break;
  }
  throw std::logic_error("write_value: an object field of type " + std::to_string(int(row.type)) + " (" + row.path + ")");
}

}  // namespace

json write_object(const SceneObject& object) {
  const ShapeFields& shape = shape_fields_of(object.type);
  json j = {{"type", shape.type}};
  for (const ObjectField& row : shape.rows) {
    FieldValue v;
    if (row.get && row.get(object, v)) j[row.key()] = write_value(row, v);
  }
  return j;
}

}  // namespace umbra
