// Mesh objects drawn by the real renderer: a model shaped like an analytic
// object must cast that object's shadow, placed by the same transform, and
// open models must cast theirs although the shadow pass culls front faces.
#include <gtest/gtest.h>

#include <string>

#include "core/light_math.hpp"
#include "model_support.hpp"
#include "reference/ray_cast.hpp"
#include "render_support.hpp"
#include "reference/shadow_error.hpp"

namespace umbra {
namespace {

RenderResult render(const RenderRequest& r) { return service().submit(r).get(); }

const ModelLookup& models() {
  static const ModelLookup lookup = test::lookup_of({{"sha256:box", test::box_model({0.5f, 0.5f, 0.5f})},
                                                     {"sha256:quad", test::quad_model(2.0f)}});
  return lookup;
}

// A "shadow" frame of `object` over a 20 x 20 floor, seen and lit from
// fixed places so that two scenes with the same bounds or not are framed alike.
RenderRequest shadow_frame(const std::string& object, const std::string& shadow = "{}",
                           const std::string& projection = "orthographic") {
  return request(R"({"width": 320, "height": 180, "output": "shadow",
      "camera": {"position": [2.5, 3.0, 5.0], "target": [0.3, -0.3, 0.3]},
      "light": {"position": [-2, 4, -1], "target": [0, 0, 0], "projection": ")" + projection + R"("},
      "shadow": )" + shadow + R"(,
      "scene": {"objects": [{"type": "plane", "center": [0, -0.5, 0], "size": [20, 20]}, )" + object + "]}}",
                 models());
}

int dark_pixels(const Image& image) {
  int n = 0;
  for (unsigned char v : image.pixels) n += v < 128;
  return n;
}

// Pixels whose shadow value differs by more than a rounding step.
int differing_pixels(const Image& a, const Image& b) {
  EXPECT_EQ(a.pixels.size(), b.pixels.size());
  int n = 0;
  for (std::size_t i = 0; i < a.pixels.size() && i < b.pixels.size(); ++i) n += std::abs(int(a.pixels[i]) - int(b.pixels[i])) > 2;
  return n;
}

struct Twin {
  const char* name;
  const char* analytic;
  const char* mesh;
};

class MeshTwin : public testing::TestWithParam<Twin> {};

// The budget: 0.1 % of the pixels. The mesh's vertices are transformed in
// double by one matrix, the analytic box's by rotate_y and a sum, so a
// corner may land an ulp apart in float: a rasterised edge pixel, or a
// shadow-map texel on the silhouette, may then fall on the other side.
// Anything more (a wrong rotation order, scale or winding) moves whole
// edges: thousands of pixels.
TEST_P(MeshTwin, CastsTheSameShadowAsTheAnalyticObject) {
  // A perspective light this close fits a cone or cube faces to the
  // bounds: the mesh's bounds must feed them as the box's do.
  for (const char* projection : {"orthographic", "perspective"}) {
    for (const char* cull : {R"({"cull": "front"})", R"({"cull": "back"})"}) {
      const RenderResult analytic = render(shadow_frame(GetParam().analytic, cull, projection));
      const RenderResult mesh = render(shadow_frame(GetParam().mesh, cull, projection));
      const int total = analytic.image.width * analytic.image.height;
      ASSERT_GT(dark_pixels(analytic.image), total / 50) << "the frame should show a real shadow";
      const int differing = differing_pixels(analytic.image, mesh.image);
      EXPECT_LE(differing, total / 1000) << projection << " " << cull;
      RecordProperty(std::string("differing_pixels_") + projection + (cull[10] == 'f' ? "_front" : "_back"), differing);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Placements, MeshTwin,
    testing::Values(
        Twin{"UnitBox", R"({"type": "box", "center": [0, 0, 0], "size": [1, 1, 1]})",
             R"({"type": "mesh", "model": "sha256:box"})"},
        // X first: the model's y (scaled to 2) becomes z and its z (0.5)
        // becomes y; then 30 degrees about Y, as the box's rotation_y_deg.
        Twin{"RotatedScaledMovedBox",
             R"({"type": "box", "center": [0.3, 0.25, -0.2], "size": [1, 0.5, 2], "rotation_y_deg": 30})",
             R"({"type": "mesh", "model": "sha256:box", "position": [0.3, 0.25, -0.2], "rotation_deg": [90, 30, 0],
                 "scale": [1, 2, 0.5]})"},
        // An open model (a roof: one quad facing up) is drawn two-sided in
        // the shadow pass, like the analytic plane: with front faces culled
        // as for closed models, its only face, facing the light, would be
        // dropped and it would cast nothing.
        Twin{"OpenQuadAsPlane", R"({"type": "plane", "center": [0.5, 0.8, 0], "size": [2, 2]})",
             R"({"type": "mesh", "model": "sha256:quad", "position": [0.5, 0.8, 0]})"}),
    [](const testing::TestParamInfo<Twin>& info) { return std::string(info.param.name); });

TEST(MeshRender, TheSceneCacheTellsModelsAndTransformsApart) {
  // Each frame after the first could reuse the uploaded scene if its key
  // missed the model or the transform: it would then repeat the first shadow.
  const int unit = dark_pixels(render(shadow_frame(R"({"type": "mesh", "model": "sha256:box"})")).image);
  const int scaled =
      dark_pixels(render(shadow_frame(R"({"type": "mesh", "model": "sha256:box", "scale": 1.5})")).image);
  const int turned = dark_pixels(
      render(shadow_frame(R"({"type": "mesh", "model": "sha256:box", "scale": 1.5, "rotation_deg": [0, 45, 0]})")).image);
  const int quad = dark_pixels(render(shadow_frame(R"({"type": "mesh", "model": "sha256:quad", "scale": 1.5})")).image);
  EXPECT_GT(scaled, unit * 3 / 2);
  EXPECT_NE(turned, scaled);
  EXPECT_NE(quad, scaled);
}

// The exact reference covers meshes (Embree): "exact" of the mesh is the
// analytic twin's, and the GL shadow of the mesh measured against it is as
// right as the twin's: nothing wrong, no artifact. "error" is their
// difference, as for analytic scenes.
TEST_P(MeshTwin, TheExactReferenceSeesTheMeshAsItsTwin) {
  RenderRequest analytic = shadow_frame(GetParam().analytic), mesh = shadow_frame(GetParam().mesh);
  analytic.output = mesh.output = Output::Exact;
  const Image analytic_exact = render(analytic).image, mesh_exact = render(mesh).image;
  EXPECT_EQ(differing_pixels(analytic_exact, mesh_exact), 0);

  mesh.output = Output::Shadow;
  const Image shadow = render(mesh).image;
  const std::vector<ExactPixel> exact = cast_exact_pixels(mesh);
  EXPECT_EQ(exact_image(exact, mesh.width, mesh.height).pixels, mesh_exact.pixels);
  const ShadowError error = measure_shadow_error(shadow, exact);
  EXPECT_GT(error.interior_pixels, 10000u);
  EXPECT_LT(error.wrong, 0.002) << "MAE " << error.mae;
  EXPECT_EQ(error.artifacts, 0.0) << "of " << error.interior_pixels << " interior pixels";
  RecordProperty("wrong_percent", std::to_string(100.0 * error.wrong));

  mesh.output = Output::Error;
  const Image error_output = render(mesh).image;
  EXPECT_EQ(error_output.pixels, error_image(shadow, mesh_exact).pixels);
}

// An octahedron whose vertex normals are a sphere's: 8 triangles, closed.
std::shared_ptr<const TriangleModel> smooth_octahedron() {
  ModelPart part;
  part.positions = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  part.normals = part.positions;
  for (std::uint32_t x : {0u, 1u})
    for (std::uint32_t y : {2u, 3u})
      for (std::uint32_t z : {4u, 5u}) {
        // (x, y, z) faces out where an odd number of the signs is negative
        // flips it: (b - a) x (c - a) = (sy sz, sx sz, sx sy).
        const bool outward = (x == 0) == ((y == 2) == (z == 4));
        part.indices.insert(part.indices.end(), {x, outward ? y : z, outward ? z : y});
      }
  auto model = std::make_shared<TriangleModel>();
  model->parts.push_back(std::move(part));
  finish_model(*model);
  return model;
}

// The main pass draws a closed mesh in two parts: with the shadow lookup
// where its points may face the light, without it (visibility 0) where none
// can. A triangle is split where dot(normal, light - p) interpolated from
// its vertices crosses 0, but scene.frag interpolates the normal, not the
// product: across the octahedron's faces a point light lights points up to
// 1 - |p|^2 (2/3 at a face's centre) past the vertices' line. The split
// allows for it (Mesh::smooth_normal_span); without that those points came
// out dark.
TEST(MeshRender, ASmoothClosedMeshIsLitUpToItsInterpolatedTerminator) {
  const ModelLookup lookup = test::lookup_of({{"sha256:octahedron", smooth_octahedron()}});
  ASSERT_TRUE(lookup("sha256:octahedron")->model->closed);
  const RenderRequest r = request(R"({"width": 320, "height": 180, "output": "shadow",
      "camera": {"position": [0.5, 2.0, 4.0], "target": [0, 1.2, 0]},
      "light": {"position": [3, 2, 1], "target": [0, 0, 0], "projection": "perspective"},
      "scene": {"objects": [{"type": "plane", "center": [0, 0, 0], "size": [20, 20]},
                            {"type": "mesh", "model": "sha256:octahedron", "position": [0, 1.2, 0]}]}})",
                                  lookup);
  ASSERT_TRUE(objects_split_by_the_light(tessellate(r.scene), r.camera, r.width, r.height)[1])
      << "the octahedron is drawn in two parts";
  const Image image = render(r).image;
  const std::vector<ExactPixel> exact = cast_exact_pixels(r);
  int lit = 0, dark = 0;
  for (std::size_t i = 0; i < exact.size(); ++i) {
    const ExactPixel& p = exact[i];
    if (!p.geometry || p.object != 1 || p.visibility != 1.0 || p.n_dot_l < 0.05) continue;
    ++lit;
    dark += image.pixels[i] < 128;
  }
  EXPECT_GT(lit, 2000);
  EXPECT_LE(dark, lit / 200) << "of " << lit << " lit pixels";
}

}  // namespace
}  // namespace umbra
