// Scenes and meshes: bounds, winding, built-ins.
#include <gtest/gtest.h>

#include <stdexcept>

#include <glm/geometric.hpp>

#include "core/mesh_instance.hpp"
#include "model_support.hpp"
#include "core/scene.hpp"

namespace umbra {
namespace {

// The triangles of scene object `object`.
const ObjectRange& range_of(const Mesh& mesh, std::size_t object) {
  for (const ObjectRange& r : mesh.object_ranges)
    if (r.object == object) return r;
  throw std::out_of_range("no range for that object");
}

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
  // The floor's own range, its height, and where the cube lies against it.
  ASSERT_EQ(mesh.planes.size(), 1u);
  EXPECT_EQ(range_of(mesh, mesh.planes[0].object).first_index, 36u);
  EXPECT_EQ(range_of(mesh, mesh.planes[0].object).index_count, 6u);
  EXPECT_EQ(mesh.planes[0].height, -0.5);
  EXPECT_EQ(mesh.planes[0].lowest_other, -0.5);
  EXPECT_EQ(mesh.planes[0].highest_other, 0.5);
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

SceneObject mesh_object(std::shared_ptr<const TriangleModel> model, const std::string& id) {
  SceneObject o;
  o.type = SceneObject::Type::Mesh;
  o.model = std::move(model);
  o.model_id = id;
  return o;
}

glm::dvec3 world_position(const Mesh& mesh, std::uint32_t index) {
  const Vertex& v = mesh.vertices[mesh.indices[index]];
  return glm::dvec3(v.position[0], v.position[1], v.position[2]) + mesh.origin;
}

TEST(Scene, AMeshIsPlacedScaleThenRotateXThenYThenZThenTranslate) {
  SceneObject o = mesh_object(test::box_model({0.5f, 0.5f, 0.5f}), "box");
  o.center = {10, 20, 30};
  o.mesh_scale = {2, 4, 6};
  o.rotation_deg = {90, 90, 0};
  // The model's +Y (scaled to 4) turns to +Z under X's 90 degrees, then to
  // +X under Y's: a point (0, 0.5, 0) lands at (2, 0, 0) + position.
  const glm::dmat4 m = mesh_transform(o);
  const glm::dvec3 p(m * glm::dvec4(0, 0.5, 0, 1));
  EXPECT_NEAR(p.x, 12, 1e-12);
  EXPECT_NEAR(p.y, 20, 1e-12);
  EXPECT_NEAR(p.z, 30, 1e-12);
  // Its bounds: the transformed corners, x half 2 (from y), y half 3 (from
  // z), z half 1 (from x).
  const Aabb b = object_bounds(o);
  EXPECT_NEAR(b.min.x, 8, 1e-12);
  EXPECT_NEAR(b.max.y, 23, 1e-12);
  EXPECT_NEAR(b.max.z, 31, 1e-12);
}

TEST(Scene, ATurnedMeshsSurfaceBoundsAreThoseOfItsPositionsNotOfItsTurnedBox) {
  // An octahedron with corners on the axes at distance 1: turned 45 degrees
  // about Z, its box's corners reach sqrt(2) along x and y; its positions
  // reach only cos(45) = 0.707 along both.
  auto model = std::make_shared<TriangleModel>();
  ModelPart part;
  part.positions = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  part.normals = part.positions;
  part.indices = {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5};
  model->parts.push_back(part);
  finish_model(*model);
  SceneObject o = mesh_object(model, "octahedron");
  o.center = {5, 6, 7};
  o.rotation_deg = {0, 0, 45};
  const Aabb surface = mesh_surface_bounds(o);
  EXPECT_NEAR(surface.min.x, 5 - std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(surface.max.x, 5 + std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(surface.min.y, 6 - std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(surface.max.y, 6 + std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(surface.min.z, 6, 1e-12);
  EXPECT_NEAR(surface.max.z, 8, 1e-12);
  const Aabb box = mesh_bounds(o);
  EXPECT_NEAR(box.max.y, 6 + std::sqrt(2.0), 1e-12);
}

TEST(Scene, TheTorusKnotsFloorCastsNothingUnderALightAbove) {
  // The knot's turned box reaches below the floor, which made the floor a
  // caster drawn into every layer of the map for nothing (most of that
  // scene's shadow pass); its surface stays above the floor.
  Scene scene;
  scene.objects = find_builtin_scene("torus-knot")->objects;
  const Mesh mesh = tessellate(scene);
  ASSERT_EQ(mesh.planes.size(), 1u);
  ASSERT_LT(object_bounds(scene.objects[1]).min.y, mesh.planes[0].height);
  EXPECT_GT(mesh.planes[0].lowest_other, mesh.planes[0].height);
}

TEST(Scene, ClosedMeshesJoinTheCulledSectionAndOpenOnesThePlanes) {
  Scene scene;
  SceneObject closed = mesh_object(test::box_model({0.5f, 0.5f, 0.5f}), "closed");
  SceneObject open = mesh_object(test::box_model({0.5f, 0.5f, 0.5f}, false), "open");
  ASSERT_TRUE(closed.model->closed);
  ASSERT_FALSE(open.model->closed);
  open.center = {3, 0, 0};
  scene.objects = {open, closed};
  const Mesh mesh = tessellate(scene);
  EXPECT_EQ(mesh.closed_index_count, 36u);
  EXPECT_EQ(mesh.open_index_count, 30u);
  for (std::uint32_t i = 0; i < mesh.closed_index_count; ++i) EXPECT_LT(world_position(mesh, i).x, 1.0);
  for (std::uint32_t i = mesh.closed_index_count; i < mesh.indices.size(); ++i) EXPECT_GT(world_position(mesh, i).x, 2.0);
}

TEST(Scene, TheSmoothNormalSpanIsTheLongestEdgeOfAClosedTriangleWhoseNormalsDiffer) {
  Scene scene;
  SceneObject box;  // flat faces: each triangle's normals are one
  box.type = SceneObject::Type::Box;
  box.size = {3, 3, 3};
  SceneObject plane;  // open: drawn whole in the main pass, never split
  plane.type = SceneObject::Type::Plane;
  plane.size = {50, 1, 50};
  scene.objects = {box, plane};
  EXPECT_EQ(tessellate(scene).smooth_normal_span, 0.0);
  SceneObject sphere;
  sphere.type = SceneObject::Type::Sphere;
  sphere.radius = 2.0;
  sphere.center = {5, 0, 0};
  scene.objects.push_back(sphere);
  // 48 stacks by 96 slices: a triangle at the equator spans 2 sin(pi / 96)
  // along each side and the diagonal between, r * 0.0925 in all.
  EXPECT_NEAR(tessellate(scene).smooth_normal_span, 2.0 * 0.0925, 2.0 * 0.001);
}

TEST(Scene, PlanesComeLastEachWithTheRangeOfTheOtherObjectsHeights) {
  Scene scene;
  SceneObject floor, roof, box;
  floor.type = roof.type = SceneObject::Type::Plane;
  floor.size = roof.size = {4, 0, 4};
  roof.center = {0, 3, 0};
  box.center = {0, 1, 0};
  SceneObject open = mesh_object(test::box_model({0.5f, 0.5f, 0.5f}, false), "open");
  open.center = {0, 5, 0};
  scene.objects = {floor, open, roof, box};
  const Mesh mesh = tessellate(scene);
  ASSERT_EQ(mesh.planes.size(), 2u);
  // The open model first, then the floor and the roof in the scene's order.
  const ObjectRange& floor_range = range_of(mesh, mesh.planes[0].object);
  const ObjectRange& roof_range = range_of(mesh, mesh.planes[1].object);
  EXPECT_EQ(floor_range.first_index, mesh.closed_index_count + 30u);
  EXPECT_EQ(roof_range.first_index, floor_range.first_index + 6u);
  EXPECT_EQ(roof_range.first_index + 6u, mesh.closed_index_count + mesh.open_index_count);
  EXPECT_EQ(mesh.planes[0].height, 0.0);
  EXPECT_EQ(mesh.planes[0].lowest_other, 0.5);   // the box's bottom
  EXPECT_EQ(mesh.planes[0].highest_other, 5.5);  // the open model's top
  EXPECT_EQ(mesh.planes[1].height, 3.0);
  EXPECT_EQ(mesh.planes[1].lowest_other, 0.0);  // the floor
  for (std::uint32_t i = roof_range.first_index; i < roof_range.first_index + 6u; ++i)
    EXPECT_EQ(world_position(mesh, i).y, 3.0);
}

TEST(Scene, ClosedMeshesAreSeenFromOutsideUnlessTheEyeOrTheNearPlaneReachesOne) {
  Scene scene;
  SceneObject floor, box;
  floor.type = SceneObject::Type::Plane;
  floor.size = {20, 0, 20};
  box.center = {0, 1, 0};
  box.size = {2, 2, 2};
  SceneObject open = mesh_object(test::box_model({1.0f, 1.0f, 1.0f}, false), "open");
  open.center = {5, 1, 0};
  scene.objects = {floor, box, open};
  const Mesh mesh = tessellate(scene);
  Camera camera;
  camera.position = {0, 1, 6};
  EXPECT_TRUE(closed_meshes_seen_from_outside(mesh, camera, 16.0 / 9.0));
  camera.position = {0.5, 1.5, 0.5};  // inside the box
  EXPECT_FALSE(closed_meshes_seen_from_outside(mesh, camera, 16.0 / 9.0));
  // Outside by 0.108, farther than the near plane (0.1), but its corners
  // reach 0.1 x sqrt(1 + tan^2(22.5 deg) (1 + aspect^2)) = 0.116 at aspect
  // 1: the near plane may cut into the box.
  camera.position = {0, 1, 1.108};
  EXPECT_FALSE(closed_meshes_seen_from_outside(mesh, camera, 1.0));
  camera.position = {0, 1, 1.12};
  EXPECT_TRUE(closed_meshes_seen_from_outside(mesh, camera, 1.0));
  camera.position = {0, 1, 1.05};
  camera.near_plane = 0.01;
  EXPECT_TRUE(closed_meshes_seen_from_outside(mesh, camera, 1.0));
  // Inside the open model and above the floor: those are drawn two-sided
  // whatever the camera does.
  camera.position = {5, 1, 0};
  EXPECT_TRUE(closed_meshes_seen_from_outside(mesh, camera, 1.0));
  camera.position = {0, 0, 5};
  EXPECT_TRUE(closed_meshes_seen_from_outside(mesh, camera, 1.0));
}

TEST(Scene, EveryObjectsTrianglesAreOneRangeInIndexOrder) {
  Scene scene;
  SceneObject floor, box, ball;
  floor.type = SceneObject::Type::Plane;
  floor.size = {4, 0, 4};
  box.center = {0, 1, 0};
  ball.type = SceneObject::Type::Sphere;
  ball.center = {2, 1, 0};
  SceneObject open = mesh_object(test::box_model({0.5f, 0.5f, 0.5f}, false), "open");
  open.center = {-2, 1, 0};
  scene.objects = {floor, open, box, ball};
  const Mesh mesh = tessellate(scene);
  ASSERT_EQ(mesh.object_ranges.size(), 4u);
  // Closed (the box, the ball), then open (the open model, the floor).
  const std::size_t order[] = {2, 3, 1, 0};
  std::uint32_t next = 0;
  for (std::size_t k = 0; k < 4; ++k) {
    const ObjectRange& r = mesh.object_ranges[k];
    EXPECT_EQ(r.object, order[k]);
    EXPECT_EQ(r.first_index, next);
    next += r.index_count;
    // Each range holds that object's triangles: its vertices lie in its bounds.
    const Aabb& b = mesh.bounds[r.object];
    for (std::uint32_t i = r.first_index; i < r.first_index + r.index_count; ++i) {
      const glm::dvec3 p = world_position(mesh, i);
      EXPECT_TRUE(p.x >= b.min.x - 1e-5 && p.x <= b.max.x + 1e-5 && p.y >= b.min.y - 1e-5 &&
                  p.y <= b.max.y + 1e-5 && p.z >= b.min.z - 1e-5 && p.z <= b.max.z + 1e-5)
          << "object " << r.object;
    }
  }
  EXPECT_EQ(next, mesh.indices.size());
  EXPECT_EQ(mesh.object_ranges[2].first_index, mesh.closed_index_count);
  EXPECT_EQ(mesh.object_ranges[3].object, mesh.planes[0].object);
}

TEST(Scene, AMirroringOrNonUniformTransformKeepsMeshesWoundOutwardWithTrueNormals) {
  for (const glm::dvec3 scale : {glm::dvec3(1, 1, 1), glm::dvec3(3, 0.5, 1), glm::dvec3(-1, 1, 1), glm::dvec3(2, -3, -0.5)}) {
    SceneObject o = mesh_object(test::box_model({0.5f, 0.5f, 0.5f}), "box");
    o.center = {1, 2, 3};
    o.rotation_deg = {20, 30, 40};
    o.mesh_scale = scale;  // negative only here: the API takes scale > 0
    Scene scene;
    scene.objects = {o};
    const Mesh mesh = tessellate(scene);
    ASSERT_EQ(mesh.indices.size(), 36u);
    for (std::uint32_t i = 0; i < 36; i += 3) {
      const glm::dvec3 a = world_position(mesh, i), b = world_position(mesh, i + 1), c = world_position(mesh, i + 2);
      const glm::dvec3 face_normal = glm::normalize(glm::cross(b - a, c - a));
      const glm::dvec3 centroid = (a + b + c) / 3.0;
      EXPECT_GT(glm::dot(face_normal, centroid - o.center), 0.0) << "scale " << scale.x << " triangle " << i / 3;
      const Vertex& v = mesh.vertices[mesh.indices[i]];
      const glm::dvec3 n(v.normal[0], v.normal[1], v.normal[2]);
      EXPECT_NEAR(glm::length(n), 1.0, 1e-6);
      // A flat face's vertex normal is its geometric normal, however the
      // transform stretches it: what the inverse transpose gives.
      EXPECT_GT(glm::dot(n, face_normal), 1.0 - 1e-5) << "scale " << scale.x << " triangle " << i / 3;
    }
  }
}

TEST(Scene, AMeshTakesItsPartsColoursUnlessTheObjectGivesOne) {
  SceneObject o = mesh_object(test::box_model({0.5f, 0.5f, 0.5f}, true, {0.25f, 0.5f, 1.0f}), "box");
  Scene scene;
  scene.objects = {o};
  EXPECT_FLOAT_EQ(tessellate(scene).vertices[0].color[0], 0.25f);
  scene.objects[0].mesh_color_override = true;
  scene.objects[0].color = {0.75, 0.0, 0.0};
  EXPECT_FLOAT_EQ(tessellate(scene).vertices[0].color[0], 0.75f);
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
