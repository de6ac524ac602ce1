#include "service/render_service.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <mutex>
#include <optional>
#include <memory>
#include <thread>

#include <malloc.h>

#include "gpu/egl_context.hpp"
#include "reference/certified_frame.hpp"
#include "reference/ray_cast.hpp"
#include "reference/sun_hours_footprints.hpp"
#include "reference/sun_hours_ray_cast.hpp"
#include "service/request_cost.hpp"
#include "reference/shadow_error.hpp"
#include "gpu/shadow_renderer.hpp"

namespace umbra {

namespace {

// How long the GL thread waits without work before it releases what it
// keeps beyond kIdleShare of the budget: long enough that a client's next
// request of a burst still finds its scene and map, short enough that a
// burst's gigabytes do not stay resident for the idle hours after it.
constexpr std::chrono::milliseconds kIdleRelease{1500};
// Kept while idle: 1/32 of the budget (64 MiB by default) holds the default
// frame's map and framebuffers and small scenes, not a 4096^2 frame's
// 128 MiB or a 1000-sphere scene's 280 MB.
constexpr std::uint64_t kIdleShare = 32;
// Cached scenes keep at most a third of the budget: two 1000-sphere scenes by
// default, leaving the rest to one request at its largest.
constexpr std::uint64_t kSceneShare = 3;

std::uint64_t minus_or_zero(std::uint64_t a, std::uint64_t b) { return a > b ? a - b : 0; }

}  // namespace

struct RenderService::Impl {
  struct Job {
    RenderRequest request;
    std::promise<RenderResult> promise;
    std::chrono::steady_clock::time_point queued;
    bool holds_place = true;  // false: part of a job that holds one already
    ClientGoneCheck client_gone;
    // Estimated peak bytes the GL thread must make room for (0 when a ray
    // cast's reservation covers it, see reserved_bytes).
    std::uint64_t peak_bytes = 0;
    // The estimate's dominant part: what a frame cut short at max_run_time
    // tells its client to lower.
    CostPart dominant;
    // Filter "exact": the path the estimate priced lowest for this GL
    // (RequestCost::exact_filter_path).
    CertifiedPath certified_path = CertifiedPath::Maps;
  };

  std::future<RenderResult> enqueue(RenderRequest request, bool holds_place, ClientGoneCheck client_gone,
                                    std::uint64_t peak_bytes, CostPart dominant, CertifiedPath certified_path) {
    Job job{std::move(request), {},        std::chrono::steady_clock::now(), holds_place, std::move(client_gone),
            peak_bytes,         std::move(dominant), certified_path};
    std::future<RenderResult> result = job.promise.get_future();
    {
      std::lock_guard<std::mutex> lock(mutex);
      jobs.push_back(std::move(job));
    }
    wake.notify_one();
    reaper_wake.notify_one();
    return result;
  }

  explicit Impl(ServiceLimits l) : limits(l) {}

  // Claims a place in the queue; false when it is full.
  bool try_reserve() {
    std::size_t current = in_flight.load();
    do {
      if (current >= limits.queue_capacity) return false;
    } while (!in_flight.compare_exchange_weak(current, current + 1));
    return true;
  }
  // Claims a place in the queue, or throws QueueFull.
  void reserve() {
    if (try_reserve()) return;
    rejected_count.fetch_add(1);
    throw QueueFull();
  }

  const ServiceLimits limits;
  std::atomic<std::uint64_t> rejected_count{0};
  std::atomic<std::uint64_t> expired_count{0};
  std::atomic<std::uint64_t> abandoned_count{0};
  std::atomic<std::uint64_t> too_costly_count{0};
  std::atomic<std::uint64_t> overran_count{0};

  // Throws RequestTooCostly if `cost` is over the budget; else returns.
  void check_budget(const RequestCost& cost, std::chrono::milliseconds budget = std::chrono::milliseconds(0),
                    const char* budget_of = " ms a request", const char* to = " to render") {
    const auto mib = [](double bytes) { return std::to_string(std::llround(bytes / double(1 << 20))); };
    if (budget.count() == 0) budget = limits.max_request_cost;
    const double budget_ms = double(budget.count());
    if (cost.total_ms > budget_ms) {
      const CostPart& part = cost.dominant();
      too_costly_count.fetch_add(1);
      throw RequestTooCostly("the request would take about " + std::to_string(std::llround(cost.total_ms)) +
                                 " ms" + to + ", over the budget of " + std::to_string(budget.count()) +
                                 budget_of + "; most of it is " + part.name + " (about " +
                                 std::to_string(std::llround(part.ms)) + " ms): " + part.advice,
                             part.field);
    }
    // The memory budget bounds the whole renderer, so one request's peak
    // too; what is cached is released to make room, never refused for.
    const bool budget_binds = limits.memory_budget_bytes < limits.max_request_bytes;
    const std::uint64_t allowed = budget_binds ? limits.memory_budget_bytes : limits.max_request_bytes;
    if (cost.peak_bytes > allowed) {
      // The shadow map's layers, or the images: whichever is the larger share.
      const double map_bytes = cost.factors.shadow_texels * sizeof(float);
      const bool map = map_bytes > 0.5 * double(cost.peak_bytes);
      const bool own = !cost.memory_field.empty();
      too_costly_count.fetch_add(1);
      throw RequestTooCostly("the request would need about " + mib(double(cost.peak_bytes)) +
                                 " MiB of memory at once, over the " +
                                 (budget_binds ? "renderer's memory budget of " : "budget of ") +
                                 mib(double(allowed)) + (budget_binds ? " MiB; " : " MiB a request; ") +
                                 (own ? cost.memory_advice
                                      : map ? "lower shadow.map_size or shadow.cascades" : "lower width and height"),
                             own ? cost.memory_field : map ? "shadow.map_size" : "width");
    }
  }

  // What a frame cut short at max_run_time answers: how long it ran, where
  // it stopped, and the estimate's advice.
  RunTimeExceeded frame_overran(const FrameCutShort& cut, std::chrono::steady_clock::time_point started,
                                const CostPart& dominant) const {
    const auto ran = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - started);
    return RunTimeExceeded("the frame ran past the limit of " + std::to_string(limits.max_run_time.count()) +
                               " ms a request and was stopped (" + cut.what() + ", after " +
                               std::to_string(ran.count()) + " ms); nothing of it is returned: " + dominant.advice,
                           dominant.field);
  }

  // Filter "exact": the pixels the maps left uncertain are ray cast here,
  // on the GL thread (the cast itself uses every core), under the frame's
  // watch: past max_run_time it is cut short like a frame (FrameCutShort),
  // and a client that left stops it (ClientGone).
  void settle(RenderResult& result, const Job& job, std::chrono::steady_clock::time_point started) {
    const auto until = started + limits.max_run_time;
    bool gone = false;
    const auto stop = [&] {
      gone = job.client_gone && job.client_gone();
      return gone || std::chrono::steady_clock::now() > until;
    };
    try {
      settle_certified_frame(result, job.request, stop);
    } catch (const CastStopped&) {
      if (!gone) throw FrameCutShort("stopped during the ray cast of the pixels the shadow maps left uncertain");
      abandoned_count.fetch_add(1);
      throw ClientGone();
    }
  }

  // Throws if the job should not run: its client left, or it waited too long.
  void check_still_wanted(std::chrono::steady_clock::time_point queued, const ClientGoneCheck& client_gone) {
    if (client_gone && client_gone()) {
      abandoned_count.fetch_add(1);
      throw ClientGone();
    }
    if (std::chrono::steady_clock::now() - queued > limits.deadline) {
      expired_count.fetch_add(1);
      throw DeadlineExceeded();
    }
  }

  mutable std::mutex mutex;
  std::condition_variable wake;         // the GL thread: a job arrived, or stop
  std::condition_variable reaper_wake;  // the reaper: a job arrived, or stop
  std::deque<Job> jobs;
  bool stopping = false;
  std::atomic<std::size_t> in_flight{0};
  // Sun-hours jobs run one at a time, in the order they were submitted (a
  // mutex polled by each waiting thread would let any of them in first).
  struct JobLine {
    std::mutex mutex;
    std::condition_variable turn_free;
    std::deque<std::uint64_t> waiting;  // tickets, oldest first
    std::uint64_t next_ticket = 0;
    bool running = false;
  } job_line;
  std::atomic<std::uint64_t> frames{0};
  std::atomic<std::uint64_t> shadow_reuses{0};
  std::atomic<std::uint64_t> scene_uploads{0};
  std::atomic<std::uint64_t> context_renewals{0};  // fresh GL contexts made when idle (release_when_idle)
  // Estimated peak bytes of the ray casts running ("exact", "error"): the
  // GL thread leaves them room in the budget.
  std::atomic<std::uint64_t> reserved_bytes{0};
  std::atomic<std::uint64_t> cached{0};  // ShadowRenderer::cached_bytes after the last job or release
  bool idle_release_due = false;  // guarded by mutex: work was done since the last idle release
  RendererInfo info;
  // llvmpipe (which request_cost's estimates are calibrated on) or a GPU:
  // filter "exact"'s estimate prices the path this GL takes. Set with
  // info, before the service takes its first request (run's `ready`).
  CertifyingGl certifying_gl = CertifyingGl::Llvmpipe;
  std::thread thread;
  std::thread reaper;

  // Answers each job that has waited past the deadline as soon as it has,
  // while the GL thread may still be busy with a long one before it: the GL
  // thread alone would only find it when its turn came, and the client would
  // wait for the long job first. Jobs wait in order, so the first one is
  // always the next to expire.
  void reap() {
    std::unique_lock<std::mutex> lock(mutex);
    while (!stopping) {
      const auto now = std::chrono::steady_clock::now();
      while (!jobs.empty() && now - jobs.front().queued > limits.deadline) {
        Job job = std::move(jobs.front());
        jobs.pop_front();
        // Counters first, then the answer (as on the GL thread).
        expired_count.fetch_add(1);
        if (job.holds_place) in_flight.fetch_sub(1);
        job.promise.set_exception(std::make_exception_ptr(DeadlineExceeded()));
      }
      if (jobs.empty())
        reaper_wake.wait(lock, [this] { return stopping || !jobs.empty(); });
      else
        reaper_wake.wait_until(lock, jobs.front().queued + limits.deadline + std::chrono::milliseconds(1));
    }
  }

  // On the GL thread, once it has had no work for kIdleRelease: the big
  // resources a burst left go, then the free pages of every thread's malloc
  // arena (frames' images and PNGs, llvmpipe's scratch, ray casts' records)
  // go back to the system, so that resident memory follows the work, not
  // the history.
  //
  // llvmpipe holds on to much of the GL memory released until its context
  // goes (ShadowRenderer::released_gl_bytes), so when that passes
  // renewal_bytes() the GL context itself is made anew: what is lost is
  // the kept scene and the compiled shader variants, which the next request
  // rebuilds (its first frame took 0.13 s instead of 0.035 s at 960 x 540),
  // against hundreds of megabytes held for as long as the server runs idle.
  void release_when_idle(std::optional<gl::EglContext>& context, std::optional<ShadowRenderer>& renderer) {
    // No renderer: a fresh context failed before, and the next job tries again.
    if (renderer) {
      cached.store(renderer->release_cached(limits.memory_budget_bytes / kIdleShare));
      if (limits.fresh_context_bytes != 0 && renderer->released_gl_bytes() > renewal_bytes()) renew(context, renderer);
    }
    malloc_trim(0);
  }

  void renew(std::optional<gl::EglContext>& context, std::optional<ShadowRenderer>& renderer) {
    try {
      make_renderer(context, renderer);
      cached.store(renderer->cached_bytes());
      context_renewals.fetch_add(1);
    } catch (const std::exception& e) {
      cached.store(0);
      std::fprintf(stderr, "umbra: a fresh GL context could not be made (%s); the next render tries again\n", e.what());
    } catch (...) {
      cached.store(0);
      std::fprintf(stderr, "umbra: a fresh GL context could not be made; the next render tries again\n");
    }
  }

  // At least fresh_context_bytes of GL memory released (or the idle share of
  // the budget, if larger): a server with a small budget that idles between
  // small frames must not pay a renewal after every one. (A rule on resident
  // memory instead was tried: the same workload then renewed or not
  // depending on how far the allocator had grown.)
  std::uint64_t renewal_bytes() const {
    return std::max(limits.fresh_context_bytes, limits.memory_budget_bytes / kIdleShare);
  }

  // A GL context and a renderer in it, the old ones (if any) destroyed
  // first, renderer before context. Throws what EglContext and
  // ShadowRenderer throw, leaving the renderer empty.
  void make_renderer(std::optional<gl::EglContext>& context, std::optional<ShadowRenderer>& renderer) {
    renderer.reset();
    context.reset();
    context.emplace();
    renderer.emplace(limits.memory_budget_bytes / kSceneShare);
  }

  // A ray cast's place in the queue and its reserved bytes, given back
  // however the cast ends.
  // A job's place in job_line: it leaves the line when its turn comes, or
  // when it is dropped (cancelled, or its thread never ran).
  struct JobTicket {
    Impl* const impl;
    const std::uint64_t number;
    JobTicket(Impl* impl, std::uint64_t number) : impl(impl), number(number) {}
    JobTicket(const JobTicket&) = delete;
    JobTicket& operator=(const JobTicket&) = delete;
    ~JobTicket() { impl->leave_job_line(number); }
  };
  // Held by the job running; the next in line goes once it is dropped.
  struct JobTurn {
    Impl* const impl;
    explicit JobTurn(Impl* impl) : impl(impl) {}
    JobTurn(const JobTurn&) = delete;
    JobTurn& operator=(const JobTurn&) = delete;
    ~JobTurn() {
      {
        std::lock_guard<std::mutex> lock(impl->job_line.mutex);
        impl->job_line.running = false;
      }
      impl->job_line.turn_free.notify_all();
    }
  };

  std::shared_ptr<JobTicket> join_job_line() {
    std::lock_guard<std::mutex> lock(job_line.mutex);
    const std::uint64_t number = job_line.next_ticket++;
    job_line.waiting.push_back(number);
    return std::make_shared<JobTicket>(this, number);
  }

  void leave_job_line(std::uint64_t number) {
    {
      std::lock_guard<std::mutex> lock(job_line.mutex);
      const auto it = std::find(job_line.waiting.begin(), job_line.waiting.end(), number);
      if (it == job_line.waiting.end()) return;
      job_line.waiting.erase(it);
    }
    job_line.turn_free.notify_all();
  }

  // Waits until no job runs and `ticket` is first in line, then takes the
  // turn; null (out of the line) once `cancelled` says so.
  template <class Cancelled>
  std::unique_ptr<JobTurn> wait_for_job_turn(const JobTicket& ticket, Cancelled cancelled) {
    std::unique_lock<std::mutex> lock(job_line.mutex);
    while (job_line.running || job_line.waiting.empty() || job_line.waiting.front() != ticket.number) {
      if (cancelled()) {
        lock.unlock();
        leave_job_line(ticket.number);
        return nullptr;
      }
      job_line.turn_free.wait_for(lock, std::chrono::milliseconds(50));
    }
    job_line.waiting.pop_front();
    job_line.running = true;
    return std::make_unique<JobTurn>(this);
  }

  struct CastPlace {
    Impl* impl;
    std::uint64_t peak_bytes;
    ~CastPlace() {
      impl->ray_cast_ended(peak_bytes);
      impl->in_flight.fetch_sub(1);
    }
  };

  // Called when a ray cast ends: its memory is freed in its own thread's
  // arena, which the GL thread's idle release trims too.
  void ray_cast_ended(std::uint64_t peak_bytes) {
    reserved_bytes.fetch_sub(peak_bytes);
    {
      std::lock_guard<std::mutex> lock(mutex);
      idle_release_due = true;
    }
    wake.notify_one();
  }

  // The GL thread: context, renderer and every GL call live and die here.
  void run(std::promise<void>& ready) {
    std::optional<gl::EglContext> context;
    std::optional<ShadowRenderer> renderer;
    try {
      make_renderer(context, renderer);
      // Read by other threads without a lock, so set once: a fresh context
      // is chosen by the same rules (EglContext) and is on the same driver.
      info = {renderer->gl_renderer(), renderer->gl_version(), context->source()};
      const bool llvmpipe = info.gl_renderer.find("llvmpipe") != std::string::npos;
      certifying_gl = llvmpipe ? CertifyingGl::Llvmpipe : CertifyingGl::Gpu;
    } catch (...) {
      ready.set_exception(std::current_exception());
      return;
    }
    ready.set_value();
    for (;;) {
      Job job;
      {
        std::unique_lock<std::mutex> lock(mutex);
        while (!stopping && jobs.empty()) {
          if (!idle_release_due) {
            wake.wait(lock);
          } else if (wake.wait_for(lock, kIdleRelease) == std::cv_status::timeout && jobs.empty() && !stopping) {
            // Idle for kIdleRelease (a wake-up from a job or a finished ray
            // cast starts the wait again).
            idle_release_due = false;
            lock.unlock();
            release_when_idle(context, renderer);
            lock.lock();
          }
        }
        if (jobs.empty()) return;  // stopping, and nothing left to do
        job = std::move(jobs.front());
        jobs.pop_front();
        idle_release_due = true;
      }
      std::optional<RenderResult> result;
      std::exception_ptr error;
      const auto started = std::chrono::steady_clock::now();
      try {
        check_still_wanted(job.queued, job.client_gone);
        if (!renderer) make_renderer(context, renderer);
        // Room for this frame's peak and the ray casts running beside it:
        // what is kept goes first, so the request is not refused for it.
        // What the frame draws into as it is counts in its peak already;
        // finding it plans the light (milliseconds for a thousand objects),
        // so only when something would have to go.
        const std::uint64_t needed = job.peak_bytes + reserved_bytes.load();
        if (renderer->cached_bytes() > minus_or_zero(limits.memory_budget_bytes, needed))
          renderer->release_cached(
              minus_or_zero(limits.memory_budget_bytes + renderer->bytes_reused_by(job.request), needed));
        // The watchdog: the estimate admitted the frame, but one it
        // misjudged, or a busy machine, must not hold the GL thread (and
        // every request queued behind it, and a drain) without bound.
        // Filter "exact" takes the path its estimate priced lowest for
        // this GL (request_cost.hpp).
        result = renderer->render(job.request, FrameWatch{started + limits.max_run_time}, job.certified_path);
        if (result->certificates) settle(*result, job, started);
        if (result->shadow_reused) shadow_reuses.fetch_add(1);
        if (result->scene_uploaded) scene_uploads.fetch_add(1);
        frames.fetch_add(1);
      } catch (const FrameCutShort& e) {
        overran_count.fetch_add(1);
        error = std::make_exception_ptr(frame_overran(e, started, job.dominant));
      } catch (...) {
        error = std::current_exception();
      }
      cached.store(renderer ? renderer->cached_bytes() : 0);
      // Counters first, then the answer: whoever holds the answer sees the
      // place already given back.
      if (job.holds_place) in_flight.fetch_sub(1);
      if (error)
        job.promise.set_exception(error);
      else
        job.promise.set_value(std::move(*result));
    }
  }
};

RenderService::RenderService(ServiceLimits limits) : impl_(std::make_unique<Impl>(limits)) {
  std::promise<void> ready;
  std::future<void> started = ready.get_future();
  impl_->thread = std::thread([this, &ready] { impl_->run(ready); });
  try {
    started.get();
  } catch (...) {
    impl_->thread.join();
    throw;
  }
  impl_->reaper = std::thread([this] { impl_->reap(); });
}

RenderService::~RenderService() {
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->stopping = true;
  }
  impl_->wake.notify_all();
  impl_->reaper_wake.notify_all();
  impl_->thread.join();
  impl_->reaper.join();
  // Ray casts run on their own threads and give their place back when they
  // end: wait for them, since they hold a pointer to impl_.
  while (impl_->in_flight.load() > 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

void RenderService::check_cost(const RenderRequest& request) {
  impl_->check_budget(estimate_cost(request, impl_->certifying_gl));
}

std::future<RenderResult> RenderService::submit(RenderRequest request, ClientGoneCheck client_gone) {
  // Before anything is queued: a GL frame cannot be stopped once it is
  // drawing, so refusing what would take too long is what bounds the time
  // one request holds the GL thread.
  const bool ray_cast = request.output == Output::Exact || request.output == Output::Error;
  const RequestCost cost = estimate_cost(request, impl_->certifying_gl);
  impl_->check_budget(cost);
  if (ray_cast) return submit_reference(std::move(request), std::move(client_gone), cost);
  impl_->reserve();
  return impl_->enqueue(std::move(request), true, std::move(client_gone), cost.peak_bytes, cost.dominant(),
                        cost.exact_filter_path);
}

// The exact reference needs no GL: it is ray cast on its own thread so the GL
// thread keeps rendering. "error" also needs the GL "shadow" output. The
// ray cast holds a place in the queue too, so that CPU work is bounded.
std::future<RenderResult> RenderService::submit_reference(RenderRequest request, ClientGoneCheck client_gone,
                                                         const RequestCost& cost) {
  const CostPart& dominant = cost.dominant();
  const std::uint64_t peak_bytes = cost.peak_bytes;
  impl_->reserve();
  // The whole request's peak, "error"'s GL frame included, is reserved
  // until the cast ends; its GL job then needs no room of its own.
  impl_->reserved_bytes.fetch_add(peak_bytes);
  std::future<RenderResult> rendered;
  if (request.output == Output::Error) {
    RenderRequest shadow = request;
    shadow.output = Output::Shadow;
    rendered = impl_->enqueue(std::move(shadow), false, client_gone, 0, dominant, cost.exact_filter_path);
  }
  std::string dominant_field = dominant.field;
  Impl* impl = impl_.get();
  const auto queued = std::chrono::steady_clock::now();
  return std::async(std::launch::async, [impl, queued, request = std::move(request), rendered = std::move(rendered),
                                         client_gone = std::move(client_gone),
                                         dominant_field = std::move(dominant_field), peak_bytes]() mutable {
    const Impl::CastPlace place{impl, peak_bytes};
    // "error": its GL job checks the client and the deadline (and counts
    // them). If the client has already left, wait for that job's verdict
    // rather than cast rays for nobody.
    std::optional<RenderResult> shadow;
    if (request.output == Output::Exact)
      impl->check_still_wanted(queued, client_gone);
    else if (client_gone && client_gone())
      shadow = rendered.get();
    const auto start = std::chrono::steady_clock::now();
    // A client that leaves while its rays are cast stops the cast: an area
    // light at 4096^2 is minutes of CPU for nobody otherwise. So does a cast
    // that runs past max_run_time for a client that stays: the estimate
    // admitted it, but a busy machine or a scene the estimate misjudged must
    // not hold the cores without bound.
    auto run_until = start + impl->limits.max_run_time;
    bool overran = false;
    const auto stop = [&client_gone, &overran, &run_until] {
      if (client_gone && client_gone()) return true;
      overran = std::chrono::steady_clock::now() > run_until;
      return overran;
    };
    std::vector<ExactPixel> pixels;
    std::optional<ShadowError> error;
    std::chrono::steady_clock::duration cast_time{};
    try {
      const ExactView view(request, stop);
      pixels = view.pixels(stop);
      cast_time = std::chrono::steady_clock::now() - start;
      if (request.output == Output::Error) {
        if (!shadow) shadow = rendered.get();
        // Artifact candidates are sampled finer (shadow_error.hpp) with the
        // same view, under what is left of max_run_time: the wait for the
        // GL frame above is not the cast's, and the finer look is.
        const auto finer_start = std::chrono::steady_clock::now();
        run_until = finer_start + (impl->limits.max_run_time - cast_time);
        error = measure_shadow_error(shadow->image, pixels, view.coverage_of(stop));
        cast_time += std::chrono::steady_clock::now() - finer_start;
      }
    } catch (const CastStopped&) {
      if (overran) {
        impl->overran_count.fetch_add(1);
        throw RunTimeExceeded("the ray cast ran past the limit of " +
                                  std::to_string(impl->limits.max_run_time.count()) +
                                  " ms a request and was stopped; lower width and height, light.size or the objects",
                              dominant_field);
      }
      // "error": its GL half is still queued. It checks the client itself
      // when its turn comes, and counts it: wait for that verdict, so that
      // the client is counted once, and so that the check runs while the
      // connection (whose socket client_gone asks) is still this client's.
      if (request.output == Output::Error && !shadow) (void)rendered.get();
      impl->abandoned_count.fetch_add(1);
      throw ClientGone();
    }
    const Image exact = exact_image(pixels, request.width, request.height);
    RenderResult result;
    if (request.output == Output::Error) {
      result = std::move(*shadow);
      result.error = error;
      result.image = error_image(result.image, exact);
    } else {
      result.image = exact;  // no GL pass ran: shadow, main and read-back stay 0
    }
    result.timings.ray_cast_ms = std::chrono::duration<double, std::milli>(cast_time).count();
    return result;
  });
}

SunHoursPlan RenderService::plan_sun_hours(const SunHoursRequest& request) const {
  return umbra::plan_sun_hours(request);
}

// A sun-hours analysis needs no GL: like the exact output, it runs on its
// own thread (the cast itself on every core) and holds a place in the queue
// while it runs. A job waiting for its turn holds none: sixteen jobs
// waiting must not fill the queue that renders share.
std::future<SunHoursResult> RenderService::submit_sun_hours(SunHoursRequest request, ClientGoneCheck client_gone,
                                                            bool job, std::shared_ptr<SunHoursProgress> progress,
                                                            std::optional<SunHoursPlan> planned) {
  const SunHoursPlan plan = planned ? std::move(*planned) : plan_sun_hours(request);
  const RequestCost& cost = plan.estimate.cost;
  if (job)
    impl_->check_budget(cost, impl_->limits.max_job_cost, " ms a job (--max-job-ms)", " to run");
  else
    impl_->check_budget(cost, impl_->limits.max_request_cost, " ms a request", " to run");
  if (!job) {
    impl_->reserve();
    impl_->reserved_bytes.fetch_add(cost.peak_bytes);
  }
  if (!progress) progress = std::make_shared<SunHoursProgress>();
  Impl* impl = impl_.get();
  const auto queued = std::chrono::steady_clock::now();
  // The ticket is taken here, on the submitting thread, so the line keeps
  // the order of submission whatever order the threads start in.
  std::shared_ptr<Impl::JobTicket> ticket;
  if (job) ticket = impl->join_job_line();
  return std::async(std::launch::async, [impl, queued, plan, job, progress, ticket, request = std::move(request),
                                         client_gone = std::move(client_gone), dominant = cost.dominant(),
                                         peak_bytes = cost.peak_bytes]() {
    std::unique_ptr<Impl::CastPlace> place;
    if (!job) place.reset(new Impl::CastPlace{impl, peak_bytes});
    // Jobs one after another, first submitted first: each uses every core.
    // A job waits for its turn however long it takes (its client comes back
    // for it later), and then for a place in the queue.
    std::unique_ptr<Impl::JobTurn> turn;
    if (job) {
      const auto cancelled = [&] {
        if (!progress->cancel) return false;
        impl->abandoned_count.fetch_add(1);
        return true;
      };
      turn = impl->wait_for_job_turn(*ticket, [&] { return progress->cancel.load(); });
      if (!turn && cancelled()) throw ClientGone();
      while (!impl->try_reserve()) {
        if (cancelled()) throw ClientGone();
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
      impl->reserved_bytes.fetch_add(peak_bytes);
      place.reset(new Impl::CastPlace{impl, peak_bytes});
      if (cancelled()) throw ClientGone();
    } else {
      impl->check_still_wanted(queued, client_gone);
    }
    progress->started = true;
    const auto start = std::chrono::steady_clock::now();
    const auto run_time = job ? 2 * impl->limits.max_job_cost : impl->limits.max_run_time;
    const auto run_until = start + run_time;
    bool overran = false;
    const auto stop = [&client_gone, &overran, &run_until, &progress] {
      if (progress->cancel || (client_gone && client_gone())) return true;
      overran = std::chrono::steady_clock::now() > run_until;
      return overran;
    };
    SunHoursResult result;
    result.step_minutes = request.period.step_minutes;
    try {
      result.samples = sun_samples_on_all_cores(request.site, request.period, plan.samples, stop);
      std::uint64_t up = 0;
      for (const SunSample& s : result.samples) up += s.up() ? 1 : 0;
      const std::uint64_t pixels =
          request.picture ? std::uint64_t(request.view.width) * std::uint64_t(request.view.height) : 0;
      progress->pairs_total = up * (std::uint64_t(request.grid.points()) + pixels);
      if (request.picture) {
        // The camera's view: its own rays (ExactView builds the scene's).
        const ExactView view(request.view, stop);
        result.pixel_hours = sun_hours_per_pixel(view, request.view.width, request.view.height, result.samples,
                                                 request.period.step_minutes, stop, &progress->pairs_done);
        result.pixel_pairs = pixels * up;
      }
      const RayScene rays(request.view.scene, stop);
      if (request.grid.points() == 0)
        result.samples_up = std::size_t(up);
      else if (plan.estimate.footprints)
        footprint_sun_hours(rays, request.view.scene, request.grid, result.samples, result, stop,
                            &progress->pairs_done);
      else
        ray_cast_sun_hours(rays, request.grid, result.samples, result, stop, &progress->pairs_done);
    } catch (const CastStopped&) {
      if (overran) {
        impl->overran_count.fetch_add(1);
        throw RunTimeExceeded("the sun-hours analysis ran past the limit of " + std::to_string(run_time.count()) +
                                  " ms " + (job ? "a job" : "a request") + " and was stopped: " + dominant.advice,
                              dominant.field);
      }
      impl->abandoned_count.fetch_add(1);
      throw ClientGone();
    }
    result.elapsed_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return result;
  });
}

const RendererInfo& RenderService::info() const { return impl_->info; }
std::uint64_t RenderService::frames_rendered() const { return impl_->frames.load(); }
std::size_t RenderService::queue_depth() const { return impl_->in_flight.load(); }
std::uint64_t RenderService::shadow_cache_hits() const { return impl_->shadow_reuses.load(); }
std::uint64_t RenderService::rejected() const { return impl_->rejected_count.load(); }
std::uint64_t RenderService::scene_uploads() const { return impl_->scene_uploads.load(); }
std::uint64_t RenderService::context_renewals() const { return impl_->context_renewals.load(); }
std::uint64_t RenderService::abandoned() const { return impl_->abandoned_count.load(); }
std::uint64_t RenderService::expired() const { return impl_->expired_count.load(); }
std::uint64_t RenderService::too_costly() const { return impl_->too_costly_count.load(); }
std::uint64_t RenderService::overran() const { return impl_->overran_count.load(); }
std::uint64_t RenderService::cached_bytes() const { return impl_->cached.load(); }
const ServiceLimits& RenderService::limits() const { return impl_->limits; }

}  // namespace umbra
