#include "core/sun_hours.hpp"

#include <algorithm>
#include <cmath>

#include "core/light_math.hpp"

namespace umbra {

glm::dvec3 SunGrid::origin() const {
  return {center.x - 0.5 * size_x + 0.5 * spacing, center.y, center.z - 0.5 * size_z + 0.5 * spacing};
}

glm::dvec3 SunGrid::point(std::size_t i) const {
  if (columns <= 0) return center;
  const glm::dvec3 o = origin();
  const double column = double(i % std::size_t(columns)), row = double(i / std::size_t(columns));
  return {o.x + column * spacing, o.y, o.z + row * spacing};
}

double sample_time(const SunPeriod& period, std::size_t k) {
  return period.start_unix_s + (double(k) + 0.5) * period.step_seconds();
}

std::optional<std::size_t> sample_count(const SunPeriod& period) {
  const double steps = (period.end_unix_s - period.start_unix_s) / period.step_seconds();
  if (!(steps >= 0.5) || !std::isfinite(steps)) return std::nullopt;
  const double whole = std::round(steps);
  if (std::abs(steps - whole) > 1e-9 * std::max(1.0, whole)) return std::nullopt;
  return std::size_t(whole);
}

namespace {

SunSample sample_at(const SunSite& site, double utc) {
  SunSample s;
  s.utc_unix_s = utc;
  s.sun = solar_position(site.latitude_deg, site.longitude_deg, utc);
  s.direction = sun_direction(s.sun.azimuth_deg, s.sun.elevation_deg, site.north_deg);
  return s;
}

}  // namespace

SunSample sun_sample(const SunSite& site, const SunPeriod& period, std::size_t k) {
  return sample_at(site, sample_time(period, k));
}

std::vector<SunSample> sun_samples(const SunSite& site, const SunPeriod& period, std::size_t count) {
  std::vector<SunSample> samples;
  samples.reserve(count);
  for (std::size_t k = 0; k < count; ++k) samples.push_back(sample_at(site, sample_time(period, k)));
  return samples;
}

std::vector<SunSample> probe_samples(const SunSite& site, const SunPeriod& period, std::size_t count,
                                     std::size_t probes) {
  std::vector<SunSample> out;
  if (count == 0) return out;
  const std::size_t n = std::min(count, std::max<std::size_t>(1, probes));
  for (std::size_t i = 0; i < n; ++i) {
    // Probe i stands for the samples of the i-th of n equal stretches; it
    // lies at a golden-ratio fraction of its stretch, not the middle: when
    // a stretch is a whole number of days (737,280 one-minute samples from
    // noon over 512 probes) the middles all fall at one time of day.
    const double jitter = std::fmod(0.5 + double(i) * 0.6180339887498949, 1.0);
    const std::size_t k = std::min(count - 1, std::size_t((double(i) + jitter) * double(count) / double(n)));
    out.push_back(sample_at(site, sample_time(period, k)));
  }
  return out;
}

double sun_up_share(const std::vector<SunSample>& samples) {
  if (samples.empty()) return 0.0;
  std::size_t up = 0;
  for (const SunSample& s : samples) up += s.up() ? 1 : 0;
  return double(up) / double(samples.size());
}

double SunHoursResult::pass_share(double require_hours) const {
  if (tally.empty()) return 0.0;
  // Compared in minutes, where whole-minute steps and hours are exact.
  const double need = require_hours * 60.0;
  std::size_t pass = 0;
  for (const PointTally& t : tally) pass += double(t.lit) * step_minutes >= need - 1e-9 * std::max(1.0, need) ? 1 : 0;
  return double(pass) / double(tally.size());
}

}  // namespace umbra
