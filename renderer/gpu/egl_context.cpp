#include "gpu/egl_context.hpp"

#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include <EGL/egl.h>
#include <EGL/eglext.h>

namespace umbra::gl {

namespace {

bool has_extension(const char* list, const char* name) {
  if (list == nullptr) return false;
  const std::size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n) {
    const bool starts = p == list || p[-1] == ' ';
    const bool ends = p[n] == '\0' || p[n] == ' ';
    if (starts && ends) return true;
  }
  return false;
}

std::string egl_error_name(EGLint error) {
  switch (error) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    default: return "EGL error " + std::to_string(error);
  }
}

struct Candidate {
  EGLDisplay display;
  std::string source;
};

// Tries to initialise `display` and create a current GL 4.5 core context on
// it. Returns the context, or EGL_NO_CONTEXT with `why` filled in.
EGLContext try_create_context(EGLDisplay display, std::string& why) {
  EGLint major = 0, minor = 0;
  if (display == EGL_NO_DISPLAY || !eglInitialize(display, &major, &minor)) {
    why = "eglInitialize failed: " + egl_error_name(eglGetError());
    return EGL_NO_CONTEXT;
  }
  const char* extensions = eglQueryString(display, EGL_EXTENSIONS);
  if (!has_extension(extensions, "EGL_KHR_surfaceless_context")) {
    why = "display lacks EGL_KHR_surfaceless_context";
    eglTerminate(display);
    return EGL_NO_CONTEXT;
  }
  if (!eglBindAPI(EGL_OPENGL_API)) {
    why = "eglBindAPI(EGL_OPENGL_API) failed: " + egl_error_name(eglGetError());
    eglTerminate(display);
    return EGL_NO_CONTEXT;
  }
  EGLConfig config = nullptr;
  if (!has_extension(extensions, "EGL_KHR_no_config_context")) {
    const EGLint config_attributes[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLint count = 0;
    if (!eglChooseConfig(display, config_attributes, &config, 1, &count) || count < 1) {
      why = "no EGL config renders OpenGL";
      eglTerminate(display);
      return EGL_NO_CONTEXT;
    }
  }
  const EGLint context_attributes[] = {EGL_CONTEXT_MAJOR_VERSION, 4,
                                       EGL_CONTEXT_MINOR_VERSION, 5,
                                       EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                       EGL_NONE};
  EGLContext context = eglCreateContext(display, config, EGL_NO_CONTEXT, context_attributes);
  if (context == EGL_NO_CONTEXT) {
    why = "no OpenGL 4.5 core context: " + egl_error_name(eglGetError());
    eglTerminate(display);
    return EGL_NO_CONTEXT;
  }
  if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
    why = "eglMakeCurrent failed: " + egl_error_name(eglGetError());
    eglDestroyContext(display, context);
    eglTerminate(display);
    return EGL_NO_CONTEXT;
  }
  return context;
}

}  // namespace

EglContext::EglContext() {
  const char* client_extensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (client_extensions == nullptr)
    throw std::runtime_error("EGL is not usable: no client extensions (is libEGL / Mesa installed?)");

  std::vector<Candidate> hardware, software;
  std::string failures;  // "\n  source: why" for each way that gave no context
  const auto get_platform_display =
      reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
  // EGL_EXT_device_base is EGL_EXT_device_enumeration + _query in one
  // name; glvnd's libEGL (NVIDIA's driver behind it) lists only that one.
  const bool enumerates_devices = has_extension(client_extensions, "EGL_EXT_device_enumeration") ||
                                  has_extension(client_extensions, "EGL_EXT_device_base");
  if (get_platform_display != nullptr && enumerates_devices &&
      has_extension(client_extensions, "EGL_EXT_platform_device")) {
    const auto query_devices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    const auto query_device_string =
        reinterpret_cast<PFNEGLQUERYDEVICESTRINGEXTPROC>(eglGetProcAddress("eglQueryDeviceStringEXT"));
    EGLDeviceEXT devices[16];
    EGLint count = 0;
    if (query_devices == nullptr || query_device_string == nullptr || !query_devices(16, devices, &count))
      failures += "\n  EGL devices: eglQueryDevicesEXT failed";
    else if (count == 0)
      failures += "\n  EGL devices: none enumerated";
    else {
      for (EGLint i = 0; i < count; ++i) {
        const char* device_extensions = query_device_string(devices[i], EGL_EXTENSIONS);
        const bool is_software = has_extension(device_extensions, "EGL_MESA_device_software");
        EGLDisplay display = get_platform_display(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
        const std::string source =
            "EGL device " + std::to_string(i) + (is_software ? " (software)" : " (hardware)");
        (is_software ? software : hardware).push_back({display, source});
      }
    }
  } else {
    failures += "\n  EGL devices: the client offers no EGL_EXT_device_enumeration (or _base) and EGL_EXT_platform_device";
  }
  std::vector<Candidate> candidates = hardware;
  if (get_platform_display != nullptr && has_extension(client_extensions, "EGL_MESA_platform_surfaceless")) {
    candidates.push_back(
        {get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr), "Mesa surfaceless platform"});
  }
  candidates.insert(candidates.end(), software.begin(), software.end());
  if (candidates.empty())
    throw std::runtime_error(
        "EGL offers neither device enumeration (EGL_EXT_platform_device) nor Mesa's surfaceless platform "
        "(EGL_MESA_platform_surfaceless): no headless display to render on");

  for (const Candidate& candidate : candidates) {
    std::string why;
    EGLContext context = try_create_context(candidate.display, why);
    if (context != EGL_NO_CONTEXT) {
      display_ = candidate.display;
      context_ = context;
      // The ones tried before it and why they failed: an operator who
      // expected the GPU learns here why it is not used.
      source_ = candidate.source + (failures.empty() ? "" : "; passed over:" + failures);
      return;
    }
    failures += "\n  " + candidate.source + ": " + why;
  }
  throw std::runtime_error("could not create a headless OpenGL 4.5 core context:" + failures);
}

EglContext::~EglContext() {
  eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  eglDestroyContext(display_, context_);
  eglTerminate(display_);
}

}  // namespace umbra::gl
