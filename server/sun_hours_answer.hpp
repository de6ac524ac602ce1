// What POST /api/sun-hours answers, by the request's Accept header: the
// JSON document or the CSV table of docs/api.md. Pure: no GL, no sockets.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "core/sun_hours.hpp"

namespace umbra {

enum class SunHoursFormat { Json, Csv };

/// The format an Accept header asks for: the media range with the highest
/// q that application/json or text/csv match (JSON on a tie, and when the
/// header is absent or empty); nullopt when it accepts neither (406).
std::optional<SunHoursFormat> sun_hours_format(std::string_view accept);

/// The JSON answer: the grid, hours and longest run per point (row-major,
/// row 0 first), the pass share when require_hours was given, the pairs
/// and the path that settled them, and with include_samples the samples.
std::string sun_hours_json(const SunHoursRequest& request, const SunHoursResult& result);

/// The CSV answer: a header line, then one line per point (row-major):
/// x,y,z,hours,longest_run_hours.
std::string sun_hours_csv(const SunHoursRequest& request, const SunHoursResult& result);

/// An instant as RFC 3339 UTC: whole seconds, or with the fraction where
/// there is one (a 45-second step's half is 22.5 s).
std::string sun_hours_utc(double unix_seconds);

}  // namespace umbra
