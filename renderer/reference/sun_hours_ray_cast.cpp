#include "reference/sun_hours_ray_cast.hpp"

#include <algorithm>
#include <atomic>
#include <limits>
#include <mutex>
#include <thread>

#include "reference/ray_cast.hpp"

namespace umbra {

bool StopPoll::ask() {
  if (!ask_ || stopped()) return stopped();
  std::lock_guard<std::mutex> lock(asking_);
  if (!stopped() && ask_()) stopped_ = true;
  return stopped();
}

namespace {

// Calls task(i, poll) for every i in [0, count) on all hardware threads,
// each thread taking the next i; asks stop_requested (StopPoll) before
// each, and throws CastStopped once it answered true. A long task asks
// within itself (poll.after) and returns early once poll.stopped().
void run_tasks(std::size_t count, const std::function<bool()>& stop_requested,
               const std::function<void(std::size_t, StopPoll&)>& task) {
  std::atomic<std::size_t> next{0};
  StopPoll poll(stop_requested);
  const auto work = [&] {
    for (;;) {
      if (poll.ask()) return;
      const std::size_t i = next.fetch_add(1);
      if (i >= count) return;
      task(i, poll);
    }
  };
  const unsigned threads =
      std::max(1u, std::min<unsigned>(std::thread::hardware_concurrency(), unsigned(std::min<std::size_t>(count, 1u << 16))));
  std::vector<std::thread> pool;
  for (unsigned i = 1; i < threads; ++i) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  if (poll.stopped()) throw CastStopped();
}

}  // namespace

std::vector<SunSample> sun_samples_on_all_cores(const SunSite& site, const SunPeriod& period, std::size_t count,
                                                const std::function<bool()>& stop_requested) {
  std::vector<SunSample> samples(count);
  constexpr std::size_t kBlock = 4096;
  run_tasks((count + kBlock - 1) / kBlock, stop_requested, [&](std::size_t b, StopPoll&) {
    for (std::size_t k = b * kBlock; k < std::min(count, (b + 1) * kBlock); ++k) samples[k] = sun_sample(site, period, k);
  });
  return samples;
}

bool sees_sun(const RayScene& rays, const glm::dvec3& point, const glm::dvec3& direction) {
  return !rays.occluded(point, direction, std::numeric_limits<double>::infinity());
}

void ray_cast_sun_hours(const RayScene& rays, const SunGrid& grid, const std::vector<SunSample>& samples,
                        SunHoursResult& result, const std::function<bool()>& stop_requested,
                        std::atomic<std::uint64_t>* pairs_done) {
  const std::size_t points = grid.points();
  result.tally.assign(points, PointTally{});
  const std::size_t up = std::size_t(std::count_if(samples.begin(), samples.end(), [](const SunSample& s) { return s.up(); }));
  result.samples_up = up;
  result.pairs = std::uint64_t(points) * up;
  // About 2^16 rays a chunk: a few milliseconds, so a stop is seen soon.
  const std::size_t chunk = std::max<std::size_t>(1, (std::size_t(1) << 16) / std::max<std::size_t>(1, up));
  const std::size_t chunks = (points + chunk - 1) / chunk;
  run_tasks(chunks, stop_requested, [&](std::size_t c, StopPoll& poll) {
    const std::size_t first = c * chunk, last = std::min(points, first + chunk);
    std::uint64_t since = 0;
    for (const SunSample& sample : samples) {
      const bool sun_up = sample.up();
      for (std::size_t i = first; i < last; ++i) {
        result.tally[i].record(sun_up && sees_sun(rays, grid.point(i), sample.direction));
        // Asked by rays, not chunks: a ray through a thousand overlapping
        // objects costs a thousand tests.
        if (sun_up && poll.after(since, 1)) return;
      }
    }
    if (pairs_done) pairs_done->fetch_add(std::uint64_t(last - first) * up);
  });
  result.pairs_ray_cast = result.pairs;
}

std::vector<float> sun_hours_per_pixel(const ExactView& view, int width, int height,
                                       const std::vector<SunSample>& samples, double step_minutes,
                                       const std::function<bool()>& stop_requested,
                                       std::atomic<std::uint64_t>* pairs_done) {
  std::vector<float> hours(std::size_t(width) * std::size_t(height), std::numeric_limits<float>::quiet_NaN());
  std::vector<glm::dvec3> up;
  for (const SunSample& s : samples)
    if (s.up()) up.push_back(s.direction);
  const RayScene& rays = view.rays();
  run_tasks(std::size_t(std::max(0, height)), stop_requested, [&](std::size_t y, StopPoll& poll) {
    std::uint64_t since = 0;
    for (int x = 0; x < width; ++x) {
      if (poll.after(since, up.size() + 1)) return;
      const std::optional<RayHit> hit = view.surface_at(x + 0.5, double(y) + 0.5);
      if (!hit) continue;
      std::uint32_t lit = 0;
      for (const glm::dvec3& d : up) lit += sees_sun(rays, hit->leave_front, d) ? 1 : 0;
      hours[y * std::size_t(width) + std::size_t(x)] = float(double(lit) * step_minutes / 60.0);
    }
    if (pairs_done) pairs_done->fetch_add(std::uint64_t(width) * up.size());
  });
  return hours;
}

}  // namespace umbra
