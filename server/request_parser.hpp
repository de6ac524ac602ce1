// JSON body -> typed, validated RenderRequest. Pure: no GL, no HTTP.
//
// The one place where the API's defaults are applied and every bad input of
// docs/api.md is rejected: malformed JSON, wrong types, unknown fields,
// out-of-range or non-finite numbers, degenerate inputs, unknown scenes.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/request.hpp"

namespace umbra {

/// Why a body was rejected. `field` is the JSON path of the offending value
/// ("light.color[1]", "scene.objects[3].size"), or "" for the body as a whole.
struct RequestError {
  std::string message;
  std::string field;
};

struct ParsedRequest {
  std::optional<RenderRequest> request;  ///< set on success
  RequestError error;                     ///< set on failure
  /// Fields the client sent that cannot affect this output (e.g. shadow.near
  /// with fit "scene"): accepted, since the contract's own default body
  /// (docs/api.md) includes them, but reported back so that nothing is
  /// silently ignored. On /api/depth, an `output` other than "depth" is
  /// listed too.
  std::vector<std::string> unused_fields;

  bool ok() const { return request.has_value(); }
};

/// Limits beyond the original contract's, chosen so every accepted request
/// renders in bounded time and in float precision. Documented in docs/api.md.
struct RequestLimits {
  static constexpr std::size_t kMaxObjects = 1000;
  static constexpr int kMaxNesting = 32;            ///< JSON nesting depth
  static constexpr double kMaxCoordinate = 1e6;     ///< |x|, |y|, |z| of any position
  static constexpr double kMinExtent = 1e-6;        ///< smallest size / radius
  static constexpr double kMaxExtent = 1e6;         ///< largest size / radius
  static constexpr double kMaxAnimationSpeed = 1000;  ///< |speed| of a mesh's animation
  static constexpr double kMaxTime = 1e9;           ///< |time|, seconds
  static constexpr double kMaxOrbitSpeed = 1e6;     ///< |orbit_deg_per_s|
  static constexpr double kMaxLightAngularSize = 90.0;
  /// light.sun.utc: years 0001 to kMaxSunYear. NREL SPA is valid for years
  /// -2000 to 6000, so the clock stays inside it with any `time`
  /// (|time| <= kMaxTime is under 32 years).
  static constexpr int kMaxSunYear = 5000;
  static constexpr double kMinSunUnixSeconds = -62135596800.0;  ///< 0001-01-01T00:00:00Z
  static constexpr double kMaxSunUnixSeconds = 95649120000.0;   ///< 5001-01-01T00:00:00Z
  /// Narrowest field of view, degrees (camera and light): below it a
  /// projection's scale (1 / tan(fov / 2)) leaves float range and the frame
  /// would come back empty.
  static constexpr double kMinFovDeg = 1e-3;
  /// Longest piece of a client's own text (a string value, a key) that an
  /// error message quotes back, bytes; the rest is cut and counted.
  static constexpr std::size_t kMaxQuotedBytes = 64;
};

/// Where the body was posted. POST /api/depth always renders the depth map:
/// its body's `output` may be any value /api/render takes (the same body,
/// docs/api.md), and one other than "depth" is reported in `unused_fields`.
/// The parser needs to know, so that fields are judged used or unused
/// against the output that is really drawn.
enum class Route { Render, Depth };

/// A model that a mesh object names, as the server holds it.
struct FoundModel {
  std::string id;  ///< "sha256:...", whatever name found it
  std::shared_ptr<const TriangleModel> model;
};
/// Finds a model by id or name (ModelStore::find); nullopt if none is held.
using ModelLookup = std::function<std::optional<FoundModel>(const std::string& id_or_name)>;

/// Told every distinct model key ("model" of a mesh object) a custom scene
/// names, in order, once the JSON is read and before find_model is asked
/// for any: so that a server can count what it would load against its
/// budget first (and refuse by throwing, which parse_render_request lets
/// through). Not called for a body that is not JSON or names no model.
using ModelsNamed = std::function<void(const std::vector<std::string>& keys)>;

/// `find_model` resolves mesh objects' "model"; a name or id it does not
/// know is looked up among the built-in models (builtin_models.hpp), and
/// refused as an unknown model if it is not one of them either.
ParsedRequest parse_render_request(std::string_view body, Route route = Route::Render,
                                   const ModelLookup& find_model = {}, const ModelsNamed& models_named = {});

/// A body read as JSON the way parse_render_request reads it: duplicate
/// keys, absurd nesting and bad numbers refused, naming the field they are
/// in. An empty body (or only spaces) is {}.
struct ParsedJson {
  nlohmann::json value;
  std::optional<RequestError> error;  ///< set: not JSON, or refused
};
ParsedJson read_json_body(std::string_view body);

/// parse_render_request's second half: a JSON value already read (by
/// read_json_body) to a RenderRequest. POST /api/sun-hours reads its
/// `scene` through this, so that a scene means the same on every route.
ParsedRequest parse_render_json(const nlohmann::json& root, Route route = Route::Render,
                                const ModelLookup& find_model = {}, const ModelsNamed& models_named = {});

}  // namespace umbra
