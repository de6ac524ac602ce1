// Triangle models: the user's own geometry (glTF meshes, gltf_loader.hpp),
// held by the ModelStore and, later, drawn and ray-cast like the analytic
// primitives. Pure CPU code, no GL: unit tested in tests/test_model.cpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <glm/vec3.hpp>

#include "core/scene.hpp"

namespace umbra {

/// The triangles of one base colour. Counter-clockwise triangles face out
/// (glTF's convention, and tessellate()'s): a loader flips the winding of
/// mirrored instances so that this holds in model space.
struct ModelPart {
  std::vector<glm::vec3> positions;     ///< model space (the glTF scene's root space)
  std::vector<glm::vec3> normals;       ///< one per position, unit length
  std::vector<std::uint32_t> indices;   ///< three per triangle, each < positions.size()
  glm::vec3 base_color{1.0f};           ///< linear RGB in [0, 1] (baseColorFactor)

  std::size_t triangle_count() const { return indices.size() / 3; }
  /// Adds a primitive's vertices and its triangles (indices into those
  /// vertices), moved past the vertices the part holds already.
  void append(const std::vector<glm::vec3>& more_positions, const std::vector<glm::vec3>& more_normals,
              const std::vector<std::uint32_t>& more_indices);
};

/// Triangles whose longest edge is about one length (within a factor of 2):
/// how many, and the sum of their longest edges squared. A projection that
/// stretches world lengths by at most sx along screen x and sy along y
/// gives each triangle a bounding box of at most sx * sy * edge^2.
struct EdgeLengthBin {
  double triangles = 0.0;
  double squared_edges = 0.0;
};

/// A whole model: its parts (one per distinct base colour), bounds, and
/// whether it is closed, which decides front-face culling in the shadow pass.
struct ModelRig;  // model_rig.hpp

struct TriangleModel {
  std::vector<ModelPart> parts;
  Aabb bounds;          ///< of every position; empty for a model without triangles
  bool closed = false;  ///< see is_closed(): set by finish_model()
  /// The triangles' area vectors (normal times area, model space) summed
  /// by direction (binned_area_vectors): set by finish_model(), read by the
  /// cost estimate (projected_area) to count how deep the triangles overlap
  /// in a view, which the bounds alone do not tell.
  std::vector<glm::dvec3> area_vectors;
  /// The triangles' longest edges (model space), squared and summed by
  /// length (edge_length_bins): set by finish_model(), read by the cost
  /// estimate and the renderer (mesh_tile_tests) to bound how many 64 x 64
  /// tiles llvmpipe tests the triangles against, which grows with their
  /// projected bounding boxes, not with their area: a long sliver has
  /// almost none.
  std::vector<EdgeLengthBin> edge_lengths;
  /// Primitives of points or lines the file held (once per node that
  /// instances them), left out: they cast no shadow.
  std::size_t skipped_primitives = 0;
  /// What moves, for a file with animations (model_rig.hpp): these parts
  /// are its rest pose, and pose_model() makes the others. Null otherwise.
  std::shared_ptr<const ModelRig> rig;

  std::size_t triangle_count() const;
  /// What the model holds in memory (its vectors' capacities, its rig and
  /// itself): what the ModelStore's budget counts.
  std::size_t bytes() const;
};

/// How many directions binned_area_vectors sorts triangles' areas into.
constexpr std::size_t kAreaDirectionBins = 384;

/// How many lengths edge_length_bins sorts triangles into (powers of 2,
/// from 2^-32 to 2^31 and beyond at either end).
constexpr std::size_t kEdgeLengthBins = 64;

/// The most TriangleModel::bytes() can be for a finished model (after
/// finish_model) of `triangles` triangles, `vertices` positions and
/// `parts` parts: what a loader knows before it reads a vertex, so that a
/// model is counted against a memory budget before it is built.
std::uint64_t model_bytes_bound(std::uint64_t triangles, std::uint64_t vertices, std::uint64_t parts);

/// True when the triangles form closed, consistently wound surfaces that
/// face out: every edge is shared by exactly two triangles that run along it
/// in opposite directions, and every shell (triangles joined by edges)
/// encloses a positive volume, so that it winds counter-clockwise seen from
/// outside. Only then is a face that looks away from the eye hidden behind
/// one of its own shell's faces that looks toward it, which is what lets the
/// shadow pass cull front faces and the main pass back faces. (A hollow
/// solid's inner shell faces into the cavity, so it is not closed: drawn
/// two-sided, only slower.) Vertices are welded by exact position (glTF
/// splits vertices at hard edges and colour seams), across parts. Triangles
/// with two equal welded corners are ignored (they have no area and cast no
/// shadow). An empty model is not closed. Time O(n log n), memory about 24
/// bytes per triangle corner.
bool is_closed(const std::vector<ModelPart>& parts);

/// Area-weighted vertex normals of one indexed triangle list: each
/// triangle adds its unnormalized cross product (twice its area) to its
/// three corners. A vertex that only degenerate triangles touch gets +Y.
std::vector<glm::vec3> area_weighted_normals(const std::vector<glm::vec3>& positions,
                                             const std::vector<std::uint32_t>& indices);

/// Each triangle's area vector ((b - a) x (c - a) / 2: its normal times its
/// area), summed over bins of direction (the 6 faces of a cube of
/// directions, 8 x 8 bins each; empty bins left out). Within a bin the
/// vectors point within about 11 degrees of each other, so
/// sum |d . bin| is sum |d . triangle| but for the few bins that straddle
/// the plane normal to d. O(triangles), once per model.
std::vector<glm::dvec3> binned_area_vectors(const std::vector<ModelPart>& parts);

/// The area of the model's triangles projected along `direction` (model
/// space; its length scales the result), each triangle counted once
/// whichever way it faces: sum |direction . a| over area_vectors. What
/// rasterising every triangle (no culling) along that direction fills,
/// overlaps counted as often as they are drawn. O(area_vectors.size() <= 384).
double projected_area(const TriangleModel& model, const glm::dvec3& direction);

/// Each triangle's longest edge, squared, summed by its power of 2
/// (empty bins and triangles with no edge left out). O(triangles), once per
/// model.
std::vector<EdgeLengthBin> edge_length_bins(const std::vector<ModelPart>& parts);

/// Sets bounds, closed, area_vectors and edge_lengths from the parts, and trims spare
/// capacity.
void finish_model(TriangleModel& model);

/// "sha256:" and the 64 lowercase hex digits of SHA-256(bytes): the id of
/// an uploaded or folder model (the hash of its file).
std::string model_id_for(std::string_view bytes);

/// model_id_for() of the model's geometry (each part's positions,
/// normals, indices and base colour, as stored): the id of a model that
/// has no file, such as the built-in ones.
std::string model_geometry_id(const TriangleModel& model);

}  // namespace umbra
