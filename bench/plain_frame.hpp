// The plain frame: the seeds' shadow mapping (LearnOpenGL's algorithm) as a
// skilled engineer would write it for speed in a small demo, so that
// `umbra-bench --speed` can say what Umbra's accuracy costs against it.
//
// One 2D depth map, one light box that holds the whole scene's bounds,
// front faces of closed meshes culled in the depth pass and back faces in the
// main pass, the seeds' slope bias and 3x3 PCF of
// nearest-texel comparisons, Blinn-Phong with Umbra's own lighting formula.
// None of Umbra's cleverness: no fitting to the camera, no cascades or cube
// faces, no receiver-plane depth, no map reuse between frames.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gpu/egl_context.hpp"
#include "gpu/objects.hpp"
#include "core/image.hpp"
#include "core/request.hpp"
#include "core/scene.hpp"

namespace umbra {

struct PlainFrame {
  /// Row 0 at the top; RGB for colour output, 1 channel (visibility as grey)
  /// for shadow output, as ShadowRenderer reads them back.
  Image image;
  /// Measured as ShadowRenderer measures: wall clock around each pass plus
  /// glFinish, and around glReadPixels plus the row flip.
  FrameTimings timings;
};

/// Construct, render and destroy on one thread: it owns its own EGL context,
/// current on the thread that constructs it (a RenderService in the same
/// process keeps its own context on its own thread).
class PlainFrameRenderer {
 public:
  /// Creates the context and compiles the shaders; throws std::runtime_error
  /// with the reason (no EGL / GL 4.5 core context, a GLSL error).
  PlainFrameRenderer();

  /// Draws `request` with the light orbited to request.time; the shadow map
  /// is drawn anew every frame. Uses width, height, scene, camera, light and
  /// shadow.map_size; every other shadow setting is the plain algorithm's own.
  /// `shadow_output`: the direct-light visibility in [0, 1] as grey (what
  /// Umbra's "shadow" output shows) instead of the lit colour.
  PlainFrame render(const RenderRequest& request, bool shadow_output);

  std::string gl_renderer() const;

 private:
  // The main pass's program, in one of two variants built with a #define.
  struct MainProgram {
    gl::Program program;
    GLint view_projection = -1, light_space = -1, light_vector = -1, shadow_map = -1;
    // Colour variant only: the shadow variant compiles the lighting out.
    GLint camera_position = -1, light_color = -1, ambient = -1;
  };
  static MainProgram build_main_program(bool shadow_output);

  void use_scene(const Scene& scene);
  void resize_shadow_map(int size);
  void resize_display(int width, int height);
  // Draws the uploaded scene; closed meshes with `closed_cull` faces culled
  // (GL_NONE: none), planes always two-sided.
  void draw_scene(GLenum closed_cull) const;
  Image read_pixels(int channels) const;

  // Declared first: the context must exist before, and outlive, every GL object below.
  gl::EglContext context_;

  gl::Program depth_program_;
  GLint depth_light_space_ = -1;
  MainProgram color_program_;
  MainProgram shadow_program_;

  // The scene uploaded last; a request with the same objects draws it again.
  std::vector<SceneObject> scene_objects_;
  bool has_scene_ = false;
  gl::VertexArray vertex_array_;
  gl::Buffer vertices_;
  gl::Buffer indices_;
  glm::dvec3 origin_{0.0};
  Aabb bounds_;
  std::uint32_t closed_index_count_ = 0;
  std::uint32_t open_index_count_ = 0;

  gl::Texture shadow_map_;  // DEPTH_COMPONENT32F, shadow_map_size_^2
  gl::Framebuffer shadow_framebuffer_;
  int shadow_map_size_ = 0;

  gl::Renderbuffer color_;  // RGBA8
  gl::Renderbuffer depth_;  // DEPTH_COMPONENT32F
  gl::Framebuffer display_framebuffer_;
  int width_ = 0, height_ = 0;
};

}  // namespace umbra
