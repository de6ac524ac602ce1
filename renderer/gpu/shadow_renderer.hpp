// The GL renderer: executes a frame's plan (plan/frame_plan.hpp): a shadow
// pass into a depth texture, then a main pass that lights the scene from the
// camera with that texture (or the depth preview), then read-back. What to
// draw is decided by plan_frame; what is decided here is only how GL holds
// it (which scenes, maps and programs are kept) and how a long draw is
// split into chunks while it runs.
#pragma once

#include <chrono>
#include <cstdint>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>

#include "core/byte_bounded_lru.hpp"
#include "gpu/objects.hpp"
#include "gpu/program.hpp"
#include "gpu/shader_interface.hpp"
#include "core/light_math.hpp"
#include "core/render_result.hpp"
#include "core/request.hpp"
#include "core/scene.hpp"
#include "plan/conservative_maps.hpp"
#include "plan/sliver_marks.hpp"
#include "plan/frame_plan.hpp"

namespace umbra {

/// When a frame must give up: render() checks it between the chunks that a
/// deep or long mesh's draws are split into (see draw_scene_indices) and between
/// passes.
struct FrameWatch {
  std::chrono::steady_clock::time_point until = std::chrono::steady_clock::time_point::max();
};

/// render() gave up on a frame at its FrameWatch: nothing of it is
/// returned, and the renderer is ready for the next one (the GL state
/// restored, the half-drawn shadow map not reused).
struct FrameCutShort : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Call order: construct with a current GL 4.5 context, then render() any
/// number of times, destroy before the context. Not thread-safe: it lives on
/// the GL thread (see render_service.hpp).
class ShadowRenderer {
 public:
  /// Compiles the shaders; throws std::runtime_error with the GLSL log.
  /// Uploaded scenes are kept while they hold at most `scene_cache_bytes`
  /// together (the scene being drawn is always kept).
  explicit ShadowRenderer(std::uint64_t scene_cache_bytes = std::numeric_limits<std::uint64_t>::max());

  /// Renders `request` and reads the chosen output back. `request` must be
  /// valid (as the request parser guarantees). Throws FrameCutShort once
  /// past `watch.until` (checked between chunks and passes: a chunk is
  /// about kChunkMs of work, so the frame ends within about that of it).
  /// `path`: plan_frame's (filter "exact" frames only).
  RenderResult render(const RenderRequest& request, const FrameWatch& watch = {},
                      CertifiedPath path = CertifiedPath::Maps);

  /// Bytes of GL memory kept between requests: cached scenes' buffers, the
  /// shadow map, the display framebuffer, the depth preview (as allocated:
  /// llvmpipe holds each in ordinary process memory).
  std::uint64_t cached_bytes() const;
  /// Releases what is kept until at most `max_bytes` is: scenes other than
  /// the last one drawn (least recently used first), then the depth
  /// preview, the shadow map, the display framebuffer, and last the last
  /// scene. Returns cached_bytes() after.
  std::uint64_t release_cached(std::uint64_t max_bytes);
  /// The part of cached_bytes() that `request`'s frame would draw into as it
  /// is (a shadow map of its size with enough layers, framebuffers of its
  /// size): its estimated peak (request_cost.hpp) counts that memory
  /// already, so releasing it to make room for the frame would only
  /// allocate it again (a 1 GiB map: seconds of page faults a frame).
  std::uint64_t bytes_reused_by(const RenderRequest& request) const;
  /// Bytes of GL memory released since this renderer was made: render
  /// targets (shadow maps, display and preview framebuffers) and evicted
  /// scenes' buffers. llvmpipe (Mesa 22.3) keeps much of it until the GL
  /// context is destroyed: every render target it drew into but the last
  /// (a 4-layer 4096^2 map: 256 MB after glDeleteTextures; measured in a
  /// 60-line EGL program), and most of three 999-sphere scenes drawn whole
  /// (~130 MB). So this is memory the process may still hold: RenderService
  /// starts a fresh context when it grows too large.
  std::uint64_t released_gl_bytes() const { return released_gl_bytes_; }

  std::string gl_renderer() const;
  /// Filter "exact"'s conservative maps and sliver marks drawn on the CPU
  /// (plan/conservative_maps.hpp, plan/sliver_marks.hpp; the default on
  /// llvmpipe) or by the shaders (certify.geom, sliver.geom; the default on
  /// a GPU). Tests draw both: the kept certified maps are dropped, so the
  /// next certified frame draws its maps the way asked.
  void set_certified_passes_on_cpu(bool on_cpu) {
    certified_passes_on_cpu_ = on_cpu;
    pixels_listed_on_gpu_ = !on_cpu;
    certify_.kept.holds_plan = false;
  }
  /// Filter "exact"'s pixels to ray cast listed by the GPU (cast_list.comp:
  /// only the list is read back, PixelCertificates::listed; the default on
  /// a GPU, and with set_certified_passes_on_cpu(false)) or found on the
  /// CPU from every pixel's certificate read back (the default on
  /// llvmpipe, whose shaders run on the same cores as the CPU's loops).
  /// The GPU lists only where the sliver marks are the shaders' and the
  /// ring is at most kMostListedRing, and no object may be misplaced
  /// (misplaced_rectangles: cast whole, found on the CPU).
  void set_pixels_listed_on_gpu(bool on_gpu) { pixels_listed_on_gpu_ = on_gpu; }
  std::string gl_version() const;

 private:
  // A scene's triangles, uploaded once per distinct scene (see scenes_).
  struct SceneGeometry {
    gl::VertexArray vertex_array;
    gl::Buffer vertices;
    gl::Buffer indices;
    Mesh mesh;           // CPU copy: origin and index ranges (vertices cleared)
    // Per object: how many layers deep its triangles may lie
    // (mesh_deepest_layers; 0 for the analytic ones, which the cost
    // estimate bounds by their bounds).
    std::vector<double> deep_layers;
    // Filter "exact" (certificate.glsl), made when a certified frame first
    // draws the scene: each triangle's object and its owner where it turns
    // to the light (RG32UI: light_facing_owners), each object's facts
    // (RGBA32F), as buffer textures.
    gl::Buffer triangle_objects_buffer, object_facts_buffer;
    gl::Texture triangle_objects, object_facts;
    // ... and on the CPU: each triangle's object, each object's facts as
    // the conservative maps drawn there take them, and (only where they
    // are drawn there: certified_passes_on_cpu_, at most
    // kMostConservativeTriangles) the positions and indices, read back.
    std::vector<std::uint32_t> triangle_object_ids;
    std::vector<std::uint32_t> facing_owners;  // light_facing_owners
    std::vector<ConservativeObject> conservative_objects;
    std::vector<glm::vec3> positions;
    std::vector<std::uint32_t> position_indices;
    // Their edges, paired (with the positions).
    std::optional<SliverEdges> sliver_edges;
  };
  // Filter "exact"'s maps of the light's view (certify.frag), one array
  // layer per view, all at certified_map_size; a certified frame neither
  // draws nor reads the shadow map.
  struct CertifyMaps {
    gl::ProgramVariants centre{"shadow_depth.vert", "certify.frag", 2};
    gl::ProgramVariants conservative{"shadow_depth.vert", "certify.geom", "certify.frag", 4};
    // The centre map, at the conservative maps' size (certified_map_size):
    gl::Texture centre_depth;     // DEPTH_COMPONENT32F: depth at each texel centre
    gl::Texture centre_triangle;  // R32UI: triangle + 1 at each texel centre, 0 none
    gl::Texture nearest_depth;    // DEPTH_COMPONENT32F: conservative nearest depth
    gl::Texture nearest_owner;    // R32UI: its owner
    gl::Texture others_depth;     // DEPTH_COMPONENT32F: nearest of every other owner
    gl::Texture cover_depth;      // R32F: the cover map (drawn on the CPU only; else far)
    gl::Framebuffer framebuffer;
    int size = 0, layers = 0;
    // What the maps hold now (plan_frame decides whether they serve a frame).
    KeptCertifiedMaps kept;
  };
  // Depth-only framebuffer seen from the light, one array layer per view.
  struct ShadowPass {
    gl::Program program;
    GLint layer = -1;       // u_layer: the view a draw fills
    gl::Texture depth_map;  // 2D array of DEPTH_COMPONENT32F, size^2 x layers
    gl::Framebuffer framebuffer;
    int size = 0;
    int layers = 0;
    // What the map holds now (plan_frame decides whether it serves a frame).
    KeptShadowMap kept;
  };
  // The camera's view, into an offscreen colour + depth framebuffer.
  struct DisplayPass {
    gl::ProgramVariants programs{"scene.vert", "scene.frag", kKeptVariants};  // per DisplayVariant
    gl::Renderbuffer color;  // RGBA8
    gl::Renderbuffer depth;  // DEPTH32F_STENCIL8
    // Filter "exact": the certificates (an R32UI texture, which the sliver
    // pass reads) and the unlit colours (RGBA8), attached as colour 1 and 2
    // once a certified frame asks; the sliver pass's marks (R8UI) in a
    // framebuffer of their own, with the main pass's depth.
    gl::Texture certificate;
    gl::Texture unlit;
    gl::Texture slivers;
    // Where the GPU lists the pixels to ray cast (cast_list.comp): two R8UI
    // images of marks and the list (kCastListHeaderBytes, then a
    // ListedPixel per pixel at most), made when first asked for; its
    // programs per CastPass, then the list's with the unlit colour.
    gl::Texture cast_marks[2];
    gl::Buffer cast_list;
    std::size_t cast_list_guess = 0;  // how many the last frame listed
    std::optional<gl::Program> cast_programs[4];
    gl::Framebuffer sliver_framebuffer;
    std::optional<gl::Program> sliver_program;
    gl::Framebuffer framebuffer;
    int width = 0, height = 0;
    // The planes that cast nothing, drawn as cells (receiver_cells.hpp):
    // this frame's DisplayPassPlan::cell_vertices and cell_indices.
    gl::VertexArray cells_vertex_array;
    gl::Buffer cell_vertices;
    gl::Buffer cell_indices;
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

  RenderResult render_frame(const RenderRequest& request, CertifiedPath path);
  /// Makes `scene` the current one (scenes_.front()), uploading it unless a
  /// scene with the same content is cached; true if it was uploaded.
  bool use_scene(const Scene& scene);
  SceneGeometry& scene() { return scenes_.front().value; }
  const SceneGeometry& scene() const { return scenes_.front().value; }
  /// Content of the current scene (see scene_key in the .cpp).
  const std::string& current_scene_key() const { return scenes_.front().key; }
  std::uint64_t shadow_map_bytes() const;
  std::uint64_t display_bytes() const;
  std::uint64_t depth_preview_bytes() const;
  std::uint64_t certify_bytes() const;
  void resize_certify_maps(int size, int layers);
  // The display framebuffer's certificate and unlit attachments.
  void add_certificate_targets();
  void drop_certificate_targets();
  // The current scene's buffer textures for `scene` (its content).
  void use_certificate_buffers(const Scene& scene);
  void run_certified_shadow_pass(const FramePlan& plan, const FrameBlock& block);
  // One layer's nearest and others maps drawn on the CPU
  // (plan/conservative_maps.hpp) and uploaded; false when the layer holds
  // more triangles than that path takes (the shaders draw it then).
  bool upload_conservative_maps(const FramePlan& plan, const FrameBlock& block, const ShadowLayerDraw& layer);
  void run_sliver_pass(const DisplayPassPlan& pass);
  // Draws with u_triangle_base set to each draw's first triangle (the
  // certified programs name triangles by it).
  bool set_triangle_base_ = false;
  void draw_indices(std::size_t first, std::size_t count);
  /// Every pixel's certificate (and the unlit colours, and the shaders'
  /// sliver marks) read back; or, with a `list_ring` of 1 or more, only the
  /// pixels pixels_to_ray_cast would find for that ring, as
  /// dispatch_cast_list(list_ring, ...) listed them.
  PixelCertificates read_certificates(const ReadBack& read_back, int list_ring);
  /// cast_list.comp's passes over the display's certificates, queued; and
  /// the list they made, read back.
  void dispatch_cast_list(int ring, bool unlit);
  std::vector<PixelCertificates::ListedPixel> read_cast_list();
  /// The ring the GPU lists a certified frame's pixels for, or 0 where the
  /// CPU finds them (set_pixels_listed_on_gpu).
  int list_ring(const RenderRequest& request, const FramePlan& plan) const;
  void resize_shadow_map(int size, int layers);
  void resize_display(int width, int height);
  void resize_depth_preview(int size, int bits);
  /// One draw of nothing that matters into unbind_framebuffer_, with no
  /// vertex buffer and no texture: Mesa drops its references to the
  /// buffers, textures and framebuffers of the last frame, so that those
  /// released are freed now, not at the next request.
  void unbind_released();
  // A mesh more layers deep than this (mesh_deepest_layers) has its draws
  // split into chunks of about kChunkMs each, the watch checked between
  // them: one draw call of 4,000 stacked quads is seconds that llvmpipe
  // cannot interrupt. Ordinary models are at most about 2 (a closed
  // surface seen without culling), so their draws are never split.
  static constexpr double kDeepLayers = 4.0;
  static constexpr double kChunkMs = 20.0;
  // A mesh whose triangles the estimate prices at more than this in a pass
  // (the plan's object_draw_ms, mesh_draw_ms: per triangle and per 64 x 64
  // tile their bounding boxes cover) is drawn in chunks too: 200,000
  // slivers across a 4096^2 map are not deep at all, yet one draw of them
  // is seconds. The teapot is well under a millisecond.
  static constexpr double kLongDrawMs = 2.0 * kChunkMs;
  // The fragments a first chunk is sized for, assuming the deep mesh fills
  // the view (so never too large): about kChunkMs on the reference machine
  // (issue 29's stack: 2.5e-5 ms a camera fragment with PCF radius 1, 5e-7
  // ms a shadow texel). Later chunks are sized by the time the earlier
  // ones took.
  static constexpr double kMainChunkFragments = 1 << 20;
  static constexpr double kShadowChunkFragments = 1 << 25;
  // The conservative maps drawn on the CPU go up in bands of rows of at
  // most this many bytes, one per core at a time.
  static constexpr std::size_t kConservativeBandBytes = std::size_t(4) << 20;
  // The frame's watch, and the chunking state of the pass being drawn.
  FrameWatch watch_;
  double pass_pixels_ = 0.0;          // the pass's viewport
  double ms_per_fragment_ = 0.0;      // kChunkMs over the pass's first chunk of a deep mesh's fragments
  std::vector<double> pass_draw_ms_;  // per scene object: the plan's object_draw_ms for this pass
  double chunk_ms_ = 0.0;             // estimated ms a chunk is sized for, adapted to the time chunks take
  // Draws indices [first, first + count) of the current scene: in one call
  // unless they hold a deep mesh (kDeepLayers) or a long one (kLongDrawMs),
  // whose triangles are drawn in chunks with wait_for_chunk() after each,
  // in index order (the same pixels as one call).
  void draw_scene_indices(std::size_t first, std::size_t count);
  // Starts a pass's chunking: `fragments_per_chunk` of a deep mesh in a
  // viewport of `width` x `height`, each mesh's draw estimated at
  // `object_draw_ms` (one per scene object).
  void begin_pass(const std::vector<double>& object_draw_ms, double width, double height,
                  double fragments_per_chunk);
  // Waits for the GL to finish what was issued (a fence: llvmpipe draws
  // when flushed), sizes the next chunk by the time this one took, and
  // throws FrameCutShort if the watch has run out.
  void wait_for_chunk(std::chrono::steady_clock::time_point chunk_start);
  void check_watch(const char* where) const;
  // After a frame that threw: what the passes set is set back, the map it
  // may have half drawn is not reused.
  void abandon_frame();
  // Draws `draws` of the current scene (draw_scene_indices each) with
  // their cull modes; leaves face culling off.
  void draw_scene(const std::vector<DrawRange>& draws);
  // The passes of `plan`, as it orders them.
  void run_shadow_pass(const FramePlan& plan);
  void run_display_pass(const FramePlan& plan);
  void run_depth_preview(const FramePlan& plan);
  Image read_pixels(const ReadBack& read_back);

  // The last few distinct scenes, keyed by content, most recently used
  // first, so that clients alternating between scenes do not re-upload them;
  // at most kCachedScenes and scene_cache_bytes_ (a 1000-sphere scene is
  // about 280 MB).
  static constexpr std::size_t kCachedScenes = 8;
  std::uint64_t scene_cache_bytes_;
  std::uint64_t released_gl_bytes_ = 0;  // see released_gl_bytes()
  // The GL is a software rasteriser (llvmpipe): filter "exact"'s
  // conservative maps are drawn by plan/conservative_maps.cpp, ten times
  // faster there than through its geometry shader.
  bool certified_passes_on_cpu_ = false;
  bool pixels_listed_on_gpu_ = true;
  // This frame's sliver marks are found on the CPU (render_frame), not by
  // the sliver pass.
  bool slivers_on_cpu_ = false;
  bool map_allocated_ = false;           // this frame allocated its shadow map (RenderResult)
  // scenes_.evict_to, counting what goes in released_gl_bytes_.
  void evict_scenes_to(std::uint64_t max_bytes, std::size_t keep);
  ByteBoundedLru<SceneGeometry> scenes_;
  ShadowPass shadow_;
  DisplayPass display_;
  DepthPreviewPass preview_;
  CertifyMaps certify_;
  gl::Buffer frame_block_;  // FrameBlock, binding 0: every pass reads it
  gl::VertexArray empty_vertex_array_;  // for the full-screen triangle
  // A 1x1 depth-only target for unbind_released(): what the last frame drew
  // with is bound in Mesa's state until another draw replaces it.
  gl::Texture unbind_depth_;
  gl::Framebuffer unbind_framebuffer_;
};

}  // namespace umbra
