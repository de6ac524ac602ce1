#include "shadow_renderer.hpp"

#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <stdexcept>

#include <glm/ext/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "gl/program.hpp"

namespace umbra {

namespace {

using Clock = std::chrono::steady_clock;

double elapsed_ms(Clock::time_point since) {
  return std::chrono::duration<double, std::milli>(Clock::now() - since).count();
}

// Origin-relative float matrix: vertex positions are stored relative to the
// mesh origin, so the translation by the origin is folded in while still in
// double precision.
glm::mat4 relative_to(const glm::dmat4& m, const glm::dvec3& origin) {
  return glm::mat4(m * glm::translate(glm::dmat4(1.0), origin));
}

// glProgramUniform* for the types the shaders use; `at` is a location
// looked up once (see DisplayPass::Uniforms).
void set_uniform(const gl::Program& p, GLint at, const glm::mat4& m) {
  glProgramUniformMatrix4fv(p.id(), at, 1, GL_FALSE, glm::value_ptr(m));
}
void set_uniform(const gl::Program& p, GLint at, const glm::vec3& v) { glProgramUniform3f(p.id(), at, v.x, v.y, v.z); }
void set_uniform(const gl::Program& p, GLint at, float v) { glProgramUniform1f(p.id(), at, v); }
void set_uniform(const gl::Program& p, GLint at, int v) { glProgramUniform1i(p.id(), at, v); }

// One float per view of the light, for a uniform array.
std::vector<float> per_view(const ShadowPlan& light, double ShadowView::*member) {
  std::vector<float> out;
  for (const ShadowView& v : light.views) out.push_back(float(v.*member));
  return out;
}

// Every number that shapes the geometry, so an identical scene is recognised
// and not uploaded again.
std::string scene_key(const Scene& scene) {
  std::string key;
  key.reserve(scene.objects.size() * 12 * sizeof(double));
  auto put = [&key](double v) { key.append(reinterpret_cast<const char*>(&v), sizeof v); };
  for (const auto& o : scene.objects) {
    put(double(int(o.type)));
    for (int i = 0; i < 3; ++i) put(o.center[i]), put(o.size[i]), put(o.color[i]);
    put(o.radius);
    put(o.rotation_y_deg);
  }
  return key;
}

}  // namespace

ShadowRenderer::ShadowRenderer() {
  shadow_.program = gl::build_program("shadow_depth.vert", "shadow_depth.frag");
  shadow_.light_view_projection = gl::uniform_location(shadow_.program, "u_light_view_projection");
  display_.program = gl::build_program("scene.vert", "scene.frag");
  {
    const auto at = [&](const char* name) { return gl::uniform_location(display_.program, name); };
    display_.uniforms = {at("u_view_projection"), at("u_camera_position"),
                         at("u_light_perspective"), at("u_light_position"), at("u_light_direction"),
                         at("u_light_color"), at("u_ambient"), at("u_light_size"),
                         at("u_shadows_enabled"), at("u_output"), at("u_shadow_map"),
                         at("u_view_count"), at("u_filter_reach"), at("u_light_view"),
                         at("u_light_view_projection"), at("u_light_near"), at("u_light_far"),
                         at("u_texel_size"), at("u_tan_half"),
                         at("u_filter"), at("u_pcf_radius"), at("u_bias_auto"), at("u_bias_constant"),
                         at("u_bias_slope"), at("u_bias_normal_offset")};
  }
  preview_.program = gl::build_program("fullscreen.vert", "depth_preview.frag");
  {
    const auto at = [&](const char* name) { return gl::uniform_location(preview_.program, name); };
    preview_.uniforms = {at("u_shadow_map"), at("u_view_count"), at("u_grid"), at("u_image_size"),
                         at("u_light_perspective"), at("u_light_near"), at("u_light_far")};
  }
  empty_vertex_array_ = gl::create_vertex_array();
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
}

std::string ShadowRenderer::gl_renderer() const {
  return reinterpret_cast<const char*>(glGetString(GL_RENDERER));
}

std::string ShadowRenderer::gl_version() const {
  return reinterpret_cast<const char*>(glGetString(GL_VERSION));
}

bool ShadowRenderer::use_scene(const Scene& scene) {
  std::string key = scene_key(scene);
  for (auto it = scenes_.begin(); it != scenes_.end(); ++it) {
    if (it->key != key) continue;
    if (it != scenes_.begin()) {
      SceneGeometry found = std::move(*it);
      scenes_.erase(it);
      scenes_.push_front(std::move(found));
    }
    return false;
  }
  Mesh mesh = tessellate(scene);
  SceneGeometry g;
  g.vertices = gl::create_buffer();
  g.indices = gl::create_buffer();
  g.vertex_array = gl::create_vertex_array();
  // glNamedBufferStorage needs a non-zero size; an empty scene draws nothing.
  glNamedBufferStorage(g.vertices.id(), GLsizeiptr(std::max<std::size_t>(1, mesh.vertices.size()) * sizeof(Vertex)),
                       mesh.vertices.empty() ? nullptr : mesh.vertices.data(), 0);
  glNamedBufferStorage(g.indices.id(),
                       GLsizeiptr(std::max<std::size_t>(1, mesh.indices.size()) * sizeof(std::uint32_t)),
                       mesh.indices.empty() ? nullptr : mesh.indices.data(), 0);
  const GLuint vao = g.vertex_array.id();
  glVertexArrayVertexBuffer(vao, 0, g.vertices.id(), 0, sizeof(Vertex));
  glVertexArrayElementBuffer(vao, g.indices.id());
  const GLuint offsets[3] = {offsetof(Vertex, position), offsetof(Vertex, normal), offsetof(Vertex, color)};
  for (GLuint attribute = 0; attribute < 3; ++attribute) {
    glEnableVertexArrayAttrib(vao, attribute);
    glVertexArrayAttribFormat(vao, attribute, 3, GL_FLOAT, GL_FALSE, offsets[attribute]);
    glVertexArrayAttribBinding(vao, attribute, 0);
  }
  mesh.vertices.clear();
  mesh.vertices.shrink_to_fit();
  mesh.indices.clear();
  mesh.indices.shrink_to_fit();
  g.mesh = std::move(mesh);
  g.key = std::move(key);
  scenes_.push_front(std::move(g));
  if (scenes_.size() > kCachedScenes) scenes_.pop_back();
  return true;
}

void ShadowRenderer::resize_shadow_map(int size, int layers) {
  // Kept while it is big enough: a light that needs fewer views uses the
  // first layers.
  if (shadow_.size == size && shadow_.layers >= layers) return;
  shadow_.holds_plan = false;
  shadow_.depth_map = gl::create_texture(GL_TEXTURE_2D_ARRAY);
  const GLuint map = shadow_.depth_map.id();
  // 32-bit float depth: precision that holds at every scene scale.
  glTextureStorage3D(map, 1, GL_DEPTH_COMPONENT32F, size, size, layers);
  glTextureParameteri(map, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTextureParameteri(map, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  // Outside the map nothing is known to occlude: border depth 1 = far = lit.
  // (scene.frag fetches texels itself and applies the same rule.)
  glTextureParameteri(map, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_BORDER);
  glTextureParameteri(map, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_BORDER);
  const float border[4] = {1.0f, 1.0f, 1.0f, 1.0f};
  glTextureParameterfv(map, GL_TEXTURE_BORDER_COLOR, border);
  glTextureParameteri(map, GL_TEXTURE_COMPARE_MODE, GL_NONE);

  shadow_.framebuffer = gl::create_framebuffer();
  glNamedFramebufferTextureLayer(shadow_.framebuffer.id(), GL_DEPTH_ATTACHMENT, map, 0, 0);
  // Depth only: no colour buffer to draw into or read from.
  glNamedFramebufferDrawBuffer(shadow_.framebuffer.id(), GL_NONE);
  glNamedFramebufferReadBuffer(shadow_.framebuffer.id(), GL_NONE);
  if (glCheckNamedFramebufferStatus(shadow_.framebuffer.id(), GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw std::runtime_error("shadow framebuffer incomplete");
  shadow_.size = size;
  shadow_.layers = layers;
}

void ShadowRenderer::resize_display(int width, int height) {
  if (display_.width == width && display_.height == height) return;
  display_.color = gl::create_renderbuffer();
  display_.depth = gl::create_renderbuffer();
  glNamedRenderbufferStorage(display_.color.id(), GL_RGBA8, width, height);
  glNamedRenderbufferStorage(display_.depth.id(), GL_DEPTH_COMPONENT32F, width, height);
  display_.framebuffer = gl::create_framebuffer();
  glNamedFramebufferRenderbuffer(display_.framebuffer.id(), GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, display_.color.id());
  glNamedFramebufferRenderbuffer(display_.framebuffer.id(), GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, display_.depth.id());
  if (glCheckNamedFramebufferStatus(display_.framebuffer.id(), GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw std::runtime_error("display framebuffer incomplete");
  display_.width = width;
  display_.height = height;
}

void ShadowRenderer::resize_depth_preview(int size) {
  if (preview_.size == size) return;
  preview_.grey = gl::create_texture(GL_TEXTURE_2D);
  glTextureStorage2D(preview_.grey.id(), 1, GL_R8, size, size);
  preview_.framebuffer = gl::create_framebuffer();
  glNamedFramebufferTexture(preview_.framebuffer.id(), GL_COLOR_ATTACHMENT0, preview_.grey.id(), 0);
  if (glCheckNamedFramebufferStatus(preview_.framebuffer.id(), GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw std::runtime_error("depth preview framebuffer incomplete");
  preview_.size = size;
}

void ShadowRenderer::draw_scene(CullMode closed_mesh_cull) {
  const Mesh& mesh = scene().mesh;
  glBindVertexArray(scene().vertex_array.id());
  if (mesh.closed_index_count > 0) {
    if (closed_mesh_cull == CullMode::None) {
      glDisable(GL_CULL_FACE);
    } else {
      glEnable(GL_CULL_FACE);
      glCullFace(closed_mesh_cull == CullMode::Front ? GL_FRONT : GL_BACK);
    }
    glDrawElements(GL_TRIANGLES, GLsizei(mesh.closed_index_count), GL_UNSIGNED_INT, nullptr);
  }
  if (mesh.open_index_count > 0) {
    // A plane has one side: culling it would drop it from the pass entirely.
    glDisable(GL_CULL_FACE);
    glDrawElements(GL_TRIANGLES, GLsizei(mesh.open_index_count), GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>(std::size_t(mesh.closed_index_count) * sizeof(std::uint32_t)));
  }
  glDisable(GL_CULL_FACE);
}

void ShadowRenderer::run_shadow_pass(const RenderRequest& request, const ShadowPlan& light) {
  resize_shadow_map(light.layer_size, int(light.views.size()));
  const GLuint framebuffer = shadow_.framebuffer.id();
  glBindFramebuffer(GL_FRAMEBUFFER, framebuffer);
  // The map has its own resolution: without its own viewport it would be
  // drawn partly or not at all.
  glViewport(0, 0, light.layer_size, light.layer_size);
  glUseProgram(shadow_.program.id());
  for (std::size_t layer = 0; layer < light.views.size(); ++layer) {
    const ShadowView& view = light.views[layer];
    glNamedFramebufferTextureLayer(framebuffer, GL_DEPTH_ATTACHMENT, shadow_.depth_map.id(), 0, GLint(layer));
    glClear(GL_DEPTH_BUFFER_BIT);
    if (view.empty) continue;  // cleared to far: nothing there to cast
    glProgramUniformMatrix4fv(shadow_.program.id(), shadow_.light_view_projection, 1, GL_FALSE,
                              glm::value_ptr(relative_to(view.view_projection(), scene().mesh.origin)));
    // Culling front faces stores the far side of closed objects: their lit
    // faces then sit well in front of the stored depth, so no bias is needed
    // against self-shadowing there, and the bias stays small elsewhere (less
    // peter panning). See ShadowSettings::cull for why planes are exempt.
    draw_scene(request.shadow.cull);
  }
  shadow_.holds_plan = true;
  shadow_.plan = light;
  shadow_.scene_key = scene().key;
  shadow_.cull = request.shadow.cull;
}

bool ShadowRenderer::shadow_map_serves(const RenderRequest& request, const ShadowPlan& light) const {
  return shadow_.holds_plan && shadow_.scene_key == scene().key && shadow_.cull == request.shadow.cull &&
         plan_covers(shadow_.plan, light);
}

void ShadowRenderer::run_display_pass(const RenderRequest& request, const ShadowPlan& light) {
  resize_display(request.width, request.height);
  const glm::dvec3 origin = scene().mesh.origin;
  const gl::Program& p = display_.program;
  const DisplayPass::Uniforms& u = display_.uniforms;
  const CameraMatrices camera = camera_matrices(request.camera, request.width, request.height);
  const bool shadows = request.shadow.enabled;
  const ShadowSettings& s = request.shadow;

  set_uniform(p, u.view_projection, relative_to(camera.projection * camera.view, origin));
  set_uniform(p, u.camera_position, glm::vec3(request.camera.position - origin));
  set_uniform(p, u.light_perspective, int(light.perspective));
  set_uniform(p, u.light_position, glm::vec3(light.position - origin));
  set_uniform(p, u.light_direction, glm::vec3(light.direction));
  set_uniform(p, u.light_color, glm::vec3(request.light.color));
  set_uniform(p, u.ambient, float(request.light.ambient));
  set_uniform(p, u.shadows_enabled, int(shadows));
  set_uniform(p, u.output, request.output == Output::Shadow ? 1 : 0);
  // Per view: origin-relative matrices, clip planes and texel footprints.
  const int views = int(light.views.size());
  std::vector<glm::mat4> view_matrices, view_projections;
  std::vector<glm::vec2> texel_sizes;
  for (const ShadowView& v : light.views) {
    view_matrices.push_back(relative_to(v.view, origin));
    view_projections.push_back(relative_to(v.view_projection(), origin));
    texel_sizes.push_back(glm::vec2(v.texel_size));
  }
  set_uniform(p, u.view_count, views);
  set_uniform(p, u.filter_reach, filter_reach_texels(s));
  glProgramUniformMatrix4fv(p.id(), u.light_view, views, GL_FALSE,
                            glm::value_ptr(view_matrices[0]));
  glProgramUniformMatrix4fv(p.id(), u.light_view_projection, views, GL_FALSE,
                            glm::value_ptr(view_projections[0]));
  glProgramUniform1fv(p.id(), u.light_near, views,
                      per_view(light, &ShadowView::near_plane).data());
  glProgramUniform1fv(p.id(), u.light_far, views,
                      per_view(light, &ShadowView::far_plane).data());
  glProgramUniform2fv(p.id(), u.texel_size, views, glm::value_ptr(texel_sizes[0]));
  glProgramUniform1fv(p.id(), u.tan_half, views, per_view(light, &ShadowView::tan_half).data());
  set_uniform(p, u.filter, s.filter == ShadowFilter::Hard ? 0 : s.filter == ShadowFilter::Pcf ? 1 : 2);
  set_uniform(p, u.pcf_radius, s.pcf_radius);
  set_uniform(p, u.bias_auto, int(s.bias.automatic));
  set_uniform(p, u.bias_constant, float(s.bias.constant));
  set_uniform(p, u.bias_slope, float(s.bias.slope));
  set_uniform(p, u.bias_normal_offset, float(s.bias.normal_offset));
  const double light_size = light.perspective ? request.light.size
                                              : std::tan(0.5 * request.light.size * 3.14159265358979323846 / 180.0);
  set_uniform(p, u.light_size, float(light_size));
  set_uniform(p, u.shadow_map, 0);
  glBindTextureUnit(0, shadows ? shadow_.depth_map.id() : 0);

  glBindFramebuffer(GL_FRAMEBUFFER, display_.framebuffer.id());
  glViewport(0, 0, display_.width, display_.height);
  if (request.output == Output::Shadow)
    glClearColor(1.0f, 1.0f, 1.0f, 1.0f);  // no geometry: nothing blocks the light
  else
    glClearColor(0.11f, 0.12f, 0.14f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glUseProgram(p.id());
  draw_scene(CullMode::None);
}

void ShadowRenderer::run_depth_preview(const ShadowPlan& light, int image_size) {
  resize_depth_preview(image_size);
  const gl::Program& p = preview_.program;
  const DepthPreviewPass::Uniforms& u = preview_.uniforms;
  const int views = int(light.views.size());
  int grid = 1;
  while (grid * grid < views) ++grid;
  set_uniform(p, u.shadow_map, 0);
  set_uniform(p, u.view_count, views);
  set_uniform(p, u.grid, grid);
  set_uniform(p, u.image_size, float(image_size));
  set_uniform(p, u.light_perspective, int(light.perspective));
  glProgramUniform1fv(p.id(), u.light_near, views,
                      per_view(light, &ShadowView::near_plane).data());
  glProgramUniform1fv(p.id(), u.light_far, views,
                      per_view(light, &ShadowView::far_plane).data());
  glBindTextureUnit(0, shadow_.depth_map.id());
  glBindFramebuffer(GL_FRAMEBUFFER, preview_.framebuffer.id());
  glViewport(0, 0, preview_.size, preview_.size);
  glDisable(GL_DEPTH_TEST);
  glUseProgram(p.id());
  glBindVertexArray(empty_vertex_array_.id());
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glEnable(GL_DEPTH_TEST);
}

Image ShadowRenderer::read_pixels(GLuint framebuffer, int width, int height, int channels) {
  Image image;
  image.width = width;
  image.height = height;
  image.channels = channels;
  image.pixels.resize(std::size_t(width) * height * channels);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, framebuffer);
  glNamedFramebufferReadBuffer(framebuffer, GL_COLOR_ATTACHMENT0);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, width, height, channels == 1 ? GL_RED : GL_RGB, GL_UNSIGNED_BYTE, image.pixels.data());
  // GL's row 0 is the bottom; images start at the top.
  const std::size_t stride = std::size_t(width) * channels;
  std::vector<std::uint8_t> swap(stride);
  for (int y = 0; y < height / 2; ++y) {
    std::uint8_t* a = image.row(y);
    std::uint8_t* b = image.row(height - 1 - y);
    std::memcpy(swap.data(), a, stride);
    std::memcpy(a, b, stride);
    std::memcpy(b, swap.data(), stride);
  }
  return image;
}

RenderResult ShadowRenderer::render(const RenderRequest& request) {
  RenderResult result;
  result.scene_uploaded = use_scene(request.scene);
  ShadowPlan light = plan_shadow(request);
  const bool depth_output = request.output == Output::Depth;

  if (request.shadow.enabled || depth_output) {
    if (shadow_map_serves(request, light)) {
      // Nothing the map depends on changed (typically only the camera
      // moved): draw with the views it was made for; shadow_ms stays 0.
      light = shadow_.plan;
      result.shadow_reused = true;
    } else {
      const auto start = Clock::now();
      run_shadow_pass(request, light);
      glFinish();
      result.timings.shadow_ms = elapsed_ms(start);
    }
    const char* layout = light.layout == ShadowLayout::Cascades ? "cascades"
                         : light.layout == ShadowLayout::Cube   ? "cube"
                                                                : "single";
    result.shadow_views = std::string(layout) + "; views=" + std::to_string(light.views.size()) +
                          "; size=" + std::to_string(light.layer_size);
  }

  const auto main_start = Clock::now();
  if (depth_output)
    run_depth_preview(light, request.shadow.map_size);
  else
    run_display_pass(request, light);
  glFinish();
  result.timings.main_ms = elapsed_ms(main_start);

  const auto readback_start = Clock::now();
  if (depth_output)
    result.image = read_pixels(preview_.framebuffer.id(), preview_.size, preview_.size, 1);
  else
    result.image = read_pixels(display_.framebuffer.id(), display_.width, display_.height,
                               request.output == Output::Shadow ? 1 : 3);
  result.timings.readback_ms = elapsed_ms(readback_start);
  return result;
}

}  // namespace umbra
