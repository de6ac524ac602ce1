// The renderer as a service: one thread owns the GL context and runs every
// job that touches GL, in order. Callers on any thread submit a typed request
// and wait on a future for pixels. This header includes no GL.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <future>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

#include "core/render_result.hpp"
#include "core/request.hpp"
#include "core/sun_hours.hpp"
#include "service/request_cost.hpp"

namespace umbra {

struct RendererInfo {
  std::string gl_renderer;  ///< GL_RENDERER, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)"
  std::string gl_version;   ///< GL_VERSION
  std::string egl_source;   ///< how the EGL display was found
};

/// How much work the service accepts. A full queue refuses at once rather
/// than building a backlog; a job that waited past its deadline is not
/// rendered for a client that has likely given up.
struct ServiceLimits {
  /// Jobs waiting or being rendered (GL and ray-cast alike), 1.. Default 16.
  std::size_t queue_capacity = 16;
  /// Longest a job may wait for its turn, milliseconds, > 0. Default 10 s.
  std::chrono::milliseconds deadline{10000};
  /// Most work one request may be estimated to take (renderer/service/request_cost.hpp:
  /// milliseconds of this 2-core llvmpipe machine, GL thread and ray cast
  /// together), > 0. More is refused before it is queued (RequestTooCostly).
  /// Default 4 s: the heaviest requests the tests and benchmarks make (a
  /// 4096^2 "shadow" with pcf_radius 8, about 3.2 s estimated) pass, the
  /// 142 s one of issue 11 (about 45 s estimated) does not. What it
  /// admits, max_run_time bounds.
  std::chrono::milliseconds max_request_cost{4000};
  /// Most memory one request may be estimated to need at its peak, bytes,
  /// > 0. More is refused before it is queued. Default 2 GiB (the largest
  /// map the API allows, 4 layers of 8192^2 32-bit depth, is 1 GiB).
  std::uint64_t max_request_bytes = std::uint64_t(2) << 30;
  /// Longest a request may run once started, milliseconds, > 0
  /// (RunTimeExceeded). A ray cast ("exact", "error") is checked between
  /// rows, so it ends within a row of it. A GL frame (the watchdog) is
  /// checked between passes and between the chunks a deep or long mesh's draws are
  /// split into (ShadowRenderer, about 20 ms each), so it holds the GL
  /// thread for at most about this plus a chunk, plus the one draw or
  /// upload in progress that the estimate priced (scene triangles, map
  /// clears: at most max_request_cost of it). Default 8 s, twice the cost
  /// budget: room for an estimate that was low or a machine that is busy.
  /// With the queue's deadline it bounds a drain: every request already
  /// queued is answered within deadline + max_run_time.
  std::chrono::milliseconds max_run_time{8000};
  /// Memory the renderer may hold, bytes, >= 64 MiB: what it keeps between
  /// requests (uploaded scenes, the shadow map, framebuffers: see
  /// ShadowRenderer::cached_bytes) plus the estimated peak of the requests
  /// running (renderer/service/request_cost.hpp). Before a frame, what is kept is
  /// released, least recently used first, until the frame fits; a request
  /// is refused (RequestTooCostly) only if its own peak exceeds the budget.
  /// Cached scenes keep at most a third of it; after 1.5 s without work the
  /// renderer keeps at most 1/32 of it and returns free heap pages to the
  /// system. Default 2 GiB: one 24 GiB, 2-core machine runs this beside
  /// other services; it holds the largest request the API allows (a 1 GiB
  /// map), or two cached 1000-sphere scenes (280 MB each) and a 4096^2 frame.
  std::uint64_t memory_budget_bytes = std::uint64_t(2) << 30;
  /// When idle, the GL context is made anew once the GL memory released
  /// since the last one passes this (or 1/32 of memory_budget_bytes, if
  /// larger), bytes; 0: never. llvmpipe keeps much of what is deleted until
  /// its context goes (ShadowRenderer::released_gl_bytes); each renewal
  /// costs the next request its shader compiles and scene upload. Default
  /// 64 MiB.
  std::uint64_t fresh_context_bytes = std::uint64_t(64) << 20;
  /// A sun-hours analysis over max_request_cost runs as a job (202, then
  /// GET for progress and the result) when its estimate is at most this,
  /// milliseconds, > 0; more is refused (RequestTooCostly). Jobs run one
  /// at a time, each for at most twice this. Default 10 minutes.
  std::chrono::milliseconds max_job_cost{600000};
};

/// How far a sun-hours analysis has come, shared by the service (which
/// counts) and whoever watches (a job's GET). Pairs are (point, sample)
/// pairs with the sun up; they are known once the samples are.
struct SunHoursProgress {
  std::atomic<std::uint64_t> pairs_total{0};
  std::atomic<std::uint64_t> pairs_done{0};
  /// Set by the watcher: the analysis stops (ClientGone) at its next check.
  std::atomic<bool> cancel{false};
  /// Set by the service when the analysis leaves the queue and starts.
  std::atomic<bool> started{false};
};



/// submit() refused the job: the queue holds queue_capacity jobs already.
struct QueueFull : std::runtime_error {
  QueueFull() : std::runtime_error("the render queue is full") {}
};
/// The client that asked for the job went away before its turn; it was
/// dropped unrendered.
struct ClientGone : std::runtime_error {
  ClientGone() : std::runtime_error("the client disconnected before its turn") {}
};
/// submit() refused the job before queueing it: its estimated time or peak
/// memory (renderer/service/request_cost.hpp) exceeds ServiceLimits' budget. The
/// message names the part that dominates, the estimate and the budget.
struct RequestTooCostly : std::runtime_error {
  RequestTooCostly(const std::string& message, std::string field)
      : std::runtime_error(message), field(std::move(field)) {}
  /// The JSON field whose lowering helps most, e.g. "shadow.map_size".
  std::string field;
};
/// A ray cast or a GL frame ran past ServiceLimits::max_run_time and was
/// stopped; nothing of it is returned.
struct RunTimeExceeded : std::runtime_error {
  RunTimeExceeded(const std::string& message, std::string field)
      : std::runtime_error(message), field(std::move(field)) {}
  /// The JSON field whose lowering helps most (the estimate's dominant part).
  std::string field;
};
/// The job waited longer than the deadline and was dropped unrendered.
struct DeadlineExceeded : std::runtime_error {
  DeadlineExceeded() : std::runtime_error("the request waited past the render deadline") {}
};

class RenderService {
 public:
  /// Starts the GL thread and waits until it has a context and compiled
  /// shaders. Throws std::runtime_error with the reason if it cannot (no EGL,
  /// no GL 4.5 core context, a GLSL error).
  explicit RenderService(ServiceLimits limits = {});
  /// Finishes the jobs already queued, then stops the GL thread. Destroy
  /// the service before the process exits, not from a static destructor:
  /// Mesa's exit handlers are registered after it starts, run before such a
  /// destructor, and free state the GL thread may still be using.
  ~RenderService();
  RenderService(const RenderService&) = delete;
  RenderService& operator=(const RenderService&) = delete;

  /// Queues a render; throws RequestTooCostly at once if its estimate is
  /// over the budget, QueueFull if the queue is full. The future holds the
  /// result, DeadlineExceeded if the job waited too long, RunTimeExceeded if
  /// its frame or ray cast ran too long, or the exception the renderer threw. `request` must be valid (see server/request_parser.hpp).
  /// "exact" is ray cast on the CPU off the GL thread (its time is reported
  /// as `main`); "error" renders "shadow" on the GL thread, then compares.
  ///
  /// `client_gone`, if given, is asked (on another thread) just before the
  /// job's turn; if it answers true the job is dropped with ClientGone.
  using ClientGoneCheck = std::function<bool()>;
  std::future<RenderResult> submit(RenderRequest request, ClientGoneCheck client_gone = {});
  /// Throws RequestTooCostly as submit() would for `request`, queueing
  /// nothing: asked of a scene's rest pose before its animated models are
  /// posed (posing a large model is seconds of work a refusal should not
  /// cost).
  void check_cost(const RenderRequest& request);

  /// Queues a sun-hours analysis (core/sun_hours.hpp): refused at once as
  /// submit() refuses (RequestTooCostly by estimate_sun_hours_cost,
  /// QueueFull); it holds a place in the queue while it runs. Run off the
  /// GL thread on every core: the sun's samples, then every (point,
  /// sample) pair with the sun up by the exact ray cast. The future holds
  /// the result, or DeadlineExceeded, ClientGone, RunTimeExceeded (past
  /// max_run_time) as submit()'s do.
  ///
  /// With `job`, the budget is max_job_cost and the run time twice that,
  /// and jobs run one after another; a job takes its place in the queue
  /// when its turn comes (waiting for one if the queue is full), so jobs
  /// waiting leave the queue to renders. `progress`, if given, is counted as the
  /// pairs are settled, and its `cancel` stops the analysis (ClientGone).
  /// `plan`, if given, is plan_sun_hours(request) made already (the route
  /// plans first, to choose between an answer and a job): not made again.
  std::future<SunHoursResult> submit_sun_hours(SunHoursRequest request, ClientGoneCheck client_gone = {},
                                               bool job = false, std::shared_ptr<SunHoursProgress> progress = {},
                                               std::optional<SunHoursPlan> plan = std::nullopt);
  /// The path and cost estimate submit_sun_hours uses (plan_sun_hours,
  /// request_cost.hpp).
  SunHoursPlan plan_sun_hours(const SunHoursRequest& request) const;

  const RendererInfo& info() const;
  std::uint64_t frames_rendered() const;
  /// Frames that reused the shadow map of an earlier frame (no shadow pass).
  std::uint64_t shadow_cache_hits() const;
  /// Scenes whose meshes were uploaded: the renderer keeps the last 8
  /// distinct scenes (within a third of the memory budget), so a scene seen
  /// recently costs no upload.
  std::uint64_t scene_uploads() const;
  /// Fresh GL contexts made when idle: llvmpipe keeps the memory of render
  /// targets it drew into (and of deleted scene buffers) until their context
  /// goes, so after a burst whose released GL memory exceeds the idle share
  /// of the budget the GL thread makes its context anew
  /// (ShadowRenderer::released_gl_bytes).
  std::uint64_t context_renewals() const;
  /// Jobs waiting or being rendered.
  std::size_t queue_depth() const;
  /// Jobs refused because the queue was full, and jobs dropped at their
  /// deadline, since start.
  std::uint64_t rejected() const;
  std::uint64_t expired() const;
  /// Jobs dropped because their client disconnected before their turn.
  std::uint64_t abandoned() const;
  /// Requests refused by the cost budget, and frames and ray casts stopped
  /// at max_run_time, since start.
  std::uint64_t too_costly() const;
  std::uint64_t overran() const;
  /// Bytes the GL thread keeps between requests (ShadowRenderer::cached_bytes),
  /// as of its last job or idle release.
  std::uint64_t cached_bytes() const;
  const ServiceLimits& limits() const;

 private:
  std::future<RenderResult> submit_reference(RenderRequest request, ClientGoneCheck client_gone, const RequestCost& cost);

  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace umbra
