// What POST /api/sun-hours answers, by the request's Accept header: the
// JSON document or the CSV table of docs/api.md. Pure: no GL, no sockets.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "core/image.hpp"
#include "core/sun_hours.hpp"

namespace umbra {

enum class SunHoursFormat { Json, Csv, Png };

/// The format an Accept header asks for: the media range with the highest
/// q that application/json, text/csv or image/png match (in that order of
/// preference on a tie; JSON when the header is absent or empty); nullopt
/// when it accepts none of them (406).
/// With `png` false (a job posted for a grid), image/png is not among the
/// formats and the best of the other two is chosen.
std::optional<SunHoursFormat> sun_hours_format(std::string_view accept, bool png = true);

/// The JSON answer: the grid, hours and longest run per point (row-major,
/// row 0 first), the pass share when require_hours was given, the pairs
/// and the path that settled them, and with include_samples the samples.
std::string sun_hours_json(const SunHoursRequest& request, const SunHoursResult& result);

/// The CSV answer: a header line, then one line per point (row-major):
/// x,y,z,hours,longest_run_hours.
std::string sun_hours_csv(const SunHoursRequest& request, const SunHoursResult& result);

/// The image/png answer: the camera's view coloured by hours, with the
/// legend drawn in (sun_hours_picture.hpp): the scale up to the sun-up
/// hours of the period, the threshold, the place, the period and step, the
/// grid's pass share when there is a grid, and the path.
Image sun_hours_image(const SunHoursRequest& request, const SunHoursResult& result);

/// An instant as RFC 3339 UTC: whole seconds, or with the fraction where
/// there is one (a 45-second step's half is 22.5 s).
std::string sun_hours_utc(double unix_seconds);

}  // namespace umbra
