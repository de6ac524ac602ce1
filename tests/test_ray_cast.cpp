// The exact reference against cases solved by hand.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <memory>
#include <random>
#include <string>

#include <glm/geometric.hpp>

#include "reference/mesh_ray_cast.hpp"
#include "core/model.hpp"
#include "model_support.hpp"
#include "reference/ray_cast.hpp"
#include "core/scene.hpp"
#include "reference/shadow_error.hpp"

namespace umbra {
namespace {

std::shared_ptr<const TriangleModel> unit_box_mesh() {
  static const auto model = test::box_model({0.5f, 0.5f, 0.5f});
  return model;
}

SceneObject mesh_object(std::shared_ptr<const TriangleModel> model, const glm::dvec3& position,
                        const glm::dvec3& rotation_deg = glm::dvec3(0.0), const glm::dvec3& scale = glm::dvec3(1.0)) {
  SceneObject o;
  o.type = SceneObject::Type::Mesh;
  o.model = std::move(model);
  o.model_id = "test";
  o.center = position;
  o.rotation_deg = rotation_deg;
  o.mesh_scale = scale;
  return o;
}

SceneObject box_object(const glm::dvec3& center, const glm::dvec3& size, double rotation_y_deg = 0.0) {
  SceneObject o;
  o.type = SceneObject::Type::Box;
  o.center = center;
  o.size = size;
  o.rotation_y_deg = rotation_y_deg;
  return o;
}

SceneObject plane_object(const glm::dvec3& center, double size) {
  SceneObject o;
  o.type = SceneObject::Type::Plane;
  o.center = center;
  o.size = {size, 0.0, size};
  return o;
}

// A closed UV sphere of radius 1 with smooth (unit position) normals.
std::shared_ptr<const TriangleModel> sphere_mesh(int stacks, int slices) {
  ModelPart part;
  constexpr double kPi = 3.14159265358979323846;
  for (int i = 0; i <= stacks; ++i) {
    for (int j = 0; j <= slices; ++j) {
      const double theta = kPi * i / stacks, phi = 2.0 * kPi * (j % slices) / slices;
      // Exact poles, so that their vertices weld (is_closed).
      const double ring = i == stacks ? 0.0 : std::sin(theta), y = i == stacks ? -1.0 : std::cos(theta);
      const glm::vec3 p(ring * std::cos(phi), y, ring * std::sin(phi));
      part.positions.push_back(p);
      part.normals.push_back(p);
    }
  }
  for (int i = 0; i < stacks; ++i) {
    for (int j = 0; j < slices; ++j) {
      const auto a = std::uint32_t(i * (slices + 1) + j), b = a + std::uint32_t(slices + 1);
      // Counter-clockwise seen from outside.
      if (i > 0) part.indices.insert(part.indices.end(), {a, a + 1, b});
      if (i < stacks - 1) part.indices.insert(part.indices.end(), {a + 1, b + 1, b});
    }
  }
  auto model = std::make_shared<TriangleModel>();
  model->parts.push_back(std::move(part));
  finish_model(*model);
  return model;
}

RenderRequest cube_on_plane() {
  RenderRequest r;
  r.scene.objects = find_builtin_scene("cube-on-plane")->objects;
  r.light.position = {0, 10, 0};  // straight overhead
  return r;
}

TEST(RayCast, HitsTheNearestSurfaceWithANormalFacingTheRay) {
  const RenderRequest r = cube_on_plane();
  const auto hit = cast_ray(r.scene, {0, 5, 0}, {0, -1, 0}, 0.0, 1e9);
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->object, 1);  // the cube's top, not the floor
  EXPECT_NEAR(hit->point.y, 0.5, 1e-12);
  EXPECT_NEAR(hit->normal.y, 1.0, 1e-12);
  const auto below = cast_ray(r.scene, {3, -5, 0}, {0, 1, 0}, 0.0, 1e9);
  ASSERT_TRUE(below);
  EXPECT_NEAR(below->normal.y, -1.0, 1e-12);  // the floor seen from below
}

TEST(RayCast, RotatedBoxIsHitWhereItReallyIs) {
  Scene scene;
  SceneObject box;
  box.size = {2, 1, 0.2};
  box.rotation_y_deg = 90;  // now long along z
  scene.objects = {box};
  EXPECT_TRUE(cast_ray(scene, {0, 5, 0.9}, {0, -1, 0}, 0, 1e9));
  EXPECT_FALSE(cast_ray(scene, {0.9, 5, 0}, {0, -1, 0}, 0, 1e9));
}

TEST(RayCast, SphereHitFromOutsideAndInside) {
  Scene scene;
  SceneObject s;
  s.type = SceneObject::Type::Sphere;
  s.center = {0, 0, 0};
  s.radius = 2;
  scene.objects = {s};
  const auto outside = cast_ray(scene, {0, 0, 10}, {0, 0, -1}, 0, 1e9);
  ASSERT_TRUE(outside);
  EXPECT_NEAR(outside->t, 8.0, 1e-12);
  const auto inside = cast_ray(scene, {0, 0, 0}, {0, 0, -1}, 0, 1e9);
  ASSERT_TRUE(inside);
  EXPECT_NEAR(inside->t, 2.0, 1e-12);
}

TEST(ExactVisibility, UnderTheCubeIsDarkAndFarAwayIsLit) {
  const RenderRequest r = cube_on_plane();
  const glm::dvec3 up{0, 1, 0};
  // Directional light straight down: the floor right next to the cube is lit.
  EXPECT_EQ(exact_visibility(r, r.light.position, {0.4, -0.5, 0.4}, up), 0.0);
  EXPECT_EQ(exact_visibility(r, r.light.position, {0.6, -0.5, 0.0}, up), 1.0);
  // Facing away from the light: 0.
  EXPECT_EQ(exact_visibility(r, r.light.position, {0.6, -0.5, 0.0}, -up), 0.0);
}

TEST(ExactVisibility, PointLightShadowSpreads) {
  RenderRequest r = cube_on_plane();
  r.light.projection = LightProjection::Perspective;
  r.light.position = {0, 1.5, 0};  // 1 above the cube's top
  // The cube's top edge at x = 0.5 projects from y=1.5 down to y=-0.5 at x = 1.0.
  EXPECT_EQ(exact_visibility(r, r.light.position, {0.9, -0.5, 0.0}, {0, 1, 0}), 0.0);
  EXPECT_EQ(exact_visibility(r, r.light.position, {1.1, -0.5, 0.0}, {0, 1, 0}), 1.0);
}

TEST(ExactVisibility, AreaLightGivesAPenumbra) {
  RenderRequest r = cube_on_plane();
  r.light.size = 20.0;  // degrees: a wide sun
  // Right at the edge of the hard shadow, part of the disc is hidden.
  const double v = exact_visibility(r, r.light.position, {0.52, -0.5, 0.0}, {0, 1, 0});
  EXPECT_GT(v, 0.0);
  EXPECT_LT(v, 1.0);
}

// The default camera looks down at the cube from (0, 3, 6): it sees the floor
// from above and the cube's top and front. A visible face of a convex box lies
// between its centre and the camera, so its normal points from the centre
// towards the camera by more than the half size.
TEST(ExactPixels, NormalsAreUnitAndFaceTheCamera) {
  RenderRequest r = cube_on_plane();
  r.width = 64;
  r.height = 36;
  int floor_pixels = 0, cube_pixels = 0;
  for (const ExactPixel& p : cast_exact_pixels(r)) {
    if (!p.geometry) continue;
    EXPECT_NEAR(glm::length(p.normal), 1.0f, 1e-6f);
    if (p.object == 0) {
      ++floor_pixels;
      EXPECT_TRUE(p.normal == glm::vec3(0.0f, 1.0f, 0.0f));
    } else {
      ++cube_pixels;
      EXPECT_GT(glm::dot(glm::dvec3(p.normal), r.camera.position - glm::dvec3(0.0)), 0.5);
    }
  }
  EXPECT_GT(floor_pixels, 0);
  EXPECT_GT(cube_pixels, 0);
}

TEST(ExactImages, ErrorIsRedForFalseShadowAndBlueForFalseLight) {
  Image rendered{2, 1, 1, {0, 255}};
  Image exact{2, 1, 1, {255, 0}};
  const Image e = error_image(rendered, exact);
  EXPECT_EQ(e.pixels[0], 255);  // pixel 0 red
  EXPECT_EQ(e.pixels[2], 0);
  EXPECT_EQ(e.pixels[3], 0);
  EXPECT_EQ(e.pixels[5], 255);  // pixel 1 blue
}

// A bar's thin shadow line that runs exactly between two rows of pixel
// centres: the centres all see the floor lit, so the exact image shows no
// edge there, but the line covers a sixth of each of those pixels. The
// finer coverage sees it (shadow_error.hpp: such a line is no artifact).
RenderRequest shadow_line_between_pixel_centres() {
  RenderRequest r;
  r.width = 64;
  r.height = 36;
  r.scene.objects = {plane_object(glm::dvec3(0.0), 20.0),
                     // Its shadow: z in [-2.02 + 2 * 0.99, -1.98 + 2 * 1.01] = [-0.04, 0.04].
                     box_object({0.0, 1.0, -2.0}, {8.0, 0.02, 0.04})};
  r.light.position = {0.0, 10.0, -20.0};  // orthographic: z moves 2 per unit of height
  r.light.target = glm::dvec3(0.0);
  // Straight down, image up = -z: z = 0 is the line between rows 17 and 18,
  // whose centres lie half a pixel (8.28 / 36 / 2 = 0.115 units) off it,
  // and the samples nearest it 0.029; the bar itself is seen 2.2 units up,
  // 9.7 pixels off.
  r.camera.position = {0.0, 10.0, 0.0};
  r.camera.target = glm::dvec3(0.0);
  r.camera.up = {0.0, 0.0, -1.0};
  return r;
}

TEST(ExactPixelCoverage, SeesAShadowLineThatMissesEveryPixelCentre) {
  const RenderRequest r = shadow_line_between_pixel_centres();
  const std::vector<ExactPixel> centres = cast_exact_pixels(r);
  std::vector<std::uint8_t> which(centres.size(), 0);
  const auto at = [&r](int x, int y) { return std::size_t(y) * r.width + x; };
  for (int x = 20; x < 44; ++x)
    for (const int y : {10, 17, 18, 26}) which[at(x, y)] = 1;
  const std::vector<PixelCoverage> coverage = ExactView(r).coverage(which);
  ASSERT_EQ(coverage.size(), centres.size());
  for (int x = 20; x < 44; ++x) {
    for (const int y : {17, 18}) {
      ASSERT_TRUE(centres[at(x, y)].geometry);
      EXPECT_EQ(centres[at(x, y)].object, 0) << x << "," << y;
      EXPECT_EQ(centres[at(x, y)].visibility, 1.0) << x << "," << y;
      EXPECT_EQ(coverage[at(x, y)], PixelCoverage::mixed) << x << "," << y;
    }
    // Away from the line and the bar: the floor, lit all over.
    for (const int y : {10, 26}) EXPECT_EQ(coverage[at(x, y)], PixelCoverage::lit) << x << "," << y;
  }
  // Pixels not asked for are not sampled.
  EXPECT_EQ(coverage[at(0, 0)], PixelCoverage::unknown);
  EXPECT_EQ(coverage[at(30, 17 - 3)], PixelCoverage::unknown);
}

// A render that shows the line (PCF over a fine map gives the covered fifth
// as 0.7 at the centres either side) has no artifact there: with the finer
// coverage those pixels are near an edge, as the image shows; the centres
// alone called 2 x 24 of them artifacts.
TEST(ExactPixelCoverage, ALineBetweenPixelCentresIsNoArtifact) {
  const RenderRequest r = shadow_line_between_pixel_centres();
  const std::vector<ExactPixel> exact = cast_exact_pixels(r);
  Image rendered = exact_image(exact, r.width, r.height);
  for (int x = 20; x < 44; ++x)
    for (const int y : {17, 18}) rendered.pixels[std::size_t(y) * r.width + x] = 178;
  const ShadowError by_centres = measure_shadow_error(rendered, exact);
  EXPECT_GE(by_centres.artifacts * by_centres.interior_pixels, 48.0 - 0.5);
  const ExactView view(r);
  const ShadowError finer = measure_shadow_error(rendered, exact, view.coverage_of());
  EXPECT_EQ(finer.artifacts, 0.0);
  EXPECT_LE(finer.interior_pixels, by_centres.interior_pixels - 48);
  EXPECT_GT(finer.interior_pixels, 0u);
  // A real artifact beside it, in the floor's lit interior (the bar is
  // seen around row 8), is still one.
  rendered.pixels[std::size_t(28) * r.width + 32] = 100;
  const ShadowError with_speck = measure_shadow_error(rendered, exact, view.coverage_of());
  EXPECT_DOUBLE_EQ(with_speck.artifacts * with_speck.interior_pixels, 1.0);
}

// The hierarchy must answer exactly as testing every object in order:
// random scenes of boxes, spheres, planes and box meshes (touching and
// overlapping ones included), random rays, compared with a brute-force cast;
// and occluded() must agree with cast().
TEST(RayScene, AnswersExactlyAsTestingEveryObject) {
  std::mt19937 random(12345);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    Scene scene;
    const int n = 1 + trial * 25;
    for (int i = 0; i < n; ++i) {
      SceneObject o;
      o.type = SceneObject::Type(i % 3);
      // On a coarse grid, so that objects touch and share faces often.
      o.center = glm::dvec3(std::round(5 * u(random)), std::round(2 * u(random)), std::round(5 * u(random)));
      o.size = glm::dvec3(1.0 + std::round(u(random)), 1.0, 1.0 + std::round(u(random)));
      o.radius = 0.5 + 0.25 * std::round(u(random));
      o.rotation_y_deg = i % 4 == 0 ? 30.0 * std::round(3 * u(random)) : 0.0;
      if (i % 5 == 4) {
        // A box as a mesh (Embree), placed as an analytic box would be: it
        // ties with analytic faces on the grid, and mirrored ones too.
        o.type = SceneObject::Type::Mesh;
        o.model = unit_box_mesh();
        o.model_id = "box";
        o.rotation_deg = {0.0, o.rotation_y_deg, 0.0};
        o.mesh_scale = glm::max(o.size, 0.5) * glm::dvec3(i % 2 ? -1.0 : 1.0, 1.0, 1.0);  // sizes may be 0
      }
      scene.objects.push_back(o);
    }
    const RayScene rays(scene);
    // Brute force: each object on its own, asked in index order (built once
    // a trial: RayScene keeps a reference to its scene).
    std::vector<Scene> singles(scene.objects.size());
    for (std::size_t i = 0; i < scene.objects.size(); ++i) singles[i].objects.push_back(scene.objects[i]);
    std::vector<std::unique_ptr<RayScene>> single_rays;
    for (const Scene& one : singles) single_rays.push_back(std::make_unique<RayScene>(one));
    for (int k = 0; k < 2000; ++k) {
      const glm::dvec3 origin(8 * u(random), 4 * u(random), 8 * u(random));
      glm::dvec3 dir(u(random), u(random), u(random));
      if (k % 5 == 0) dir[k % 3] = 0.0;  // axis-parallel rays too
      if (glm::length(dir) < 1e-3) continue;
      dir = glm::normalize(dir);
      RayHit best;
      best.t = 1e9;
      for (std::size_t i = 0; i < single_rays.size(); ++i) {
        const auto hit = single_rays[i]->cast(origin, dir, 0.0, best.t);
        if (hit && hit->t < best.t) best = *hit, best.object = int(i);
      }
      const auto hit = rays.cast(origin, dir, 0.0, 1e9);
      ASSERT_EQ(hit.has_value(), best.object >= 0) << "trial " << trial << " ray " << k;
      if (hit) {
        EXPECT_EQ(hit->object, best.object) << "trial " << trial << " ray " << k << " t " << hit->t;
        EXPECT_EQ(hit->t, best.t);
        EXPECT_EQ(hit->normal, best.normal);
      }
      const double reach = 3.0 * (1.0 + u(random));
      EXPECT_EQ(rays.occluded(origin, dir, reach), best.object >= 0 && best.t < reach) << "trial " << trial;
    }
  }
}


// A box posted as 12 triangles and the analytic box it copies, placed alike
// (the mesh's X rotation is 0, so rotation_deg.y is the box's
// rotation_y_deg; a negative scale mirrors it, which a box does not see).
struct Placement {
  const char* name;
  glm::dvec3 center, size;
  double rotation_y_deg;
  glm::dvec3 mirror;  // signs of the mesh's scale
};

// The same shape at every scale: the frames below are one picture scaled.
const Placement kPlacements[] = {
    {"unit", {0, 0, 0}, {1, 1, 1}, 0, {1, 1, 1}},
    {"turned-scaled-moved", {0.3, 0.25, -0.2}, {1, 0.5, 2}, 30, {1, 1, 1}},
    {"mirrored", {0.3, 0.25, -0.2}, {1, 0.5, 2}, 30, {-1, 1, 1}},
    {"tiny", {0.002, -0.001, 0.003}, {0.001, 0.0005, 0.002}, 30, {1, 1, 1}},
    {"huge-far", {1.0e4, 0.0, -3.0e3}, {1000, 500, 2000}, 30, {1, 1, -1}},
};

TEST(MeshRayCast, ABoxMeshIsHitWhereTheAnalyticBoxIs) {
  std::mt19937 random(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const Placement& p : kPlacements) {
    Scene analytic, mesh;
    analytic.objects = {box_object(p.center, p.size, p.rotation_y_deg)};
    mesh.objects = {mesh_object(unit_box_mesh(), p.center, {0, p.rotation_y_deg, 0}, p.size * p.mirror)};
    const RayScene analytic_rays(analytic), mesh_rays(mesh);
    const double scale = glm::length(p.size);
    int hits = 0;
    for (int k = 0; k < 4000; ++k) {
      // From around the box (inside it too) towards points near it.
      const glm::dvec3 origin = p.center + scale * glm::dvec3(2 * u(random), 2 * u(random), 2 * u(random));
      const glm::dvec3 toward = p.center + 0.6 * scale * glm::dvec3(u(random), u(random), u(random));
      if (glm::length(toward - origin) < 1e-3 * scale) continue;
      const glm::dvec3 dir = glm::normalize(toward - origin);
      const auto a = analytic_rays.cast(origin, dir, 0.0, 1e30);
      const auto m = mesh_rays.cast(origin, dir, 0.0, 1e30);
      ASSERT_EQ(a.has_value(), m.has_value()) << p.name << " ray " << k;
      if (!a) continue;
      ++hits;
      EXPECT_NEAR(m->t, a->t, 1e-12 * (scale + a->t)) << p.name << " ray " << k;
      EXPECT_LT(glm::length(m->point - a->point), 1e-12 * (scale + glm::length(a->point))) << p.name;
      EXPECT_LT(glm::length(m->normal - a->normal), 1e-9) << p.name << " ray " << k;
      EXPECT_LT(glm::length(m->geometric_normal - a->normal), 1e-9) << p.name << " ray " << k;
      // occluded() agrees with cast(), short of the hit and past it.
      EXPECT_FALSE(mesh_rays.occluded(origin, dir, 0.999 * m->t)) << p.name << " ray " << k;
      EXPECT_TRUE(mesh_rays.occluded(origin, dir, 1.001 * m->t)) << p.name << " ray " << k;
    }
    EXPECT_GT(hits, 1000) << p.name;
  }
}

// A frame of a box on a floor with a tall post casting a shadow across the
// box's top, everything scaled by p.size.x relative to the unit placement
// and moved to p.center, with the box analytic or a mesh.
RenderRequest box_frame(const Placement& p, bool box_as_mesh, double light_size = 0.0) {
  const double s = p.size.x;
  const glm::dvec3 c = p.center;
  RenderRequest r;
  r.width = 240;
  r.height = 135;
  r.scene.objects = {plane_object(c + s * glm::dvec3(0, -0.5 * p.size.y / s, 0), 8 * s),
                     box_object(c + s * glm::dvec3(-1.2, 0.5, 0.3), s * glm::dvec3(0.3, 2.0, 0.3), 10)};
  if (box_as_mesh)
    r.scene.objects.push_back(mesh_object(unit_box_mesh(), c, {0, p.rotation_y_deg, 0}, p.size * p.mirror));
  else
    r.scene.objects.push_back(box_object(c, p.size, p.rotation_y_deg));
  r.camera.position = c + s * glm::dvec3(1.5, 2.2, 3.0);
  r.camera.target = c + s * glm::dvec3(-0.2, -0.2, 0.0);
  r.camera.near_plane = 0.05 * s;
  r.camera.far_plane = 50 * s;
  r.light.position = c + s * glm::dvec3(-4.0, 2.5, 1.0);
  r.light.target = c;
  r.light.size = light_size;
  return r;
}

int differing_pixels(const Image& a, const Image& b, int tolerance) {
  int n = 0;
  for (std::size_t i = 0; i < a.pixels.size(); ++i) n += std::abs(int(a.pixels[i]) - int(b.pixels[i])) > tolerance;
  return n;
}

// Pixel for pixel under a hard light: the mesh's hits are the analytic
// box's to 1e-12, and its shadow rays leave from within 1e-5 of the box's.
// Under an area light, within one sample of 64 (4 grey levels) on at most
// 0.1 % of the box's pixels.
TEST(MeshRayCast, ABoxMeshGivesTheAnalyticBoxsExactImage) {
  for (const Placement& p : kPlacements) {
    for (double light_size : {0.0, 8.0}) {
      const RenderRequest analytic = box_frame(p, false, light_size), mesh = box_frame(p, true, light_size);
      const std::vector<ExactPixel> a = cast_exact_pixels(analytic), m = cast_exact_pixels(mesh);
      const Image ai = exact_image(a, analytic.width, analytic.height);
      const Image mi = exact_image(m, mesh.width, mesh.height);
      int box_pixels = 0, dark_box_pixels = 0, lit_box_pixels = 0;
      for (const ExactPixel& px : m) {
        if (px.object != 2) continue;
        ++box_pixels;
        dark_box_pixels += px.n_dot_l > 0.0 && px.visibility == 0.0;
        lit_box_pixels += px.visibility == 1.0;
      }
      EXPECT_GT(box_pixels, 2000) << p.name;
      EXPECT_GT(dark_box_pixels, 50) << p.name << ": the post should shadow the box's top";
      EXPECT_GT(lit_box_pixels, 500) << p.name;
      if (light_size == 0.0) {
        EXPECT_EQ(differing_pixels(ai, mi, 0), 0) << p.name;
      } else {
        // One of the 64 samples may go the other way where it grazes the
        // post's edge: the mesh's rays start a float offset off its faces
        // (about 1e-5 of the box), the box's 1e-9 off.
        EXPECT_EQ(differing_pixels(ai, mi, 4), 0) << p.name << " light.size " << light_size;
        EXPECT_LE(differing_pixels(ai, mi, 0), box_pixels / 1000) << p.name << " light.size " << light_size;
      }
    }
  }
}

// Rays that leave a mesh face must not find it again: a lit face of a
// mesh alone under a low light is lit at every pixel, at every scale and
// far from the origin. Without the offset (leave_front = the hit point)
// about half of the points round to below the float triangle and shadow
// themselves: this test fails then.
TEST(MeshRayCast, ALitMeshFaceHasNoSelfShadowSpeckle) {
  for (const Placement& p : kPlacements) {
    for (const glm::dvec3& light : {glm::dvec3(-4.0, 0.6, 1.0), glm::dvec3(1.0, 4.0, 3.0)}) {
      RenderRequest r = box_frame(p, true);
      r.scene.objects = {r.scene.objects[2]};  // the mesh alone
      r.light.position = p.center + p.size.x * light;
      r.light.target = p.center;
      for (LightProjection projection : {LightProjection::Orthographic, LightProjection::Perspective}) {
        r.light.projection = projection;
        int facing = 0, speckles = 0;
        for (const ExactPixel& px : cast_exact_pixels(r)) {
          if (!px.geometry || px.n_dot_l <= 0.0) continue;
          ++facing;
          speckles += px.visibility != 1.0;
        }
        EXPECT_GT(facing, 1000) << p.name;
        EXPECT_EQ(speckles, 0) << p.name << " light " << light.x << "," << light.y << "," << light.z << " of "
                               << facing;
      }
    }
  }
}

// An open quad (no volume, one triangle layer) is hit from both sides, its
// normal facing each ray, and shadows whatever is on the far side of the
// light: from above and from below.
TEST(MeshRayCast, AnOpenQuadShadowsFromBothSides) {
  RenderRequest r;
  r.scene.objects = {mesh_object(test::quad_model(2.0f), {0, 0, 0}), plane_object({0, 1, 0}, 10),
                     plane_object({0, -1, 0}, 10)};
  const RayScene rays(r.scene);
  const auto from_above = rays.cast({0.2, 0.5, 0.1}, {0, -1, 0}, 0.0, 1e9);
  const auto from_below = rays.cast({0.2, -0.5, 0.1}, {0, 1, 0}, 0.0, 1e9);
  ASSERT_TRUE(from_above && from_below);
  EXPECT_EQ(from_above->object, 0);
  EXPECT_EQ(from_below->object, 0);
  EXPECT_EQ(from_above->t, 0.5);
  EXPECT_EQ(from_below->t, 0.5);
  EXPECT_NEAR(from_above->normal.y, 1.0, 1e-12);
  EXPECT_NEAR(from_below->normal.y, -1.0, 1e-12);
  EXPECT_NEAR(from_below->geometric_normal.y, -1.0, 1e-12);
  // Light from above: under the quad, the lower floor is dark.
  r.scene.objects.pop_back();
  r.scene.objects.erase(r.scene.objects.begin() + 1);
  r.scene.objects.push_back(plane_object({0, -1, 0}, 10));
  r.light.position = {0, 10, 0};
  EXPECT_EQ(exact_visibility(r, r.light.position, {0.5, -1, 0.5}, {0, 1, 0}), 0.0);
  EXPECT_EQ(exact_visibility(r, r.light.position, {1.5, -1, 0.5}, {0, 1, 0}), 1.0);
  // Light from below: over the quad, the underside of the upper ceiling is dark.
  r.scene.objects.back() = plane_object({0, 1, 0}, 10);
  r.light.position = {0, -10, 0};
  EXPECT_EQ(exact_visibility(r, r.light.position, {0.5, 1, 0.5}, {0, -1, 0}), 0.0);
  EXPECT_EQ(exact_visibility(r, r.light.position, {1.5, 1, 0.5}, {0, -1, 0}), 1.0);
}

// A closed sphere-like mesh: hit from outside and from inside near where
// the analytic sphere is (within the tessellation's sag), with its
// interpolated normals near the sphere's; it shadows the floor under it and
// is lit on top without speckle.
TEST(MeshRayCast, ASphereMeshIsClosedAndCastsTheSphereShadow) {
  const auto model = sphere_mesh(48, 96);
  ASSERT_TRUE(model->closed);
  RenderRequest r;
  r.scene.objects = {mesh_object(model, {0, 1, 0})};
  const RayScene rays(r.scene);
  const double sag = 1.0 - std::cos(3.14159265358979 / 48);  // the most a facet lies inside the sphere
  std::mt19937 random(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < 500; ++k) {
    const glm::dvec3 dir = glm::normalize(glm::dvec3(u(random), u(random), u(random)));
    const auto outside = rays.cast(glm::dvec3(0, 1, 0) + 5.0 * dir, -dir, 0.0, 1e9);
    const auto inside = rays.cast({0, 1, 0}, dir, 0.0, 1e9);
    ASSERT_TRUE(outside && inside);
    EXPECT_EQ(outside->object, 0);
    EXPECT_NEAR(outside->t, 4.0, 1.5 * sag);
    EXPECT_NEAR(inside->t, 1.0, 1.5 * sag);
    EXPECT_GT(glm::dot(outside->normal, dir), 0.999);
    EXPECT_LT(glm::dot(inside->normal, dir), -0.999);  // the inside, seen from the centre
    EXPECT_TRUE(rays.occluded(glm::dvec3(0, 1, 0) + 5.0 * dir, -dir, 4.0 + 2 * sag));
    EXPECT_FALSE(rays.occluded(glm::dvec3(0, 1, 0) + 5.0 * dir, -dir, 4.0 - 2 * sag));
  }
  r.scene.objects.push_back(plane_object({0, -0.5, 0}, 10));
  r.light.position = {0, 10, 0};
  EXPECT_EQ(exact_visibility(r, r.light.position, {0.5, -0.5, 0.5}, {0, 1, 0}), 0.0);
  EXPECT_EQ(exact_visibility(r, r.light.position, {1.5, -0.5, 0.0}, {0, 1, 0}), 1.0);
  const RayScene with_floor(r.scene);
  const auto top = with_floor.cast({0.3, 5, 0.2}, {0, -1, 0}, 0.0, 1e9);
  ASSERT_TRUE(top);
  EXPECT_EQ(top->object, 0);
  EXPECT_EQ(exact_visibility(with_floor, r, r.light.position, *top), 1.0);
}

// The tie rule (RayScene): equally near hits go to the lower object index,
// whichever kind each is. A box mesh and an analytic box in the same place,
// hit straight on: both distances are exact in double here (unit normals,
// small integers), so they are equal, and the order of the objects decides.
TEST(MeshRayCast, AMeshAndAnAnalyticObjectEquallyNearGoToTheLowerIndex) {
  Scene mesh_first, analytic_first;
  mesh_first.objects = {mesh_object(unit_box_mesh(), {2, 0, 0}), box_object({2, 0, 0}, {1, 1, 1})};
  analytic_first.objects = {mesh_first.objects[1], mesh_first.objects[0]};
  for (const glm::dvec3& dir : {glm::dvec3(0, -1, 0), glm::dvec3(-1, 0, 0), glm::dvec3(0, 0, 1)}) {
    const glm::dvec3 origin = glm::dvec3(2.25, 0.125, -0.375) - 4.0 * dir;
    const auto a = RayScene(mesh_first).cast(origin, dir, 0.0, 1e9);
    const auto b = RayScene(analytic_first).cast(origin, dir, 0.0, 1e9);
    ASSERT_TRUE(a && b);
    EXPECT_EQ(a->t, b->t);
    EXPECT_EQ(a->object, 0) << "the mesh, listed first";
    EXPECT_EQ(b->object, 0) << "the analytic box, listed first";
    // The mesh's hit carries its float offsets; the box's its double lift.
    EXPECT_GT(glm::length(a->leave_front - a->point), 10.0 * glm::length(b->leave_front - b->point));
  }
}

TEST(MeshRayCast, AMeshWithoutTrianglesIsNeverHit) {
  auto empty = std::make_shared<TriangleModel>();
  finish_model(*empty);
  Scene scene;
  scene.objects = {mesh_object(empty, {0, 0, 0}), box_object({0, -2, 0}, {1, 1, 1})};
  const auto hit = RayScene(scene).cast({0, 5, 0}, {0, -1, 0}, 0.0, 1e9);
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->object, 1);
}

// The offset of Wächter and Binder: whole ULPs away from the surface, and
// near the origin (where ULPs vanish) a step relative to the model's extent.
TEST(MeshRayCast, TheSurfaceOffsetLeavesTheFloatSurfaceAtEveryScale) {
  for (float extent : {0.001f, 1.0f, 1000.0f}) {
    for (float x : {0.7f * extent, -0.3f * extent, 1e-6f * extent}) {
      const glm::vec3 p(x, x, x);
      const glm::vec3 up = offset_off_surface(p, {0, 1, 0}, extent), down = offset_off_surface(p, {0, -1, 0}, extent);
      EXPECT_EQ(up.x, p.x);
      EXPECT_GT(up.y, p.y);
      EXPECT_LT(down.y, p.y);
      // More than a few ULPs, far less than the model.
      EXPECT_GT(up.y - p.y, 16.0f * (std::nextafter(std::abs(p.y), 1e30f) - std::abs(p.y)));
      EXPECT_LT(up.y - p.y, 1e-3f * extent);
    }
  }
}

// A huge model's BVH build asks the stop callback: a cast whose client has
// left ends during the build, with CastStopped, and caches nothing.
TEST(MeshRayCast, TheStopCallbackEndsTheBvhBuild) {
  clear_model_bvh_cache();
  RenderRequest r;
  r.width = 64;
  r.height = 36;
  r.scene.objects = {mesh_object(sphere_mesh(400, 800), {0, 0, 0})};  // 640 k triangles
  int asked = 0;
  EXPECT_THROW(cast_exact_pixels(r, [&asked] { return ++asked > 1; }), CastStopped);
  EXPECT_GE(asked, 2) << "asked during the build, not only before it";
  EXPECT_EQ(model_bvh_cache_use().entries, 0u);
  // Not stopped, the same cast runs, and its BVH is kept for the next.
  EXPECT_EQ(cast_exact_pixels(r).size(), 64u * 36u);
  EXPECT_EQ(model_bvh_cache_use().entries, 1u);
  EXPECT_GT(model_bvh_cache_use().bytes, 640000u * 20u);
}

// The cache keeps a model's BVH no longer than the model.
TEST(MeshRayCast, TheBvhCacheDropsModelsThatAreGone) {
  clear_model_bvh_cache();
  auto model = sphere_mesh(8, 16);
  const auto first = model_bvh(model);
  EXPECT_EQ(model_bvh(model), first) << "reused";
  EXPECT_EQ(model_bvh_cache_use().entries, 1u);
  const auto other = sphere_mesh(8, 16);
  model.reset();
  model_bvh(other);
  EXPECT_EQ(model_bvh_cache_use().entries, 1u) << "the first model is gone: its entry too";
}

}  // namespace
}  // namespace umbra
