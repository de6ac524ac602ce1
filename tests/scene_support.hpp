// What the pure tests of scenes and lights share (no GL): a built-in scene
// as a typed request, and vectors compared component by component.
#pragma once

#include <gtest/gtest.h>

#include <glm/vec3.hpp>

#include "core/request.hpp"
#include "core/scene.hpp"

namespace umbra::test {

/// A built-in scene as its own defaults show it: its objects, camera and
/// light position; every other field at the typed request's default.
inline RenderRequest builtin_request(const char* name) {
  RenderRequest r;
  const BuiltinScene* s = find_builtin_scene(name);
  r.scene.name = s->name;
  r.scene.objects = s->objects;
  r.camera.position = s->camera_position;
  r.camera.target = s->camera_target;
  r.light.position = s->light_position;
  return r;
}

inline void expect_near(const glm::dvec3& got, const glm::dvec3& want, double tolerance = 1e-12) {
  EXPECT_NEAR(got.x, want.x, tolerance);
  EXPECT_NEAR(got.y, want.y, tolerance);
  EXPECT_NEAR(got.z, want.z, tolerance);
}

}  // namespace umbra::test
