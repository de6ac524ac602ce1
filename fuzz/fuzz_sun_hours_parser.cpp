// libFuzzer target: any bytes as a POST /api/sun-hours body. The parser
// must answer every input with a request or an error naming what is wrong,
// never crash, hang or hit undefined behaviour (ASan + UBSan), and what it
// accepts must be bounded as docs/api.md says: the service sizes its
// memory and work from these numbers before anything runs.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "sun_hours_parser.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const umbra::ParsedSunHours parsed =
      umbra::parse_sun_hours_request(std::string_view(reinterpret_cast<const char*>(data), size));
  if (!parsed.ok()) {
    if (parsed.error.message.empty()) std::abort();  // every error says what is wrong
    return 0;
  }
  const umbra::SunHoursRequest& q = *parsed.request;
  using Limits = umbra::SunHoursLimits;
  const std::optional<std::size_t> samples = umbra::sample_count(q.period);
  if (!samples || *samples != parsed.samples || *samples == 0 || *samples > Limits::kMaxSamples) std::abort();
  if (!(q.period.end_unix_s > q.period.start_unix_s)) std::abort();
  if (!(q.period.step_minutes >= Limits::kMinStepMinutes && q.period.step_minutes <= Limits::kMaxStepMinutes)) std::abort();
  if (q.grid.points() > Limits::kMaxPoints) std::abort();
  if (parsed.grid_given && (q.grid.columns < 1 || q.grid.rows < 1 || !(q.grid.spacing > 0.0))) std::abort();
  if (!(std::abs(q.site.latitude_deg) <= 90.0 && std::abs(q.site.longitude_deg) <= 180.0)) std::abort();
  if (q.require_hours && !(*q.require_hours >= 0.0)) std::abort();
  if (q.view.width < 16 || q.view.width > 4096 || q.view.height < 16 || q.view.height > 4096) std::abort();
  return 0;
}
