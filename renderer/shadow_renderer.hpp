// The GL renderer: a shadow pass into a depth texture, then a main pass that
// lights the scene from the camera with that texture, then read-back.
#pragma once

#include <deque>
#include <string>

#include "gl/objects.hpp"
#include "gl/program.hpp"
#include "render_result.hpp"
#include "light_math.hpp"
#include "request.hpp"
#include "scene.hpp"

namespace umbra {

/// Call order: construct with a current GL 4.5 context, then render() any
/// number of times, destroy before the context. Not thread-safe: it lives on
/// the GL thread (see render_service.hpp).
class ShadowRenderer {
 public:
  /// Compiles the shaders; throws std::runtime_error with the GLSL log.
  ShadowRenderer();

  /// Renders `request` and reads the chosen output back. `request` must be
  /// valid (as the request parser guarantees).
  RenderResult render(const RenderRequest& request);

  std::string gl_renderer() const;
  std::string gl_version() const;

 private:
  // A scene's triangles, uploaded once per distinct scene (see scenes_).
  struct SceneGeometry {
    gl::VertexArray vertex_array;
    gl::Buffer vertices;
    gl::Buffer indices;
    Mesh mesh;           // CPU copy: origin and index ranges (vertices cleared)
    std::string key;     // content of the scene it was built from
  };
  // Depth-only framebuffer seen from the light, one array layer per view.
  struct ShadowPass {
    gl::Program program;
    GLint layer = -1;       // u_layer: the view a draw fills
    gl::Texture depth_map;  // 2D array of DEPTH_COMPONENT32F, size^2 x layers
    gl::Framebuffer framebuffer;
    int size = 0;
    int layers = 0;
    // What the map holds now, so that a frame whose light, scene and cull
    // mode are unchanged (a camera-only change) reuses it.
    bool holds_plan = false;
    ShadowPlan plan;
    std::string scene_key;
    CullMode cull = CullMode::Front;
  };
  // The camera's view, into an offscreen colour + depth framebuffer.
  struct DisplayPass {
    gl::ProgramVariants programs{"scene.vert", "scene.frag", kKeptVariants};  // per DisplayVariant
    gl::Renderbuffer color;  // RGBA8
    gl::Renderbuffer depth;  // DEPTH_COMPONENT32F
    gl::Framebuffer framebuffer;
    int width = 0, height = 0;
  };
  // The depth map turned into a grey image for the "depth" output.
  struct DepthPreviewPass {
    gl::ProgramVariants programs{"fullscreen.vert", "depth_preview.frag", kKeptVariants};  // per PreviewVariant
    gl::Texture grey;        // R8 or R16 (depth_bits), map_size^2
    gl::Framebuffer framebuffer;
    int size = 0;
    int bits = 0;
  };
  // Compiled variants kept per pass: every combination a client can ask
  // for is a few hundred, each a large program on a software rasteriser.
  static constexpr std::size_t kKeptVariants = 24;

  /// Makes `scene` the current one (scenes_.front()), uploading it unless a
  /// scene with the same content is cached; true if it was uploaded.
  bool use_scene(const Scene& scene);
  SceneGeometry& scene() { return scenes_.front(); }
  const SceneGeometry& scene() const { return scenes_.front(); }
  void resize_shadow_map(int size, int layers);
  void resize_display(int width, int height);
  void resize_depth_preview(int size, int bits);
  void draw_scene(CullMode closed_mesh_cull);
  void upload_frame_block(const RenderRequest& request, const ShadowPlan& light);
  void run_shadow_pass(const RenderRequest& request, const ShadowPlan& light);
  bool shadow_map_serves(const RenderRequest& request, const ShadowPlan& light) const;
  void run_display_pass(const RenderRequest& request, const ShadowPlan& light);
  void run_depth_preview(const ShadowPlan& light, int image_size, int bits);
  Image read_pixels(GLuint framebuffer, int width, int height, int channels, int bit_depth = 8);

  // The last few distinct scenes, most recently used first, so that
  // clients alternating between scenes do not re-upload them.
  static constexpr std::size_t kCachedScenes = 8;
  std::deque<SceneGeometry> scenes_;
  ShadowPass shadow_;
  DisplayPass display_;
  DepthPreviewPass preview_;
  gl::Buffer frame_block_;  // FrameBlock, binding 0: every pass reads it
  gl::VertexArray empty_vertex_array_;  // for the full-screen triangle
};

}  // namespace umbra
