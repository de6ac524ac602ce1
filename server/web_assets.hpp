// The files of web/, embedded at build time (cmake/EmbedFiles.cmake).
#pragma once

#include <string_view>
#include <vector>

namespace umbra {
std::string_view web_asset(std::string_view name);
const std::vector<std::string_view>& web_asset_names();
}  // namespace umbra
