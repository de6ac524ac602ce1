#include "gpu/shadow_renderer.hpp"

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <map>
#include <stdexcept>

#include "gpu/program.hpp"
#include "core/mesh_instance.hpp"
#include "plan/draw_cost.hpp"
#include "plan/receiver_cells.hpp"
#include "plan/umbras.hpp"
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
    }
  }
  return key;
}

// Texels cleared around each layer's casters' rectangle for `shadow`: a
// point is read for only if its filter (FILTER_READ texels) meets the
// rectangle, and then reads up to FILTER_READ beyond where it is.
int clear_margin_texels(const ShadowSettings& shadow) { return 2 * filter_read_texels(shadow) + 1; }

// Whether clearing all of a layer of `layer_size`^2 texels costs less than
// clearing only `rect` of it. On llvmpipe, glClear of the whole attachment
// is done tile by tile by the rasteriser threads as they draw, so a tile's
// depths are written and then drawn over while in cache, whereas
// glClearTexSubImage writes the rectangle to memory on the GL thread and
// the draw reads it back. Measured per layer (clear and draw, 960x540):
// `point-close`'s -Y face, over 90 % of the layer, 7.7 -> 4.5 ms cleared
// whole; a face of 30 %, about even; of 17 %, 1.4 -> 2.1 ms. A GPU clears
// whole attachments fastest too.
bool clears_whole_layer(const TexelRect& rect, int layer_size) {
  const glm::dvec2 size = rect.max - rect.min;
  return size.x * size.y > 0.4 * double(layer_size) * double(layer_size);
}

// Vertex array `vao` reads Vertex records from `vertices` and indices from
// `indices`.
void describe_vertices(GLuint vao, GLuint vertices, GLuint indices) {
  glVertexArrayVertexBuffer(vao, 0, vertices, 0, sizeof(Vertex));
  glVertexArrayElementBuffer(vao, indices);
  const GLuint offsets[3] = {offsetof(Vertex, position), offsetof(Vertex, normal), offsetof(Vertex, color)};
  for (GLuint attribute = 0; attribute < 3; ++attribute) {
    glEnableVertexArrayAttrib(vao, attribute);
    glVertexArrayAttribFormat(vao, attribute, 3, GL_FLOAT, GL_FALSE, offsets[attribute]);
    glVertexArrayAttribBinding(vao, attribute, 0);
  }
}

void draw_indices(std::size_t first, std::size_t count) {
  if (count > 0)
    glDrawElements(GL_TRIANGLES, GLsizei(count), GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>(first * sizeof(std::uint32_t)));
}

}  // namespace

ShadowRenderer::ShadowRenderer(std::uint64_t scene_cache_bytes) : scene_cache_bytes_(scene_cache_bytes) {
  shadow_.program = gl::build_program("shadow_depth.vert", "shadow_depth.frag", glsl_prelude(""));
  shadow_.layer = gl::uniform_location(shadow_.program, "u_layer");
  // Built now, so that a GLSL error shows at start-up: the default frame's
  // variant (the others are built when first asked for).
  RenderRequest defaults;
  defaults.scene.objects.push_back({});
  display_.programs.get(display_variant(defaults, plan_shadow(defaults)).defines());
  frame_block_ = gl::create_buffer();
  glNamedBufferStorage(frame_block_.id(), sizeof(FrameBlock), nullptr, GL_DYNAMIC_STORAGE_BIT);
  glBindBufferBase(GL_UNIFORM_BUFFER, 0, frame_block_.id());
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
  const std::uint64_t bytes = std::uint64_t(vertex_count) * sizeof(Vertex) + std::uint64_t(index_count) * sizeof(std::uint32_t);
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
  // RGBA8, and 32F depth with an 8-bit stencil (llvmpipe stores the pair in 8 bytes)
  return std::uint64_t(display_.width) * std::uint64_t(display_.height) * (4 + 8);
}

std::uint64_t ShadowRenderer::depth_preview_bytes() const {
  return std::uint64_t(preview_.size) * std::uint64_t(preview_.size) * std::uint64_t(preview_.bits / 8);
}

std::uint64_t ShadowRenderer::cached_bytes() const {
  return scenes_.bytes() + shadow_map_bytes() + display_bytes() + depth_preview_bytes();
}

std::uint64_t ShadowRenderer::bytes_reused_by(const RenderRequest& request) const {
  std::uint64_t bytes = 0;
  const ShadowPlan light = plan_shadow(request);
  const bool needs_map = (request.shadow.enabled && light.direct_light) || request.output == Output::Depth;
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
    shadow_.holds_plan = false;
    shadow_.scene_key.clear();
  }
  if (cached_bytes() > max_bytes) {
    released_gl_bytes_ += display_bytes();
    display_.framebuffer.reset();
    display_.color.reset();
    display_.depth.reset();
    display_.width = display_.height = 0;
  }
  evict_scenes_to(max_bytes, 0);
  unbind_released();
  return cached_bytes();
}

void ShadowRenderer::unbind_released() {
  glBindTextureUnit(0, 0);
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
  released_gl_bytes_ += display_bytes();
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

void ShadowRenderer::draw_scene(CullMode closed_mesh_cull, const std::vector<bool>& objects, MeshPart part) {
  const Mesh& mesh = scene().mesh;
  glBindVertexArray(scene().vertex_array.id());
  // Runs of consecutive objects to draw, one call each: closed meshes, open
  // models and planes apart (in that order in the index buffer).
  using Run = std::pair<std::uint32_t, std::uint32_t>;  // first index, count
  std::vector<bool> is_plane(mesh.bounds.size(), false);
  for (const PlaneRange& plane : mesh.planes) is_plane[plane.object] = true;
  std::vector<Run> closed, open_models, planes;
  for (const ObjectRange& r : mesh.object_ranges) {
    if ((!objects.empty() && !objects[r.object]) || r.index_count == 0) continue;
    std::vector<Run>& runs = r.first_index < mesh.closed_index_count ? closed : is_plane[r.object] ? planes : open_models;
    if (!runs.empty() && runs.back().first + runs.back().second == r.first_index)
      runs.back().second += r.index_count;
    else
      runs.emplace_back(r.first_index, r.index_count);
  }
  // Many scattered objects (a thousand spheres, some in the view): one call
  // for all of their kind costs less than hundreds; those outside the view
  // draw nothing. Planes keep their flags: a plane left out of the shadow
  // pass must stay out, and there are few of them.
  if (closed.size() > kMaxRuns) closed = {Run{0, mesh.closed_index_count}};
  if (open_models.size() > kMaxRuns) {
    const std::uint32_t end = open_models.back().first + open_models.back().second;
    open_models = {Run{open_models.front().first, end - open_models.front().first}};  // no plane lies between
  }
  if (part == MeshPart::Closed) open_models.clear(), planes.clear();
  if (!closed.empty()) {
    if (closed_mesh_cull == CullMode::None) {
      glDisable(GL_CULL_FACE);
    } else {
      glEnable(GL_CULL_FACE);
      glCullFace(closed_mesh_cull == CullMode::Front ? GL_FRONT : GL_BACK);
    }
    for (const Run& run : closed) draw_scene_indices(run.first, run.second);
  }
  // A plane or an open model has one side: culling it could drop it from
  // the pass entirely.
  glDisable(GL_CULL_FACE);
  for (const Run& run : open_models) draw_scene_indices(run.first, run.second);
  for (const Run& run : planes) draw_scene_indices(run.first, run.second);
}

void ShadowRenderer::begin_pass(const Scene& scene, const std::vector<glm::dmat4>& view_projections, double width,
                                double height, double fragments_per_chunk) {
  pass_pixels_ = width * height;
  ms_per_fragment_ = kChunkMs / fragments_per_chunk;
  chunk_ms_ = kChunkMs;
  pass_draw_ms_.assign(scene.objects.size(), 0.0);
  for (std::size_t i = 0; i < scene.objects.size(); ++i)
    for (const glm::dmat4& view_projection : view_projections)
      pass_draw_ms_[i] = std::max(pass_draw_ms_[i], mesh_draw_ms(scene.objects[i], view_projection, width, height));
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
  shadow_.holds_plan = false;
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

std::vector<bool> ShadowRenderer::drawn_objects(const std::vector<bool>& planes) const {
  const Mesh& mesh = scene().mesh;
  std::vector<bool> drawn(mesh.bounds.size(), true);
  for (std::size_t i = 0; i < mesh.planes.size(); ++i)
    if (!planes.empty() && !planes[i]) drawn[mesh.planes[i].object] = false;
  return drawn;
}

std::vector<bool> ShadowRenderer::casting_planes(const RenderRequest& request, const ShadowPlan& light) const {
  std::vector<bool> planes;
  for (const PlaneRange& plane : scene().mesh.planes)
    planes.push_back(request.output == Output::Depth || plane_can_shadow(plane, light));
  return planes;
}

CasterTexels ShadowRenderer::caster_table(const RenderRequest& request, const ShadowPlan& light,
                                          const std::vector<bool>& planes) const {
  const Mesh& mesh = scene().mesh;
  CasterTexels table = caster_texels_by_view(light, mesh.bounds, drawn_objects(planes));
  if (request.output == Output::Depth || light.layout != ShadowLayout::Cascades) return table;
  // Only meshes whose triangles cost more to draw again than the test
  // costs (a few microseconds per box near them), and at most kMaxRuns of
  // them (draw_scene may draw more in one call, dropped or not).
  std::vector<bool> heavy(mesh.bounds.size(), false);
  std::size_t count = 0;
  for (const ObjectRange& r : mesh.object_ranges)
    if (r.index_count / 3 >= kHeavyTriangles) heavy[r.object] = true, ++count;
  if (count == 0 || count > kMaxRuns) return table;
  drop_casters_held_by_earlier_cascades(light, mesh.bounds, heavy, request.shadow, table);
  return table;
}

void ShadowRenderer::upload_frame_block(const RenderRequest& request, const ShadowPlan& light,
                                        const std::vector<TexelRect>& casters) {
  const FrameBlock block = frame_block(request, light, scene().mesh, casters);
  glNamedBufferSubData(frame_block_.id(), 0, sizeof block, &block);
}

void ShadowRenderer::run_shadow_pass(const RenderRequest& request, const ShadowPlan& light,
                                     const std::vector<bool>& planes, const CasterTexels& casters) {
  resize_shadow_map(light.layer_size, int(light.views.size()));
  // Whatever the map held is drawn over from here: a frame that stops
  // half way must not leave it to be reused.
  shadow_.holds_plan = false;
  std::vector<glm::dmat4> views;
  for (const ShadowView& view : light.views)
    if (!view.empty) views.push_back(view.projection * view.view);
  begin_pass(request.scene, views, double(light.layer_size), double(light.layer_size), kShadowChunkFragments);
  const GLuint framebuffer = shadow_.framebuffer.id();
  glBindFramebuffer(GL_FRAMEBUFFER, framebuffer);
  // The map has its own resolution: without its own viewport it would be
  // drawn partly or not at all.
  glViewport(0, 0, light.layer_size, light.layer_size);
  glUseProgram(shadow_.program.id());
  // The depth output shows whole layers. A frame's main pass reads a layer
  // only for points whose filter (FILTER_READ texels around them) meets the
  // casters' rectangle, so only within twice that of it: only that much is
  // cleared, unless the rectangle is most of the layer. On llvmpipe,
  // clearing a 2048^2 layer costs ~2 ms, most of what a layer of a few
  // objects costs once the floor is left out.
  const bool whole_layers = request.output == Output::Depth;
  const int margin = clear_margin_texels(request.shadow);
  // What the main pass sets and restores, set here too, so that a frame
  // that ended early (a program that failed to build) leaves no trace:
  // glClear's depth is far, and the shadow program writes no clip distance.
  glClearDepth(1.0);
  glDisable(GL_CLIP_DISTANCE0);
  for (std::size_t layer = 0; layer < light.views.size(); ++layer) {
    // An empty view (no object reaches into it) holds no receiver either,
    // so the main pass never reads its layer: it is not even cleared (the
    // depth preview clears it before showing it). Nor is a layer that no
    // drawn object reaches: the main pass sees its rectangle empty.
    if (light.views[layer].empty || (!whole_layers && casters.by_view[layer].empty())) continue;
    glNamedFramebufferTextureLayer(framebuffer, GL_DEPTH_ATTACHMENT, shadow_.depth_map.id(), 0, GLint(layer));
    if (whole_layers || clears_whole_layer(casters.by_view[layer], light.layer_size)) {
      glClear(GL_DEPTH_BUFFER_BIT);
    } else {
      const TexelRect& c = casters.by_view[layer];
      const int x0 = std::max(0, int(c.min.x) - margin), y0 = std::max(0, int(c.min.y) - margin);
      const int x1 = std::min(light.layer_size, int(c.max.x) + margin);
      const int y1 = std::min(light.layer_size, int(c.max.y) + margin);
      const float far = 1.0f;
      glClearTexSubImage(shadow_.depth_map.id(), 0, x0, y0, GLint(layer), x1 - x0, y1 - y0, 1, GL_DEPTH_COMPONENT,
                         GL_FLOAT, &far);
    }
    glProgramUniform1i(shadow_.program.id(), shadow_.layer, GLint(layer));
    // Culling front faces stores the far side of closed objects: their lit
    // faces then sit well in front of the stored depth, so no bias is needed
    // against self-shadowing there, and the bias stays small elsewhere (less
    // peter panning). See ShadowSettings::cull for why planes are exempt.
    // Only what reaches into this view: a sphere beside a point light is
    // in one or two of its six faces, and each face it is drawn into
    // shades all its vertices.
    std::vector<bool> in_view;
    for (const TexelRect& object : casters.by_object[layer]) in_view.push_back(!object.empty());
    draw_scene(request.shadow.cull, in_view);
  }
  shadow_.holds_plan = true;
  shadow_.plan = light;
  shadow_.scene_key = current_scene_key();
  shadow_.cull = request.shadow.cull;
  shadow_.planes = planes;
  shadow_.whole_layers = whole_layers;
  shadow_.clear_margin = margin;
  shadow_.automatic_bias = request.shadow.bias.automatic;
}

bool ShadowRenderer::shadow_map_serves(const RenderRequest& request, const ShadowPlan& light,
                                       const std::vector<bool>& planes) const {
  // A map cleared only around its casters serves frames whose filter
  // reads no further than the one it was cleared for, and no depth output.
  const bool cleared_enough =
      shadow_.whole_layers ||
      (request.output != Output::Depth && clear_margin_texels(request.shadow) <= shadow_.clear_margin);
  // The depth output draws every object into every layer; a map drawn
  // with the automatic bias may lack some (caster_table).
  const bool drawn_for_lookups_like_these =
      shadow_.whole_layers || !shadow_.automatic_bias || request.shadow.bias.automatic;
  return shadow_.holds_plan && shadow_.scene_key == current_scene_key() && shadow_.cull == request.shadow.cull &&
         shadow_.planes == planes && cleared_enough && drawn_for_lookups_like_these &&
         plan_covers(shadow_.plan, light);
}

ShadowRenderer::CellDraws ShadowRenderer::upload_plane_cells(const RenderRequest& request, const ShadowPlan& light,
                                                             const std::vector<bool>& planes,
                                                             const CasterTexels& casters) {
  const Mesh& mesh = scene().mesh;
  CellDraws draws;
  draws.whole_planes.assign(mesh.planes.size(), true);
  // The seeds' bias moves the point along its normal before it is looked
  // up: such frames draw every plane whole. So do scenes of many planes,
  // whose regions would cost more to find than they save.
  if (!request.shadow.bias.automatic || mesh.planes.size() > kMaxPlanesInCells) return draws;
  const double margin = double(filter_read_texels(request.shadow)) + 1.0;
  // One region per view and caster, or past that many pairs one per view
  // around all its casters (looser, and as cheap for a thousand casters).
  constexpr std::size_t kMaxRegionPairs = 128;
  std::size_t pairs = 0;
  for (const std::vector<TexelRect>& row : casters.by_object)
    pairs += std::size_t(std::count_if(row.begin(), row.end(), [](const TexelRect& r) { return !r.empty(); }));
  const bool per_caster = pairs <= kMaxRegionPairs;
  // Under a light of no size, the umbras of boxes and spheres are drawn
  // dark without the lookup (umbras.hpp).
  const bool umbras = request.light.size == 0.0;
  CellTriangles cells;
  std::map<double, std::vector<PlanePolygon>> regions_at;  // by plane height
  for (std::size_t i = 0; i < mesh.planes.size(); ++i) {
    const PlaneRange& plane = mesh.planes[i];
    // A plane in the map is a caster: all of it can be shadowed.
    if (planes[i]) continue;
    const Aabb& bounds = mesh.bounds[plane.object];
    PlaneDraw draw;
    draw.dark.first = cells.dark.size();
    draw.bounds.first = cells.bounds.size();
    draw.shadowable.first = cells.shadowable.size();
    draw.unshadowable.first = cells.unshadowable.size();
    if (umbras) {
      const std::vector<PlanePolygon> dark = umbras_on_plane(bounds, light, request.scene.objects, margin);
      append_dark_triangles(dark, plane.height, plane.color, mesh.origin, cells);
      draws.umbras += dark.size();
    }
    if (const std::optional<std::vector<PlanePolygon>> shadows =
            shadow_bounds_on_plane(bounds, plane.object, light, mesh.bounds, margin)) {
      append_polygon_triangles(*shadows, plane.height, plane.color, mesh.origin, cells, cells.bounds);
      draw.lookup_only_near = true;
    }
    auto at = regions_at.find(plane.height);
    if (at == regions_at.end())
      at = regions_at
               .emplace(plane.height, per_caster ? shadowable_regions(plane.height, light, casters.by_object, margin)
                                                 : view_regions(plane.height, light, casters.by_view, margin))
               .first;
    append_cell_triangles(plane_cells(bounds, at->second), plane.height, plane.color, mesh.origin, cells);
    draw.dark.count = cells.dark.size() - draw.dark.first;
    draw.bounds.count = cells.bounds.size() - draw.bounds.first;
    draw.shadowable.count = cells.shadowable.size() - draw.shadowable.first;
    draw.unshadowable.count = cells.unshadowable.size() - draw.unshadowable.first;
    draws.planes.push_back(draw);
    draws.whole_planes[i] = false;
  }
  if (draws.planes.empty()) return draws;
  // One index buffer: every plane's umbras, then the shadows of the
  // objects' bounds, then the shadowable cells, then the others.
  std::vector<std::uint32_t> indices = std::move(cells.dark);
  for (std::vector<std::uint32_t>* part : {&cells.bounds, &cells.shadowable, &cells.unshadowable}) {
    for (PlaneDraw& draw : draws.planes) {
      IndexRange& range = part == &cells.bounds ? draw.bounds : part == &cells.shadowable ? draw.shadowable : draw.unshadowable;
      range.first += indices.size();
    }
    indices.insert(indices.end(), part->begin(), part->end());
  }
  glNamedBufferData(display_.cell_vertices.id(), GLsizeiptr(cells.vertices.size() * sizeof(Vertex)),
                    cells.vertices.data(), GL_STREAM_DRAW);
  glNamedBufferData(display_.cell_indices.id(), GLsizeiptr(indices.size() * sizeof(std::uint32_t)), indices.data(),
                    GL_STREAM_DRAW);
  return draws;
}

std::size_t ShadowRenderer::run_display_pass(const RenderRequest& request, const ShadowPlan& light,
                                      const std::vector<bool>& planes, const CasterTexels& casters) {
  resize_display(request.width, request.height);
  const CameraMatrices camera = camera_matrices(request.camera, request.width, request.height);
  begin_pass(request.scene, {camera.projection * camera.view}, double(request.width), double(request.height),
             kMainChunkFragments);
  const DisplayVariant variant = display_variant(request, light);
  CellDraws cells;
  if (variant.shadows) cells = upload_plane_cells(request, light, planes, casters);
  glUseProgram(display_.programs.get(variant.defines()).id());
  if (variant.shadows) glBindTextureUnit(0, shadow_.depth_map.id());
  glBindFramebuffer(GL_FRAMEBUFFER, display_.framebuffer.id());
  glViewport(0, 0, display_.width, display_.height);
  if (request.output == Output::Shadow)
    glClearColor(1.0f, 1.0f, 1.0f, 1.0f);  // no geometry: nothing blocks the light
  else
    glClearColor(0.11f, 0.12f, 0.14f, 1.0f);
  // Reversed depth (reversed_depth_projection): near is 1, far 0, so the
  // nearest surface has the greatest depth. Only this pass; the shadow pass
  // keeps GL's conventional clip volume and depth test.
  glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  glClearDepth(0.0);
  glDepthFunc(GL_GREATER);
  glClearStencil(0);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT);
  // A box's far faces, drawn before its near ones, would be shaded in full
  // and then drawn over: with the camera outside every closed mesh they
  // are culled (about a sixth of a box scene's main pass on llvmpipe).
  const CullMode closed_cull =
      closed_meshes_seen_from_outside(scene().mesh, request.camera, double(request.width) / request.height)
          ? CullMode::Back
          : CullMode::None;
  std::vector<bool> objects = drawn_objects(cells.whole_planes);
  // The faces of a closed mesh that turn from the light get no direct
  // light, yet llvmpipe would run the whole shadow lookup for each of
  // their pixels (it runs both sides of a branch): `contact-line`'s box
  // face fills a third of the frame. So closed meshes are drawn in two
  // parts (LIGHT_SIDE, scene.vert): with the lookup where a point may face
  // the light, without it where none can. Their front faces only: a back
  // face's normal would be turned to the camera in scene.frag.
  std::vector<bool> split;
  if (variant.shadows && closed_cull == CullMode::Back)
    split = objects_split_by_the_light(scene().mesh, request.camera, request.width, request.height);
  std::size_t split_count = 0, unsplit_closed = 0;
  for (const ObjectRange& r : scene().mesh.object_ranges) {
    if (r.first_index >= scene().mesh.closed_index_count || !objects[r.object] || split.empty()) continue;
    split[r.object] ? ++split_count : ++unsplit_closed;
  }
  // Past kMaxRuns draw_scene draws every closed mesh in one call: the split
  // would then draw the unsplit ones too, or the last draw the split ones
  // again. Counting objects, not runs, errs towards fewer draws.
  if (split_count > kMaxRuns && unsplit_closed > 0) {
    for (const ObjectRange& r : scene().mesh.object_ranges)
      if (r.first_index < scene().mesh.closed_index_count) split[r.object] = true;
  } else if (unsplit_closed > kMaxRuns) {
    split.clear();
  }
  if (std::find(split.begin(), split.end(), true) != split.end()) {
    for (std::size_t i = 0; i < split.size(); ++i) {
      split[i] = split[i] && objects[i];
      objects[i] = objects[i] && !split[i];
    }
    DisplayVariant facing = variant;
    facing.light_side = 1;
    DisplayVariant away = without_shadows(variant);
    away.light_side = -1;
    glEnable(GL_CLIP_DISTANCE0);
    glUseProgram(display_.programs.get(facing.defines()).id());
    draw_scene(closed_cull, split, MeshPart::Closed);
    glUseProgram(display_.programs.get(away.defines()).id());
    draw_scene(closed_cull, split, MeshPart::Closed);
    glDisable(GL_CLIP_DISTANCE0);
    glUseProgram(display_.programs.get(variant.defines()).id());
  }
  draw_scene(closed_cull, objects);
  if (!cells.planes.empty()) {
    // Plane by plane, with the stencil (llvmpipe skips the shader for a
    // block of pixels that the early stencil test rejects, not for lanes
    // that a branch masks off):
    // 1. the shadows of its objects' bounds, marked `near` and not drawn;
    // 2. its umbras, with the program of a light that reaches no surface,
    //    marked `dark` instead;
    // 3. its shadowable cells with the lookup where marked `near`, then
    //    lit where marked neither;
    // 4. its other cells lit where not dark (an umbra never reaches them).
    // The lookup's pixels are drawn from the cells' triangles, as without
    // the marks, so it interpolates the same positions. The two marks
    // differ in their lowest bit only, and each plane has its own pair:
    // coplanar parts of different planes would not mark each other.
    // Without the shadows of the bounds (a point light whose foot is
    // inside an object's bounds), the lookup runs on every shadowable cell
    // but the umbras.
    DisplayVariant dark = without_shadows(variant);
    dark.direct_light = false;
    const GLuint dark_program = display_.programs.get(dark.defines()).id();
    const GLuint lookup_program = display_.programs.get(variant.defines()).id();
    const GLuint lit_program = display_.programs.get(without_shadows(variant).defines()).id();
    glBindVertexArray(display_.cells_vertex_array.id());
    glEnable(GL_STENCIL_TEST);
    static_assert(2 * kMaxPlanesInCells + 1 <= 0xFF, "each plane's two marks fit in the 8-bit stencil");
    GLint plane_marks = 0;
    for (const PlaneDraw& draw : cells.planes) {
      plane_marks += 2;
      const GLint dark_mark = plane_marks, near_mark = plane_marks + 1;
      const bool marked_near = draw.lookup_only_near;
      glStencilOp(GL_KEEP, GL_KEEP, GL_REPLACE);
      glUseProgram(dark_program);
      if (draw.bounds.count > 0) {
        // Marked whatever is in front: only this plane's draws below read
        // the mark, and they test depth themselves. (With the depth test,
        // a plane coplanar with one drawn before would be marked where its
        // polygons lose to that plane by a rounding and drawn lit where its
        // cells win.)
        glStencilFunc(GL_ALWAYS, near_mark, 0xFF);
        glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
        glDepthMask(GL_FALSE);
        glDepthFunc(GL_ALWAYS);
        draw_indices(draw.bounds.first, draw.bounds.count);
        glDepthFunc(GL_GREATER);
        glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
        glDepthMask(GL_TRUE);
      }
      if (draw.dark.count > 0) {
        glStencilFunc(GL_ALWAYS, dark_mark, 0xFF);
        draw_indices(draw.dark.first, draw.dark.count);
      }
      glStencilOp(GL_KEEP, GL_KEEP, GL_KEEP);
      if (draw.shadowable.count > 0) {
        marked_near ? glStencilFunc(GL_EQUAL, near_mark, 0xFF) : glStencilFunc(GL_NOTEQUAL, dark_mark, 0xFF);
        glUseProgram(lookup_program);
        draw_indices(draw.shadowable.first, draw.shadowable.count);
        if (marked_near) {
          glStencilFunc(GL_NOTEQUAL, dark_mark, 0xFE);  // neither mark
          glUseProgram(lit_program);
          draw_indices(draw.shadowable.first, draw.shadowable.count);
        }
      }
      if (draw.unshadowable.count > 0) {
        glStencilFunc(GL_NOTEQUAL, dark_mark, 0xFF);
        glUseProgram(lit_program);
        draw_indices(draw.unshadowable.first, draw.unshadowable.count);
      }
    }
    glDisable(GL_STENCIL_TEST);
  }
  glClipControl(GL_LOWER_LEFT, GL_NEGATIVE_ONE_TO_ONE);
  glClearDepth(1.0);
  glDepthFunc(GL_LESS);
  return cells.umbras;
}

void ShadowRenderer::run_depth_preview(const ShadowPlan& light, int image_size, int bits) {
  resize_depth_preview(image_size, bits);
  // The shadow pass leaves empty views' layers as they were: show them as
  // cleared, far everywhere.
  const float far = 1.0f;
  for (std::size_t layer = 0; layer < light.views.size(); ++layer)
    if (light.views[layer].empty)
      glClearTexSubImage(shadow_.depth_map.id(), 0, 0, 0, GLint(layer), light.layer_size, light.layer_size, 1,
                         GL_DEPTH_COMPONENT, GL_FLOAT, &far);
  const PreviewVariant variant{light.perspective, int(light.views.size())};
  glUseProgram(preview_.programs.get(variant.defines()).id());
  glBindTextureUnit(0, shadow_.depth_map.id());
  glBindFramebuffer(GL_FRAMEBUFFER, preview_.framebuffer.id());
  glViewport(0, 0, preview_.size, preview_.size);
  glDisable(GL_DEPTH_TEST);
  glBindVertexArray(empty_vertex_array_.id());
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glEnable(GL_DEPTH_TEST);
}

Image ShadowRenderer::read_pixels(GLuint framebuffer, int width, int height, int channels, int bit_depth) {
  Image image;
  image.width = width;
  image.height = height;
  image.channels = channels;
  image.bit_depth = bit_depth;
  image.pixels.resize(image.row_bytes() * std::size_t(height));
  glBindFramebuffer(GL_READ_FRAMEBUFFER, framebuffer);
  glNamedFramebufferReadBuffer(framebuffer, GL_COLOR_ATTACHMENT0);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  // 16 bits: GL writes host-order uint16_t samples, which is what Image holds.
  const GLenum type = bit_depth == 16 ? GL_UNSIGNED_SHORT : GL_UNSIGNED_BYTE;
  glReadPixels(0, 0, width, height, channels == 1 ? GL_RED : GL_RGB, type, image.pixels.data());
  image.flip_rows();
  return image;
}

RenderResult ShadowRenderer::render(const RenderRequest& request, const FrameWatch& watch) {
  watch_ = watch;
  try {
    return render_frame(request);
  } catch (...) {
    abandon_frame();
    throw;
  }
}

RenderResult ShadowRenderer::render_frame(const RenderRequest& request) {
  RenderResult result;
  map_allocated_ = false;
  result.scene_uploaded = use_scene(request.scene);
  check_watch("the scene's upload");
  ShadowPlan light = plan_shadow(request);
  const bool depth_output = request.output == Output::Depth;

  // A sun below the horizon casts no shadow: its frame is ambient only.
  const bool needs_map = (request.shadow.enabled && light.direct_light) || depth_output;
  const std::vector<bool> planes = casting_planes(request, light);
  if (needs_map && shadow_map_serves(request, light, planes)) {
    // Nothing the map depends on changed (typically only the camera
    // moved): draw with the views it was made for; shadow_ms stays 0.
    light = shadow_.plan;
    result.shadow_reused = true;
  }
  const CasterTexels casters = caster_table(request, light, planes);
  upload_frame_block(request, light, casters.by_view);
  if (needs_map) {
    if (!result.shadow_reused) {
      const auto start = Clock::now();
      run_shadow_pass(request, light, planes, casters);
      glFinish();
      result.timings.shadow_ms = elapsed_ms(start);
      check_watch("the shadow pass");
    }
    const char* layout = light.layout == ShadowLayout::Cascades ? "cascades"
                         : light.layout == ShadowLayout::Cube   ? "cube"
                                                                : "single";
    result.shadow_views = std::string(layout) + "; views=" + std::to_string(light.views.size()) +
                          "; size=" + std::to_string(light.layer_size);
  }

  const auto main_start = Clock::now();
  if (depth_output)
    run_depth_preview(light, request.shadow.map_size, request.depth_bits);
  else
    result.umbras = run_display_pass(request, light, planes, casters);
  glFinish();
  result.timings.main_ms = elapsed_ms(main_start);

  const auto readback_start = Clock::now();
  if (depth_output)
    result.image = read_pixels(preview_.framebuffer.id(), preview_.size, preview_.size, 1, preview_.bits);
  else
    result.image = read_pixels(display_.framebuffer.id(), display_.width, display_.height,
                               request.output == Output::Shadow ? 1 : 3);
  result.timings.readback_ms = elapsed_ms(readback_start);
  result.shadow_map_allocated = map_allocated_;
  return result;
}

}  // namespace umbra
