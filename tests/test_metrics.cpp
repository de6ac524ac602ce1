// The Prometheus page: counters, histograms and gauges in the text
// exposition format. promtool checks a real server's page in
// tests/test_server_process.cpp.
#include <gtest/gtest.h>

#include <string>

#include "metrics.hpp"

namespace umbra {
namespace {

bool has_line(const std::string& page, const std::string& line) {
  return page.find("\n" + line + "\n") != std::string::npos || page.rfind(line + "\n", 0) == 0;
}

TEST(Metrics, CountsRequestsByRouteAndStatusAndFramesByOutputAndStatus) {
  Metrics m;
  m.request_answered("/api/render", 200, 0.030);
  m.request_answered("/api/render", 200, 0.040);
  m.request_answered("/api/render", 400, 0.0002);
  m.request_answered("static", 200, 0.001);
  FrameTimings t;
  t.shadow_ms = 4.0;
  t.main_ms = 20.0;
  t.readback_ms = 1.0;
  m.frame_answered("color", 200, &t, 3.0, 0.5);
  m.frame_answered("color", 200, &t, 3.0, 0.5);
  m.frame_answered("invalid", 400, nullptr, 0.0, 0.0);
  const std::string page = m.exposition({});
  EXPECT_TRUE(has_line(page, R"(umbra_http_requests_total{route="/api/render",status="200"} 2)")) << page;
  EXPECT_TRUE(has_line(page, R"(umbra_http_requests_total{route="/api/render",status="400"} 1)")) << page;
  EXPECT_TRUE(has_line(page, R"(umbra_http_requests_total{route="static",status="200"} 1)")) << page;
  EXPECT_TRUE(has_line(page, R"(umbra_frames_total{output="color",status="200"} 2)")) << page;
  EXPECT_TRUE(has_line(page, R"(umbra_frames_total{output="invalid",status="400"} 1)")) << page;
  // Only frames that rendered have stages; no ray cast ran, so no raycast.
  EXPECT_TRUE(has_line(page, R"(umbra_render_stage_seconds_count{stage="main"} 2)")) << page;
  EXPECT_TRUE(has_line(page, R"(umbra_render_stage_seconds_sum{stage="main"} 0.04)")) << page;
  EXPECT_EQ(page.find("stage=\"raycast\""), std::string::npos);
  t.ray_cast_ms = 700.0;
  m.frame_answered("exact", 200, &t, 2.0, 0.0);
  EXPECT_TRUE(has_line(m.exposition({}), R"(umbra_render_stage_seconds_count{stage="raycast"} 1)"));
}

TEST(Metrics, HistogramBucketsAreCumulativeAndEndInInf) {
  LatencyHistogram h;
  for (double s : {0.0005, 0.001, 0.003, 0.2, 50.0}) h.observe(s);
  std::string out;
  h.write(out, "x", "route=\"r\"");
  // le is inclusive: 0.001 falls in the 0.001 bucket.
  EXPECT_TRUE(has_line(out, R"(x_bucket{route="r",le="0.001"} 2)")) << out;
  EXPECT_TRUE(has_line(out, R"(x_bucket{route="r",le="0.005"} 3)")) << out;
  EXPECT_TRUE(has_line(out, R"(x_bucket{route="r",le="0.25"} 4)")) << out;
  EXPECT_TRUE(has_line(out, R"(x_bucket{route="r",le="30"} 4)")) << out;
  EXPECT_TRUE(has_line(out, R"(x_bucket{route="r",le="+Inf"} 5)")) << out;
  EXPECT_TRUE(has_line(out, R"(x_count{route="r"} 5)")) << out;
  // The sum of doubles: 50.2045 to within rounding.
  const std::size_t at = out.find("x_sum{route=\"r\"} ");
  ASSERT_NE(at, std::string::npos) << out;
  EXPECT_NEAR(std::stod(out.substr(at + 16)), 50.2045, 1e-9) << out;
}

TEST(Metrics, GaugesAndLabelValuesAreWrittenAsTheFormatAsks) {
  MetricsGauges g;
  g.gl_renderer = "llvmpipe \"LLVM\" \\ 15\nx";
  g.queue_capacity = 16;
  g.models = 2;
  const std::string page = Metrics().exposition(g);
  EXPECT_NE(page.find(R"(gl_renderer="llvmpipe \"LLVM\" \\ 15\nx")"), std::string::npos) << page;
  EXPECT_TRUE(has_line(page, "umbra_queue_capacity 16")) << page;
  EXPECT_TRUE(has_line(page, "umbra_models 2")) << page;
  EXPECT_TRUE(has_line(page, "# TYPE umbra_frames_total counter")) << page;
  EXPECT_TRUE(has_line(page, "# TYPE umbra_http_request_duration_seconds histogram")) << page;
}

}  // namespace
}  // namespace umbra
