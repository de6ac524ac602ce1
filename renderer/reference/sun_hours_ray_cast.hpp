// Sun hours by the exact ray cast: every (point, sample) pair with the sun
// up is settled by one shadow ray against the scene as it is (RayScene:
// analytic shapes in double, meshes through Embree). This is the answer
// the maps' path must equal pair for pair, and the path the cost model
// picks where it is the faster one.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <mutex>
#include <vector>

#include "core/sun_hours.hpp"

namespace umbra {

class RayScene;   // reference/ray_cast.hpp
class ExactView;  // reference/ray_cast.hpp

/// A stop_requested shared by many threads: asked by one thread at a time
/// (it need not be thread-safe), by each thread once per kWorkPerAsk units
/// of work it reports (a ray cast, a point visited), so a stop is seen
/// within milliseconds however long one sample or one row of work is; once
/// it answered true, stopped() is true for every thread.
class StopPoll {
 public:
  static constexpr std::uint64_t kWorkPerAsk = 4096;
  explicit StopPoll(const std::function<bool()>& ask) : ask_(ask) {}
  /// Asks now (no-op without a stop_requested). True once stopped.
  bool ask();
  /// Adds `work` to the calling thread's own count `since`; asks when it
  /// reaches kWorkPerAsk. True once stopped.
  bool after(std::uint64_t& since, std::uint64_t work) {
    since += work;
    if (since < kWorkPerAsk) return stopped();
    since = 0;
    return ask();
  }
  bool stopped() const { return stopped_.load(std::memory_order_relaxed); }

 private:
  const std::function<bool()>& ask_;
  std::atomic<bool> stopped_{false};
  std::mutex asking_;
};

/// Every sample of the period (sun_sample) on all hardware threads: a
/// year at one-minute steps is half a million positions by NREL SPA.
/// `stop_requested`, if given, is asked every 4096 samples (one thread at a
/// time); once it answers true this throws CastStopped.
std::vector<SunSample> sun_samples_on_all_cores(const SunSite& site, const SunPeriod& period, std::size_t count,
                                                const std::function<bool()>& stop_requested = nullptr);

/// Whether the segment from `point` towards the sun (unit `direction`)
/// meets no surface: nothing on point + t direction for t in (0, inf).
bool sees_sun(const RayScene& rays, const glm::dvec3& point, const glm::dvec3& direction);

/// Tallies every point of `grid` over `samples` (in time order) into
/// result.tally, and counts the pairs cast (result.pairs,
/// result.pairs_ray_cast). On all hardware threads, in chunks of points
/// that each walk the samples in order (neighbouring rays share a
/// direction). `stop_requested`, if given, is asked every few thousand rays
/// (StopPoll); once it answers true the cast throws CastStopped.
void ray_cast_sun_hours(const RayScene& rays, const SunGrid& grid, const std::vector<SunSample>& samples,
                        SunHoursResult& result, const std::function<bool()>& stop_requested = nullptr,
                        std::atomic<std::uint64_t>* pairs_done = nullptr);

/// Hours at every pixel the view's camera sees (width x height, row 0 at
/// the top): from just off the surface its camera ray meets first (the
/// side the camera sees: RayHit::leave_front), one sees_sun query per
/// sample with the sun up; NaN where the ray meets nothing. A surface
/// turned away from the sun is dark: its own ray goes through it. On all
/// hardware threads by rows; `stop_requested` as ray_cast_sun_hours asks
/// it, and each row's pairs are counted into `pairs_done`.
std::vector<float> sun_hours_per_pixel(const ExactView& view, int width, int height,
                                       const std::vector<SunSample>& samples, double step_minutes,
                                       const std::function<bool()>& stop_requested = nullptr,
                                       std::atomic<std::uint64_t>* pairs_done = nullptr);

}  // namespace umbra
