#include "bench_report.hpp"

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "service/render_service.hpp"

namespace umbra::bench {

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n == 0 ? 0.0 : n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

std::string machine_description(const RenderService& service) {
  std::string cpu = "unknown CPU";
  std::ifstream cpuinfo("/proc/cpuinfo");
  for (std::string line; std::getline(cpuinfo, line);) {
    if (line.rfind("model name", 0) == 0) {
      cpu = line.substr(line.find(':') + 2);
      break;
    }
  }
  return cpu + ", " + std::to_string(std::thread::hardware_concurrency()) + " hardware threads; GL: " +
         service.info().gl_renderer;
}

std::string format(const char* pattern, double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, pattern, value);
  return buffer;
}

std::string percent(double share) { return format("%.3f", 100.0 * share); }

void write_file(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  out.close();
  if (!out) throw std::runtime_error("cannot write " + path);
}

RenderResult frame_with_shadow_pass(RenderService& service, const RenderRequest& request, int& remeasured) {
  RenderResult result = service.submit(request).get();
  if (!result.shadow_reused) return result;
  RenderRequest other = request;
  other.shadow.cull = request.shadow.cull == CullMode::Back ? CullMode::Front : CullMode::Back;
  service.submit(other).get();
  result = service.submit(request).get();
  if (result.shadow_reused) throw std::runtime_error("the shadow map was reused after a change of cull mode");
  ++remeasured;
  return result;
}

std::vector<int> parse_int_list(const std::string& text) {
  std::vector<int> out;
  std::stringstream in(text);
  for (std::string item; std::getline(in, item, ',');) out.push_back(std::stoi(item));
  return out;
}

}  // namespace umbra::bench
