// A headless OpenGL 4.5 core context through EGL, with no window system.
#pragma once

#include <string>

namespace umbra::gl {

/// Owns an EGL display and context and makes the context current on the
/// thread that constructs it. Construct, use and destroy it on one thread.
///
/// Device choice: with EGL_EXT_device_enumeration + EGL_EXT_platform_device,
/// a hardware device (one without EGL_MESA_device_software) is preferred; if
/// none works, Mesa's surfaceless platform (llvmpipe) is used, then any
/// remaining software device. The context renders into framebuffer objects
/// only (EGL_KHR_surfaceless_context), so no pbuffer is needed.
class EglContext {
 public:
  /// Throws std::runtime_error with a message naming what is missing (EGL
  /// extensions, a display, a GL 4.5 core context).
  EglContext();
  ~EglContext();
  EglContext(const EglContext&) = delete;
  EglContext& operator=(const EglContext&) = delete;

  /// How the display was obtained, e.g. "EGL device 0 (hardware)" or
  /// "Mesa surfaceless platform".
  const std::string& source() const { return source_; }

 private:
  void* display_ = nullptr;
  void* context_ = nullptr;
  std::string source_;
};

}  // namespace umbra::gl
