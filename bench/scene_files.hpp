// The hard-case scenes in bench/scenes/: API request bodies that the
// benchmark and the tests load and then vary (size, shadow settings, output).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/request.hpp"

namespace umbra {

/// The orbit sweep (umbra-bench --speed and the OrbitSweep test): a scene
/// at `count` light angles spread evenly over one turn of the default orbit
/// (20 degrees per second turns once in kOrbitTurnSeconds); angle k of count
/// is at orbit_sweep_time(k, count) seconds.
inline constexpr double kOrbitTurnSeconds = 18.0;
inline constexpr int kOrbitSweepTimes = 9;
inline double orbit_sweep_time(int k, int count) { return kOrbitTurnSeconds * k / count; }

/// Names (file stems) of every *.json in `directory`, sorted.
std::vector<std::string> scene_file_names(const std::string& directory);

/// The body in `directory/name.json` with `overrides` merged over it
/// (RFC 7386 merge patch: objects merge key by key, other values replace),
/// parsed as an API request. Throws std::runtime_error naming the file and
/// the field if the file is unreadable or the merged body is not valid.
RenderRequest load_scene_request(const std::string& directory, const std::string& name,
                                 const nlohmann::json& overrides);

}  // namespace umbra
