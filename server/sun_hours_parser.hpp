// JSON body of POST /api/sun-hours -> typed, validated SunHoursRequest.
// Pure: no GL, no HTTP. Its `scene` is read by the render request's own
// parser (parse_render_json), so a scene means the same on every route;
// the rest (site, period, grid, require_hours, exact, include_samples) is
// read here. Every refusal names the field (docs/api.md).
#pragma once

#include <optional>
#include <string_view>

#include "core/sun_hours.hpp"
#include "request_parser.hpp"

namespace umbra {

struct ParsedSunHours {
  std::optional<SunHoursRequest> request;  ///< set on success
  RequestError error;                       ///< set on failure
  std::size_t samples = 0;                  ///< the period's sample count, on success
  /// The picture's fields sent (camera, width, height): used by the
  /// image/png answer only.
  std::vector<std::string> picture_fields;
  /// The objects' colours sent (scene.objects[i].color): no answer shows
  /// them, the picture colours every surface by its hours.
  std::vector<std::string> colour_fields;
  bool grid_given = false;
  bool ok() const { return request.has_value(); }
};

ParsedSunHours parse_sun_hours_request(std::string_view body, const ModelLookup& find_model = {},
                                       const ModelsNamed& models_named = {});

}  // namespace umbra
