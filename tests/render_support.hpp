// What the GL tests share: one render service for the whole test binary
// (one GL thread and context, however many files use it), and requests
// parsed from API bodies as a client would send them.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "render_service.hpp"
#include "request_parser.hpp"

namespace umbra {

inline RenderService& service() {
  static std::unique_ptr<RenderService> instance = std::make_unique<RenderService>();
  return *instance;
}

/// The body parsed as the server would (mesh objects resolved by
/// `find_model`); a test fails if it is not valid.
inline RenderRequest request(const std::string& body, const ModelLookup& find_model = {}) {
  ParsedRequest p = parse_render_request(body, Route::Render, find_model);
  EXPECT_TRUE(p.ok()) << p.error.field << ": " << p.error.message;
  return *p.request;
}

}  // namespace umbra
