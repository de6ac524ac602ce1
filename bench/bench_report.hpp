// Helpers that umbra-bench's modes share for measuring and writing reports:
// one copy, so the accuracy grid and the speed comparison describe the
// machine, round numbers and write files the same way.
#pragma once

#include "machine.hpp"

#include <string>
#include <vector>

#include "core/render_result.hpp"
#include "core/request.hpp"

namespace umbra {

class RenderService;

namespace bench {

/// The middle value (mean of the two middle ones for an even count); 0 if empty.
double median(std::vector<double> values);

/// "CPU model, N hardware threads; GL: <GL_RENDERER of the service's context>".
std::string machine_description(const RenderService& service);


/// One double through a printf pattern, e.g. format("%.2f", 1.234) == "1.23".
std::string format(const char* pattern, double value);

/// A share in [0, 1] as a percentage with three decimals.
std::string percent(double share);

/// Writes `text` to `path` (binary, replacing it); throws std::runtime_error if it cannot.
void write_file(const std::string& path, const std::string& text);

/// Renders `request` with a shadow pass. Umbra keeps its shadow map while
/// the light, scene and views still serve the frame; a benchmark moves the
/// light between frames, but orbiting does not move a light straight above
/// its target. Then one untimed frame with the other cull mode makes the map
/// stale, the frame is rendered again, and `remeasured` counts it.
RenderResult frame_with_shadow_pass(RenderService& service, const RenderRequest& request, int& remeasured);

/// "512,1024" -> {512, 1024}.
std::vector<int> parse_int_list(const std::string& text);

}  // namespace bench
}  // namespace umbra
