// What drawing a mesh object's triangles costs on llvmpipe, as the cost
// model (service/request_cost.hpp) prices it: the renderer sizes the chunks
// of a long draw by the same numbers, so they live below both. Pure C++, no
// GL.
#pragma once

#include <glm/mat4x4.hpp>

#include "core/scene.hpp"

namespace umbra {

// Calibration (see request_cost.cpp for how every constant was measured):
// milliseconds on the reference machine.
inline constexpr double kMsPerDrawnTriangle = 1.0e-4;     // per view: 895 ms main, 417..594 ms shadow, 9.0 M
// A triangle tested against a 64 x 64 tile (mesh_tile_tests), measured with
// issue 29's slivers: triangles 100 x 100 world units corner to corner and
// 1e-4 wide, one object seen face on from a point light and a camera at
// 60 units, map 1024^2, 2048^2 and 4096^2 (each sliver's box covers the
// whole map: 256, 1,024 and 4,096 tiles), 20,000 and 200,000 slivers:
// Server-Timing's shadow pass over the tiles the estimate counts,
// rounded up (see the comment at mesh_tile_tests' test).
inline constexpr double kMsPerTileTest = 1.0e-5;

/// An upper bound on the 64 x 64 tiles llvmpipe tests a mesh object's
/// triangles against when it draws them into a `width` x `height` view
/// (0 for other objects): llvmpipe bins a triangle into every tile its
/// bounding box overlaps, so a long sliver costs about (its length in
/// pixels / 64)^2 tile tests however thin it is. Each triangle's box is at
/// most its longest edge squared (TriangleModel::edge_lengths) times the
/// view's stretch at the object's nearest point, and at most the object's
/// bounds' rectangle in the view. O(the model's edge length bins).
double mesh_tile_tests(const SceneObject& mesh, const glm::dmat4& view_projection, double width, double height);

/// Estimated milliseconds to draw a mesh object's triangles into that view,
/// depth only, as the estimate prices them: per triangle and per tile test
/// (not the fragments of its layers, ViewLayers). What the renderer sizes
/// the chunks of a long draw by.
double mesh_draw_ms(const SceneObject& mesh, const glm::dmat4& view_projection, double width, double height);

}  // namespace umbra
