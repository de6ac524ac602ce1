// What one frame draws, decided without GL: a FramePlan value made by the
// pure function plan_frame from the request, the scene's mesh and what the
// shadow map holds from earlier frames. ShadowRenderer (gpu/) only executes
// it: it turns each step into gl* calls in order, and decides nothing but
// how to split a long draw into chunks while it runs (a matter of time, not
// of pixels). Every decision here is unit tested without a GL context
// (tests/test_frame_plan.cpp).
//
//   light      the light's views (plan_shadow), or the kept map's
//   shadow     drawn or reused; per layer: clear whole or a rectangle, the
//              objects' index ranges
//   display    the main pass: clear colour, steps in order (program, cull,
//              stencil, index ranges of the scene or of the floor's cells)
//   preview    the depth output's grey image
//   read_back  which image, its size, channels and bit depth
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/vec4.hpp>

#include "core/light_math.hpp"
#include "core/request.hpp"
#include "core/scene.hpp"
#include "plan/shader_variants.hpp"

namespace umbra {

// Runs of closed meshes, and of open models, that a pass draws with a call
// each; past that many, all of their kind in one call.
inline constexpr std::size_t kMaxRuns = 16;
// Filter "exact": how far (texels) from a layer's casters' rectangle the
// certificate may read its maps (scene.frag verdict_by_maps: within 2 it
// reads, and a 2 x 2 block from there).
inline constexpr int kCertifiedReadTexels = 4;
/// Filter "exact": texels per side of the conservative maps of a layer of
/// `layer_size`: half of it (at least 64). On llvmpipe their passes cost
/// about four times less than at the layer's own size; a texel twice as
/// wide only widens the band around shadow edges left to the ray cast (the
/// centre map, which proves shadow, keeps the layer's size).
int certified_map_size(int layer_size);
// Triangles from which an object is worth leaving out of a cascade it
// shadows nothing in: on llvmpipe about 0.4 ms of a shadow pass.
inline constexpr std::size_t kHeavyTriangles = 4096;
// Planes past that many are drawn whole: their regions would cost more to
// find than they save.
inline constexpr std::size_t kMaxPlanesInCells = 8;

/// How a filter "exact" frame settles its pixels (docs/certified-shadows.md):
/// - Maps: the certified maps and the proved plane parts prove what they
///   can, the rest is ray cast;
/// - Proofs: no maps: the proved plane parts are proved, every other pixel
///   is ray cast;
/// - RayCast: no maps, no proofs, no sliver pass: every pixel is ray cast
///   (the main pass only shades).
enum class CertifiedPath { Maps, Proofs, RayCast };
const char* to_string(CertifiedPath path);

/// What the shadow map holds from the frame that drew it, so that a frame
/// whose light, scene and cull mode are unchanged (a camera-only change)
/// reuses it. The renderer keeps it beside the map.
struct KeptShadowMap {
  bool holds_plan = false;  ///< false: nothing to reuse (none drawn, reallocated, or a frame cut short)
  ShadowPlan plan;
  std::string scene_key;  ///< the scene's content key (the renderer's scene cache key)
  CullMode cull = CullMode::Front;
  std::vector<bool> planes;  ///< casting_planes() it was drawn with
  /// Whole layers cleared (the depth output), or only the casters'
  /// rectangles with this many texels around them.
  bool whole_layers = false;
  int clear_margin = 0;
  /// Drawn for a frame with the automatic bias, so heavy meshes may be
  /// missing from cascades where that frame's lookups cannot see them
  /// (drop_casters_held_by_earlier_cascades); a frame with the seeds'
  /// bias looks further and must not reuse it.
  bool automatic_bias = false;
};

/// What filter "exact"'s maps (ShadowPassPlan::certify: the centre map and
/// the two conservative maps, apart from the shadow map) hold.
struct KeptCertifiedMaps {
  bool holds_plan = false;  ///< false: nothing to reuse (none drawn, reallocated, or a frame cut short)
  ShadowPlan plan;
  std::string scene_key;     ///< the scene's content key
  std::vector<bool> planes;  ///< casting_planes() they were drawn with
  FrustumFit fit = FrustumFit::Scene;
};

/// Indices [first, first + count) of an index buffer (the scene's or the
/// cells'), drawn as triangles with `cull` (closed meshes only; everything
/// else two-sided).
struct DrawRange {
  std::size_t first = 0, count = 0;
  CullMode cull = CullMode::None;
};

/// Which triangles of the scene a draw list holds.
enum class MeshPart {
  All,
  Closed,  ///< closed meshes only (Mesh::closed_index_count)
};

/// One layer of the shadow pass.
struct ShadowLayerDraw {
  int layer = 0;
  /// glClear the whole layer, or only [x0, x1) x [y0, y1) to far.
  bool clear_whole = true;
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  /// The objects that reach into this view, as scene index ranges.
  std::vector<DrawRange> draws;
  /// Filter "exact": an object's corners move in this view by more than
  /// kMostRoundingTexels (light_view_rounding: far from the mesh origin,
  /// over tiny texels). Its conservative maps would prove next to nothing
  /// and cost a swollen box per triangle: they are not drawn but hold
  /// depth 0, owned by no point (kEveryOwner), and the cover map is far.
  bool proves_nothing = false;
};
/// See ShadowLayerDraw::proves_nothing.
inline constexpr double kMostRoundingTexels = 16.0;

struct ShadowPassPlan {
  /// The frame reads or shows a shadow map (a shadow lookup, or the depth
  /// output).
  bool needed = false;
  /// The kept map (the kept certified maps, with `certify`) serves this
  /// frame: no shadow pass runs.
  bool reused = false;
  /// Filter "exact": the layers are drawn as the certificate reads them
  /// (docs/certified-shadows.md): the map itself (every object; closed
  /// meshes' faces turned from the light culled) with each texel's triangle beside it, and
  /// two conservative maps: the nearest depth any triangle reaches
  /// anywhere in each texel, with its owner, and the nearest of all other
  /// owners. These maps are kept apart from the shadow map
  /// (certified_kept_after).
  bool certify = false;
  /// ... and the faces of closed shapes that turn from the light are left
  /// out (docs/certified-shadows.md, "Faces turned from the light"): the
  /// centre map culls them (DrawRange::cull Back for closed meshes; the
  /// conservative passes' quads always face the light, so GL culls none of
  /// them), the conservative passes drop an analytic shape's face whose
  /// projection is clearly clockwise (CULL_CLOSED_BACK). Off when a point
  /// light lies within a closed object's bounds.
  bool cull_closed_back = false;
  /// Layers drawn, ascending (empty views and, unless whole, layers no drawn
  /// object reaches are left out: nothing reads them).
  std::vector<ShadowLayerDraw> layers;
  /// Per scene object: estimated ms to draw it in the pass (mesh_draw_ms,
  /// the most over the drawn views), by which long draws are chunked.
  std::vector<double> object_draw_ms;
  /// What the map holds once drawn (holds_plan true).
  KeptShadowMap kept_after;
  /// With `certify`: what the certified maps hold once drawn.
  KeptCertifiedMaps certified_kept_after;
};

/// The program a display step draws with: the frame's main-pass variant
/// (DisplayPassPlan::variant) or one derived from it (program_variant).
enum class DisplayProgram {
  Frame,        ///< the frame's variant: with the shadow lookup when it has one
  Lit,          ///< without_shadows(frame): no lookup; filter "exact": a part proved lit (proof 1)
  Dark,         ///< without_shadows(frame) with no direct light: an umbra; filter "exact": proved dark (proof -1)
  LightFacing,  ///< the frame's, LIGHT_SIDE 1: closed meshes' part that may face the light
  LightAway,    ///< without_shadows(frame), LIGHT_SIDE -1: the part that cannot
};

/// The variant `which` draws with, given the frame's.
DisplayVariant program_variant(const DisplayVariant& frame, DisplayProgram which);

/// The stencil test a display step draws with (8-bit stencil, cleared to 0).
struct StencilStep {
  bool enabled = false;
  enum class Test { Always, Equal, NotEqual } test = Test::Always;
  int ref = 0;
  int mask = 0xFF;
  bool replace = false;  ///< where drawn, the stencil becomes `ref` (else kept)
  /// Only marks the stencil: no colour or depth written, drawn whatever is
  /// in front (depth test always).
  bool marks_only = false;
};

/// One draw of the main pass.
struct DisplayStep {
  /// What the step is, for tests and for reading a plan.
  enum class Kind {
    ClosedFacingLight,  ///< closed meshes split by the light: the part that may face it
    ClosedAwayFromLight,
    Objects,            ///< every object not drawn otherwise
    BoundsMarks,        ///< a plane's shadows of the objects' bounds: marked `near`, not drawn
    DarkUmbras,         ///< a plane's umbras, drawn dark and marked `dark`
    ShadowableLookup,   ///< a plane's shadowable cells, with the lookup
    ShadowableLit,      ///< the same cells, lit where marked neither
    UnshadowableCells,  ///< a plane's other cells, lit where not dark
    CertifiedNear,      ///< filter "exact": a plane's own triangles, certified by the maps where marked `near`
    ProvedLit,          ///< filter "exact": the same, proved lit where marked neither
  } kind = Kind::Objects;
  DisplayProgram program = DisplayProgram::Frame;
  bool cells = false;  ///< draws from the cells' buffers (DisplayPassPlan), else the scene's
  std::vector<DrawRange> draws;
  /// GL_CLIP_DISTANCE0 (LIGHT_SIDE's split, scene.vert).
  bool clip_by_light_side = false;
  StencilStep stencil;
  std::size_t plane = 0;  ///< cell steps: the plane's index in Mesh::planes
  /// Proved parts (program Lit or Dark in a certified frame): the plane's
  /// scene object, whose certificate its pixels carry (u_proof_object).
  std::size_t object = 0;
  /// ... and the part of its pixels' reach that is not their footprint:
  /// float rounding, bounded over the plane (u_proof_rounding).
  float proof_rounding = 0.0f;
};

struct DisplayPassPlan {
  int width = 0, height = 0;
  /// Filter "exact": the main pass also writes each pixel's certificate
  /// and its unlit colour (PixelCertificates). No cells or light side
  /// split, whose shortcuts prove nothing; but the planes the maps leave
  /// out are drawn in parts that geometry proves lit or dark (umbras and
  /// the shadows of objects' bounds grown by 3 proof_margin), certified by
  /// the maps only near those shadows (plan_proved_planes).
  bool certificates = false;
  /// ... the reach (world units) a proved part's pixel may have: past it,
  /// the pixel is uncertain (u_proof_margin).
  float proof_margin = 0.0f;
  /// ... the certificate of a pixel nothing is drawn at: "no object, lit"
  /// (the reference decides around the objects' outlines), or, with every
  /// pixel ray cast and no sliver pass to find what the raster missed,
  /// "no object, uncertain".
  std::uint32_t background_certificate = 0;
  /// ... and then draws every triangle's edges (the sliver pass: sliver.geom),
  /// no face culled by the GL (the pass draws each edge as a quad) ...
  std::vector<DrawRange> sliver_draws;
  /// ... but, where the main pass culls closed meshes' back faces, the
  /// geometry shader skips those faces (their edges are front faces' or
  /// hidden by their own mesh).
  bool sliver_skips_closed_back = false;
  glm::vec4 clear_color{0.0f};
  /// The frame's main-pass variant (display_variant); each step's program
  /// is it or one derived from it (program_variant). `variant.shadows`:
  /// the frame has the shadow lookup (shadows enabled, direct light).
  DisplayVariant variant;
  /// Per scene object: mesh_draw_ms in the camera's view.
  std::vector<double> object_draw_ms;
  /// The cells of the planes the shadow pass leaves out (receiver_cells.hpp),
  /// positions relative to Mesh::origin, uploaded for this frame; indices:
  /// every plane's umbras, then the shadows of the objects' bounds, then the
  /// shadowable cells, then the others. Empty: no plane in cells.
  std::vector<Vertex> cell_vertices;
  std::vector<std::uint32_t> cell_indices;
  /// Umbras drawn dark without the lookup (RenderResult::umbras).
  std::size_t umbras = 0;
  std::vector<DisplayStep> steps;
};

struct DepthPreviewPlan {
  int size = 0;  ///< pixels per side (shadow.map_size)
  int bits = 8;  ///< 8 or 16 (depth_bits)
  bool perspective = false;
  int view_count = 1;
  /// Layers of empty views, cleared to far before they are shown.
  std::vector<int> empty_layers;
};

struct ReadBack {
  bool depth_preview = false;  ///< read the preview's image, else the main pass's
  int width = 0, height = 0;
  int channels = 3;   ///< 1 (shadow, depth) or 3 (RGB)
  int bit_depth = 8;  ///< 8, or 16 for a 16-bit depth preview
  /// Filter "exact": the main pass's certificates too, and for the colour
  /// output its image with visibility 0 (PixelCertificates).
  bool certificates = false;
  bool unlit = false;
};

/// Everything one frame draws, in order: the shadow pass (unless reused),
/// then the main pass or the depth preview, then the read-back.
struct FramePlan {
  /// The views the frame draws with: plan_shadow's, or the kept map's when
  /// it is reused.
  ShadowPlan light;
  /// The scene's planes the shadow pass draws (one per Mesh::planes entry).
  std::vector<bool> casting_planes;
  /// Where each object the shadow pass draws reaches into each view
  /// (by_view goes to the frame block).
  CasterTexels casters;
  ShadowPassPlan shadow;
  /// RenderResult::shadow_views: "cascades; views=3; size=2048", or empty
  /// without a shadow map.
  std::string shadow_views;
  bool depth_output = false;
  DisplayPassPlan display;   ///< unless depth_output
  DepthPreviewPlan preview;  ///< depth_output only
  ReadBack read_back;
  /// Filter "exact": how the frame was certified (plan_frame's `path`, or
  /// Maps under a sun below the horizon, which draws none).
  CertifiedPath certified_path = CertifiedPath::Maps;
};

/// The plan of `request`'s frame (valid, as the parser guarantees) drawing
/// `mesh` (tessellate(request.scene); vertices and indices not needed),
/// whose content key is `scene_key`, with `kept` in the shadow map.
/// `path`: how a filter "exact" frame under a light that is up is
/// certified (the caller's choice, by exact_filter_paths in
/// service/request_cost.hpp); `kept_certified`: what the certified maps
/// hold.
FramePlan plan_frame(const RenderRequest& request, const Mesh& mesh, const std::string& scene_key,
                     const KeptShadowMap& kept, CertifiedPath path = CertifiedPath::Maps,
                     const KeptCertifiedMaps& kept_certified = {});

// The steps plan_frame is made of, exposed for tests.

/// Whether the frame is certified: filter "exact" with a shadow lookup.
bool certified_frame(const RenderRequest& request, const ShadowPlan& light);

/// Whether the frame reads or shows a shadow map: a lookup under a direct
/// light (a sun below the horizon casts no shadow), or the depth output.
bool needs_shadow_map(const RenderRequest& request, const ShadowPlan& light);

/// One flag per scene object: all of them but the planes `planes` leaves
/// out (one flag per Mesh::planes entry; empty: none).
std::vector<bool> drawn_objects(const Mesh& mesh, const std::vector<bool>& planes);

/// The scene's planes that the shadow pass for `light` draws: all of them
/// for the depth output (it shows what the light sees), else those that
/// can shadow something (plane_can_shadow).
std::vector<bool> casting_planes(const RenderRequest& request, const ShadowPlan& light, const Mesh& mesh);

/// Where each object the shadow pass draws (all but the planes that
/// `planes` leaves out) reaches into each view of `light`. Heavy meshes
/// (kHeavyTriangles, at most kMaxRuns of them) are left out of cascades
/// where they shadow nothing (drop_casters_held_by_earlier_cascades),
/// except for the depth output, which shows whole layers.
CasterTexels caster_table(const RenderRequest& request, const ShadowPlan& light, const Mesh& mesh,
                          const std::vector<bool>& planes);

/// Texels cleared around each layer's casters' rectangle for `shadow`: a
/// point is read for only if its filter (FILTER_READ texels) meets the
/// rectangle, and then reads up to FILTER_READ beyond where it is.
int clear_margin_texels(const ShadowSettings& shadow);

/// Whether clearing all of a layer of `layer_size`^2 texels costs less than
/// clearing only `rect` of it (see the .cpp for the measurements).
bool clears_whole_layer(const TexelRect& rect, int layer_size);

/// Whether the map `kept` holds serves a frame of `request` with the
/// views `light`, the planes `planes`, of the scene `scene_key`.
bool shadow_map_serves(const KeptShadowMap& kept, const RenderRequest& request, const ShadowPlan& light,
                       const std::vector<bool>& planes, const std::string& scene_key);

/// Whether the certified maps `kept` holds serve a certified frame of
/// `request` with the views `light`, the planes `planes`, of the scene
/// `scene_key`: they depend on nothing else of the request (not the
/// camera), and the frame then reads them with the views they were drawn
/// for.
bool certified_maps_serve(const KeptCertifiedMaps& kept, const RenderRequest& request, const ShadowPlan& light,
                          const std::vector<bool>& planes, const std::string& scene_key);

/// The draws of the objects `objects` marks (one flag per scene object;
/// empty: all) in `part` of the mesh: closed meshes with `closed_cull`, then
/// open models, then planes, a range per run of consecutive objects. Closed
/// objects scattered over more than kMaxRuns runs are all drawn in one
/// range, and so are open models; what is drawn outside the view leaves no
/// texel. Planes are drawn exactly as marked.
std::vector<DrawRange> scene_draw_ranges(const Mesh& mesh, CullMode closed_cull, const std::vector<bool>& objects,
                                         MeshPart part = MeshPart::All);

/// Per scene object, the most mesh_draw_ms over `view_projections` in a
/// `width` x `height` viewport (0 for objects that are not meshes).
std::vector<double> object_draw_ms(const Scene& scene, const std::vector<glm::dmat4>& view_projections,
                                   double width, double height);

/// How the depth preview lays out the views of `plan` as tiles, for the
/// panel (appended to Umbra-Shadow-Views on the depth output):
/// "; grid=<tiles per row>", and for a cube "; faces=+X,-X,+Y,-Y,+Z,-Z",
/// the face each layer holds. The tiles are layer 0 top left, row by row
/// (depth_preview.frag).
std::string preview_tiles_parameters(const ShadowPlan& plan);

}  // namespace umbra
