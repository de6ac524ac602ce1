// The hard-case scenes in bench/scenes/: API request bodies that the
// benchmark and the tests load and then vary (size, shadow settings, output).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "request.hpp"

namespace umbra {

/// Names (file stems) of every *.json in `directory`, sorted.
std::vector<std::string> scene_file_names(const std::string& directory);

/// The body in `directory/name.json` with `overrides` merged over it
/// (RFC 7386 merge patch: objects merge key by key, other values replace),
/// parsed as an API request. Throws std::runtime_error naming the file and
/// the field if the file is unreadable or the merged body is not valid.
RenderRequest load_scene_request(const std::string& directory, const std::string& name,
                                 const nlohmann::json& overrides);

}  // namespace umbra
