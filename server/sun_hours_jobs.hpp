// Sun-hours analyses too long for one response run as jobs: POST answers
// 202 with an id, GET on /api/sun-hours/jobs/{id} gives progress and then
// the result, DELETE cancels. This holds them: a bounded number, each kept
// a bounded time after it ends, their results within a byte budget. No GL.
#pragma once

#include <chrono>
#include <cstdint>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "core/sun_hours.hpp"
#include "sun_hours_answer.hpp"
#include "service/render_service.hpp"

namespace umbra {

struct SunHoursJob {
  std::string id;
  SunHoursRequest request;  ///< what the answer is formatted from (the grid, the period)
  std::shared_ptr<SunHoursProgress> progress;
  std::shared_future<SunHoursResult> result;
  std::chrono::steady_clock::time_point created;
  double estimate_ms = 0.0;
  std::uint64_t result_bytes = 0;  ///< the tally and samples it will hold
  /// Set once the result is ready: when the job may be dropped.
  std::optional<std::chrono::steady_clock::time_point> finished;
  /// The last answer sent (its format and body, counted in result_bytes):
  /// a client that fetches a big finished job again is not answered by
  /// encoding a hundred megabytes again.
  std::mutex encoded_mutex;
  std::optional<SunHoursFormat> encoded_format;
  std::string encoded;
  bool ready() const;
};

class SunHoursJobs {
 public:
  struct Limits {
    std::size_t max_jobs = 16;                 ///< running, waiting or finished and kept
    std::chrono::seconds keep{600};            ///< how long a finished job is kept (--job-keep-s)
    std::uint64_t max_result_bytes = std::uint64_t(1) << 30;  ///< the results held together
  };
  SunHoursJobs(Limits limits, std::string name);
  /// Cancels every job still running or waiting: a server that stops does
  /// not wait out minutes of analysis nobody can fetch.
  ~SunHoursJobs();

  /// A fresh job id: the server's --name and a dot, then 16 random hex
  /// digits (so that HAProxy can send the id's requests back here).
  std::string new_id();
  /// Holds `job` if there is room: first drops finished jobs past their
  /// keep time, then the oldest finished ones while over a limit. False:
  /// no room, only running or waiting jobs fill it.
  bool add(std::shared_ptr<SunHoursJob> job);
  std::shared_ptr<SunHoursJob> find(const std::string& id);
  /// Cancels (if it runs) and drops the job; null if there was none.
  std::shared_ptr<SunHoursJob> remove(const std::string& id);
  std::size_t size() const;
  const Limits& limits() const { return limits_; }

 private:
  void drop_expired(std::chrono::steady_clock::time_point now);
  Limits limits_;
  std::string prefix_;
  mutable std::mutex mutex_;
  std::map<std::string, std::shared_ptr<SunHoursJob>> jobs_;
};

}  // namespace umbra
