// Triangle models built in code for the tests of mesh objects, and a model
// lookup over them such as the server's ModelStore gives the parser.
#pragma once

#include <map>
#include <memory>
#include <string>

#include <glm/vec3.hpp>

#include "core/model.hpp"
#include "request_parser.hpp"

namespace umbra::test {

/// The box [-half, half] as 6 faces of 4 vertices with flat normals, wound
/// as tessellate() winds an analytic box (so the two draw alike). Without
/// its bottom face (-Y) the model is open.
inline std::shared_ptr<const TriangleModel> box_model(const glm::vec3& half, bool with_bottom = true,
                                                      const glm::vec3& color = glm::vec3(0.8f)) {
  ModelPart part;
  part.base_color = color;
  for (int k = 0; k < 3; ++k) {
    for (float sign : {1.0f, -1.0f}) {
      if (k == 1 && sign < 0.0f && !with_bottom) continue;
      glm::vec3 n(0.0f), u(0.0f), v(0.0f);
      n[k] = sign;
      const int iu = (k + 1) % 3, iv = (k + 2) % 3;
      u[iu] = half[iu];
      v[iv] = half[iv] * sign;
      const glm::vec3 center = n * half[k];
      const auto first = std::uint32_t(part.positions.size());
      for (const glm::vec3& p : {center - u - v, center + u - v, center + u + v, center - u + v}) {
        part.positions.push_back(p);
        part.normals.push_back(n);
      }
      part.indices.insert(part.indices.end(), {first, first + 1, first + 2, first, first + 2, first + 3});
    }
  }
  auto model = std::make_shared<TriangleModel>();
  model->parts.push_back(std::move(part));
  finish_model(*model);
  return model;
}

/// A block of `n` x `n` closed boxes in one model, as a city's buildings
/// come in one file: box (i, j) stands on y = 0 at x = i * pitch, z = j *
/// pitch, `width` wide and 2 + (3 i + 5 j) % 7 tall. Without floors, each
/// box lacks its ground face (as many city files write buildings).
inline std::shared_ptr<const TriangleModel> city_model(int n, float pitch, float width, bool with_floors = true) {
  ModelPart part;
  const auto one = box_model({0.5f, 0.5f, 0.5f}, with_floors);
  const ModelPart& cube = one->parts[0];
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const glm::vec3 size(width, float(2 + (3 * i + 5 * j) % 7), width);
      const glm::vec3 at(float(i) * pitch, size.y / 2, float(j) * pitch);
      std::vector<glm::vec3> positions;
      for (const glm::vec3& p : cube.positions) positions.push_back(at + p * size);
      part.append(positions, cube.normals, cube.indices);
    }
  auto model = std::make_shared<TriangleModel>();
  model->parts.push_back(std::move(part));
  finish_model(*model);
  return model;
}

/// A horizontal square of edge `size` facing +Y: two triangles, open.
inline std::shared_ptr<const TriangleModel> quad_model(float size) {
  const float h = size / 2;
  ModelPart part;
  part.positions = {{-h, 0, h}, {h, 0, h}, {h, 0, -h}, {-h, 0, -h}};
  part.normals.assign(4, glm::vec3(0, 1, 0));
  part.indices = {0, 1, 2, 0, 2, 3};
  auto model = std::make_shared<TriangleModel>();
  model->parts.push_back(std::move(part));
  finish_model(*model);
  return model;
}

/// A lookup holding `models` by id; `names` maps a name to one of the ids.
inline ModelLookup lookup_of(std::map<std::string, std::shared_ptr<const TriangleModel>> models,
                             std::map<std::string, std::string> names = {}) {
  return [models = std::move(models), names = std::move(names)](const std::string& key) -> std::optional<FoundModel> {
    const auto named = names.find(key);
    const std::string id = named == names.end() ? key : named->second;
    const auto it = models.find(id);
    if (it == models.end()) return std::nullopt;
    return FoundModel{id, it->second};
  };
}

}  // namespace umbra::test
