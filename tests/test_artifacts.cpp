// Thin artifacts against the exact reference: the "artifacts" measure of
// shadow_error.hpp (interior pixels, exactly lit or dark and away from every
// edge, off by more than 0.1). `wrong` (> 0.5) never saw the dotted line a
// cascade's far plane drew across the lit floor; these tests would.
#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <sys/stat.h>

#include <glm/trigonometric.hpp>

#include "png.hpp"
#include "reference/ray_cast.hpp"
#include "render_support.hpp"
#include "service/render_service.hpp"
#include "request_parser.hpp"
#include "scene_files.hpp"
#include "reference/shadow_error.hpp"

namespace umbra {
namespace {

struct Measured {
  ShadowError error;
  std::string shadow_views;
  // Where the images of a case with artifacts went; empty when there were none.
  std::string images;
};

std::string describe(const Measured& m) {
  std::ostringstream s;
  s << "artifacts " << m.error.artifacts * 100.0 << " % of " << m.error.interior_pixels << " interior pixels"
    << " (wrong " << m.error.wrong * 100.0 << " %, MAE " << m.error.mae << "); shadow views: " << m.shadow_views;
  if (!m.images.empty()) s << "; images: " << m.images;
  return s.str();
}

std::string file_safe(std::string name) {
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '-') c = '_';
  return name;
}

bool write_png(const std::string& path, const Image& image) {
  std::ofstream out(path, std::ios::binary);
  out << encode_png(image);
  return bool(out);
}

// Renders `r` (output "shadow") and measures it against the exact reference.
// A case with artifacts leaves its rendered, exact and error images in
// <TempDir>/sweep-failures/ (/tmp/ unless TEST_TMPDIR says otherwise), since
// a share alone does not show whether it is a seam, speckle or a line.
Measured render_and_measure(const RenderRequest& r, const std::string& label) {
  const RenderResult result = service().submit(r).get();
  const ExactView view(r);
  const std::vector<ExactPixel> exact = view.pixels();
  Measured m{measure_shadow_error(result.image, exact, view.coverage_of()), result.shadow_views, {}};
  if (m.error.artifacts > 0.0) {
    const std::string dir = testing::TempDir() + "sweep-failures";
    ::mkdir(dir.c_str(), 0755);
    const std::string stem = dir + "/" + file_safe(label);
    const Image exact_shadow = exact_image(exact, r.width, r.height);
    const bool written = write_png(stem + "-shadow.png", result.image) &&
                         write_png(stem + "-exact.png", exact_shadow) &&
                         write_png(stem + "-error.png", error_image(result.image, exact_shadow));
    m.images = written ? stem + "-{shadow,exact,error}.png" : "(could not be written to " + dir + ")";
  }
  return m;
}

bool starts_with(const std::string& s, const char* prefix) { return s.rfind(prefix, 0) == 0; }

// The default scene used to show 0.6-0.9 along the boundary between two
// cascades where the floor is fully lit: receivers near the nearer cascade's
// far plane compared their PCF kernel against cleared texels beyond it.
TEST(CascadeSeam, TheDefaultSceneAtTimeFiveHasNoArtifact) {
  const RenderRequest r = request(R"({"time": 5, "width": 960, "height": 540, "output": "shadow"})");
  const Measured m = render_and_measure(r, "default-time-5");
  // Without a second cascade there is no seam to test.
  ASSERT_TRUE(starts_with(m.shadow_views, "cascades")) << m.shadow_views;
  // Most of the frame is floor far from the cube's shadow: an artifact-free
  // answer must come from measuring it, not from measuring nothing.
  EXPECT_GT(m.error.interior_pixels, 100000u) << describe(m);
  EXPECT_EQ(m.error.artifacts, 0.0) << describe(m);
}

// A sun 3 degrees above the horizon stretches the cascades' depth ranges
// along the floor, and the seam used to show as a full line across it.
TEST(CascadeSeam, AThreeDegreeSunDrawsNoLineAcrossTheFloor) {
  RenderRequest r = request(R"({"width": 960, "height": 540, "output": "shadow"})");
  const double elevation = glm::radians(3.0), distance = 20.0;
  // Time 0 with the default orbit: the light stays where it is put.
  ASSERT_EQ(r.time, 0.0);
  r.light.target = glm::dvec3(0.0);
  r.light.position = glm::dvec3(std::cos(elevation) * distance, std::sin(elevation) * distance, 0.0);
  const Measured m = render_and_measure(r, "sun-3deg");
  ASSERT_TRUE(starts_with(m.shadow_views, "cascades")) << m.shadow_views;
  // The floor's N.L = sin 3 deg = 0.052 is just above kGrazingNDotL, so the
  // floor is measured: its lit interior covers far more than a fifth of the
  // frame. Were it cut as grazing, the test would check next to nothing.
  ASSERT_GT(std::sin(elevation), kGrazingNDotL);
  EXPECT_GT(m.error.interior_pixels, 960u * 540u / 5u) << describe(m);
  EXPECT_EQ(m.error.artifacts, 0.0) << describe(m);
}

// The speed bench's sweep saw one artifact pixel in mesh-teapots-1m at
// 640x360, t = 4 s: the tip of a thin lit wedge between two teapots'
// shadows, narrower than a pixel, which every pixel centre of the exact
// image missed for 5 pixels; the render showed its light (0.23 where 4 of
// the pixel's 16 finer samples are lit). The measure samples such pixels
// finer (ExactView::coverage), and so finds none.
TEST(SubPixelEdges, TheTipOfAThinLitWedgeIsNoArtifact) {
  const RenderRequest r = load_scene_request(UMBRA_SCENES_DIR, "mesh-teapots-1m",
                                             {{"width", 640}, {"height", 360}, {"output", "shadow"}, {"time", 4}});
  const Measured m = render_and_measure(r, "mesh-teapots-1m-t4-640x360");
  EXPECT_GT(m.error.interior_pixels, 640u * 360u / 2u) << describe(m);
  EXPECT_EQ(m.error.artifacts, 0.0) << describe(m);
  // The case still holds what it was kept for: by the centres alone, the
  // same render has an artifact.
  const Image shadow = service().submit(r).get().image;
  const ShadowError by_centres = measure_shadow_error(shadow, cast_exact_pixels(r));
  EXPECT_GT(by_centres.artifacts, 0.0) << "no wedge tip left to look at: this case tests nothing now";
}

// Every hard case over one full turn of its light (the default orbit, 20
// degrees per second, turns once in 18 s): a seam or speckle that shows only
// at some light angle is caught here, not by the single time of
// HardCaseAtDefaults.
class OrbitSweep : public testing::TestWithParam<std::string> {};

TEST_P(OrbitSweep, EveryBenchSceneHasNoArtifactOverOneTurnOfTheLight) {
  // The default size, so the sweep sees what a client sees. All 14 scenes x 9
  // times took 37-51 s on the 2-core development machine (80 s while another
  // build ran), most of it the exact reference of the two area lights (64
  // shadow rays per pixel). 640x360 took 23 s but missed artifacts that
  // 960x540 shows (wide-x40 at 9 s, huge-plane at 4.5 and 9 s).
#ifdef UMBRA_SANITIZED
  // Under ASan + UBSan (3-4x slower) every third time at a quarter of the
  // pixels: the sanitizers look for memory errors and undefined behaviour,
  // which depend neither on the light's angle nor on the image size; the
  // normal build sweeps all nine at 960x540, and it alone judges the
  // artifacts (fewer pixels only hide them). The area lights' exact
  // references took 74 and 34 s at 960x540 even so.
  constexpr int kWidth = 480, kHeight = 270;
  constexpr int kTimeStride = 3;
#else
  constexpr int kWidth = 960, kHeight = 540;
  constexpr int kTimeStride = 1;
#endif
  for (int k = 0; k < kOrbitSweepTimes; k += kTimeStride) {
    const double time = orbit_sweep_time(k, kOrbitSweepTimes);
    const RenderRequest r = load_scene_request(
        UMBRA_SCENES_DIR, GetParam(), {{"width", kWidth}, {"height", kHeight}, {"output", "shadow"}, {"time", time}});
    std::ostringstream label;
    label << GetParam() << "-t" << time;
    const Measured m = render_and_measure(r, label.str());
    // Zero artifacts over next to nothing measured would prove nothing: each
    // scene keeps well over 1 % of the frame interior at every light angle.
    EXPECT_GT(m.error.interior_pixels, std::size_t(kWidth) * kHeight / 100)
        << GetParam() << " at time " << time << " s: " << describe(m);
    EXPECT_EQ(m.error.artifacts, 0.0) << GetParam() << " at time " << time << " s: " << describe(m);
  }
}

// This sweep found a second artifact besides the cascade seam: huge-plane
// (at 2.25-11.25 s) and wide-x40 (at 9 s) drew a stair-stepped false shadow,
// 0.1-0.4 dark, on box faces lit at a shallow angle (N.L 0.06-0.27) along
// their base: the face's plane, extended past its edge, ran beneath the
// floor. Fixed by never comparing a texel deeper than the point itself
// (reference_at in shaders/scene.frag).
INSTANTIATE_TEST_SUITE_P(BenchScenes, OrbitSweep, testing::ValuesIn(scene_file_names(UMBRA_SCENES_DIR)),
                         [](const testing::TestParamInfo<std::string>& info) {
                           std::string name = info.param;
                           for (char& c : name)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return name;
                         });

}  // namespace
}  // namespace umbra
