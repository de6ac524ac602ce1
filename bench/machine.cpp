#include "machine.hpp"

#include <ctime>
#include <fstream>

namespace umbra {
namespace bench {

std::string cpu_model_and_threads() {
  std::ifstream in("/proc/cpuinfo");
  std::string line, model = "unknown CPU";
  int threads = 0;
  bool found = false;
  while (std::getline(in, line)) {
    if (!found && line.rfind("model name", 0) == 0) model = line.substr(line.find(':') + 2), found = true;
    if (line.rfind("processor", 0) == 0) ++threads;
  }
  return model + ", " + std::to_string(threads) + " hardware threads (/proc/cpuinfo)";
}

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  char buffer[32];
  std::strftime(buffer, sizeof buffer, "%Y-%m-%d %H:%M UTC", std::gmtime(&t));
  return buffer;
}

}  // namespace bench
}  // namespace umbra
