#include "scene_files.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "request_parser.hpp"

namespace umbra {

std::vector<std::string> scene_file_names(const std::string& directory) {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(directory))
    if (entry.is_regular_file() && entry.path().extension() == ".json") names.push_back(entry.path().stem().string());
  std::sort(names.begin(), names.end());
  return names;
}

RenderRequest load_scene_request(const std::string& directory, const std::string& name,
                                 const nlohmann::json& overrides) {
  const std::string path = directory + "/" + name + ".json";
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot be read");
  std::stringstream text;
  text << in.rdbuf();
  nlohmann::json body = nlohmann::json::parse(text.str(), nullptr, false);
  if (body.is_discarded()) throw std::runtime_error(path + ": not valid JSON");
  body.merge_patch(overrides);
  ParsedRequest parsed = parse_render_request(body.dump());
  if (!parsed.ok()) throw std::runtime_error(path + ": " + parsed.error.field + ": " + parsed.error.message);
  return *parsed.request;
}

}  // namespace umbra
