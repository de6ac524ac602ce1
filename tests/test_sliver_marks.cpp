// The sliver marks drawn on the CPU (plan/sliver_marks.hpp): what the
// certificate needs of them (docs/certified-shadows.md, "The sliver pass")
// is every pixel centre within kSliverPixels of an object's outline on the
// screen, where another object was drawn. Checked on random boxes, thin
// ones among them, whose outline is the convex hull of their corners'
// images; and that edges inside the outline are left out.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <map>
#include <cmath>
#include <random>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "core/builtin_models.hpp"
#include "core/render_result.hpp"
#include "core/request.hpp"
#include "core/scene.hpp"
#include "plan/sliver_marks.hpp"

namespace umbra {
namespace {

struct SceneTriangles {
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices, objects;
  glm::dvec3 origin{0.0};
};

SceneTriangles triangles_of(const Scene& scene) {
  const Mesh mesh = tessellate(scene);
  SceneTriangles t;
  t.origin = mesh.origin;
  for (const Vertex& v : mesh.vertices) t.positions.emplace_back(v.position[0], v.position[1], v.position[2]);
  t.indices = mesh.indices;
  t.objects.resize(mesh.indices.size() / 3);
  for (const ObjectRange& r : mesh.object_ranges)
    for (std::uint32_t i = r.first_index / 3; i < (r.first_index + r.index_count) / 3; ++i) t.objects[i] = std::uint32_t(r.object);
  return t;
}

// The convex hull of points (Andrew's monotone chain), counter-clockwise.
std::vector<glm::dvec2> hull_of(std::vector<glm::dvec2> p) {
  std::sort(p.begin(), p.end(), [](const glm::dvec2& a, const glm::dvec2& b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
  std::vector<glm::dvec2> h(2 * p.size());
  std::size_t k = 0;
  const auto cross = [](glm::dvec2 o, glm::dvec2 a, glm::dvec2 b) { return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x); };
  for (std::size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (std::size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross(h[k - 2], h[k - 1], p[i - 1]) <= 0) --k;
    h[k++] = p[i - 1];
  }
  h.resize(k - 1);
  return h;
}

double distance_to_segment(glm::dvec2 x, glm::dvec2 a, glm::dvec2 b) {
  const glm::dvec2 ab = b - a;
  const double t = std::clamp(glm::dot(x - a, ab) / std::max(1e-300, glm::dot(ab, ab)), 0.0, 1.0);
  return glm::length(x - (a + t * ab));
}

TEST(SliverMarks, EveryCentreNearABoxsOutlineIsMarkedAndNoneInside) {
  std::mt19937 random(5);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const int width = 160, height = 90;
  std::size_t checked = 0, inner_marks = 0;
  for (int scene_index = 0; scene_index < 60; ++scene_index) {
    SceneObject box;
    box.type = SceneObject::Type::Box;
    box.center = {unit(random) * 2 - 1, unit(random) * 2, unit(random) * 2 - 1};
    // Thin ones: a needle or a sheet a small part of a pixel across.
    box.size = {0.002 + unit(random), 0.002 + unit(random), 0.002 + unit(random)};
    if (scene_index % 3 == 0) box.size.y = 0.004;
    if (scene_index % 3 == 1) box.size.x = box.size.z = 0.003;
    box.rotation_y_deg = unit(random) * 90.0;
    Scene scene;
    scene.objects.push_back(box);
    const SceneTriangles t = triangles_of(scene);
    const SliverEdges edges(t.positions, t.indices, t.objects);
    const glm::dvec3 eye(unit(random) * 8 - 4, 1 + unit(random) * 4, 5 + unit(random) * 3);
    const glm::dmat4 view_projection = glm::perspective(glm::radians(40.0), double(width) / height, 0.1, 100.0) *
                                       glm::lookAt(eye, box.center, glm::dvec3(0, 1, 0)) *
                                       glm::translate(glm::dmat4(1.0), t.origin);
    const std::vector<std::uint32_t> nothing_drawn(std::size_t(width) * height, 0);
    std::vector<std::uint8_t> marks;
    edges.mark(t.positions, view_projection, 0.1, width, height, nothing_drawn, marks);
    std::vector<glm::dvec2> corners;
    for (const glm::vec3& p : t.positions) {
      const glm::dvec4 c = view_projection * glm::dvec4(glm::dvec3(p), 1.0);
      corners.push_back((glm::dvec2(c) / c.w * 0.5 + 0.5) * glm::dvec2(width, height));
    }
    const std::vector<glm::dvec2> hull = hull_of(corners);
    for (int j = 0; j < height; ++j)
      for (int i = 0; i < width; ++i) {
        const glm::dvec2 x(i + 0.5, j + 0.5);
        double d = 1e300;
        for (std::size_t k = 0; k < hull.size(); ++k) d = std::min(d, distance_to_segment(x, hull[k], hull[(k + 1) % hull.size()]));
        const bool marked = marks[std::size_t(height - 1 - j) * width + std::size_t(i)] != 0;
        if (d <= kSliverPixels * 0.999) {
          ++checked;
          EXPECT_TRUE(marked) << "scene " << scene_index << ": pixel " << i << ", " << j << " is " << d
                              << " px from the outline and not marked";
        }
        // A band twice as wide as the marks' holds every edge inside the
        // outline that is drawn as if it were one.
        if (marked && d > 3.0 * kSliverPixels) ++inner_marks;
      }
  }
  EXPECT_GT(checked, 50u);
  EXPECT_EQ(inner_marks, 0u) << "marks away from every outline: an edge inside it was drawn";
}

// Where the object itself was drawn, nothing is marked (unless it is a
// model); where another one (or none) was, its outline is.
TEST(SliverMarks, OnlyPixelsWhereAnotherObjectWasDrawnAreMarked) {
  SceneObject box;
  box.type = SceneObject::Type::Box;
  box.size = {1, 1, 1};
  Scene scene;
  scene.objects.push_back(box);
  const SceneTriangles t = triangles_of(scene);
  const SliverEdges edges(t.positions, t.indices, t.objects);
  const glm::dmat4 view_projection = glm::perspective(glm::radians(40.0), 2.0, 0.1, 100.0) *
                                     glm::lookAt(glm::dvec3(2, 2, 3), glm::dvec3(0), glm::dvec3(0, 1, 0)) *
                                     glm::translate(glm::dmat4(1.0), t.origin);
  std::vector<std::uint8_t> marks;
  edges.mark(t.positions, view_projection, 0.1, 80, 40, std::vector<std::uint32_t>(80 * 40, 1), marks);
  EXPECT_EQ(std::count(marks.begin(), marks.end(), 1), 0);
  edges.mark(t.positions, view_projection, 0.1, 80, 40, std::vector<std::uint32_t>(80 * 40, 2), marks);
  EXPECT_GT(std::count(marks.begin(), marks.end(), 1), 0);
  // The certificates' codes, read through their object shift.
  const unsigned shift = PixelCertificates::kObjectShift;
  edges.mark(t.positions, view_projection, 0.1, 80, 40, std::vector<std::uint32_t>(80 * 40, (1u << shift) | 6u), marks,
             shift);
  EXPECT_EQ(std::count(marks.begin(), marks.end(), 1), 0);
  edges.mark(t.positions, view_projection, 0.1, 80, 40, std::vector<std::uint32_t>(80 * 40, (2u << shift) | 1u), marks,
             shift);
  EXPECT_GT(std::count(marks.begin(), marks.end(), 1), 0);
  // A model's edges mark over the model itself too: its outline can pass
  // in front of a farther part of it.
  SliverEdges(t.positions, t.indices, t.objects, {true})
      .mark(t.positions, view_projection, 0.1, 80, 40, std::vector<std::uint32_t>(80 * 40, 1), marks);
  EXPECT_GT(std::count(marks.begin(), marks.end(), 1), 0);
}

// Given the normals, a box's edges are creases (each face its own
// normals): marked over the box itself, inside its outline too; a smooth
// sphere's shared edges are not.
TEST(SliverMarks, CreasesAreMarkedOverTheObjectItself) {
  for (const SceneObject::Type type : {SceneObject::Type::Box, SceneObject::Type::Sphere}) {
    SceneObject o;
    o.type = type;
    o.size = {1, 1, 1};
    o.radius = 0.5;
    Scene scene;
    scene.objects.push_back(o);
    const Mesh mesh = tessellate(scene);
    const SceneTriangles t = triangles_of(scene);
    std::vector<glm::vec3> normals;
    for (const Vertex& v : mesh.vertices) normals.emplace_back(v.normal[0], v.normal[1], v.normal[2]);
    const SliverEdges edges(t.positions, t.indices, t.objects, {}, &normals);
    std::size_t creases = 0;
    for (const SliverEdges::Edge& e : edges.all()) creases += e.crease ? 1 : 0;
    const glm::dmat4 view_projection = glm::perspective(glm::radians(40.0), 2.0, 0.1, 100.0) *
                                       glm::lookAt(glm::dvec3(2, 2, 3), glm::dvec3(0), glm::dvec3(0, 1, 0)) *
                                       glm::translate(glm::dmat4(1.0), t.origin);
    std::vector<std::uint8_t> marks;
    edges.mark(t.positions, view_projection, 0.1, 160, 80, std::vector<std::uint32_t>(160 * 80, 1), marks);
    if (type == SceneObject::Type::Box) {
      EXPECT_EQ(creases, 12u);  // the cube's edges; the faces' diagonals are flat
      EXPECT_GT(std::count(marks.begin(), marks.end(), 1), 0);
    } else {
      EXPECT_EQ(creases, 0u);
      EXPECT_EQ(std::count(marks.begin(), marks.end(), 1), 0);
    }
  }
}

// A torus knot folds on the screen everywhere. Its outline there is where
// a face turned to the camera meets one turned away, found here by brute
// force in double: every centre near such an edge is marked.
TEST(SliverMarks, EveryCentreNearAFoldedMeshsOutlineIsMarked) {
  SceneObject knot;
  knot.type = SceneObject::Type::Mesh;
  knot.model = torus_knot(1.0, 0.3, 64, 12);
  knot.model_id = "knot";
  Scene scene;
  scene.objects.push_back(knot);
  const SceneTriangles t = triangles_of(scene);
  const SliverEdges edges(t.positions, t.indices, t.objects);
  const int width = 200, height = 120;
  std::mt19937 random(9);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::size_t checked = 0;
  for (int view = 0; view < 6; ++view) {
    const double angle = unit(random) * 6.283, elevation = unit(random) * 2.0 - 1.0;
    const glm::dvec3 eye = 7.0 * glm::dvec3(std::cos(angle) * std::cos(elevation), std::sin(elevation),
                                            std::sin(angle) * std::cos(elevation));
    const glm::dmat4 view_projection = glm::perspective(glm::radians(40.0), double(width) / height, 0.1, 100.0) *
                                       glm::lookAt(eye, glm::dvec3(0.0), glm::dvec3(0, 1, 0)) *
                                       glm::translate(glm::dmat4(1.0), t.origin);
    std::vector<std::uint8_t> marks;
    edges.mark(t.positions, view_projection, 0.1, width, height, std::vector<std::uint32_t>(std::size_t(width) * height, 0),
               marks);
    std::vector<glm::dvec2> window;
    for (const glm::vec3& p : t.positions) {
      const glm::dvec4 c = view_projection * glm::dvec4(glm::dvec3(p), 1.0);
      window.push_back((glm::dvec2(c) / c.w * 0.5 + 0.5) * glm::dvec2(width, height));
    }
    // Each edge's faces' signed areas on the screen (counter-clockwise:
    // turned to the camera), by its corners' positions.
    std::map<std::array<float, 6>, std::vector<double>> areas_of_edge;
    std::map<std::array<float, 6>, std::pair<glm::dvec2, glm::dvec2>> ends_of_edge;
    for (std::size_t k = 0; k + 2 < t.indices.size(); k += 3) {
      const std::uint32_t* v = &t.indices[k];
      const glm::dvec2 e1 = window[v[1]] - window[v[0]], e2 = window[v[2]] - window[v[0]];
      for (int i = 0; i < 3; ++i) {
        const glm::vec3 pa = t.positions[v[i]], pb = t.positions[v[(i + 1) % 3]];
        std::array<float, 6> key{pa.x, pa.y, pa.z, pb.x, pb.y, pb.z};
        key = std::min(key, std::array<float, 6>{pb.x, pb.y, pb.z, pa.x, pa.y, pa.z});
        areas_of_edge[key].push_back(e1.x * e2.y - e1.y * e2.x);
        ends_of_edge[key] = {window[v[i]], window[v[(i + 1) % 3]]};
      }
    }
    std::vector<std::pair<glm::dvec2, glm::dvec2>> outline;
    for (const auto& [key, areas] : areas_of_edge) {
      const bool front = std::any_of(areas.begin(), areas.end(), [](double a) { return a > -1e-6; });
      const bool back = std::any_of(areas.begin(), areas.end(), [](double a) { return a < 1e-6; });
      if (front && back) outline.push_back(ends_of_edge[key]);
    }
    for (int j = 0; j < height; ++j)
      for (int i = 0; i < width; ++i)
        for (const auto& [a, b] : outline)
          if (distance_to_segment(glm::dvec2(i + 0.5, j + 0.5), a, b) <= kSliverPixels * 0.999) {
            ++checked;
            EXPECT_TRUE(marks[std::size_t(height - 1 - j) * width + std::size_t(i)])
                << "view " << view << ": pixel " << i << ", " << j << " is near the outline and not marked";
            break;
          }
  }
  EXPECT_GT(checked, 100u);
}


// An edge whose end lies just in front of half the near plane projects
// 1e10 pixels away: it is walked over the image only (a red-team pass found
// the pixel range converted to int before it was clamped).
TEST(SliverMarks, AnEdgeReachingFarOffTheImageIsWalkedOverItOnly) {
  // The edge from (1e5, 0, -5.0001e-5) to (-1, 0, -5) lies on the image's
  // middle row of centres (41 rows: row 20's centres at window y 20.5);
  // its first end, just past half the near plane (1e-4), 1e11 pixels right.
  const std::vector<glm::vec3> positions = {{1e5f, 0.0f, -5.0001e-5f}, {-1.0f, 0.0f, -5.0f}, {0.0f, 1.0f, -5.0f}};
  const SliverEdges edges(positions, {0, 1, 2}, {0});
  const int width = 80, height = 41;
  const glm::dmat4 view_projection = glm::perspective(glm::radians(40.0), double(width) / height, 1e-4, 100.0);
  std::vector<std::uint8_t> marks;
  edges.mark(positions, view_projection, 1e-4, width, height, std::vector<std::uint32_t>(std::size_t(width * height), 0),
             marks);
  const auto row = marks.begin() + std::ptrdiff_t(20 * width);
  EXPECT_GT(std::count(row, row + width, 1), width / 2);
}

}  // namespace
}  // namespace umbra
