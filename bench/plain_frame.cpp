#include "plain_frame.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <stdexcept>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/geometric.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "gpu/program.hpp"
#include "core/light_math.hpp"

namespace umbra {

namespace {

using Clock = std::chrono::steady_clock;

double elapsed_ms(Clock::time_point since) {
  return std::chrono::duration<double, std::milli>(Clock::now() - since).count();
}

// ---------------------------------------------------------------------------
// Shaders: LearnOpenGL's shadow mapping, in GLSL 4.50.

constexpr const char* kDepthVertex = R"(#version 450 core
layout(location = 0) in vec3 a_position;  // relative to the mesh origin
uniform mat4 u_light_space;
void main() { gl_Position = u_light_space * vec4(a_position, 1.0); }
)";

constexpr const char* kDepthFragment = R"(#version 450 core
void main() {}
)";

constexpr const char* kMainVertex = R"(#version 450 core
layout(location = 0) in vec3 a_position;  // relative to the mesh origin
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec3 a_color;
uniform mat4 u_view_projection;
uniform mat4 u_light_space;
out vec3 v_position;
out vec3 v_normal;
out vec3 v_color;
out vec4 v_light_space;
void main() {
  v_position = a_position;
  v_normal = a_normal;
  v_color = a_color;
  v_light_space = u_light_space * vec4(a_position, 1.0);
  gl_Position = u_view_projection * vec4(a_position, 1.0);
}
)";

// Without its #version line: the variant's #define goes between the two.
constexpr const char* kMainFragmentBody = R"(
in vec3 v_position;
in vec3 v_normal;
in vec3 v_color;
in vec4 v_light_space;
layout(location = 0) out vec4 o_color;

uniform sampler2D u_shadow_map;
// Towards the light: xyz = -direction, w = 0 for a directional light;
// xyz = position (origin-relative), w = 1 for a point light.
uniform vec4 u_light;
#ifndef SHADOW_OUTPUT
uniform vec3 u_camera_position;
uniform vec3 u_light_color;
uniform float u_ambient;
#endif

// 1 lit, 0 shadowed: 3x3 PCF of nearest-texel depth comparisons.
float visibility(float n_dot_l) {
  vec3 proj = v_light_space.xyz / v_light_space.w * 0.5 + 0.5;
  if (proj.z > 1.0) return 1.0;  // beyond the light's far plane
  float bias = max(0.05 * (1.0 - n_dot_l), 0.005);
  vec2 texel_size = 1.0 / vec2(textureSize(u_shadow_map, 0));
  float lit = 0.0;
  for (int x = -1; x <= 1; ++x)
    for (int y = -1; y <= 1; ++y)
      lit += proj.z - bias > texture(u_shadow_map, proj.xy + vec2(x, y) * texel_size).r ? 0.0 : 1.0;
  return lit / 9.0;
}

void main() {
  vec3 normal = normalize(v_normal);
  if (!gl_FrontFacing) normal = -normal;  // planes are seen from both sides
  vec3 to_light = normalize(u_light.xyz - u_light.w * v_position);
  float n_dot_l = dot(normal, to_light);
  float shadow_visibility = n_dot_l > 0.0 ? visibility(n_dot_l) : 0.0;
#ifdef SHADOW_OUTPUT
  o_color = vec4(vec3(shadow_visibility), 1.0);
#else
  // Umbra's lighting (shaders/scene.frag), so colours compare one to one.
  vec3 to_camera = normalize(u_camera_position - v_position);
  vec3 halfway = normalize(to_light + to_camera);
  float direct = 1.0 - u_ambient;
  vec3 ambient = u_ambient * u_light_color;
  vec3 diffuse = direct * max(n_dot_l, 0.0) * u_light_color;
  vec3 specular = n_dot_l > 0.0 ? direct * 0.25 * pow(max(dot(normal, halfway), 0.0), 64.0) * u_light_color : vec3(0.0);
  vec3 lighting = (ambient + shadow_visibility * (diffuse + specular)) * v_color;
  o_color = vec4(clamp(lighting, 0.0, 1.0), 1.0);
#endif
}
)";

// ---------------------------------------------------------------------------

// Vertex positions are stored relative to the mesh origin: fold the
// translation in while still in double precision.
glm::mat4 relative_to(const glm::dmat4& m, const glm::dvec3& origin) {
  return glm::mat4(m * glm::translate(glm::dmat4(1.0), origin));
}

bool same_objects(const std::vector<SceneObject>& a, const std::vector<SceneObject>& b) {
  return std::equal(a.begin(), a.end(), b.begin(), b.end(), [](const SceneObject& x, const SceneObject& y) {
    return x.type == y.type && x.center == y.center && x.size == y.size && x.radius == y.radius &&
           x.rotation_y_deg == y.rotation_y_deg && x.color == y.color;
  });
}

// The one light box of the frame, from the scene's bounds alone.
//
// Orthographic light: the bounds' corners in the light's view give the box,
// padded by 1% of the bounds' diagonal so that surfaces on the box's faces do
// not fall just outside it by rounding (beyond far counts as lit).
// Perspective light: a 90 degree cone towards light.target. Far is the
// farthest corner's distance; near the distance to the nearest point of the
// bounds, times cos(54.7 deg) = 1/sqrt(3), the widest angle of a 90 degree
// square cone, so nothing at least that far from the light lies before the
// near plane wherever it is in the cone.
glm::dmat4 light_space(const RenderRequest& request, const Aabb& scene_box) {
  Aabb bounds = scene_box;
  if (bounds.empty()) bounds.extend(request.light.target), bounds.extend(request.light.target + glm::dvec3(1.0));
  // The bench scenes' lights orbit; a sun below the horizon (light_at's
  // `direct`) is not modelled by the plain frame, which lights it anyway.
  const glm::dvec3 position = light_at(request.light, request.time).position;
  const glm::dmat4 view = stable_look_at(position, request.light.target, glm::dvec3(0.0, 1.0, 0.0));
  if (request.light.projection == LightProjection::Orthographic) {
    Aabb box;  // in light view space, looking down -z
    for (const glm::dvec3& corner : bounds.corners()) box.extend(glm::dvec3(view * glm::dvec4(corner, 1.0)));
    const double pad = 0.01 * glm::length(bounds.extent());
    return glm::ortho(box.min.x - pad, box.max.x + pad, box.min.y - pad, box.max.y + pad, -box.max.z - pad,
                      -box.min.z + pad) *
           view;
  }
  double far_plane = 0.0;
  for (const glm::dvec3& corner : bounds.corners()) far_plane = std::max(far_plane, glm::distance(position, corner));
  const double nearest = glm::distance(position, glm::clamp(position, bounds.min, bounds.max));
  const double near_plane = std::max(nearest / std::sqrt(3.0), far_plane * 1e-3);
  return glm::perspective(glm::radians(90.0), 1.0, near_plane, far_plane) * view;
}

}  // namespace

PlainFrameRenderer::MainProgram PlainFrameRenderer::build_main_program(bool shadow_output) {
  const std::string fragment =
      std::string("#version 450 core\n") + (shadow_output ? "#define SHADOW_OUTPUT 1\n" : "") + kMainFragmentBody;
  MainProgram m;
  m.program = gl::build_program_from_sources("plain main.vert", kMainVertex,
                                             shadow_output ? "plain main.frag (shadow)" : "plain main.frag",
                                             fragment);
  const auto at = [&](const char* name) { return gl::uniform_location(m.program, name); };
  m.view_projection = at("u_view_projection");
  m.light_space = at("u_light_space");
  m.light_vector = at("u_light");
  m.shadow_map = at("u_shadow_map");
  if (!shadow_output) {
    m.camera_position = at("u_camera_position");
    m.light_color = at("u_light_color");
    m.ambient = at("u_ambient");
  }
  return m;
}

PlainFrameRenderer::PlainFrameRenderer() {
  depth_program_ = gl::build_program_from_sources("plain depth.vert", kDepthVertex, "plain depth.frag", kDepthFragment);
  depth_light_space_ = gl::uniform_location(depth_program_, "u_light_space");
  color_program_ = build_main_program(false);
  shadow_program_ = build_main_program(true);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
}

std::string PlainFrameRenderer::gl_renderer() const {
  return reinterpret_cast<const char*>(glGetString(GL_RENDERER));
}

void PlainFrameRenderer::use_scene(const Scene& scene) {
  if (has_scene_ && same_objects(scene_objects_, scene.objects)) return;
  const Mesh mesh = tessellate(scene);
  vertices_ = gl::create_buffer();
  indices_ = gl::create_buffer();
  vertex_array_ = gl::create_vertex_array();
  // glNamedBufferStorage needs a non-zero size; an empty scene draws nothing.
  glNamedBufferStorage(vertices_.id(), GLsizeiptr(std::max<std::size_t>(1, mesh.vertices.size()) * sizeof(Vertex)),
                       mesh.vertices.empty() ? nullptr : mesh.vertices.data(), 0);
  glNamedBufferStorage(indices_.id(), GLsizeiptr(std::max<std::size_t>(1, mesh.indices.size()) * sizeof(std::uint32_t)),
                       mesh.indices.empty() ? nullptr : mesh.indices.data(), 0);
  const GLuint vao = vertex_array_.id();
  glVertexArrayVertexBuffer(vao, 0, vertices_.id(), 0, sizeof(Vertex));
  glVertexArrayElementBuffer(vao, indices_.id());
  const GLuint offsets[3] = {offsetof(Vertex, position), offsetof(Vertex, normal), offsetof(Vertex, color)};
  for (GLuint attribute = 0; attribute < 3; ++attribute) {
    glEnableVertexArrayAttrib(vao, attribute);
    glVertexArrayAttribFormat(vao, attribute, 3, GL_FLOAT, GL_FALSE, offsets[attribute]);
    glVertexArrayAttribBinding(vao, attribute, 0);
  }
  origin_ = mesh.origin;
  bounds_ = scene_bounds(scene);
  closed_index_count_ = mesh.closed_index_count;
  open_index_count_ = mesh.open_index_count;
  scene_objects_ = scene.objects;
  has_scene_ = true;
}

void PlainFrameRenderer::resize_shadow_map(int size) {
  if (shadow_map_size_ == size) return;
  shadow_map_ = gl::create_texture(GL_TEXTURE_2D);
  const GLuint map = shadow_map_.id();
  glTextureStorage2D(map, 1, GL_DEPTH_COMPONENT32F, size, size);
  glTextureParameteri(map, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTextureParameteri(map, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  // Outside the map: depth 1, the far plane, so nothing there shadows.
  glTextureParameteri(map, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_BORDER);
  glTextureParameteri(map, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_BORDER);
  const float border[4] = {1.0f, 1.0f, 1.0f, 1.0f};
  glTextureParameterfv(map, GL_TEXTURE_BORDER_COLOR, border);
  shadow_framebuffer_ = gl::create_framebuffer();
  glNamedFramebufferTexture(shadow_framebuffer_.id(), GL_DEPTH_ATTACHMENT, map, 0);
  glNamedFramebufferDrawBuffer(shadow_framebuffer_.id(), GL_NONE);
  glNamedFramebufferReadBuffer(shadow_framebuffer_.id(), GL_NONE);
  if (glCheckNamedFramebufferStatus(shadow_framebuffer_.id(), GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw std::runtime_error("plain frame: shadow framebuffer incomplete");
  shadow_map_size_ = size;
}

void PlainFrameRenderer::resize_display(int width, int height) {
  if (width_ == width && height_ == height) return;
  color_ = gl::create_renderbuffer();
  depth_ = gl::create_renderbuffer();
  glNamedRenderbufferStorage(color_.id(), GL_RGBA8, width, height);
  glNamedRenderbufferStorage(depth_.id(), GL_DEPTH_COMPONENT32F, width, height);
  display_framebuffer_ = gl::create_framebuffer();
  glNamedFramebufferRenderbuffer(display_framebuffer_.id(), GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color_.id());
  glNamedFramebufferRenderbuffer(display_framebuffer_.id(), GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_.id());
  if (glCheckNamedFramebufferStatus(display_framebuffer_.id(), GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw std::runtime_error("plain frame: display framebuffer incomplete");
  width_ = width;
  height_ = height;
}

void PlainFrameRenderer::draw_scene(GLenum closed_cull) const {
  glBindVertexArray(vertex_array_.id());
  if (closed_index_count_ > 0) {
    if (closed_cull == GL_NONE) {
      glDisable(GL_CULL_FACE);
    } else {
      glEnable(GL_CULL_FACE);
      glCullFace(closed_cull);
    }
    glDrawElements(GL_TRIANGLES, GLsizei(closed_index_count_), GL_UNSIGNED_INT, nullptr);
  }
  if (open_index_count_ > 0) {
    // A plane is one-sided: culling would drop it from the depth map.
    glDisable(GL_CULL_FACE);
    glDrawElements(GL_TRIANGLES, GLsizei(open_index_count_), GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>(std::size_t(closed_index_count_) * sizeof(std::uint32_t)));
  }
  glDisable(GL_CULL_FACE);
}

Image PlainFrameRenderer::read_pixels(int channels) const {
  Image image;
  image.width = width_;
  image.height = height_;
  image.channels = channels;
  image.pixels.resize(std::size_t(width_) * height_ * channels);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, display_framebuffer_.id());
  glNamedFramebufferReadBuffer(display_framebuffer_.id(), GL_COLOR_ATTACHMENT0);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, width_, height_, channels == 1 ? GL_RED : GL_RGB, GL_UNSIGNED_BYTE, image.pixels.data());
  image.flip_rows();
  return image;
}

PlainFrame PlainFrameRenderer::render(const RenderRequest& request, bool shadow_output) {
  use_scene(request.scene);
  resize_shadow_map(request.shadow.map_size);
  resize_display(request.width, request.height);
  const glm::mat4 light = relative_to(light_space(request, bounds_), origin_);
  PlainFrame frame;

  // Depth pass: closed meshes store their back faces (front faces culled),
  // as the seeds do against peter panning.
  const auto shadow_start = Clock::now();
  glBindFramebuffer(GL_FRAMEBUFFER, shadow_framebuffer_.id());
  glViewport(0, 0, shadow_map_size_, shadow_map_size_);
  glClear(GL_DEPTH_BUFFER_BIT);
  glUseProgram(depth_program_.id());
  glProgramUniformMatrix4fv(depth_program_.id(), depth_light_space_, 1, GL_FALSE, glm::value_ptr(light));
  draw_scene(GL_FRONT);
  glFinish();
  frame.timings.shadow_ms = elapsed_ms(shadow_start);

  // Main pass: back faces of closed meshes culled, as the seeds leave it
  // (glCullFace(GL_BACK) after the depth pass) and as Umbra draws a camera
  // outside every closed mesh (every bench scene's): the time difference is
  // then the shadow technique's alone.
  const auto main_start = Clock::now();
  const MainProgram& m = shadow_output ? shadow_program_ : color_program_;
  const GLuint p = m.program.id();
  const CameraMatrices camera = camera_matrices(request.camera, request.width, request.height);
  glProgramUniformMatrix4fv(p, m.view_projection, 1, GL_FALSE,
                            glm::value_ptr(relative_to(camera.projection * camera.view, origin_)));
  glProgramUniformMatrix4fv(p, m.light_space, 1, GL_FALSE, glm::value_ptr(light));
  const glm::dvec3 light_position = light_at(request.light, request.time).position;
  const glm::dvec3 towards_light = glm::normalize(light_position - request.light.target);
  const glm::vec4 light_vector = request.light.projection == LightProjection::Perspective
                                     ? glm::vec4(glm::vec3(light_position - origin_), 1.0f)
                                     : glm::vec4(glm::vec3(towards_light), 0.0f);
  glProgramUniform4fv(p, m.light_vector, 1, glm::value_ptr(light_vector));
  glProgramUniform1i(p, m.shadow_map, 0);
  if (!shadow_output) {
    const glm::vec3 camera_position(request.camera.position - origin_);
    const glm::vec3 light_color(request.light.color);
    glProgramUniform3fv(p, m.camera_position, 1, glm::value_ptr(camera_position));
    glProgramUniform3fv(p, m.light_color, 1, glm::value_ptr(light_color));
    glProgramUniform1f(p, m.ambient, float(request.light.ambient));
  }
  glBindTextureUnit(0, shadow_map_.id());
  glBindFramebuffer(GL_FRAMEBUFFER, display_framebuffer_.id());
  glViewport(0, 0, width_, height_);
  if (shadow_output)
    glClearColor(1.0f, 1.0f, 1.0f, 1.0f);  // no geometry: nothing blocks the light
  else
    glClearColor(0.11f, 0.12f, 0.14f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glUseProgram(p);
  draw_scene(GL_BACK);
  glFinish();
  frame.timings.main_ms = elapsed_ms(main_start);

  const auto readback_start = Clock::now();
  frame.image = read_pixels(shadow_output ? 1 : 3);
  frame.timings.readback_ms = elapsed_ms(readback_start);
  return frame;
}

}  // namespace umbra
