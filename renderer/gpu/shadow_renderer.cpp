#include "gpu/shadow_renderer.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <stdexcept>

#include "gpu/program.hpp"
#include "core/mesh_instance.hpp"
#include "core/raster_outline.hpp"
#include "plan/frame_plan.hpp"
#include "gpu/shader_interface.hpp"

namespace umbra {

namespace {

using Clock = std::chrono::steady_clock;

double elapsed_ms(Clock::time_point since) {
  return std::chrono::duration<double, std::milli>(Clock::now() - since).count();
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
    if (o.type == SceneObject::Type::Mesh) {
      // The id names the model's geometry (a hash of its file); its length
      // first, so that no two (id, numbers) sequences give the same bytes.
      put(double(o.model_id.size()));
      key += o.model_id;
      for (int i = 0; i < 3; ++i) put(o.rotation_deg[i]), put(o.mesh_scale[i]);
      put(o.mesh_color_override ? 1.0 : 0.0);
      // The pose of an animated model ("" at rest), its length first too.
      put(double(o.pose.size()));
      key += o.pose;
    }
  }
  return key;
}

// Vertex array `vao` reads Vertex records from `vertices` and indices from
// `indices`.
void describe_vertices(GLuint vao, GLuint vertices, GLuint indices) {
  glVertexArrayVertexBuffer(vao, 0, vertices, 0, sizeof(Vertex));
  glVertexArrayElementBuffer(vao, indices);
  for (const VertexAttribute& attribute : kVertexAttributes) {
    glEnableVertexArrayAttrib(vao, GLuint(attribute.location));
    glVertexArrayAttribFormat(vao, GLuint(attribute.location), 3, GL_FLOAT, GL_FALSE, GLuint(attribute.offset));
    glVertexArrayAttribBinding(vao, GLuint(attribute.location), 0);
  }
}

// Face culling for a DrawRange: closed meshes as the plan says; a plane or
// an open model has one side, and culling it could drop it entirely.
void set_cull(CullMode cull) {
  if (cull == CullMode::None) {
    glDisable(GL_CULL_FACE);
  } else {
    glEnable(GL_CULL_FACE);
    glCullFace(cull == CullMode::Front ? GL_FRONT : GL_BACK);
  }
}

void draw_elements(std::size_t first, std::size_t count) {
  if (count > 0)
    glDrawElements(GL_TRIANGLES, GLsizei(count), GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>(first * sizeof(std::uint32_t)));
}

// GL's rows (bottom first) turned to the images' (row 0 at the top), as
// Image::flip_rows does for pixels of any width.
template <class T>
void flip_rows(std::vector<T>& values, int width, int height) {
  for (int y = 0; y < height / 2; ++y)
    std::swap_ranges(values.begin() + std::ptrdiff_t(y) * width, values.begin() + std::ptrdiff_t(y + 1) * width,
                     values.begin() + std::ptrdiff_t(height - 1 - y) * width);
}

// A texture array of `layers` layers of size^2 texels, read texel by texel.
gl::Texture texel_array(GLenum format, int size, int layers) {
  gl::Texture texture = gl::create_texture(GL_TEXTURE_2D_ARRAY);
  glTextureStorage3D(texture.id(), 1, format, size, size, layers);
  // Nearest: an integer texture with any other filter is incomplete.
  glTextureParameteri(texture.id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTextureParameteri(texture.id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glTextureParameteri(texture.id(), GL_TEXTURE_COMPARE_MODE, GL_NONE);
  return texture;
}

// The texels of a layer's certified maps (all at certified_map_size) that
// the certificate reads: the whole layer, or its casters' rectangle scaled
// to them and grown by a texel.
struct TexelBox {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};
TexelBox certified_read_box(const ShadowLayerDraw& layer, int layer_size) {
  const int side = certified_map_size(layer_size);
  if (layer.clear_whole) return {0, 0, side, side};
  const double scale = double(side) / double(layer_size);
  return {std::max(0, int(std::floor(layer.x0 * scale)) - 1), std::max(0, int(std::floor(layer.y0 * scale)) - 1),
          std::min(side, int(std::ceil(layer.x1 * scale)) + 1), std::min(side, int(std::ceil(layer.y1 * scale)) + 1)};
}

// A buffer texture of `format` holding `bytes` from `data`.
void make_buffer_texture(gl::Buffer& buffer, gl::Texture& texture, GLenum format, const void* data, std::size_t bytes) {
  buffer = gl::create_buffer();
  glNamedBufferStorage(buffer.id(), GLsizeiptr(std::max<std::size_t>(bytes, 16)), nullptr, GL_DYNAMIC_STORAGE_BIT);
  if (bytes > 0) glNamedBufferSubData(buffer.id(), 0, GLsizeiptr(bytes), data);
  texture = gl::create_texture(GL_TEXTURE_BUFFER);
  glTextureBuffer(texture.id(), format, buffer.id());
}

}  // namespace

void ShadowRenderer::draw_indices(std::size_t first, std::size_t count) {
  if (count == 0) return;
  if (set_triangle_base_) glUniform1i(kUniformLocationTriangleBase, GLint(first / 3));
  draw_elements(first, count);
}

ShadowRenderer::ShadowRenderer(std::uint64_t scene_cache_bytes) : scene_cache_bytes_(scene_cache_bytes) {
  shadow_.program = gl::build_program("shadow_depth.vert", "shadow_depth.frag", glsl_prelude(""));
  shadow_.layer = kUniformLocationLayer;
  // Built now, so that a GLSL error shows at start-up: the default frame's
  // variant (the others are built when first asked for).
  RenderRequest defaults;
  defaults.scene.objects.push_back({});
  display_.programs.get(variant_defines(display_variant(defaults, plan_shadow(defaults))));
  frame_block_ = gl::create_buffer();
  glNamedBufferStorage(frame_block_.id(), sizeof(FrameBlock), nullptr, GL_DYNAMIC_STORAGE_BIT);
  glBindBufferBase(GL_UNIFORM_BUFFER, kUniformBufferFrameBlock, frame_block_.id());
  empty_vertex_array_ = gl::create_vertex_array();
  display_.cells_vertex_array = gl::create_vertex_array();
  display_.cell_vertices = gl::create_buffer();
  display_.cell_indices = gl::create_buffer();
  describe_vertices(display_.cells_vertex_array.id(), display_.cell_vertices.id(), display_.cell_indices.id());
  unbind_depth_ = gl::create_texture(GL_TEXTURE_2D);
  glTextureStorage2D(unbind_depth_.id(), 1, GL_DEPTH_COMPONENT32F, 1, 1);
  unbind_framebuffer_ = gl::create_framebuffer();
  glNamedFramebufferTexture(unbind_framebuffer_.id(), GL_DEPTH_ATTACHMENT, unbind_depth_.id(), 0);
  glNamedFramebufferDrawBuffer(unbind_framebuffer_.id(), GL_NONE);
  glNamedFramebufferReadBuffer(unbind_framebuffer_.id(), GL_NONE);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  certified_passes_on_cpu_ = gl_renderer().find("llvmpipe") != std::string::npos;
  pixels_listed_on_gpu_ = !certified_passes_on_cpu_;
}

std::string ShadowRenderer::gl_renderer() const {
  return reinterpret_cast<const char*>(glGetString(GL_RENDERER));
}

std::string ShadowRenderer::gl_version() const {
  return reinterpret_cast<const char*>(glGetString(GL_VERSION));
}

bool ShadowRenderer::use_scene(const Scene& scene) {
  std::string key = scene_key(scene);
  if (scenes_.find(key)) return false;
  Mesh mesh = tessellate(scene);
  SceneGeometry g;
  g.vertices = gl::create_buffer();
  g.indices = gl::create_buffer();
  g.vertex_array = gl::create_vertex_array();
  // glNamedBufferStorage needs a non-zero size; an empty scene draws nothing.
  const std::size_t vertex_count = std::max<std::size_t>(1, mesh.vertices.size());
  const std::size_t index_count = std::max<std::size_t>(1, mesh.indices.size());
  glNamedBufferStorage(g.vertices.id(), GLsizeiptr(vertex_count * sizeof(Vertex)),
                       mesh.vertices.empty() ? nullptr : mesh.vertices.data(), 0);
  glNamedBufferStorage(g.indices.id(), GLsizeiptr(index_count * sizeof(std::uint32_t)),
                       mesh.indices.empty() ? nullptr : mesh.indices.data(), 0);
  describe_vertices(g.vertex_array.id(), g.vertices.id(), g.indices.id());
  mesh.vertices.clear();
  mesh.vertices.shrink_to_fit();
  mesh.indices.clear();
  mesh.indices.shrink_to_fit();
  g.mesh = std::move(mesh);
  for (const SceneObject& o : scene.objects)
    g.deep_layers.push_back(o.type == SceneObject::Type::Mesh ? mesh_deepest_layers(o) : 0.0);
  std::uint64_t bytes = std::uint64_t(vertex_count) * sizeof(Vertex) + std::uint64_t(index_count) * sizeof(std::uint32_t);
  // Where filter "exact"'s passes are drawn on the CPU, what a certified
  // frame keeps of the scene there (use_certificate_buffers): positions,
  // indices, each triangle's object, its paired edges (about 1.5 a
  // triangle). Counted whether or not such a frame comes.
  if (certified_passes_on_cpu_ && index_count / 3 <= kMostConservativeTriangles)
    bytes += std::uint64_t(vertex_count) * sizeof(glm::vec3) + std::uint64_t(index_count) * sizeof(std::uint32_t) +
             std::uint64_t(index_count / 3) * (sizeof(std::uint32_t) + 2 * sizeof(SliverEdges::Edge));
  scenes_.insert(std::move(key), std::move(g), bytes);
  evict_scenes_to(scene_cache_bytes_, 1);
  return true;
}

void ShadowRenderer::evict_scenes_to(std::uint64_t max_bytes, std::size_t keep) {
  const std::uint64_t before = scenes_.bytes();
  scenes_.evict_to(max_bytes, kCachedScenes, keep);
  released_gl_bytes_ += before - scenes_.bytes();
}

std::uint64_t ShadowRenderer::shadow_map_bytes() const {
  return std::uint64_t(shadow_.size) * std::uint64_t(shadow_.size) * std::uint64_t(shadow_.layers) * sizeof(float);
}

std::uint64_t ShadowRenderer::display_bytes() const {
  // RGBA8, and 32F depth with an 8-bit stencil (llvmpipe stores the pair in
  // 8 bytes); a certified frame's R32UI and RGBA8 beside them.
  const std::uint64_t certified = display_.certificate ? 4 + 4 + 1 : 0;
  // Where the GPU lists the pixels to ray cast: two bytes of marks and a
  // ListedPixel per pixel.
  const std::uint64_t listed = display_.cast_list ? 2 + sizeof(PixelCertificates::ListedPixel) : 0;
  return std::uint64_t(display_.width) * std::uint64_t(display_.height) * (4 + 8 + certified + listed);
}

std::uint64_t ShadowRenderer::depth_preview_bytes() const {
  return std::uint64_t(preview_.size) * std::uint64_t(preview_.size) * std::uint64_t(preview_.bits / 8);
}

std::uint64_t ShadowRenderer::certify_bytes() const {
  if (certify_.size == 0) return 0;
  // The centre map's depth and triangle, the nearest map's depth and
  // owner, the others' depth, the cover map: six 32-bit maps of the
  // coarse size.
  const std::uint64_t coarse = std::uint64_t(certified_map_size(certify_.size)) * std::uint64_t(certified_map_size(certify_.size));
  return 6 * coarse * std::uint64_t(certify_.layers) * 4;
}

std::uint64_t ShadowRenderer::cached_bytes() const {
  return scenes_.bytes() + shadow_map_bytes() + display_bytes() + depth_preview_bytes() + certify_bytes();
}

std::uint64_t ShadowRenderer::bytes_reused_by(const RenderRequest& request) const {
  std::uint64_t bytes = 0;
  const ShadowPlan light = plan_shadow(request);
  const bool needs_map = needs_shadow_map(request, light);
  // Only what the frame uses of a map with more layers than it needs.
  if (needs_map && shadow_.size == light.layer_size && shadow_.layers >= int(light.views.size()))
    bytes += std::uint64_t(light.layer_size) * std::uint64_t(light.layer_size) * light.views.size() * sizeof(float);
  if (request.output != Output::Depth && display_.width == request.width && display_.height == request.height)
    bytes += display_bytes();
  return bytes;
}

std::uint64_t ShadowRenderer::release_cached(std::uint64_t max_bytes) {
  if (cached_bytes() <= max_bytes) return cached_bytes();
  const std::uint64_t others = shadow_map_bytes() + display_bytes() + depth_preview_bytes();
  evict_scenes_to(max_bytes > others ? max_bytes - others : 0, 1);
  if (cached_bytes() > max_bytes) {
    released_gl_bytes_ += depth_preview_bytes();
    preview_.framebuffer.reset();
    preview_.grey.reset();
    preview_.size = preview_.bits = 0;
  }
  if (cached_bytes() > max_bytes) {
    released_gl_bytes_ += shadow_map_bytes();
    shadow_.framebuffer.reset();
    shadow_.depth_map.reset();
    shadow_.size = shadow_.layers = 0;
    shadow_.kept = {};
    released_gl_bytes_ += certify_bytes();
    certify_.framebuffer.reset();
    certify_.centre_depth.reset();
    certify_.centre_triangle.reset();
    certify_.nearest_depth.reset();
    certify_.nearest_owner.reset();
    certify_.others_depth.reset();
    certify_.cover_depth.reset();
    certify_.size = certify_.layers = 0;
    certify_.kept = {};
  }
  if (cached_bytes() > max_bytes) {
    released_gl_bytes_ += display_bytes();
    display_.framebuffer.reset();
    display_.color.reset();
    display_.depth.reset();
    drop_certificate_targets();
    display_.width = display_.height = 0;
  }
  evict_scenes_to(max_bytes, 0);
  unbind_released();
  return cached_bytes();
}

void ShadowRenderer::unbind_released() {
  glBindTextureUnit(kTextureUnitShadowMap, 0);
  glBindFramebuffer(GL_FRAMEBUFFER, unbind_framebuffer_.id());
  glViewport(0, 0, 1, 1);
  glUseProgram(shadow_.program.id());
  glProgramUniform1i(shadow_.program.id(), shadow_.layer, 0);
  glBindVertexArray(empty_vertex_array_.id());
  glDrawArrays(GL_TRIANGLES, 0, 3);
  // Deleted objects are freed once the GL has finished with them.
  glFinish();
}

void ShadowRenderer::resize_shadow_map(int size, int layers) {
  // Kept while it is big enough: a light that needs fewer views uses the
  // first layers.
  if (shadow_.size == size && shadow_.layers >= layers) return;
  map_allocated_ = true;
  released_gl_bytes_ += shadow_map_bytes();
  shadow_.kept.holds_plan = false;
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
  released_gl_bytes_ += display_bytes();
  // A certified frame attaches its own targets of the new size.
  drop_certificate_targets();
  display_.color = gl::create_renderbuffer();
  display_.depth = gl::create_renderbuffer();
  glNamedRenderbufferStorage(display_.color.id(), GL_RGBA8, width, height);
  // The stencil marks the umbras drawn dark (run_display_pass).
  glNamedRenderbufferStorage(display_.depth.id(), GL_DEPTH32F_STENCIL8, width, height);
  display_.framebuffer = gl::create_framebuffer();
  glNamedFramebufferRenderbuffer(display_.framebuffer.id(), GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, display_.color.id());
  glNamedFramebufferRenderbuffer(display_.framebuffer.id(), GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER,
                                 display_.depth.id());
  if (glCheckNamedFramebufferStatus(display_.framebuffer.id(), GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw std::runtime_error("display framebuffer incomplete");
  display_.width = width;
  display_.height = height;
}

void ShadowRenderer::resize_certify_maps(int size, int layers) {
  if (certify_.size == size && certify_.layers >= layers) return;
  released_gl_bytes_ += certify_bytes();
  certify_.kept.holds_plan = false;
  const int coarse = certified_map_size(size);
  certify_.centre_depth = texel_array(GL_DEPTH_COMPONENT32F, coarse, layers);
  certify_.centre_triangle = texel_array(GL_R32UI, coarse, layers);
  certify_.nearest_depth = texel_array(GL_DEPTH_COMPONENT32F, coarse, layers);
  certify_.nearest_owner = texel_array(GL_R32UI, coarse, layers);
  certify_.others_depth = texel_array(GL_DEPTH_COMPONENT32F, coarse, layers);
  certify_.cover_depth = texel_array(GL_R32F, coarse, layers);
  certify_.framebuffer = gl::create_framebuffer();
  certify_.size = size;
  certify_.layers = layers;
}

void ShadowRenderer::drop_certificate_targets() {
  display_.certificate.reset();
  display_.unlit.reset();
  for (gl::Texture& marks : display_.cast_marks) marks.reset();
  display_.cast_list.reset();
  display_.slivers.reset();
  display_.sliver_framebuffer.reset();
}

void ShadowRenderer::add_certificate_targets() {
  if (display_.certificate) return;
  display_.certificate = gl::create_texture(GL_TEXTURE_2D);
  glTextureStorage2D(display_.certificate.id(), 1, GL_R32UI, display_.width, display_.height);
  // Nearest: an integer texture with any other filter is incomplete, and
  // the sliver pass's texelFetch of it would read 0 (no object) everywhere.
  glTextureParameteri(display_.certificate.id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTextureParameteri(display_.certificate.id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  // A texture, which cast_list.comp reads where the GPU lists the pixels.
  display_.unlit = gl::create_texture(GL_TEXTURE_2D);
  glTextureStorage2D(display_.unlit.id(), 1, GL_RGBA8, display_.width, display_.height);
  // One level, read by texelFetch: with a mipmapped filter the texture
  // would be incomplete, and read as 0 (so would an integer texture with a
  // linear one).
  glTextureParameteri(display_.unlit.id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTextureParameteri(display_.unlit.id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glNamedFramebufferTexture(display_.framebuffer.id(), GL_COLOR_ATTACHMENT0 + kFragOutputCertificate,
                            display_.certificate.id(), 0);
  glNamedFramebufferTexture(display_.framebuffer.id(), GL_COLOR_ATTACHMENT0 + kFragOutputUnlit, display_.unlit.id(), 0);
  if (glCheckNamedFramebufferStatus(display_.framebuffer.id(), GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw std::runtime_error("display framebuffer with certificates incomplete");
  display_.slivers = gl::create_texture(GL_TEXTURE_2D);
  glTextureStorage2D(display_.slivers.id(), 1, GL_R8UI, display_.width, display_.height);
  glTextureParameteri(display_.slivers.id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTextureParameteri(display_.slivers.id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  display_.sliver_framebuffer = gl::create_framebuffer();
  glNamedFramebufferTexture(display_.sliver_framebuffer.id(), GL_COLOR_ATTACHMENT0, display_.slivers.id(), 0);
  glNamedFramebufferRenderbuffer(display_.sliver_framebuffer.id(), GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER,
                                 display_.depth.id());
  if (glCheckNamedFramebufferStatus(display_.sliver_framebuffer.id(), GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw std::runtime_error("sliver framebuffer incomplete");
}

void ShadowRenderer::run_sliver_pass(const DisplayPassPlan& pass) {
  if (!display_.sliver_program)
    display_.sliver_program = gl::build_program("sliver.vert", "sliver.geom", "sliver.frag", glsl_prelude(""));
  glBindFramebuffer(GL_FRAMEBUFFER, display_.sliver_framebuffer.id());
  const GLuint none = 0;
  glClearBufferuiv(GL_COLOR, 0, &none);
  // Against the main pass's depth (reversed: nearer is greater), not
  // written: only what reaches in front of (or to) the drawn surface marks.
  glDepthFunc(GL_GEQUAL);
  glDepthMask(GL_FALSE);
  glDisable(GL_STENCIL_TEST);
  glDisable(GL_CLIP_DISTANCE0);
  glBindTextureUnit(kTextureUnitCertificates, display_.certificate.id());
  glUseProgram(display_.sliver_program->id());
  glProgramUniform1i(display_.sliver_program->id(), kUniformLocationCullBack, pass.sliver_skips_closed_back ? 1 : 0);
  // Its triangles are the scene's: the last display step may have been a
  // proved part's, which draws without a triangle base.
  set_triangle_base_ = true;
  draw_scene(pass.sliver_draws);
  glBindTextureUnit(kTextureUnitCertificates, 0);
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_GREATER);
}

void ShadowRenderer::use_certificate_buffers(const Scene& scene_objects) {
  SceneGeometry& g = scene();
  if (!g.triangle_objects) {
    const Mesh& mesh = g.mesh;
    std::vector<std::uint32_t>& objects = g.triangle_object_ids;
    for (const ObjectRange& r : mesh.object_ranges) {
      const std::size_t first = r.first_index / 3, count = r.index_count / 3;
      if (objects.size() < first + count) objects.resize(first + count, 0);
      std::fill(objects.begin() + std::ptrdiff_t(first), objects.begin() + std::ptrdiff_t(first + count),
                std::uint32_t(r.object));
    }
    // Beside each triangle's object, its owner where it turns to the light.
    g.facing_owners = light_facing_owners(scene_objects, mesh);
    g.facing_owners.resize(objects.size(), 0);
    std::vector<std::uint32_t> ids(2 * objects.size());
    for (std::size_t t = 0; t < objects.size(); ++t) {
      ids[2 * t] = objects[t];
      ids[2 * t + 1] = g.facing_owners[t];
    }
    make_buffer_texture(g.triangle_objects_buffer, g.triangle_objects, GL_RG32UI, ids.data(),
                        ids.size() * sizeof(std::uint32_t));
    const std::vector<glm::vec4> facts = object_facts(scene_objects, mesh.origin);
    make_buffer_texture(g.object_facts_buffer, g.object_facts, GL_RGBA32F, facts.data(),
                        facts.size() * sizeof(glm::vec4));
    g.conservative_objects = conservative_objects(scene_objects, mesh.origin);
  }
  if (certified_passes_on_cpu_ && g.positions.empty() && g.triangle_object_ids.size() <= kMostConservativeTriangles) {
    // The scene's CPU copy dropped its vertices once uploaded: read back
    // (a copy, on llvmpipe) what the maps are drawn from.
    const auto buffer_bytes = [](GLuint buffer) {
      GLint64 bytes = 0;
      glGetNamedBufferParameteri64v(buffer, GL_BUFFER_SIZE, &bytes);
      return std::size_t(bytes);
    };
    std::vector<Vertex> vertices(buffer_bytes(g.vertices.id()) / sizeof(Vertex));
    glGetNamedBufferSubData(g.vertices.id(), 0, GLsizeiptr(vertices.size() * sizeof(Vertex)), vertices.data());
    g.positions.resize(vertices.size());
    std::vector<glm::vec3> normals(vertices.size());
    for (std::size_t i = 0; i < vertices.size(); ++i) {
      g.positions[i] = glm::vec3(vertices[i].position[0], vertices[i].position[1], vertices[i].position[2]);
      normals[i] = glm::vec3(vertices[i].normal[0], vertices[i].normal[1], vertices[i].normal[2]);
    }
    g.position_indices.resize(buffer_bytes(g.indices.id()) / sizeof(std::uint32_t));
    glGetNamedBufferSubData(g.indices.id(), 0, GLsizeiptr(g.position_indices.size() * sizeof(std::uint32_t)),
                            g.position_indices.data());
    std::vector<bool> models;
    for (const ConservativeObject& o : g.conservative_objects) models.push_back(o.model);
    g.sliver_edges.emplace(g.positions, g.position_indices, g.triangle_object_ids, models, &normals);
  }
}

bool ShadowRenderer::upload_conservative_maps(const FramePlan& plan, const FrameBlock& block,
                                              const ShadowLayerDraw& layer) {
  const SceneGeometry& g = scene();
  const ShadowView& v = plan.light.views.at(std::size_t(layer.layer));
  ConservativeView view;
  view.view = block.light_view[layer.layer];
  view.projection = block.light_projection[layer.layer];
  view.perspective = plan.light.perspective;
  view.near_plane = v.near_plane;
  view.far_plane = v.far_plane;
  view.texel_size = v.texel_size;
  view.tan_half = v.tan_half;
  view.layer_size = plan.light.layer_size;
  view.size = certified_map_size(plan.light.layer_size);
  view.cull_closed_back = plan.shadow.cull_closed_back;
  std::size_t triangles = 0;
  for (const DrawRange& d : layer.draws) triangles += d.count / 3;
  // A scene of more triangles keeps no copy of them here (use_certificate_buffers).
  if (triangles > kMostConservativeTriangles || (triangles > 0 && g.positions.empty())) return false;
  const ConservativeMaps maps(g.positions, g.position_indices, g.conservative_objects, g.triangle_object_ids, layer.draws, view,
                              g.facing_owners, g.sliver_edges ? &*g.sliver_edges : nullptr);
  const auto [x0, y0, x1, y1] = certified_read_box(layer, plan.light.layer_size);
  const GLint at = GLint(layer.layer);
  // Drawn where a triangle may reach; far, with no owner, in the rest of
  // the rectangle (up to four strips around it).
  int tx0 = 0, ty0 = 0, tx1 = 0, ty1 = 0;
  maps.touched(tx0, ty0, tx1, ty1);
  tx0 = std::clamp(tx0, x0, x1);
  tx1 = std::clamp(tx1, tx0, x1);
  ty0 = std::clamp(ty0, y0, y1);
  ty1 = std::clamp(ty1, ty0, y1);
  const auto clear = [&](int cx0, int cy0, int cx1, int cy1) {
    if (cx1 <= cx0 || cy1 <= cy0) return;
    const GLuint no_owner = kNoOwner;
    const float far = 1.0f;
    for (const GLuint depth : {certify_.nearest_depth.id(), certify_.others_depth.id()})
      glClearTexSubImage(depth, 0, cx0, cy0, at, cx1 - cx0, cy1 - cy0, 1, GL_DEPTH_COMPONENT, GL_FLOAT, &far);
    glClearTexSubImage(certify_.nearest_owner.id(), 0, cx0, cy0, at, cx1 - cx0, cy1 - cy0, 1, GL_RED_INTEGER,
                       GL_UNSIGNED_INT, &no_owner);
    glClearTexSubImage(certify_.cover_depth.id(), 0, cx0, cy0, at, cx1 - cx0, cy1 - cy0, 1, GL_RED, GL_FLOAT, &far);
  };
  clear(x0, y0, x1, ty0);    // below
  clear(x0, ty1, x1, y1);    // above
  clear(x0, ty0, tx0, ty1);  // left
  clear(tx1, ty0, x1, ty1);  // right
  draw_conservative_bands(maps, tx0, ty0, tx1, ty1, kConservativeBandBytes, [&](const ConservativeBand& band) {
    glTextureSubImage3D(certify_.nearest_depth.id(), 0, band.x0, band.y0, at, band.width(), band.height(), 1,
                        GL_DEPTH_COMPONENT, GL_FLOAT, band.nearest_depth.data());
    glTextureSubImage3D(certify_.nearest_owner.id(), 0, band.x0, band.y0, at, band.width(), band.height(), 1,
                        GL_RED_INTEGER, GL_UNSIGNED_INT, band.nearest_owner.data());
    // One owner in the band (a layer a single object reaches): a clear
    // writes the far depths faster than a copy of them.
    const float far = 1.0f;
    if (band.others_all_far())
      glClearTexSubImage(certify_.others_depth.id(), 0, band.x0, band.y0, at, band.width(), band.height(), 1,
                         GL_DEPTH_COMPONENT, GL_FLOAT, &far);
    else
      glTextureSubImage3D(certify_.others_depth.id(), 0, band.x0, band.y0, at, band.width(), band.height(), 1,
                          GL_DEPTH_COMPONENT, GL_FLOAT, band.others_depth.data());
    glTextureSubImage3D(certify_.cover_depth.id(), 0, band.x0, band.y0, at, band.width(), band.height(), 1, GL_RED,
                        GL_FLOAT, band.cover_depth.data());
  });
  return true;
}

void ShadowRenderer::run_certified_shadow_pass(const FramePlan& plan, const FrameBlock& block) {
  const ShadowPlan& light = plan.light;
  const int size = light.layer_size;
  // Every map is the certify_ maps' (the centre map's depth too): the
  // shadow map is neither drawn nor read, and keeps what it holds.
  resize_certify_maps(size, int(light.views.size()));
  // Until the last layer is drawn, the maps hold no plan (a frame cut short).
  certify_.kept.holds_plan = false;
  begin_pass(plan.shadow.object_draw_ms, double(size), double(size), kShadowChunkFragments);
  const GLuint framebuffer = certify_.framebuffer.id();
  glBindFramebuffer(GL_FRAMEBUFFER, framebuffer);
  glClearDepth(1.0);
  glDisable(GL_CLIP_DISTANCE0);
  glBindTextureUnit(kTextureUnitTriangleObjects, scene().triangle_objects.id());
  glBindTextureUnit(kTextureUnitObjectFacts, scene().object_facts.id());
  const bool cull = plan.shadow.cull_closed_back;
  const GLuint centre = certify_.centre.get(variant_defines(CertifyPass::Centre, light.perspective, cull)).id();
  const GLuint nearest = certify_.conservative.get(variant_defines(CertifyPass::Nearest, light.perspective, cull)).id();
  const GLuint others = certify_.conservative.get(variant_defines(CertifyPass::Others, light.perspective, cull)).id();
  const int coarse = certified_map_size(size);
  set_triangle_base_ = true;
  // One layer at a time, three maps each: what a draw's program writes
  // goes to the layer's depth and (but for the last) its colour.
  const auto attach = [&](GLuint depth, GLuint color, GLint layer) {
    glNamedFramebufferTextureLayer(framebuffer, GL_DEPTH_ATTACHMENT, depth, 0, layer);
    if (color != 0) {
      glNamedFramebufferTextureLayer(framebuffer, GL_COLOR_ATTACHMENT0, color, 0, layer);
      glNamedFramebufferDrawBuffer(framebuffer, GL_COLOR_ATTACHMENT0);
    } else {
      glNamedFramebufferTextureLayer(framebuffer, GL_COLOR_ATTACHMENT0, 0, 0, 0);
      glNamedFramebufferDrawBuffer(framebuffer, GL_NONE);
    }
    if (glCheckNamedFramebufferStatus(framebuffer, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw std::runtime_error("certified shadow framebuffer incomplete");
  };
  for (const ShadowLayerDraw& layer : plan.shadow.layers) {
    const GLint at = GLint(layer.layer);
    const GLuint none = 0, no_owner = 0xFFFFFFFFu;
    const float far = 1.0f;
    // Only what the certificate reads of the layer.
    const TexelBox read = certified_read_box(layer, size);
    const auto clear = [&](GLuint texture, GLenum format, GLenum type, const void* value) {
      glClearTexSubImage(texture, 0, read.x0, read.y0, at, read.x1 - read.x0, read.y1 - read.y0, 1, format, type, value);
    };
    attach(certify_.centre_depth.id(), certify_.centre_triangle.id(), at);
    glViewport(0, 0, coarse, coarse);
    clear(certify_.centre_depth.id(), GL_DEPTH_COMPONENT, GL_FLOAT, &far);
    clear(certify_.centre_triangle.id(), GL_RED_INTEGER, GL_UNSIGNED_INT, &none);
    glUseProgram(centre);
    glProgramUniform1i(centre, kUniformLocationLayer, at);
    draw_scene(layer.draws);
    if (layer.proves_nothing) {
      // Depth 0, owned by no point: no proof of light; the cover map far.
      const float at_light = 0.0f;
      const GLuint every_owner = kEveryOwner;
      clear(certify_.nearest_depth.id(), GL_DEPTH_COMPONENT, GL_FLOAT, &at_light);
      clear(certify_.others_depth.id(), GL_DEPTH_COMPONENT, GL_FLOAT, &at_light);
      clear(certify_.nearest_owner.id(), GL_RED_INTEGER, GL_UNSIGNED_INT, &every_owner);
      clear(certify_.cover_depth.id(), GL_RED, GL_FLOAT, &far);
      continue;
    }
    if (certified_passes_on_cpu_ && upload_conservative_maps(plan, block, layer)) continue;
    attach(certify_.nearest_depth.id(), certify_.nearest_owner.id(), at);
    glViewport(0, 0, coarse, coarse);
    clear(certify_.nearest_depth.id(), GL_DEPTH_COMPONENT, GL_FLOAT, &far);
    clear(certify_.nearest_owner.id(), GL_RED_INTEGER, GL_UNSIGNED_INT, &no_owner);
    glUseProgram(nearest);
    glProgramUniform1i(nearest, kUniformLocationLayer, at);
    draw_scene(layer.draws);
    attach(certify_.others_depth.id(), 0, at);
    clear(certify_.others_depth.id(), GL_DEPTH_COMPONENT, GL_FLOAT, &far);
    glBindTextureUnit(kTextureUnitCertifyNearestOwner, certify_.nearest_owner.id());
    glUseProgram(others);
    glProgramUniform1i(others, kUniformLocationLayer, at);
    draw_scene(layer.draws);
    glBindTextureUnit(kTextureUnitCertifyNearestOwner, 0);
    // The shaders draw no cover map (it proves nothing, far).
    clear(certify_.cover_depth.id(), GL_RED, GL_FLOAT, &far);
  }
  set_triangle_base_ = false;
  certify_.kept = plan.shadow.certified_kept_after;
}

void ShadowRenderer::resize_depth_preview(int size, int bits) {
  if (preview_.size == size && preview_.bits == bits) return;
  released_gl_bytes_ += depth_preview_bytes();
  preview_.grey = gl::create_texture(GL_TEXTURE_2D);
  // The shader's float is stored as UNORM: R8 keeps the 8-bit preview byte for byte what it was, R16 gives the 16-bit
  // one 65536 levels of the same mapping (the map itself is 32F, so they are real).
  glTextureStorage2D(preview_.grey.id(), 1, bits == 16 ? GL_R16 : GL_R8, size, size);
  preview_.framebuffer = gl::create_framebuffer();
  glNamedFramebufferTexture(preview_.framebuffer.id(), GL_COLOR_ATTACHMENT0, preview_.grey.id(), 0);
  if (glCheckNamedFramebufferStatus(preview_.framebuffer.id(), GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw std::runtime_error("depth preview framebuffer incomplete");
  preview_.size = size;
  preview_.bits = bits;
}

void ShadowRenderer::draw_scene(const std::vector<DrawRange>& draws) {
  glBindVertexArray(scene().vertex_array.id());
  for (const DrawRange& draw : draws) {
    set_cull(draw.cull);
    draw_scene_indices(draw.first, draw.count);
  }
  glDisable(GL_CULL_FACE);
}

void ShadowRenderer::begin_pass(const std::vector<double>& object_draw_ms, double width, double height,
                                double fragments_per_chunk) {
  pass_pixels_ = width * height;
  ms_per_fragment_ = kChunkMs / fragments_per_chunk;
  chunk_ms_ = kChunkMs;
  pass_draw_ms_ = object_draw_ms;
}

void ShadowRenderer::draw_scene_indices(std::size_t first, std::size_t count) {
  const SceneGeometry& g = scene();
  const std::vector<ObjectRange>& ranges = g.mesh.object_ranges;  // in index order
  const std::size_t end = first + count;
  std::size_t pending = first;  // drawn up to here
  auto it = std::lower_bound(ranges.begin(), ranges.end(), first, [](const ObjectRange& r, std::size_t i) {
    return std::size_t(r.first_index) + r.index_count <= i;
  });
  for (; it != ranges.end() && it->first_index < end; ++it) {
    const double layers = g.deep_layers[it->object];
    const double draw_ms = it->object < pass_draw_ms_.size() ? pass_draw_ms_[it->object] : 0.0;
    const bool deep = layers > kDeepLayers, long_draw = draw_ms > kLongDrawMs;
    if (!(deep || long_draw) || it->index_count < 3) continue;
    const std::size_t from = std::max<std::size_t>(it->first_index, first);
    const std::size_t to = std::min<std::size_t>(std::size_t(it->first_index) + it->index_count, end);
    draw_indices(pending, from - pending);
    // A deep mesh as if it filled the view, each of its triangles equally
    // deep: never more fragments a triangle than it can have; and each
    // triangle's share of the estimated draw.
    const double triangles = double(it->index_count / 3);
    const double ms_per_triangle =
        (deep ? layers * pass_pixels_ / triangles * ms_per_fragment_ : 0.0) + draw_ms / triangles;
    for (std::size_t at = from; at < to;) {
      const double chunk_triangles = std::clamp(chunk_ms_ / ms_per_triangle, 1.0, triangles);
      const std::size_t n = std::min(3 * std::size_t(chunk_triangles), to - at);
      const auto start = Clock::now();
      draw_indices(at, n);
      wait_for_chunk(start);
      at += n;
    }
    pending = to;
  }
  draw_indices(pending, end - pending);
}

void ShadowRenderer::wait_for_chunk(Clock::time_point chunk_start) {
  // llvmpipe bins draws on this thread and rasterises them when flushed:
  // only a fence shows how far it has got.
  const GLsync fence = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
  GLenum status = GL_TIMEOUT_EXPIRED;
  while (status == GL_TIMEOUT_EXPIRED) status = glClientWaitSync(fence, GL_SYNC_FLUSH_COMMANDS_BIT, 100'000'000);
  glDeleteSync(fence);
  // The next chunk sized to take about kChunkMs: shrunk at once if this
  // one took longer, grown at most twofold if it was quicker.
  const double ms = std::max(elapsed_ms(chunk_start), 1e-3);
  chunk_ms_ *= std::min(2.0, kChunkMs / ms);
  check_watch("a mesh's chunked draws");
}

void ShadowRenderer::check_watch(const char* where) const {
  if (Clock::now() > watch_.until) throw FrameCutShort(std::string("stopped during ") + where);
}

void ShadowRenderer::abandon_frame() {
  glFinish();
  set_triangle_base_ = false;
  shadow_.kept.holds_plan = false;
  certify_.kept.holds_plan = false;
  // What run_display_pass and run_depth_preview set, as the constructor
  // and the end of each pass leave it.
  glClipControl(GL_LOWER_LEFT, GL_NEGATIVE_ONE_TO_ONE);
  glClearDepth(1.0);
  glDepthFunc(GL_LESS);
  glEnable(GL_DEPTH_TEST);
  glDepthMask(GL_TRUE);
  glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  glDisable(GL_STENCIL_TEST);
  glStencilFunc(GL_ALWAYS, 0, 0xFF);
  glStencilOp(GL_KEEP, GL_KEEP, GL_KEEP);
  glDisable(GL_CLIP_DISTANCE0);
  glDisable(GL_CULL_FACE);
}

void ShadowRenderer::run_shadow_pass(const FramePlan& plan) {
  const ShadowPlan& light = plan.light;
  resize_shadow_map(light.layer_size, int(light.views.size()));
  // Whatever the map held is drawn over from here: a frame that stops
  // half way must not leave it to be reused.
  shadow_.kept.holds_plan = false;
  begin_pass(plan.shadow.object_draw_ms, double(light.layer_size), double(light.layer_size), kShadowChunkFragments);
  const GLuint framebuffer = shadow_.framebuffer.id();
  glBindFramebuffer(GL_FRAMEBUFFER, framebuffer);
  // The map has its own resolution: without its own viewport it would be
  // drawn partly or not at all.
  glViewport(0, 0, light.layer_size, light.layer_size);
  glUseProgram(shadow_.program.id());
  // What the main pass sets and restores, set here too, so that a frame
  // that ended early (a program that failed to build) leaves no trace:
  // glClear's depth is far, and the shadow program writes no clip distance.
  glClearDepth(1.0);
  glDisable(GL_CLIP_DISTANCE0);
  for (const ShadowLayerDraw& layer : plan.shadow.layers) {
    glNamedFramebufferTextureLayer(framebuffer, GL_DEPTH_ATTACHMENT, shadow_.depth_map.id(), 0, GLint(layer.layer));
    if (layer.clear_whole) {
      glClear(GL_DEPTH_BUFFER_BIT);
    } else {
      const float far = 1.0f;
      glClearTexSubImage(shadow_.depth_map.id(), 0, layer.x0, layer.y0, GLint(layer.layer), layer.x1 - layer.x0,
                         layer.y1 - layer.y0, 1, GL_DEPTH_COMPONENT, GL_FLOAT, &far);
    }
    glProgramUniform1i(shadow_.program.id(), shadow_.layer, GLint(layer.layer));
    draw_scene(layer.draws);
  }
  shadow_.kept = plan.shadow.kept_after;
}

void ShadowRenderer::run_display_pass(const FramePlan& plan) {
  const DisplayPassPlan& pass = plan.display;
  resize_display(pass.width, pass.height);
  begin_pass(pass.object_draw_ms, double(pass.width), double(pass.height), kMainChunkFragments);
  // The programs of the plan's steps: the frame's variant and those
  // derived from it.
  const auto program = [&](DisplayProgram which) {
    return display_.programs.get(variant_defines(program_variant(pass.variant, which))).id();
  };
  if (!pass.cell_indices.empty()) {
    glNamedBufferData(display_.cell_vertices.id(), GLsizeiptr(pass.cell_vertices.size() * sizeof(Vertex)),
                      pass.cell_vertices.data(), GL_STREAM_DRAW);
    glNamedBufferData(display_.cell_indices.id(), GLsizeiptr(pass.cell_indices.size() * sizeof(std::uint32_t)),
                      pass.cell_indices.data(), GL_STREAM_DRAW);
  }
  glUseProgram(program(DisplayProgram::Frame));
  // A certified frame's shadow map is its centre map (run_certified_shadow_pass).
  if (pass.variant.shadows)
    glBindTextureUnit(kTextureUnitShadowMap, pass.certificates ? certify_.centre_depth.id() : shadow_.depth_map.id());
  const GLenum color_only = GL_COLOR_ATTACHMENT0;
  if (pass.certificates) {
    add_certificate_targets();
    const GLenum all[3] = {GL_COLOR_ATTACHMENT0 + kFragOutputColor, GL_COLOR_ATTACHMENT0 + kFragOutputCertificate,
                           GL_COLOR_ATTACHMENT0 + kFragOutputUnlit};
    glNamedFramebufferDrawBuffers(display_.framebuffer.id(), 3, all);
    glBindTextureUnit(kTextureUnitCertifyNearest, certify_.nearest_depth.id());
    glBindTextureUnit(kTextureUnitCertifyNearestOwner, certify_.nearest_owner.id());
    glBindTextureUnit(kTextureUnitCertifyOthers, certify_.others_depth.id());
    glBindTextureUnit(kTextureUnitCertifyCentreTriangle, certify_.centre_triangle.id());
    glBindTextureUnit(kTextureUnitCertifyCover, certify_.cover_depth.id());
    glBindTextureUnit(kTextureUnitTriangleObjects, scene().triangle_objects.id());
    glBindTextureUnit(kTextureUnitObjectFacts, scene().object_facts.id());
    set_triangle_base_ = true;
  } else {
    glNamedFramebufferDrawBuffers(display_.framebuffer.id(), 1, &color_only);
  }
  glBindFramebuffer(GL_FRAMEBUFFER, display_.framebuffer.id());
  glViewport(0, 0, display_.width, display_.height);
  glClearColor(pass.clear_color.r, pass.clear_color.g, pass.clear_color.b, pass.clear_color.a);
  // Reversed depth (reversed_depth_projection): near is 1, far 0, so the
  // nearest surface has the greatest depth. Only this pass; the shadow pass
  // keeps GL's conventional clip volume and depth test.
  glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  glClearDepth(0.0);
  glDepthFunc(GL_GREATER);
  glClearStencil(0);
  if (pass.certificates) {
    // An integer buffer is cleared by value: 0 is "no object, lit" (the
    // background: what the reference finds there decides), unless the plan
    // leaves every pixel to the ray cast.
    const GLuint background = pass.background_certificate;
    const float clear[4] = {pass.clear_color.r, pass.clear_color.g, pass.clear_color.b, pass.clear_color.a};
    glClearBufferfv(GL_COLOR, 0, clear);
    glClearBufferuiv(GL_COLOR, 1, &background);
    glClearBufferfv(GL_COLOR, 2, clear);
    glClear(GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT);
  } else {
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT);
  }
  for (const DisplayStep& step : pass.steps) {
    glUseProgram(program(step.program));
    // A proved part's program: whose pixels, and the reach its proof allows.
    const bool proof = program_variant(pass.variant, step.program).proof != 0;
    if (proof) {
      glUniform1ui(kUniformLocationProofObject, GLuint(step.object));
      glUniform1f(kUniformLocationProofMargin, pass.proof_margin);
      glUniform1f(kUniformLocationProofRounding, step.proof_rounding);
    }
    // Its triangles name no scene triangle (it has no u_triangle_base).
    set_triangle_base_ = pass.certificates && !proof;
    step.clip_by_light_side ? glEnable(GL_CLIP_DISTANCE0) : glDisable(GL_CLIP_DISTANCE0);
    const StencilStep& stencil = step.stencil;
    if (stencil.enabled) {
      // llvmpipe skips the shader for a block of pixels that the early
      // stencil test rejects (see append_cell_steps in frame_plan.cpp).
      glEnable(GL_STENCIL_TEST);
      const GLenum test = stencil.test == StencilStep::Test::Always  ? GL_ALWAYS
                          : stencil.test == StencilStep::Test::Equal ? GL_EQUAL
                                                                     : GL_NOTEQUAL;
      glStencilFunc(test, stencil.ref, GLuint(stencil.mask));
      glStencilOp(GL_KEEP, GL_KEEP, stencil.replace ? GL_REPLACE : GL_KEEP);
    } else {
      glDisable(GL_STENCIL_TEST);
    }
    if (stencil.marks_only) {
      glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
      glDepthMask(GL_FALSE);
      glDepthFunc(GL_ALWAYS);
    }
    if (step.cells) {
      glBindVertexArray(display_.cells_vertex_array.id());
      for (const DrawRange& draw : step.draws) {
        set_cull(draw.cull);
        draw_elements(draw.first, draw.count);
      }
      glDisable(GL_CULL_FACE);
    } else {
      draw_scene(step.draws);
    }
    if (stencil.marks_only) {
      glDepthFunc(GL_GREATER);
      glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
      glDepthMask(GL_TRUE);
    }
  }
  glDisable(GL_STENCIL_TEST);
  glDisable(GL_CLIP_DISTANCE0);
  if (pass.certificates && !slivers_on_cpu_) run_sliver_pass(pass);
  glClipControl(GL_LOWER_LEFT, GL_NEGATIVE_ONE_TO_ONE);
  glClearDepth(1.0);
  glDepthFunc(GL_LESS);
  set_triangle_base_ = false;
}

void ShadowRenderer::run_depth_preview(const FramePlan& plan) {
  const DepthPreviewPlan& preview = plan.preview;
  resize_depth_preview(preview.size, preview.bits);
  const int layer_size = plan.light.layer_size;
  const float far = 1.0f;
  for (const int layer : preview.empty_layers)
    glClearTexSubImage(shadow_.depth_map.id(), 0, 0, 0, GLint(layer), layer_size, layer_size, 1, GL_DEPTH_COMPONENT,
                       GL_FLOAT, &far);
  const PreviewVariant variant{preview.perspective, preview.view_count};
  glUseProgram(preview_.programs.get(variant_defines(variant)).id());
  glBindTextureUnit(kTextureUnitShadowMap, shadow_.depth_map.id());
  glBindFramebuffer(GL_FRAMEBUFFER, preview_.framebuffer.id());
  glViewport(0, 0, preview_.size, preview_.size);
  glDisable(GL_DEPTH_TEST);
  glBindVertexArray(empty_vertex_array_.id());
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glEnable(GL_DEPTH_TEST);
}

Image ShadowRenderer::read_pixels(const ReadBack& read_back) {
  const GLuint framebuffer = read_back.depth_preview ? preview_.framebuffer.id() : display_.framebuffer.id();
  Image image;
  image.width = read_back.width;
  image.height = read_back.height;
  image.channels = read_back.channels;
  image.bit_depth = read_back.bit_depth;
  image.pixels.resize(image.row_bytes() * std::size_t(image.height));
  glBindFramebuffer(GL_READ_FRAMEBUFFER, framebuffer);
  glNamedFramebufferReadBuffer(framebuffer, GL_COLOR_ATTACHMENT0);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  // 16 bits: GL writes host-order uint16_t samples, which is what Image holds.
  const GLenum type = image.bit_depth == 16 ? GL_UNSIGNED_SHORT : GL_UNSIGNED_BYTE;
  glReadPixels(0, 0, image.width, image.height, image.channels == 1 ? GL_RED : GL_RGB, type, image.pixels.data());
  image.flip_rows();
  return image;
}

void ShadowRenderer::dispatch_cast_list(int ring, bool unlit) {
  using ListedPixel = PixelCertificates::ListedPixel;
  const int w = display_.width, h = display_.height;
  const std::size_t pixels = std::size_t(w) * std::size_t(h);
  if (!display_.cast_list) {
    for (gl::Texture& marks : display_.cast_marks) {
      marks = gl::create_texture(GL_TEXTURE_2D);
      glTextureStorage2D(marks.id(), 1, GL_R8UI, w, h);
      // Read as images only, but complete as a texture all the same.
      glTextureParameteri(marks.id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
      glTextureParameteri(marks.id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    }
    display_.cast_list = gl::create_buffer();
    glNamedBufferStorage(display_.cast_list.id(), GLsizeiptr(kCastListHeaderBytes + pixels * sizeof(ListedPixel)),
                         nullptr, GL_DYNAMIC_STORAGE_BIT);
  }
  // A program per pass, and the list's with the unlit colour in the last slot.
  const auto program = [&](CastPass pass, bool with_unlit) -> GLuint {
    std::optional<gl::Program>& p = display_.cast_programs[with_unlit ? 3 : int(pass)];
    if (!p)
      p = gl::build_compute_program("cast_list.comp", glsl_prelude("#define CAST_PASS " + std::to_string(int(pass)) +
                                                                  "\n#define CAST_UNLIT " + (with_unlit ? "1" : "0") +
                                                                  "\n"));
    return p->id();
  };
  const GLuint zero = 0;
  glClearNamedBufferSubData(display_.cast_list.id(), GL_R32UI, 0, sizeof zero, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
  glBindTextureUnit(kTextureUnitCertificates, display_.certificate.id());
  glBindTextureUnit(kTextureUnitSlivers, display_.slivers.id());
  glBindTextureUnit(kTextureUnitUnlit, display_.unlit.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kStorageBufferCastList, display_.cast_list.id());
  const GLuint groups_x = GLuint((w + 15) / 16), groups_y = GLuint((h + 15) / 16);
  const int r = ring - 1;
  const auto dispatch = [&](GLuint id, int in, int out) {
    glUseProgram(id);
    // The edges pass reads no ring.
    if (in >= 0) glProgramUniform1i(id, kUniformLocationCastRing, r);
    if (in >= 0) glBindImageTexture(kImageUnits[0].unit, display_.cast_marks[in].id(), 0, GL_FALSE, 0, GL_READ_ONLY, GL_R8UI);
    if (out >= 0)
      glBindImageTexture(kImageUnits[1].unit, display_.cast_marks[out].id(), 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_R8UI);
    glDispatchCompute(groups_x, groups_y, 1);
    glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
  };
  dispatch(program(CastPass::Edges, false), -1, 0);
  // With no ring to grow, the edges go to the list as they are.
  int marks = 0;
  if (r > 0) {
    dispatch(program(CastPass::Rows, false), 0, 1);
    marks = 1;
  }
  dispatch(program(CastPass::List, unlit), marks, -1);
  for (const int unit : {kTextureUnitCertificates, kTextureUnitSlivers, kTextureUnitUnlit}) glBindTextureUnit(GLuint(unit), 0);
  for (const TextureUnit& image : kImageUnits) glBindImageTexture(GLuint(image.unit), 0, 0, GL_FALSE, 0, GL_READ_ONLY, GL_R8UI);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kStorageBufferCastList, 0);
}

std::vector<PixelCertificates::ListedPixel> ShadowRenderer::read_cast_list() {
  using ListedPixel = PixelCertificates::ListedPixel;
  const std::size_t pixels = std::size_t(display_.width) * std::size_t(display_.height);
  // The count and as many entries as the last frame listed and a quarter
  // more in one read (each read waits for the GPU), the rest if it listed
  // more.
  const std::size_t guess = std::min(pixels, display_.cast_list_guess + display_.cast_list_guess / 4 + 1024);
  std::vector<ListedPixel> listed(guess + kCastListHeaderBytes / sizeof(ListedPixel));
  glGetNamedBufferSubData(display_.cast_list.id(), 0, GLsizeiptr(listed.size() * sizeof(ListedPixel)), listed.data());
  GLuint count = 0;
  std::memcpy(&count, listed.data(), sizeof count);
  if (count > pixels) throw std::runtime_error("cast_list.comp listed " + std::to_string(count) + " pixels of " + std::to_string(pixels));
  listed.erase(listed.begin(), listed.begin() + kCastListHeaderBytes / sizeof(ListedPixel));
  if (count > guess) {
    listed.resize(count);
    glGetNamedBufferSubData(display_.cast_list.id(), GLintptr(kCastListHeaderBytes + guess * sizeof(ListedPixel)),
                            GLsizeiptr((count - guess) * sizeof(ListedPixel)), listed.data() + guess);
  }
  listed.resize(count);
  display_.cast_list_guess = count;
  return listed;
}

PixelCertificates ShadowRenderer::read_certificates(const ReadBack& read_back, int list_ring) {
  PixelCertificates c;
  const int w = read_back.width, h = read_back.height;
  if (list_ring >= 1) {
    c.listed = read_cast_list();
    return c;
  }
  const GLuint framebuffer = display_.framebuffer.id();
  glBindFramebuffer(GL_READ_FRAMEBUFFER, framebuffer);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  c.codes.resize(std::size_t(w) * std::size_t(h));
  glNamedFramebufferReadBuffer(framebuffer, GL_COLOR_ATTACHMENT0 + kFragOutputCertificate);
  glReadPixels(0, 0, w, h, GL_RED_INTEGER, GL_UNSIGNED_INT, c.codes.data());
  flip_rows(c.codes, w, h);
  // Marks found on the CPU are added by render_frame.
  if (!slivers_on_cpu_) {
    c.slivers.resize(std::size_t(w) * std::size_t(h));
    glBindFramebuffer(GL_READ_FRAMEBUFFER, display_.sliver_framebuffer.id());
    glNamedFramebufferReadBuffer(display_.sliver_framebuffer.id(), GL_COLOR_ATTACHMENT0);
    glReadPixels(0, 0, w, h, GL_RED_INTEGER, GL_UNSIGNED_BYTE, c.slivers.data());
    flip_rows(c.slivers, w, h);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, framebuffer);
  }
  if (read_back.unlit) {
    c.unlit.width = w;
    c.unlit.height = h;
    c.unlit.channels = 3;
    c.unlit.bit_depth = 8;
    c.unlit.pixels.resize(c.unlit.row_bytes() * std::size_t(h));
    glNamedFramebufferReadBuffer(framebuffer, GL_COLOR_ATTACHMENT0 + kFragOutputUnlit);
    glReadPixels(0, 0, w, h, GL_RGB, GL_UNSIGNED_BYTE, c.unlit.pixels.data());
    c.unlit.flip_rows();
  }
  return c;
}

int ShadowRenderer::list_ring(const RenderRequest& request, const FramePlan& plan) const {
  // Every pixel is cast on the ray cast path: the list would be the image.
  if (!pixels_listed_on_gpu_ || slivers_on_cpu_ || plan.certified_path == CertifiedPath::RayCast) return 0;
  const int ring = silhouette_ring(request);
  if (ring - 1 > kMostListedRing) return 0;
  if (!misplaced_rectangles(request, plan.read_back.width, plan.read_back.height).empty()) return 0;
  return ring;
}

RenderResult ShadowRenderer::render(const RenderRequest& request, const FrameWatch& watch, CertifiedPath path) {
  watch_ = watch;
  try {
    return render_frame(request, path);
  } catch (...) {
    abandon_frame();
    throw;
  }
}

RenderResult ShadowRenderer::render_frame(const RenderRequest& request, CertifiedPath path) {
  RenderResult result;
  map_allocated_ = false;
  result.scene_uploaded = use_scene(request.scene);
  check_watch("the scene's upload");
  const FramePlan plan = plan_frame(request, scene().mesh, current_scene_key(), shadow_.kept, path, certify_.kept);
  if (plan.display.certificates) result.certified_path = to_string(plan.certified_path);
  result.shadow_reused = plan.shadow.reused;
  result.shadow_views = plan.shadow_views;
  const FrameBlock block = frame_block(request, plan.light, scene().mesh, plan.casters.by_view);
  glNamedBufferSubData(frame_block_.id(), 0, sizeof block, &block);
  if (plan.display.certificates) use_certificate_buffers(request.scene);
  // After use_certificate_buffers, which pairs the edges on a scene's first frame.
  slivers_on_cpu_ = plan.display.certificates && !plan.display.sliver_draws.empty() && certified_passes_on_cpu_ &&
                    scene().sliver_edges.has_value();
  if (plan.shadow.needed && !plan.shadow.reused) {
    // A reused map (typically only the camera moved) leaves shadow_ms 0.
    const auto start = Clock::now();
    plan.shadow.certify ? run_certified_shadow_pass(plan, block) : run_shadow_pass(plan);
    glFinish();
    result.timings.shadow_ms = elapsed_ms(start);
    check_watch("the shadow pass");
  }

  const auto main_start = Clock::now();
  if (plan.depth_output) {
    run_depth_preview(plan);
  } else {
    run_display_pass(plan);
    result.umbras = plan.display.umbras;
  }
  glFinish();
  result.timings.main_ms = elapsed_ms(main_start);

  const auto readback_start = Clock::now();
  // Listed first: the image's read then waits for the list too, and the
  // list's read finds the GPU done.
  const int ring = plan.read_back.certificates ? list_ring(request, plan) : 0;
  if (ring >= 1) dispatch_cast_list(ring, plan.read_back.unlit);
  result.image = read_pixels(plan.read_back);
  if (plan.read_back.certificates) {
    result.certificates = read_certificates(plan.read_back, ring);
    if (slivers_on_cpu_) {
      // With the camera's matrix and near plane as the main pass had them.
      PixelCertificates& c = *result.certificates;
      const SceneGeometry& g = scene();
      g.sliver_edges->mark(g.positions, glm::dmat4(block.camera_view_projection), request.camera.near_plane,
                           plan.read_back.width, plan.read_back.height, c.codes, c.slivers,
                           PixelCertificates::kObjectShift);
    }
  }
  result.timings.readback_ms = elapsed_ms(readback_start);
  result.shadow_map_allocated = map_allocated_;
  return result;
}

}  // namespace umbra
