#include "sun_hours_answer.hpp"

#include "sun_hours_picture.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include <nlohmann/json.hpp>

namespace umbra {

namespace {

std::string lower(std::string_view text) {
  std::string out(text);
  for (char& c : out) c = char(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string trim(std::string_view text) {
  std::size_t a = 0, b = text.size();
  while (a < b && std::isspace(static_cast<unsigned char>(text[a]))) ++a;
  while (b > a && std::isspace(static_cast<unsigned char>(text[b - 1]))) --b;
  return std::string(text.substr(a, b - a));
}

// How well `range` ("text/*", "*/*", "text/csv") matches `type`: 3 exact,
// 2 subtype wildcard, 1 any, 0 none.
int specificity(const std::string& range, const std::string& type) {
  if (range == type) return 3;
  if (range == "*/*") return 1;
  const auto slash = type.find('/');
  if (range.size() == slash + 2 && range.compare(0, slash + 1, type, 0, slash + 1) == 0 && range.back() == '*') return 2;
  return 0;
}

// RFC 9110 12.4.2: qvalue = ( "0" [ "." 0*3DIGIT ] ) / ( "1" [ "." 0*3("0") ] ).
// Anything else ("nan", "-1", "2", "0.5e1") makes its range unacceptable (0):
// a malformed weight must not outrank the others.
double qvalue(std::string_view text) {
  if (text.empty() || text.size() > 5 || (text[0] != '0' && text[0] != '1')) return 0.0;
  if (text.size() > 1 && (text[1] != '.' || text.size() == 2)) return 0.0;
  double value = text[0] - '0', scale = 0.1;
  for (std::size_t i = 2; i < text.size(); ++i, scale /= 10) {
    if (text[i] < '0' || text[i] > '9' || (text[0] == '1' && text[i] != '0')) return 0.0;
    value += (text[i] - '0') * scale;
  }
  return value;
}

// The q the header gives `type`: that of its most specific matching range
// (RFC 9110 12.5.1), -1 when none matches.
double quality(std::string_view accept, const std::string& type) {
  double q = -1.0;
  int best = 0;
  std::size_t at = 0;
  while (at <= accept.size()) {
    const std::size_t comma = std::min(accept.find(',', at), accept.size());
    const std::string_view item = accept.substr(at, comma - at);
    at = comma + 1;
    const std::size_t semi = std::min(item.find(';'), item.size());
    const std::string range = lower(trim(item.substr(0, semi)));
    if (range.empty()) continue;
    double item_q = 1.0;
    for (std::size_t p = semi; p < item.size();) {
      const std::size_t next = std::min(item.find(';', p + 1), item.size());
      const std::string param = lower(trim(item.substr(p + 1, next - p - 1)));
      if (param.rfind("q=", 0) == 0) item_q = qvalue(std::string_view(param).substr(2));
      p = next;
    }
    const int s = specificity(range, type);
    if (s > best) best = s, q = item_q;
  }
  return q;
}

// Numbers in the shortest form that reads back as the same double
// (std::to_chars): a client gets the hours exactly as computed.
void append_number(std::string& text, double v) {
  char buffer[40];
  const auto end = std::to_chars(buffer, buffer + sizeof buffer, v).ptr;
  text.append(buffer, end);
}


}  // namespace

std::optional<SunHoursFormat> sun_hours_format(std::string_view accept, bool png) {
  if (trim(accept).empty()) return SunHoursFormat::Json;
  const double json_q = quality(accept, "application/json"), csv_q = quality(accept, "text/csv"),
               png_q = png ? quality(accept, "image/png") : -1.0;
  const double best = std::max({json_q, csv_q, png_q});
  if (best <= 0.0) return std::nullopt;
  return json_q == best ? SunHoursFormat::Json : csv_q == best ? SunHoursFormat::Csv : SunHoursFormat::Png;
}

std::string sun_hours_utc(double unix_seconds) {
  const double whole = std::floor(unix_seconds);
  std::string text = format_utc(whole);
  const double fraction = unix_seconds - whole;
  if (fraction > 5e-7 && !text.empty()) {
    char buffer[16];
    std::snprintf(buffer, sizeof buffer, "%.6f", fraction);  // "0.500000"
    std::string digits(buffer + 1);
    while (!digits.empty() && digits.back() == '0') digits.pop_back();
    text.insert(text.size() - 1, digits);
  }
  return text;
}

std::string sun_hours_json(const SunHoursRequest& request, const SunHoursResult& result) {
  using json = nlohmann::json;
  const SunGrid& grid = request.grid;
  const glm::dvec3 origin = grid.origin();
  json head = {
      {"grid", {{"origin", {origin.x, origin.y, origin.z}}, {"spacing", grid.spacing}, {"columns", grid.columns},
                {"rows", grid.rows}}},
      {"site", {{"latitude", request.site.latitude_deg}, {"longitude", request.site.longitude_deg},
                {"north_deg", request.site.north_deg}}},
      {"period", {{"start", sun_hours_utc(request.period.start_unix_s)}, {"end", sun_hours_utc(request.period.end_unix_s)},
                  {"step_minutes", request.period.step_minutes}}},
      {"samples_count", result.samples.size()},
      {"samples_up", result.samples_up},
      {"pairs", result.pairs},
      {"pairs_by_maps", result.pairs_by_maps},
      {"pairs_ray_cast", result.pairs_ray_cast},
      {"path", result.path},
      // Every path is exact (docs/sun-hours.md): "exact": false skips nothing.
      {"exact", true},
  };
  if (request.require_hours) {
    head["require_hours"] = *request.require_hours;
    head["pass_share"] = result.pass_share(*request.require_hours);
  }
  if (request.include_samples) {
    json samples = json::array();
    for (const SunSample& s : result.samples)
      samples.push_back({{"utc", sun_hours_utc(s.utc_unix_s)}, {"azimuth_deg", s.sun.azimuth_deg},
                         {"elevation_deg", s.sun.elevation_deg}});
    head["samples"] = std::move(samples);
  }
  // The per-point arrays are written by hand: a million points are two
  // million numbers, which a json value would hold as 16-byte nodes.
  std::string text = head.dump();
  text.pop_back();  // the closing brace
  const auto array = [&](const char* name, auto value_of) {
    text += ",\"";
    text += name;
    text += "\":[";
    for (std::size_t i = 0; i < result.tally.size(); ++i) {
      if (i) text += ',';
      append_number(text, value_of(i));
    }
    text += ']';
  };
  text.reserve(text.size() + result.tally.size() * 24);
  array("hours", [&](std::size_t i) { return result.hours(i); });
  array("longest_run_hours", [&](std::size_t i) { return result.longest_run_hours(i); });
  text += "}";
  return text;
}

namespace {

std::string degrees(double v, char positive, char negative) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.2f %c", std::abs(v), v >= 0.0 ? positive : negative);
  return buffer;
}

std::string minutes_text(double minutes) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%g", minutes);
  return buffer;
}

}  // namespace

Image sun_hours_image(const SunHoursRequest& request, const SunHoursResult& result) {
  SunHoursLegend legend;
  // The scale reaches the most any point can get: every sample with the
  // sun up (an hour when the sun never rises, so that the ticks read).
  legend.max_hours = result.samples_up > 0 ? double(result.samples_up) * request.period.step_minutes / 60.0 : 1.0;
  if (request.require_hours) legend.require_hours = *request.require_hours;
  // Dates alone at midnight: the period fits one line.
  const auto when = [](double t) {
    const std::string text = sun_hours_utc(t);
    return text.compare(10, 9, "T00:00:00") == 0 ? text.substr(0, 10) : text.substr(0, 16);
  };
  const std::string start = when(request.period.start_unix_s), end = when(request.period.end_unix_s);
  legend.lines.push_back(degrees(request.site.latitude_deg, 'N', 'S') + ", " +
                         degrees(request.site.longitude_deg, 'E', 'W'));
  legend.lines.push_back(start + " TO " + end + " UTC");
  legend.lines.push_back("EVERY " + minutes_text(request.period.step_minutes) + " MIN, " +
                         std::to_string(result.samples_up) + " WITH SUN UP");
  if (request.grid.points() > 0 && request.require_hours) {
    char buffer[96];
    std::snprintf(buffer, sizeof buffer, "%.0f%% OF GRID >= %g H", 100.0 * result.pass_share(*request.require_hours),
                  *request.require_hours);
    legend.lines.push_back(buffer);
  }
  legend.lines.push_back("EXACT RAY CAST");
  return sun_hours_picture(result.pixel_hours, request.view.width, request.view.height, legend);
}

std::string sun_hours_csv(const SunHoursRequest& request, const SunHoursResult& result) {
  std::string text = "x,y,z,hours,longest_run_hours\n";
  text.reserve(text.size() + result.tally.size() * 64);
  for (std::size_t i = 0; i < result.tally.size(); ++i) {
    const glm::dvec3 p = request.grid.point(i);
    for (double v : {p.x, p.y, p.z, result.hours(i)}) {
      append_number(text, v);
      text += ',';
    }
    append_number(text, result.longest_run_hours(i));
    text += '\n';
  }
  return text;
}

}  // namespace umbra
