// What the GL tests share: one render service for the whole test binary
// (one GL thread and context, however many files use it), and requests
// parsed from API bodies as a client would send them.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <mutex>
#include <string>

#include "service/render_service.hpp"
#include "request_parser.hpp"

namespace umbra {

// The service is made on first use and destroyed when the tests end, inside
// RUN_ALL_TESTS, never by a static destructor at exit: Mesa registers its
// exit handlers after the service is made, so they would run first and free
// the shader compiler's state while the GL thread may still be at work (an
// idle release making a fresh context compiles shaders). ASan saw that as a
// use-after-free in swrast in a third of the runs of a test that ended about
// kIdleRelease after its frame.
class ServiceEnvironment : public testing::Environment {
 public:
  static RenderService& service() {
    std::lock_guard<std::mutex> lock(mutex_);
    // These tests judge what a frame shows, not how long it takes: the
    // watchdog (tested with services of their own) gets room for a
    // sanitizer build on a busy machine, where a 1M-triangle scene's ray
    // cast passed the default 8 s once.
    if (!instance_) {
      ServiceLimits limits;
      limits.max_run_time = std::chrono::milliseconds(120000);
      instance_ = std::make_unique<RenderService>(limits);
    }
    return *instance_;
  }
  void TearDown() override {
    std::lock_guard<std::mutex> lock(mutex_);
    instance_.reset();
  }

 private:
  static inline std::mutex mutex_;
  static inline std::unique_ptr<RenderService> instance_;
};
inline testing::Environment* const kServiceEnvironment = testing::AddGlobalTestEnvironment(new ServiceEnvironment);

inline RenderService& service() { return ServiceEnvironment::service(); }

/// The body parsed as the server would (mesh objects resolved by
/// `find_model`); a test fails if it is not valid.
inline RenderRequest request(const std::string& body, const ModelLookup& find_model = {}) {
  ParsedRequest p = parse_render_request(body, Route::Render, find_model);
  EXPECT_TRUE(p.ok()) << p.error.field << ": " << p.error.message;
  return *p.request;
}

}  // namespace umbra
