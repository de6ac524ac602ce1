// The renderer as a service: one thread owns the GL context and runs every
// job that touches GL, in order. Callers on any thread submit a typed request
// and wait on a future for pixels. This header includes no GL.
#pragma once

#include <cstdint>
#include <future>
#include <memory>
#include <string>

#include "render_result.hpp"
#include "request.hpp"

namespace umbra {

struct RendererInfo {
  std::string gl_renderer;  ///< GL_RENDERER, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)"
  std::string gl_version;   ///< GL_VERSION
  std::string egl_source;   ///< how the EGL display was found
};

class RenderService {
 public:
  /// Starts the GL thread and waits until it has a context and compiled
  /// shaders. Throws std::runtime_error with the reason if it cannot (no EGL,
  /// no GL 4.5 core context, a GLSL error).
  RenderService();
  /// Finishes the jobs already queued, then stops the GL thread.
  ~RenderService();
  RenderService(const RenderService&) = delete;
  RenderService& operator=(const RenderService&) = delete;

  /// Queues a render. The future holds the result, or the exception the
  /// renderer threw. `request` must be valid (see server/request_parser.hpp).
  /// "exact" is ray cast on the CPU off the GL thread (its time is reported
  /// as `main`); "error" renders "shadow" on the GL thread, then compares.
  std::future<RenderResult> submit(RenderRequest request);

  const RendererInfo& info() const;
  std::uint64_t frames_rendered() const;
  /// Jobs waiting or being rendered.
  std::size_t queue_depth() const;

 private:
  std::future<RenderResult> submit_reference(RenderRequest request);

  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace umbra
