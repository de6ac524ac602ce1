// Sun hours (issue 32): how long each point of a site sees the sun over a
// period. The typed request, the sun's samples, the grid of points, and the
// tally of lit samples into hours. Pure: no GL, no I/O, no threads; the
// pairs are settled by reference/sun_hours_ray_cast (and, later, the maps).
//
// The rule, as BR 209 and Ladybug's "Direct Sun Hours" count it: the period
// [start, end) is cut into n = (end - start) / step equal steps, and sample
// k stands for its step's middle, start + (k + 1/2) step. A sample counts for
// a point when the sun's apparent elevation is above 0 and the segment from
// the point towards the sun's centre meets no surface; hours = counted
// samples x step.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include <glm/vec3.hpp>

#include "core/request.hpp"
#include "core/sun_position.hpp"

namespace umbra {

/// Where the site is, as the sun light has it (SunClock).
struct SunSite {
  double latitude_deg = 0.0;   ///< [-90, 90], north positive
  double longitude_deg = 0.0;  ///< [-180, 180], east positive
  double north_deg = 0.0;      ///< north is -Z turned clockwise (seen from above) by this, [-360, 360]
};

/// The period [start, end) and its step.
struct SunPeriod {
  double start_unix_s = 0.0;  ///< UTC seconds since 1970 (RFC 3339 in the API)
  double end_unix_s = 0.0;    ///< > start
  double step_minutes = 10.0; ///< (0, ...]; (end - start) is a whole number of steps
  double step_seconds() const { return step_minutes * 60.0; }
};

/// Points at the centres of the spacing x spacing cells of a horizontal
/// rectangle at height center.y: columns along +X, rows along +Z, row 0 at
/// the rectangle's -Z edge. size is a whole number of cells each way.
struct SunGrid {
  /// A request without a grid (a picture alone) has 0 columns and rows.
  glm::dvec3 center{0.0};
  double size_x = 1.0, size_z = 1.0;  ///< world units, > 0
  double spacing = 1.0;               ///< world units, > 0
  int columns = 1, rows = 1;          ///< size / spacing, set by make_grid
  /// The first point (column 0, row 0).
  glm::dvec3 origin() const;
  /// Point i = row * columns + column.
  glm::dvec3 point(std::size_t i) const;
  std::size_t points() const { return std::size_t(columns) * std::size_t(rows); }
};

/// The analysis asked for: the scene as /api/render takes it, and what to
/// count over it.
struct SunHoursRequest {
  RenderRequest view;  ///< its scene (its camera and size: the picture)
  SunSite site;
  SunPeriod period;
  SunGrid grid;
  /// Hours a point needs to pass; unset: no pass/fail is judged.
  std::optional<double> require_hours;
  /// true: every pair is exact (the pure ray cast, or maps with the
  /// uncertain pairs ray cast); false: the maps may settle pairs alone.
  bool exact = true;
  bool include_samples = false;
  /// Also the hours at every pixel that view.camera sees (view.width x
  /// view.height): the image/png answer.
  bool picture = false;
};

/// Bounds that keep every accepted request's memory and work finite before
/// the cost model prices it (docs/api.md).
struct SunHoursLimits {
  static constexpr std::size_t kMaxSamples = 1'100'000;   ///< a year at 30-second steps: 1,051,200
  static constexpr std::size_t kMaxPoints = 4'194'304;    ///< 2048 x 2048
  static constexpr double kMinStepMinutes = 0.5;
  static constexpr double kMaxStepMinutes = 1440.0;
};

/// Sample k's instant: start + (k + 1/2) step.
double sample_time(const SunPeriod& period, std::size_t k);
/// n = (end - start) / step when that is a whole number of steps (to
/// 1e-9 of a step), else nullopt.
std::optional<std::size_t> sample_count(const SunPeriod& period);

/// One sample of the sun: its instant, apparent position, and the unit
/// vector from the scene towards it (sun_direction with the site's north).
struct SunSample {
  double utc_unix_s = 0.0;
  SunAngles sun{};
  glm::dvec3 direction{0.0};
  bool up() const { return above_horizon(sun); }
};

/// Sample k of the period at the site.
SunSample sun_sample(const SunSite& site, const SunPeriod& period, std::size_t k);
/// Every sample of the period at the site (solar_position, as a sun light
/// places its sun). `count` is sample_count(period).
std::vector<SunSample> sun_samples(const SunSite& site, const SunPeriod& period, std::size_t count);
/// At most `probes` of the period's samples, spread evenly over it (each
/// stands for an equal stretch of the period): what the cost model
/// estimates the sun's share of the period, and the footprints' share of
/// the grid, from.
std::vector<SunSample> probe_samples(const SunSite& site, const SunPeriod& period, std::size_t count,
                                     std::size_t probes = 512);
/// The share of `samples` with the sun up.
double sun_up_share(const std::vector<SunSample>& samples);

/// Per point, the lit samples and the longest run of consecutive lit
/// samples, fed sample by sample in time order.
struct PointTally {
  std::uint32_t lit = 0;
  std::uint32_t run = 0;
  std::uint32_t longest = 0;
  void record(bool sunlit) {
    if (!sunlit) {
      run = 0;
      return;
    }
    ++lit;
    longest = run + 1 > longest ? run + 1 : longest;
    ++run;
  }
};

/// What the analysis answers.
struct SunHoursResult {
  std::vector<PointTally> tally;        ///< per point, row-major
  std::vector<SunSample> samples;       ///< every sample, in time order
  double step_minutes = 0.0;
  std::size_t samples_up = 0;           ///< samples with the sun above the horizon
  std::uint64_t pairs = 0;              ///< points x samples up
  std::uint64_t pairs_by_maps = 0;      ///< settled by the shadow maps
  std::uint64_t pairs_ray_cast = 0;     ///< settled by the exact ray cast
  const char* path = "ray_cast";        ///< "ray_cast" (pure) or "maps"
  double elapsed_ms = 0.0;              ///< the analysis itself, queue excluded
  /// With request.picture: hours per pixel (row 0 at the top), NaN where
  /// the camera sees nothing; and the pairs cast for it.
  std::vector<float> pixel_hours;
  std::uint64_t pixel_pairs = 0;
  double hours(std::size_t point) const { return tally[point].lit * step_minutes / 60.0; }
  double longest_run_hours(std::size_t point) const { return tally[point].longest * step_minutes / 60.0; }
  /// Points whose hours reach `require_hours`, over all points.
  double pass_share(double require_hours) const;
};

}  // namespace umbra
