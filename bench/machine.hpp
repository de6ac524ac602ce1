// What a benchmark's numbers were measured on and when, for its report.
#pragma once

#include <string>

namespace umbra {
namespace bench {

/// "AMD EPYC ..., 2 hardware threads (/proc/cpuinfo)".
std::string cpu_model_and_threads();
/// "2026-11-26 20:00 UTC".
std::string utc_now();

}  // namespace bench
}  // namespace umbra
