#include "sun_hours_parser.hpp"

#include <cmath>
#include <set>
#include <string>

namespace umbra {

namespace {

using json = nlohmann::json;

struct Refusal {
  std::string field, message;
};

[[noreturn]] void refuse(const std::string& field, const std::string& message) { throw Refusal{field, message}; }

std::string join(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }

std::string number_text(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.10g", v);
  return buffer;
}

const char* type_of(const json& j) {
  if (j.is_object()) return "an object";
  if (j.is_array()) return "an array";
  if (j.is_string()) return "a string";
  if (j.is_boolean()) return "a boolean";
  if (j.is_null()) return "null";
  return "a number";
}

// The members of object `j` (at `path`), refusing any key not in `known`.
const json& object_at(const json& j, const std::string& path, const std::set<std::string>& known) {
  if (!j.is_object()) refuse(path, "must be an object, not " + std::string(type_of(j)));
  for (const auto& item : j.items())
    if (!known.count(item.key())) {
      std::string list;
      for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
      refuse(join(path, item.key()), "unknown field (expected one of: " + list + ")");
    }
  return j;
}

double number_at(const json& j, const std::string& path, double lo, double hi, bool open_lo = false) {
  if (!j.is_number()) refuse(path, "must be a number, not " + std::string(type_of(j)));
  const double v = j.get<double>();
  if (!std::isfinite(v) || v > hi || (open_lo ? v <= lo : v < lo))
    refuse(path, number_text(v) + " is out of range " + (open_lo ? "(" : "[") + number_text(lo) + ", " +
                     number_text(hi) + "]");
  return v;
}

bool boolean_at(const json& j, const std::string& path) {
  if (!j.is_boolean()) refuse(path, "must be true or false, not " + std::string(type_of(j)));
  return j.get<bool>();
}

double utc_at(const json& j, const std::string& path) {
  if (!j.is_string()) refuse(path, "must be an RFC 3339 date-time string, not " + std::string(type_of(j)));
  std::string why;
  const std::string& text = j.get_ref<const std::string&>();
  const std::optional<double> instant = parse_utc(text, &why);
  if (!instant)
    refuse(path, "\"" + text.substr(0, RequestLimits::kMaxQuotedBytes) + "\" is not an RFC 3339 date-time: " + why);
  if (*instant < RequestLimits::kMinSunUnixSeconds || *instant > RequestLimits::kMaxSunUnixSeconds)
    refuse(path, "must lie in years 0001 to " + std::to_string(RequestLimits::kMaxSunYear) + " (UTC)");
  return *instant;
}

const json* member(const json& j, const char* key) {
  const auto it = j.find(key);
  return it == j.end() ? nullptr : &*it;
}

const json& required(const json& j, const std::string& path, const char* key) {
  const json* m = member(j, key);
  if (!m) refuse(join(path, key), "is required");
  return *m;
}

SunSite read_site(const json& j) {
  object_at(j, "site", {"latitude", "longitude", "north_deg"});
  SunSite site;
  site.latitude_deg = number_at(required(j, "site", "latitude"), "site.latitude", -90.0, 90.0);
  site.longitude_deg = number_at(required(j, "site", "longitude"), "site.longitude", -180.0, 180.0);
  if (const json* n = member(j, "north_deg")) site.north_deg = number_at(*n, "site.north_deg", -360.0, 360.0);
  return site;
}

SunPeriod read_period(const json& j, std::size_t& samples) {
  object_at(j, "period", {"start", "end", "step_minutes"});
  SunPeriod period;
  period.start_unix_s = utc_at(required(j, "period", "start"), "period.start");
  period.end_unix_s = utc_at(required(j, "period", "end"), "period.end");
  if (const json* s = member(j, "step_minutes"))
    period.step_minutes = number_at(*s, "period.step_minutes", SunHoursLimits::kMinStepMinutes,
                                    SunHoursLimits::kMaxStepMinutes);
  if (!(period.end_unix_s > period.start_unix_s))
    refuse("period.end", format_utc(period.end_unix_s) + " is not after period.start (" +
                             format_utc(period.start_unix_s) + ")");
  const double steps = (period.end_unix_s - period.start_unix_s) / period.step_seconds();
  if (steps > double(SunHoursLimits::kMaxSamples))
    refuse("period.step_minutes", "the period holds about " + number_text(std::round(steps)) +
                                      " samples of this step, over the limit of " +
                                      std::to_string(SunHoursLimits::kMaxSamples) +
                                      " (a year at 30-second steps): take a longer step or a shorter period");
  const std::optional<std::size_t> n = sample_count(period);
  if (!n)
    refuse("period.step_minutes", "the period (" + number_text(steps * period.step_minutes) +
                                      " minutes) is not a whole number of steps of " +
                                      number_text(period.step_minutes) + " minutes");
  samples = *n;
  return period;
}

// size / spacing, when it is a whole number of cells (to 1e-9 of a cell).
int cells(double size, double spacing, const std::string& path) {
  const double n = size / spacing, whole = std::round(n);
  if (std::abs(n - whole) > 1e-9 * std::max(1.0, whole) || whole < 1.0)
    refuse("grid.spacing", path + " " + number_text(size) + " is not a whole number of cells of " +
                               number_text(spacing) + " (" + number_text(n) + ")");
  if (whole > double(SunHoursLimits::kMaxPoints))
    refuse("grid.spacing", path + " " + number_text(size) + " holds " + number_text(whole) + " cells of " +
                               number_text(spacing) + ", over the limit of " +
                               std::to_string(SunHoursLimits::kMaxPoints) + " points");
  return int(whole);
}

SunGrid read_grid(const json& j) {
  object_at(j, "grid", {"center", "size", "spacing"});
  SunGrid grid;
  if (const json* c = member(j, "center")) {
    if (!c->is_array() || c->size() != 3) refuse("grid.center", "must be [x, y, z]");
    for (int i = 0; i < 3; ++i)
      grid.center[i] = number_at((*c)[std::size_t(i)], "grid.center[" + std::to_string(i) + "]",
                                 -RequestLimits::kMaxCoordinate, RequestLimits::kMaxCoordinate);
  }
  const json& size = required(j, "grid", "size");
  if (!size.is_array() || size.size() != 2) refuse("grid.size", "must be [size_x, size_z]");
  grid.size_x = number_at(size[0], "grid.size[0]", 0.0, 2.0 * RequestLimits::kMaxCoordinate, true);
  grid.size_z = number_at(size[1], "grid.size[1]", 0.0, 2.0 * RequestLimits::kMaxCoordinate, true);
  grid.spacing = number_at(required(j, "grid", "spacing"), "grid.spacing", RequestLimits::kMinExtent,
                           RequestLimits::kMaxExtent);
  grid.columns = cells(grid.size_x, grid.spacing, "grid.size[0]");
  grid.rows = cells(grid.size_z, grid.spacing, "grid.size[1]");
  if (double(grid.columns) * double(grid.rows) > double(SunHoursLimits::kMaxPoints))
    refuse("grid.spacing", "the grid has " + std::to_string(grid.columns) + " x " + std::to_string(grid.rows) +
                               " points, over the limit of " + std::to_string(SunHoursLimits::kMaxPoints));
  return grid;
}

}  // namespace

ParsedSunHours parse_sun_hours_request(std::string_view body, const ModelLookup& find_model,
                                       const ModelsNamed& models_named) {
  ParsedSunHours result;
  ParsedJson read = read_json_body(body);
  if (read.error) {
    result.error = *read.error;
    return result;
  }
  const json& root = read.value;
  try {
    object_at(root, "", {"scene", "camera", "width", "height", "site", "period", "grid", "require_hours", "exact",
                         "include_samples"});
    SunHoursRequest q;
    q.site = read_site(required(root, "", "site"));
    q.period = read_period(required(root, "", "period"), result.samples);
    if (const json* grid = member(root, "grid")) {
      q.grid = read_grid(*grid);
      result.grid_given = true;
    } else {
      q.grid.columns = q.grid.rows = 0;
    }
    if (const json* h = member(root, "require_hours")) q.require_hours = number_at(*h, "require_hours", 0.0, 1e6);
    if (const json* e = member(root, "exact")) q.exact = boolean_at(*e, "exact");
    if (const json* s = member(root, "include_samples")) q.include_samples = boolean_at(*s, "include_samples");
    // The scene as /api/render reads it (its errors name "scene..." alike).
    json view = json::object();
    for (const char* key : {"scene", "camera", "width", "height"})
      if (const json* value = member(root, key)) {
        view[key] = *value;
        if (std::string(key) != "scene") result.picture_fields.push_back(key);
      }
    ParsedRequest parsed = parse_render_json(view, Route::Render, find_model, models_named);
    if (!parsed.ok()) {
      result.error = parsed.error;
      return result;
    }
    q.view = std::move(*parsed.request);
    if (const json* scene = member(root, "scene"); scene && scene->is_object())
      if (const json* objects = member(*scene, "objects"); objects && objects->is_array())
        for (std::size_t i = 0; i < objects->size(); ++i)
          if ((*objects)[i].is_object() && (*objects)[i].contains("color"))
            result.colour_fields.push_back("scene.objects[" + std::to_string(i) + "].color");
    result.request = std::move(q);
  } catch (const Refusal& r) {
    result.error = {r.message, r.field};
  }
  return result;
}

}  // namespace umbra
