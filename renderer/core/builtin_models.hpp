// Models every server holds without an upload: generated here from their
// mathematical definitions, so nothing is downloaded or stored as a binary
// file. They are listed by GET /api/models like a --models folder's, and a
// mesh object may name them ("model": "teapot") in any scene. Pure CPU
// code, no GL: unit tested in tests/test_builtin_models.cpp.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/model.hpp"

namespace umbra {

/// Newell's Utah teapot (1975, public domain): its 32 bicubic Bezier
/// patches, each cut into segments x segments quads (2 x 32 x segments^2
/// triangles), turned Y-up and standing on y = 0 (about 6.5 wide, 3.15
/// high). Its surface is open (the spout's tip, the gap under the lid),
/// so the shadow pass never culls it. Normals are area-weighted over the
/// patches' welded seams; triangles wind counter-clockwise seen from
/// outside. segments in [1, 200].
std::shared_ptr<const TriangleModel> utah_teapot(int segments);

/// A (2, 3) torus knot: a tube of radius `tube` around a trefoil curve of
/// radius about 1.5 x `radius`, `tubular` rings of `radial` vertices each,
/// joined end to end, so the surface is closed and consistently wound
/// (the shadow pass may cull it). 2 x tubular x radial triangles.
/// tubular in [8, 4096], radial in [3, 512].
std::shared_ptr<const TriangleModel> torus_knot(double radius, double tube, int tubular, int radial);

struct BuiltinModel {
  std::string name;  ///< what a mesh object's "model" may say
  std::string description;
  /// "sha256:" + SHA-256 of the model's geometry (model_geometry_id): a
  /// built-in has no file to hash, but its id has the form of every other.
  std::string id;
  std::shared_ptr<const TriangleModel> model;
};

/// "teapot" (the Utah teapot at 40 segments: 102,400 triangles, open) and
/// "torus-knot" (16,384 triangles, closed). Generated on first use.
const std::vector<BuiltinModel>& builtin_models();
/// By name or id; null if none.
const BuiltinModel* find_builtin_model(const std::string& id_or_name);

}  // namespace umbra
