// The GLSL files of shaders/, embedded at build time (cmake/EmbedFiles.cmake).
#pragma once

#include <string_view>
#include <vector>

namespace umbra {
/// The source of shaders/<name>, or an empty view if there is no such file.
std::string_view shader_source(std::string_view name);
const std::vector<std::string_view>& shader_source_names();
}  // namespace umbra
