#include "render_service.hpp"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>
#include <thread>

#include "gl/egl_context.hpp"
#include "ray_cast.hpp"
#include "shadow_error.hpp"
#include "shadow_renderer.hpp"

namespace umbra {

struct RenderService::Impl {
  struct Job {
    RenderRequest request;
    std::promise<RenderResult> promise;
  };

  mutable std::mutex mutex;
  std::condition_variable wake;
  std::deque<Job> jobs;
  bool stopping = false;
  std::atomic<std::size_t> in_flight{0};
  std::atomic<std::uint64_t> frames{0};
  RendererInfo info;
  std::thread thread;

  // The GL thread: context, renderer and every GL call live and die here.
  void run(std::promise<void>& ready) {
    std::optional<gl::EglContext> context;
    std::optional<ShadowRenderer> renderer;
    try {
      context.emplace();
      renderer.emplace();
      info = {renderer->gl_renderer(), renderer->gl_version(), context->source()};
    } catch (...) {
      ready.set_exception(std::current_exception());
      return;
    }
    ready.set_value();
    for (;;) {
      Job job;
      {
        std::unique_lock<std::mutex> lock(mutex);
        wake.wait(lock, [this] { return stopping || !jobs.empty(); });
        if (jobs.empty()) return;  // stopping, and nothing left to do
        job = std::move(jobs.front());
        jobs.pop_front();
      }
      try {
        job.promise.set_value(renderer->render(job.request));
        frames.fetch_add(1);
      } catch (...) {
        job.promise.set_exception(std::current_exception());
      }
      in_flight.fetch_sub(1);
    }
  }
};

RenderService::RenderService() : impl_(std::make_unique<Impl>()) {
  std::promise<void> ready;
  std::future<void> started = ready.get_future();
  impl_->thread = std::thread([this, &ready] { impl_->run(ready); });
  try {
    started.get();
  } catch (...) {
    impl_->thread.join();
    throw;
  }
}

RenderService::~RenderService() {
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->stopping = true;
  }
  impl_->wake.notify_all();
  impl_->thread.join();
}

std::future<RenderResult> RenderService::submit(RenderRequest request) {
  if (request.output == Output::Exact || request.output == Output::Error) return submit_reference(std::move(request));
  Impl::Job job{std::move(request), {}};
  std::future<RenderResult> result = job.promise.get_future();
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->jobs.push_back(std::move(job));
    impl_->in_flight.fetch_add(1);
  }
  impl_->wake.notify_one();
  return result;
}

// The exact reference needs no GL: it is ray cast on its own thread so the GL
// thread keeps rendering. "error" also needs the GL "shadow" output.
std::future<RenderResult> RenderService::submit_reference(RenderRequest request) {
  std::future<RenderResult> rendered;
  if (request.output == Output::Error) {
    RenderRequest shadow = request;
    shadow.output = Output::Shadow;
    rendered = submit(std::move(shadow));
  }
  return std::async(std::launch::async, [request = std::move(request), rendered = std::move(rendered)]() mutable {
    const auto start = std::chrono::steady_clock::now();
    const std::vector<ExactPixel> pixels = cast_exact_pixels(request);
    const Image exact = exact_image(pixels, request.width, request.height);
    const double cast_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    RenderResult result;
    if (request.output == Output::Error) {
      result = rendered.get();
      result.error = measure_shadow_error(result.image, pixels);
      result.image = error_image(result.image, exact);
      result.timings.main_ms += cast_ms;
    } else {
      result.image = exact;
      result.timings.main_ms = cast_ms;
    }
    return result;
  });
}

const RendererInfo& RenderService::info() const { return impl_->info; }
std::uint64_t RenderService::frames_rendered() const { return impl_->frames.load(); }
std::size_t RenderService::queue_depth() const { return impl_->in_flight.load(); }

}  // namespace umbra
