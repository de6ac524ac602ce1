// Scenes and meshes: bounds, winding, built-ins.
#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include "scene.hpp"

namespace umbra {
namespace {

TEST(Scene, BuiltinsExistWithTheirObjects) {
  ASSERT_NE(find_builtin_scene("cube-on-plane"), nullptr);
  ASSERT_NE(find_builtin_scene("three-cubes"), nullptr);
  EXPECT_EQ(find_builtin_scene("cube-on-plane")->objects.size(), 2u);
  EXPECT_EQ(find_builtin_scene("three-cubes")->objects.size(), 4u);
  EXPECT_EQ(find_builtin_scene("nope"), nullptr);
}

TEST(Scene, RotatedBoxBoundsGrow) {
  SceneObject box;
  box.type = SceneObject::Type::Box;
  box.size = {2, 1, 2};
  box.rotation_y_deg = 45.0;
  const Aabb b = object_bounds(box);
  EXPECT_NEAR(b.max.x, std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(b.max.y, 0.5, 1e-12);
}

// Closed meshes must wind counter-clockwise seen from outside, or face
// culling in the shadow pass would keep the wrong side.
TEST(Scene, ClosedMeshesWindOutward) {
  Scene scene;
  SceneObject box;
  box.type = SceneObject::Type::Box;
  box.center = {1, 2, 3};
  box.size = {1, 2, 3};
  box.rotation_y_deg = 30;
  SceneObject sphere;
  sphere.type = SceneObject::Type::Sphere;
  sphere.center = {-4, 1, 0};
  sphere.radius = 2;
  scene.objects = {box, sphere};
  const Mesh mesh = tessellate(scene);
  ASSERT_GT(mesh.closed_index_count, 0u);
  EXPECT_EQ(mesh.open_index_count, 0u);
  for (std::uint32_t i = 0; i < mesh.closed_index_count; i += 3) {
    const auto pos = [&](std::uint32_t k) {
      const Vertex& v = mesh.vertices[mesh.indices[k]];
      return glm::dvec3(v.position[0], v.position[1], v.position[2]) + mesh.origin;
    };
    const glm::dvec3 a = pos(i), b = pos(i + 1), c = pos(i + 2);
    const glm::dvec3 face_normal = glm::cross(b - a, c - a);
    const glm::dvec3 centroid = (a + b + c) / 3.0;
    const glm::dvec3 center = i < 36 ? box.center : sphere.center;
    EXPECT_GT(glm::dot(face_normal, centroid - center), 0.0) << "triangle " << i / 3;
  }
}

TEST(Scene, PlanesComeAfterClosedMeshesAndFaceUp) {
  Scene scene;
  scene.objects = find_builtin_scene("cube-on-plane")->objects;
  const Mesh mesh = tessellate(scene);
  EXPECT_EQ(mesh.closed_index_count, 36u);
  EXPECT_EQ(mesh.open_index_count, 6u);
  const Vertex& v = mesh.vertices[mesh.indices[mesh.closed_index_count]];
  EXPECT_FLOAT_EQ(v.normal[1], 1.0f);
}

TEST(Scene, VerticesAreStoredRelativeToTheBoundsCentre) {
  Scene scene;
  SceneObject box;
  box.center = {10000, 0, 10000};
  box.size = {1000, 1000, 1000};
  scene.objects = {box};
  const Mesh mesh = tessellate(scene);
  EXPECT_EQ(mesh.origin, box.center);
  for (const Vertex& v : mesh.vertices) EXPECT_LE(std::abs(v.position[0]), 500.0f);
}

TEST(Scene, CustomSceneDefaultViewSeesItsCentre) {
  Scene scene;
  SceneObject sphere;
  sphere.type = SceneObject::Type::Sphere;
  sphere.center = {5, 5, 5};
  sphere.radius = 1;
  scene.objects = {sphere};
  const SceneViewDefaults d = default_view_for(scene);
  EXPECT_EQ(d.camera_target, sphere.center);
  EXPECT_GT(glm::length(d.camera_position - sphere.center), 2.0);
  EXPECT_GT(glm::length(d.light_position - d.light_target), 0.0);
}

}  // namespace
}  // namespace umbra
