// Files embedded at build time (cmake/EmbedFiles.cmake): the web panel's
// (web/) and the API's OpenAPI document (docs/openapi.json).
#pragma once

#include <string_view>
#include <vector>

namespace umbra {
std::string_view web_asset(std::string_view name);
const std::vector<std::string_view>& web_asset_names();
/// "openapi.json": docs/openapi.json byte for byte (GET /api/openapi.json).
std::string_view api_document(std::string_view name);
const std::vector<std::string_view>& api_document_names();
}  // namespace umbra
