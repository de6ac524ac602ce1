#include "sun_hours_jobs.hpp"

#include <algorithm>
#include <cstdio>
#include <random>
#include <vector>

namespace umbra {

bool SunHoursJob::ready() const {
  return result.valid() && result.wait_for(std::chrono::seconds(0)) == std::future_status::ready;
}

SunHoursJobs::SunHoursJobs(Limits limits, std::string name)
    : limits_(limits), prefix_(name.empty() ? "" : name + ".") {}

SunHoursJobs::~SunHoursJobs() {
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto& [id, job] : jobs_) job->progress->cancel = true;
}

std::string SunHoursJobs::new_id() {
  static thread_local std::mt19937_64 random{std::random_device{}()};
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(random()));
  return prefix_ + hex;
}

void SunHoursJobs::drop_expired(std::chrono::steady_clock::time_point now) {
  for (auto it = jobs_.begin(); it != jobs_.end();) {
    SunHoursJob& job = *it->second;
    if (!job.finished && job.ready()) job.finished = now;
    if (job.finished && now - *job.finished > limits_.keep)
      it = jobs_.erase(it);
    else
      ++it;
  }
}

bool SunHoursJobs::add(std::shared_ptr<SunHoursJob> job) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto now = std::chrono::steady_clock::now();
  drop_expired(now);
  const auto bytes = [&] {
    std::uint64_t sum = job->result_bytes;
    for (const auto& [id, held] : jobs_) sum += held->result_bytes;
    return sum;
  };
  // Over a limit: the finished jobs go, oldest first; running ones stay.
  while (jobs_.size() + 1 > limits_.max_jobs || bytes() > limits_.max_result_bytes) {
    auto oldest = jobs_.end();
    for (auto it = jobs_.begin(); it != jobs_.end(); ++it)
      if (it->second->finished && (oldest == jobs_.end() || *it->second->finished < *oldest->second->finished))
        oldest = it;
    if (oldest == jobs_.end()) return false;
    jobs_.erase(oldest);
  }
  jobs_[job->id] = std::move(job);
  return true;
}

std::shared_ptr<SunHoursJob> SunHoursJobs::find(const std::string& id) {
  std::lock_guard<std::mutex> lock(mutex_);
  drop_expired(std::chrono::steady_clock::now());
  const auto it = jobs_.find(id);
  return it == jobs_.end() ? nullptr : it->second;
}

std::shared_ptr<SunHoursJob> SunHoursJobs::remove(const std::string& id) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = jobs_.find(id);
  if (it == jobs_.end()) return nullptr;
  std::shared_ptr<SunHoursJob> job = std::move(it->second);
  jobs_.erase(it);
  job->progress->cancel = true;
  return job;
}

std::size_t SunHoursJobs::size() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return jobs_.size();
}

}  // namespace umbra
