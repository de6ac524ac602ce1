// Filter "exact"'s sliver marks drawn on the CPU (docs/certified-shadows.md,
// "The sliver pass"): the pixels whose centre lies within kSliverPixels of
// an object's outline edge, where the main pass drew another object (or
// none). The CPU casts them.
//
// sliver.geom draws every triangle's three edges as quads, a geometry
// shader's work per triangle that llvmpipe runs slowly (columns: 11 ms).
// Only an edge where the object's surface ends on the screen can be the
// place where the raster's snapped triangles miss a centre the true ones
// cover: along an edge whose two triangles lie on opposite sides of it on
// the screen, even once snapped (kSnapPixelsBound), the snapped pair
// shares the snapped edge and covers both sides. So here only the other edges are drawn: an edge of one triangle
// (the object's border), of three or more, or of two on one side (the
// outline, where the surface turns from the camera), or of a triangle
// that reaches behind the camera. (sliver.geom also skips closed meshes'
// faces turned from the camera; here that would drop nothing more: two
// consistently wound faces turned the same way lie on either side of
// their shared edge on the screen.) The marks ignore depth: an outline
// hidden behind another object adds a few casts (a band 1/16 pixel wide
// crosses a pixel centre every 16 pixels), never a missed one. (The image's
// border is cast whole: pixels_to_ray_cast.)
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

namespace umbra {

/// Far above the rasteriser's snap (1/256 pixel), far below a pixel: the
/// half-width of the band around an edge (sliver.geom's kSliverPixels).
inline constexpr double kSliverPixels = 1.0 / 32.0;
/// A shared edge is skipped only where both triangles' third corners lie
/// on either side of it with room for the rasteriser to move every corner
/// by this much (pixels; llvmpipe snaps by 1/256, four times less): the
/// snapped pair lies on either side too.
inline constexpr double kSnapPixelsBound = 1.0 / 64.0;

/// The edges of a scene's triangles, paired once per scene: two triangles
/// of one object share an edge where its corners' positions are the same.
class SliverEdges {
 public:
  /// `positions` and `indices` as the scene's buffers (relative to the
  /// mesh origin); `triangle_objects`: each triangle's object.
  /// `model_objects`: per object, whether it is a model (a triangle mesh
  /// that need not be convex); missing ones are not.
  /// `normals` (per vertex, as the main pass interpolates them), if given,
  /// find the creases: see Edge::crease.
  SliverEdges(const std::vector<glm::vec3>& positions, const std::vector<std::uint32_t>& indices,
              const std::vector<std::uint32_t>& triangle_objects, const std::vector<bool>& model_objects = {},
              const std::vector<glm::vec3>* normals = nullptr);

  /// Marks (1) in `marks` (width x height, row 0 at the top) the pixels
  /// whose centre lies within kSliverPixels of a drawn edge (or of its
  /// ends) where `drawn_objects` (object + 1 per pixel, 0 none, in the bits
  /// from `drawn_shift` up; row 0 at the top) is not the edge's object, or
  /// whatever was drawn there where the edge is a model's: a model's
  /// outline can pass over a farther part of the same model, which the
  /// raster may show where the reference's ray meets the outline.
  /// `view_projection`: the camera's, of positions relative to the mesh
  /// origin (GL's clip space, window y up); edges are cut at half the
  /// camera's near plane (`near_plane`), as the main pass and the reference
  /// start there.
  void mark(const std::vector<glm::vec3>& positions, const glm::dmat4& view_projection, double near_plane, int width,
            int height, const std::vector<std::uint32_t>& drawn_objects, std::vector<std::uint8_t>& marks,
            unsigned drawn_shift = 0) const;

  std::size_t edges() const { return edges_.size(); }

  struct Edge {
    std::uint32_t a = 0, b = 0;  ///< corners (vertex indices)
    std::uint32_t object = 0;
    /// The third corners of the two triangles sharing it, or kOpen in
    /// `second_third` where it is not shared by exactly two.
    std::uint32_t first_third = 0, second_third = 0;
    /// The triangles (by index / 3) those corners are of (kOpen likewise).
    std::uint32_t first_triangle = 0, second_triangle = 0;
    bool model = false;  ///< the object is a model: marked over itself too
    /// Its two triangles' normals differ at an end (a box's edge, a flat-
    /// shaded model's): N.L may jump across it, so which of the two the
    /// raster shows at a centre within its snap matters even where they
    /// lie on either side of it (a face thinner than a pixel, turned to the
    /// light between two turned away, showed at no centre: a red-team
    /// pass's star prism, 1 pixel wrong). Marked over itself, always.
    bool crease = false;
  };
  static constexpr std::uint32_t kOpen = 0xFFFFFFFFu;
  /// Every edge, once (ConservativeMaps' folds read them too).
  const std::vector<Edge>& all() const { return edges_; }

 private:
  std::vector<Edge> edges_;
};

}  // namespace umbra
