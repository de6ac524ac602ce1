// Filter "exact"'s two conservative maps of a light's view, drawn on the CPU
// (docs/certified-shadows.md, "The maps"): for each texel the least window
// depth that any triangle reaches anywhere in the texel's square, with that
// triangle's owner (the nearest map), and the least depth of every other
// owner (the others map).
//
// certify.geom and certify.frag draw the same maps through the GL's
// pipeline: a geometry shader's quad per triangle, an edge test and a
// written depth per fragment. llvmpipe runs all of that on the CPU, about
// ten times slower than this loop over each row's span; on a GPU the
// shaders are the faster. Both follow one recipe, step for step, with the
// same margins; here the arithmetic is double, so every value is at least
// as safe as the shaders'.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include <glm/glm.hpp>

#include "core/scene.hpp"
#include "plan/frame_plan.hpp"
#include "plan/sliver_marks.hpp"

namespace umbra {

/// One view of the light as the shaders have it.
struct ConservativeView {
  /// The layer's light_view (relative to the mesh origin) and projection,
  /// the float matrices of the uniform block, so that the maps hold what the
  /// main pass projects its points with.
  glm::mat4 view{1.0f};
  glm::mat4 projection{1.0f};
  bool perspective = false;
  /// ShadowView's near and far planes (world units), texel size (world
  /// units; a point light's per unit of distance) and, for a point light,
  /// tan of half its field of view.
  double near_plane = 0.0, far_plane = 1.0;
  glm::dvec2 texel_size{0.0};
  double tan_half = 0.0;
  int layer_size = 0;  ///< the layer's texels per side
  int size = 0;        ///< the conservative maps' (certified_map_size)
  /// ShadowPassPlan::cull_closed_back.
  bool cull_closed_back = false;
};

/// What the maps need of each object: how far its true surface reaches past
/// its faces (ShapeKind::tessellation_error), and whether it is a model
/// (each triangle its own owner) or closed.
struct ConservativeObject {
  double swell = 0.0;
  bool model = false;
  bool closed = false;
  /// The largest |coordinate| of its bounds relative to the mesh origin:
  /// the scale of the float rounding of its corners in the light's view.
  double extent = 0.0;
};
std::vector<ConservativeObject> conservative_objects(const Scene& scene, const glm::dvec3& mesh_origin = glm::dvec3(0.0));

/// How far (world units) the maps may draw a corner of `object` from where
/// it is: its position is a float relative to the mesh origin, moved
/// through the light's float view matrix (`view`, relative to the origin
/// too), so off by up to about 1e-6 of the coordinates involved, as
/// seen_here bounds the camera's (scene.frag's light_rounding).
double light_view_rounding(const ConservativeObject& object, const glm::mat4& view);

/// Owners (certificate.glsl's owner_of): an analytic shape's triangles are
/// owned by the object; a model's triangle that turns its outward side to
/// the light with margin by its convex patch (core/convex_patches.hpp), any
/// other by itself alone: its index (the scene's) with the top bit set.
inline constexpr std::uint32_t kModelTriangleOwner = 0x80000000u;
/// A model's convex patch of two or more triangles: its first triangle's
/// index with the top two bits set. Scenes of kMostPatchOwnedTriangles or
/// more triangles get no patches, so that the two never name one owner.
inline constexpr std::uint32_t kModelPatchOwner = 0xC0000000u;
inline constexpr std::size_t kMostPatchOwnedTriangles = std::size_t(1) << 30;

/// Per triangle of `mesh` (by index / 3): its owner where it turns its
/// outward side to the light: a shape's object, a model's triangle's patch
/// (kModelPatchOwner | first triangle; the triangle's own owner for a patch
/// of one). Patches found once per model (convex_patches, each instance's
/// triangles numbered from its range's first).
std::vector<std::uint32_t> light_facing_owners(const Scene& scene, const Mesh& mesh);

/// What the maps hold where drawing them would take more than
/// kMostTexelTouches passes over the layer (the triangles' boxes summed:
/// objects whose rounding or swell spans much of the layer, as far from
/// the mesh origin): depth 0 everywhere, owned by no point's owner, so the
/// maps prove nothing there and the work stays bounded.
inline constexpr double kMostTexelTouches = 64.0;
inline constexpr std::uint32_t kEveryOwner = 0xFFFFFFFEu;
/// A texel no triangle touches: depth 1 (far), this owner.
inline constexpr std::uint32_t kNoOwner = 0xFFFFFFFFu;

/// Rows [y0, y1) x columns [x0, x1) of both maps, row-major.
struct ConservativeBand {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  std::vector<float> nearest_depth;
  std::vector<std::uint32_t> nearest_owner;
  std::vector<float> others_depth;
  /// The cover map (drawn only here, with `folds`; the shaders leave it
  /// far): where every light ray through the texel's square meets a
  /// triangle, the farthest depth that any triangle touching the square
  /// reaches in it, so that each such ray meets one no farther; 1 (far)
  /// where that is not proved (docs/certified-shadows.md, "The cover map").
  std::vector<float> cover_depth;
  std::vector<std::uint8_t> scratch;  ///< draw()'s, per texel
  int width() const { return x1 - x0; }
  int height() const { return y1 - y0; }
  /// No texel has a second owner (a layer that one object reaches): the
  /// others map is far everywhere, to be cleared rather than copied.
  bool others_all_far() const;
};

/// The triangles of one layer's draws, set up once for every band.
class ConservativeMaps {
 public:
  /// `positions` and `indices`: the scene's (Mesh: relative to its origin);
  /// `triangle_objects`: each triangle's object (by index / 3);
  /// `facing_owners`: light_facing_owners, taken for a model's triangle
  /// that clearly turns to the light (empty: every model triangle its own).
  /// `edges`: the scene's, paired (SliverEdges over the same positions),
  /// for the cover map's folds; null: no cover map (far everywhere).
  ConservativeMaps(const std::vector<glm::vec3>& positions, const std::vector<std::uint32_t>& indices,
                   const std::vector<ConservativeObject>& objects,
                   const std::vector<std::uint32_t>& triangle_objects, const std::vector<DrawRange>& draws,
                   const ConservativeView& view, const std::vector<std::uint32_t>& facing_owners = {},
                   const SliverEdges* edges = nullptr);
  /// Fills `band` (its rectangle set by the caller, within the maps).
  void draw(ConservativeBand& band) const;
  std::size_t triangles() const { return setups_.size(); }
  /// Drawing would have taken more than kMostTexelTouches passes over the
  /// layer: every texel holds depth 0 and kEveryOwner instead.
  bool proves_nothing() const { return too_much_; }
  /// The folds the cover map leaves far around (texels of the maps).
  std::size_t folds() const { return folds_.size(); }
  /// The texels any triangle may mark, [x0, x1) x [y0, y1) (empty when
  /// x0 >= x1): the rest of the maps stays far, with no owner.
  void touched(int& x0, int& y0, int& x1, int& y1) const;

  // One triangle (or, clipped by a point light's near plane, a quadrilateral)
  // as certify.geom hands it to certify.frag: corners in texels of the maps,
  // counter-clockwise; the window depth of its plane; its box grown by half a
  // texel, its swell and a rounding margin.
  struct Setup {
    glm::dvec2 corner[4];
    int edge_count = 0;  ///< 0: too thin for its edge normals; the box alone
    bool plane_valid = false;
    glm::dvec3 plane{0.0};  ///< depth = z + x (tx - origin.x) + y (ty - origin.y)
    glm::dvec2 origin{0.0};
    double min_depth = 0.0;
    double max_depth = 0.0;  ///< the farthest corner's window depth
    double swell = 0.0, depth_swell = 0.0;
    /// light_view_rounding in texels and in window depth (in swell and
    /// depth_swell too): what the cover map's own tests keep clear of.
    double rounding = 0.0, depth_rounding = 0.0;
    glm::dvec2 lo{0.0}, hi{0.0};
    std::uint32_t owner = 0;
  };

  // A fold: an edge across which the number of triangles a light ray meets
  // may change (its two triangles on one side of it on the layer, or not
  // both drawn, or one alone), in texels of the maps.
  struct Fold {
    glm::dvec2 a{0.0}, b{0.0};
    double reach = 0.0;  ///< texels whose centre lies this near it are marked
  };

 private:
  void finish_cover(ConservativeBand& band) const;
  struct ClipCorners;  // each corner's clip position, projected once
  void find_folds(ClipCorners& clip_of, const SliverEdges& edges, const std::vector<std::uint8_t>& drawn,
                  const std::vector<ConservativeObject>& objects, const ConservativeView& view);

  std::vector<Setup> setups_;
  std::vector<Fold> folds_;
  bool cover_ = false;  ///< edges given: the cover map is drawn
  bool too_much_ = false;  ///< kMostTexelTouches exceeded: the maps prove nothing
};

/// The most triangles a layer's maps are drawn from here: their setups take
/// 176 bytes each (46 MB at this count); heavier layers are drawn by the
/// shaders.
inline constexpr std::size_t kMostConservativeTriangles = 262144;
/// What the CPU's certified passes hold per triangle at most: a setup (184
/// bytes) beside the scene's copies kept for them (positions, indices,
/// objects and facing owners, about 56 bytes; the sliver edges, about 40),
/// and while the folds are found each corner's projection (up to 3 corners
/// of 32 bytes and a flag), rounded up; while the copies are first made,
/// the vertices and normals read back and the edges' halves (about 270
/// bytes) are alive instead, and before that convex_patches' work (about
/// 120 bytes).
inline constexpr std::uint64_t kCertifiedCpuBytesPerTriangle = 400;

/// Draws [x0, x1) x [y0, y1) of the maps in bands of rows of at most
/// `band_bytes`, as many at once as the machine has cores, and hands each
/// band to `take` on the calling thread, top band first (the GL's thread
/// uploads them).
void draw_conservative_bands(const ConservativeMaps& maps, int x0, int y0, int x1, int y1, std::size_t band_bytes,
                             const std::function<void(const ConservativeBand&)>& take);

}  // namespace umbra
