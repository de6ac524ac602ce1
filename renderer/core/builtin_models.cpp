#include "core/builtin_models.hpp"

#include <array>
#include <cmath>
#include <map>
#include <stdexcept>
#include <tuple>

#include <glm/geometric.hpp>

namespace umbra {

namespace {

// Newell's teapot as published in Crow's "The Origins of the Teapot" (IEEE
// CG&A, 1987) and in the "teaset" data every graphics package carries: 306
// control points (Z up) and 32 patches of 4 x 4 of them, row by row.
// Patches 0-3 are the rim, 4-11 the body, 12-15 the handle, 16-19 the
// spout, 20-27 the lid and 28-31 the bottom. Shared edges are listed in the
// same order by both patches, so their points evaluate bit for bit alike.
constexpr float kTeapotPoints[306][3] = {
    {1.4, 0.0, 2.4}, {1.4, -0.784, 2.4}, {0.784, -1.4, 2.4}, {0.0, -1.4, 2.4}, {1.3375, 0.0, 2.53125},
    {1.3375, -0.749, 2.53125}, {0.749, -1.3375, 2.53125}, {0.0, -1.3375, 2.53125}, {1.4375, 0.0, 2.53125},
    {1.4375, -0.805, 2.53125}, {0.805, -1.4375, 2.53125}, {0.0, -1.4375, 2.53125}, {1.5, 0.0, 2.4}, {1.5, -0.84, 2.4},
    {0.84, -1.5, 2.4}, {0.0, -1.5, 2.4}, {-0.784, -1.4, 2.4}, {-1.4, -0.784, 2.4}, {-1.4, 0.0, 2.4},
    {-0.749, -1.3375, 2.53125}, {-1.3375, -0.749, 2.53125}, {-1.3375, 0.0, 2.53125}, {-0.805, -1.4375, 2.53125},
    {-1.4375, -0.805, 2.53125}, {-1.4375, 0.0, 2.53125}, {-0.84, -1.5, 2.4}, {-1.5, -0.84, 2.4}, {-1.5, 0.0, 2.4},
    {-1.4, 0.784, 2.4}, {-0.784, 1.4, 2.4}, {0.0, 1.4, 2.4}, {-1.3375, 0.749, 2.53125}, {-0.749, 1.3375, 2.53125},
    {0.0, 1.3375, 2.53125}, {-1.4375, 0.805, 2.53125}, {-0.805, 1.4375, 2.53125}, {0.0, 1.4375, 2.53125},
    {-1.5, 0.84, 2.4}, {-0.84, 1.5, 2.4}, {0.0, 1.5, 2.4}, {0.784, 1.4, 2.4}, {1.4, 0.784, 2.4},
    {0.749, 1.3375, 2.53125}, {1.3375, 0.749, 2.53125}, {0.805, 1.4375, 2.53125}, {1.4375, 0.805, 2.53125},
    {0.84, 1.5, 2.4}, {1.5, 0.84, 2.4}, {1.75, 0.0, 1.875}, {1.75, -0.98, 1.875}, {0.98, -1.75, 1.875},
    {0.0, -1.75, 1.875}, {2.0, 0.0, 1.35}, {2.0, -1.12, 1.35}, {1.12, -2.0, 1.35}, {0.0, -2.0, 1.35}, {2.0, 0.0, 0.9},
    {2.0, -1.12, 0.9}, {1.12, -2.0, 0.9}, {0.0, -2.0, 0.9}, {-0.98, -1.75, 1.875}, {-1.75, -0.98, 1.875},
    {-1.75, 0.0, 1.875}, {-1.12, -2.0, 1.35}, {-2.0, -1.12, 1.35}, {-2.0, 0.0, 1.35}, {-1.12, -2.0, 0.9},
    {-2.0, -1.12, 0.9}, {-2.0, 0.0, 0.9}, {-1.75, 0.98, 1.875}, {-0.98, 1.75, 1.875}, {0.0, 1.75, 1.875},
    {-2.0, 1.12, 1.35}, {-1.12, 2.0, 1.35}, {0.0, 2.0, 1.35}, {-2.0, 1.12, 0.9}, {-1.12, 2.0, 0.9}, {0.0, 2.0, 0.9},
    {0.98, 1.75, 1.875}, {1.75, 0.98, 1.875}, {1.12, 2.0, 1.35}, {2.0, 1.12, 1.35}, {1.12, 2.0, 0.9},
    {2.0, 1.12, 0.9}, {2.0, 0.0, 0.45}, {2.0, -1.12, 0.45}, {1.12, -2.0, 0.45}, {0.0, -2.0, 0.45}, {1.5, 0.0, 0.225},
    {1.5, -0.84, 0.225}, {0.84, -1.5, 0.225}, {0.0, -1.5, 0.225}, {1.5, 0.0, 0.15}, {1.5, -0.84, 0.15},
    {0.84, -1.5, 0.15}, {0.0, -1.5, 0.15}, {-1.12, -2.0, 0.45}, {-2.0, -1.12, 0.45}, {-2.0, 0.0, 0.45},
    {-0.84, -1.5, 0.225}, {-1.5, -0.84, 0.225}, {-1.5, 0.0, 0.225}, {-0.84, -1.5, 0.15}, {-1.5, -0.84, 0.15},
    {-1.5, 0.0, 0.15}, {-2.0, 1.12, 0.45}, {-1.12, 2.0, 0.45}, {0.0, 2.0, 0.45}, {-1.5, 0.84, 0.225},
    {-0.84, 1.5, 0.225}, {0.0, 1.5, 0.225}, {-1.5, 0.84, 0.15}, {-0.84, 1.5, 0.15}, {0.0, 1.5, 0.15},
    {1.12, 2.0, 0.45}, {2.0, 1.12, 0.45}, {0.84, 1.5, 0.225}, {1.5, 0.84, 0.225}, {0.84, 1.5, 0.15},
    {1.5, 0.84, 0.15}, {-1.6, 0.0, 2.025}, {-1.6, -0.3, 2.025}, {-1.5, -0.3, 2.25}, {-1.5, 0.0, 2.25},
    {-2.3, 0.0, 2.025}, {-2.3, -0.3, 2.025}, {-2.5, -0.3, 2.25}, {-2.5, 0.0, 2.25}, {-2.7, 0.0, 2.025},
    {-2.7, -0.3, 2.025}, {-3.0, -0.3, 2.25}, {-3.0, 0.0, 2.25}, {-2.7, 0.0, 1.8}, {-2.7, -0.3, 1.8},
    {-3.0, -0.3, 1.8}, {-3.0, 0.0, 1.8}, {-1.5, 0.3, 2.25}, {-1.6, 0.3, 2.025}, {-2.5, 0.3, 2.25}, {-2.3, 0.3, 2.025},
    {-3.0, 0.3, 2.25}, {-2.7, 0.3, 2.025}, {-3.0, 0.3, 1.8}, {-2.7, 0.3, 1.8}, {-2.7, 0.0, 1.575},
    {-2.7, -0.3, 1.575}, {-3.0, -0.3, 1.35}, {-3.0, 0.0, 1.35}, {-2.5, 0.0, 1.125}, {-2.5, -0.3, 1.125},
    {-2.65, -0.3, 0.9375}, {-2.65, 0.0, 0.9375}, {-2.0, -0.3, 0.9}, {-1.9, -0.3, 0.6}, {-1.9, 0.0, 0.6},
    {-3.0, 0.3, 1.35}, {-2.7, 0.3, 1.575}, {-2.65, 0.3, 0.9375}, {-2.5, 0.3, 1.125}, {-1.9, 0.3, 0.6},
    {-2.0, 0.3, 0.9}, {1.7, 0.0, 1.425}, {1.7, -0.66, 1.425}, {1.7, -0.66, 0.6}, {1.7, 0.0, 0.6}, {2.6, 0.0, 1.425},
    {2.6, -0.66, 1.425}, {3.1, -0.66, 0.825}, {3.1, 0.0, 0.825}, {2.3, 0.0, 2.1}, {2.3, -0.25, 2.1},
    {2.4, -0.25, 2.025}, {2.4, 0.0, 2.025}, {2.7, 0.0, 2.4}, {2.7, -0.25, 2.4}, {3.3, -0.25, 2.4}, {3.3, 0.0, 2.4},
    {1.7, 0.66, 0.6}, {1.7, 0.66, 1.425}, {3.1, 0.66, 0.825}, {2.6, 0.66, 1.425}, {2.4, 0.25, 2.025},
    {2.3, 0.25, 2.1}, {3.3, 0.25, 2.4}, {2.7, 0.25, 2.4}, {2.8, 0.0, 2.475}, {2.8, -0.25, 2.475},
    {3.525, -0.25, 2.49375}, {3.525, 0.0, 2.49375}, {2.9, 0.0, 2.475}, {2.9, -0.15, 2.475}, {3.45, -0.15, 2.5125},
    {3.45, 0.0, 2.5125}, {2.8, 0.0, 2.4}, {2.8, -0.15, 2.4}, {3.2, -0.15, 2.4}, {3.2, 0.0, 2.4},
    {3.525, 0.25, 2.49375}, {2.8, 0.25, 2.475}, {3.45, 0.15, 2.5125}, {2.9, 0.15, 2.475}, {3.2, 0.15, 2.4},
    {2.8, 0.15, 2.4}, {0.0, 0.0, 3.15}, {0.0, -0.002, 3.15}, {0.002, 0.0, 3.15}, {0.8, 0.0, 3.15}, {0.8, -0.45, 3.15},
    {0.45, -0.8, 3.15}, {0.0, -0.8, 3.15}, {0.0, 0.0, 2.85}, {0.2, 0.0, 2.7}, {0.2, -0.112, 2.7}, {0.112, -0.2, 2.7},
    {0.0, -0.2, 2.7}, {-0.002, 0.0, 3.15}, {-0.45, -0.8, 3.15}, {-0.8, -0.45, 3.15}, {-0.8, 0.0, 3.15},
    {-0.112, -0.2, 2.7}, {-0.2, -0.112, 2.7}, {-0.2, 0.0, 2.7}, {0.0, 0.002, 3.15}, {-0.8, 0.45, 3.15},
    {-0.45, 0.8, 3.15}, {0.0, 0.8, 3.15}, {-0.2, 0.112, 2.7}, {-0.112, 0.2, 2.7}, {0.0, 0.2, 2.7}, {0.45, 0.8, 3.15},
    {0.8, 0.45, 3.15}, {0.112, 0.2, 2.7}, {0.2, 0.112, 2.7}, {0.4, 0.0, 2.55}, {0.4, -0.224, 2.55},
    {0.224, -0.4, 2.55}, {0.0, -0.4, 2.55}, {1.3, 0.0, 2.55}, {1.3, -0.728, 2.55}, {0.728, -1.3, 2.55},
    {0.0, -1.3, 2.55}, {1.3, 0.0, 2.4}, {1.3, -0.728, 2.4}, {0.728, -1.3, 2.4}, {0.0, -1.3, 2.4},
    {-0.224, -0.4, 2.55}, {-0.4, -0.224, 2.55}, {-0.4, 0.0, 2.55}, {-0.728, -1.3, 2.55}, {-1.3, -0.728, 2.55},
    {-1.3, 0.0, 2.55}, {-0.728, -1.3, 2.4}, {-1.3, -0.728, 2.4}, {-1.3, 0.0, 2.4}, {-0.4, 0.224, 2.55},
    {-0.224, 0.4, 2.55}, {0.0, 0.4, 2.55}, {-1.3, 0.728, 2.55}, {-0.728, 1.3, 2.55}, {0.0, 1.3, 2.55},
    {-1.3, 0.728, 2.4}, {-0.728, 1.3, 2.4}, {0.0, 1.3, 2.4}, {0.224, 0.4, 2.55}, {0.4, 0.224, 2.55},
    {0.728, 1.3, 2.55}, {1.3, 0.728, 2.55}, {0.728, 1.3, 2.4}, {1.3, 0.728, 2.4}, {0.0, 0.0, 0.0}, {1.5, 0.0, 0.15},
    {1.5, 0.84, 0.15}, {0.84, 1.5, 0.15}, {0.0, 1.5, 0.15}, {1.5, 0.0, 0.075}, {1.5, 0.84, 0.075}, {0.84, 1.5, 0.075},
    {0.0, 1.5, 0.075}, {1.425, 0.0, 0.0}, {1.425, 0.798, 0.0}, {0.798, 1.425, 0.0}, {0.0, 1.425, 0.0},
    {-0.84, 1.5, 0.15}, {-1.5, 0.84, 0.15}, {-1.5, 0.0, 0.15}, {-0.84, 1.5, 0.075}, {-1.5, 0.84, 0.075},
    {-1.5, 0.0, 0.075}, {-0.798, 1.425, 0.0}, {-1.425, 0.798, 0.0}, {-1.425, 0.0, 0.0}, {-1.5, -0.84, 0.15},
    {-0.84, -1.5, 0.15}, {0.0, -1.5, 0.15}, {-1.5, -0.84, 0.075}, {-0.84, -1.5, 0.075}, {0.0, -1.5, 0.075},
    {-1.425, -0.798, 0.0}, {-0.798, -1.425, 0.0}, {0.0, -1.425, 0.0}, {0.84, -1.5, 0.15}, {1.5, -0.84, 0.15},
    {0.84, -1.5, 0.075}, {1.5, -0.84, 0.075}, {0.798, -1.425, 0.0}, {1.425, -0.798, 0.0},
};

constexpr int kTeapotPatches[32][16] = {
    {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15},
    {3, 16, 17, 18, 7, 19, 20, 21, 11, 22, 23, 24, 15, 25, 26, 27},
    {18, 28, 29, 30, 21, 31, 32, 33, 24, 34, 35, 36, 27, 37, 38, 39},
    {30, 40, 41, 0, 33, 42, 43, 4, 36, 44, 45, 8, 39, 46, 47, 12},
    {12, 13, 14, 15, 48, 49, 50, 51, 52, 53, 54, 55, 56, 57, 58, 59},
    {15, 25, 26, 27, 51, 60, 61, 62, 55, 63, 64, 65, 59, 66, 67, 68},
    {27, 37, 38, 39, 62, 69, 70, 71, 65, 72, 73, 74, 68, 75, 76, 77},
    {39, 46, 47, 12, 71, 78, 79, 48, 74, 80, 81, 52, 77, 82, 83, 56},
    {56, 57, 58, 59, 84, 85, 86, 87, 88, 89, 90, 91, 92, 93, 94, 95},
    {59, 66, 67, 68, 87, 96, 97, 98, 91, 99, 100, 101, 95, 102, 103, 104},
    {68, 75, 76, 77, 98, 105, 106, 107, 101, 108, 109, 110, 104, 111, 112, 113},
    {77, 82, 83, 56, 107, 114, 115, 84, 110, 116, 117, 88, 113, 118, 119, 92},
    {120, 121, 122, 123, 124, 125, 126, 127, 128, 129, 130, 131, 132, 133, 134, 135},
    {123, 136, 137, 120, 127, 138, 139, 124, 131, 140, 141, 128, 135, 142, 143, 132},
    {132, 133, 134, 135, 144, 145, 146, 147, 148, 149, 150, 151, 68, 152, 153, 154},
    {135, 142, 143, 132, 147, 155, 156, 144, 151, 157, 158, 148, 154, 159, 160, 68},
    {161, 162, 163, 164, 165, 166, 167, 168, 169, 170, 171, 172, 173, 174, 175, 176},
    {164, 177, 178, 161, 168, 179, 180, 165, 172, 181, 182, 169, 176, 183, 184, 173},
    {173, 174, 175, 176, 185, 186, 187, 188, 189, 190, 191, 192, 193, 194, 195, 196},
    {176, 183, 184, 173, 188, 197, 198, 185, 192, 199, 200, 189, 196, 201, 202, 193},
    {203, 203, 203, 203, 206, 207, 208, 209, 210, 210, 210, 210, 211, 212, 213, 214},
    {203, 203, 203, 203, 209, 216, 217, 218, 210, 210, 210, 210, 214, 219, 220, 221},
    {203, 203, 203, 203, 218, 223, 224, 225, 210, 210, 210, 210, 221, 226, 227, 228},
    {203, 203, 203, 203, 225, 229, 230, 206, 210, 210, 210, 210, 228, 231, 232, 211},
    {211, 212, 213, 214, 233, 234, 235, 236, 237, 238, 239, 240, 241, 242, 243, 244},
    {214, 219, 220, 221, 236, 245, 246, 247, 240, 248, 249, 250, 244, 251, 252, 253},
    {221, 226, 227, 228, 247, 254, 255, 256, 250, 257, 258, 259, 253, 260, 261, 262},
    {228, 231, 232, 211, 256, 263, 264, 233, 259, 265, 266, 237, 262, 267, 268, 241},
    {269, 269, 269, 269, 278, 279, 280, 281, 274, 275, 276, 277, 270, 271, 272, 273},
    {269, 269, 269, 269, 281, 288, 289, 290, 277, 285, 286, 287, 273, 282, 283, 284},
    {269, 269, 269, 269, 290, 297, 298, 299, 287, 294, 295, 296, 284, 291, 292, 293},
    {269, 269, 269, 269, 299, 304, 305, 278, 296, 302, 303, 274, 293, 300, 301, 270},
};

// The cubic Bernstein weights at t. At t = 0 and t = 1 they are exactly
// (1, 0, 0, 0) and (0, 0, 0, 1), which keeps shared patch edges identical.
std::array<double, 4> bernstein(double t) {
  const double s = 1.0 - t;
  return {s * s * s, 3.0 * t * s * s, 3.0 * t * t * s, t * t * t};
}

// Adds the triangles of `grid` (rows x columns of vertex indices, row-major)
// to `indices`, counter-clockwise when `row_then_column_faces_out` says that
// the corner order (r, c), (r + 1, c), (r, c + 1) already does.
void add_grid_quads(const std::vector<std::uint32_t>& grid, int rows, int columns, bool row_then_column_faces_out,
                    std::vector<std::uint32_t>& indices) {
  for (int r = 0; r + 1 < rows; ++r) {
    for (int c = 0; c + 1 < columns; ++c) {
      const std::uint32_t a = grid[std::size_t(r) * columns + c], b = grid[std::size_t(r + 1) * columns + c];
      const std::uint32_t d = grid[std::size_t(r) * columns + c + 1], e = grid[std::size_t(r + 1) * columns + c + 1];
      if (row_then_column_faces_out)
        indices.insert(indices.end(), {a, b, d, d, b, e});
      else
        indices.insert(indices.end(), {a, d, b, b, d, e});
    }
  }
}

}  // namespace

std::shared_ptr<const TriangleModel> utah_teapot(int segments) {
  if (segments < 1 || segments > 200) throw std::invalid_argument("utah_teapot: segments must be in [1, 200]");
  ModelPart part;
  part.base_color = {0.82f, 0.80f, 0.74f};  // glazed porcelain
  // Points are welded by exact position, so that patches meeting along an
  // edge share its vertices and the normals there are smooth.
  std::map<std::tuple<float, float, float>, std::uint32_t> welded;
  const int n = segments;
  std::vector<std::uint32_t> grid(std::size_t(n + 1) * (n + 1));
  for (const auto& patch : kTeapotPatches) {
    for (int i = 0; i <= n; ++i) {
      const std::array<double, 4> bu = bernstein(double(i) / n);
      for (int j = 0; j <= n; ++j) {
        const std::array<double, 4> bv = bernstein(double(j) / n);
        glm::dvec3 p(0.0);
        for (int r = 0; r < 4; ++r)
          for (int c = 0; c < 4; ++c) {
            const float* q = kTeapotPoints[patch[4 * r + c]];
            p += (bu[std::size_t(r)] * bv[std::size_t(c)]) * glm::dvec3(q[0], q[1], q[2]);
          }
        // Z up -> Y up: a rotation of -90 degrees about X, which keeps the
        // winding.
        const glm::vec3 y_up(float(p.x), float(p.z), float(-p.y));
        const auto [it, added] =
            welded.emplace(std::make_tuple(y_up.x, y_up.y, y_up.z), std::uint32_t(part.positions.size()));
        if (added) part.positions.push_back(y_up);
        grid[std::size_t(i) * (n + 1) + j] = it->second;
      }
    }
    // Every patch of this data set has dP/du x dP/dv pointing into the pot
    // (u down the rows, v along them): the other corner order faces out.
    add_grid_quads(grid, n + 1, n + 1, false, part.indices);
  }
  part.normals = area_weighted_normals(part.positions, part.indices);
  auto model = std::make_shared<TriangleModel>();
  model->parts.push_back(std::move(part));
  finish_model(*model);
  return model;
}

std::shared_ptr<const TriangleModel> torus_knot(double radius, double tube, int tubular, int radial) {
  if (tubular < 8 || tubular > 4096 || radial < 3 || radial > 512 || !(radius > 0.0) || !(tube > 0.0))
    throw std::invalid_argument("torus_knot: tubular in [8, 4096], radial in [3, 512], radius and tube > 0");
  constexpr double kPi = 3.14159265358979323846;
  constexpr int p = 2, q = 3;
  // The (p, q) knot winds p times around the torus's axis (Y) and q times
  // through its hole; u in [0, 2 pi p) runs along it once.
  const auto curve = [&](double u) {
    const double w = double(q) / p * u;
    const double r = radius * (2.0 + std::cos(w)) * 0.5;
    return glm::dvec3(r * std::cos(u), radius * std::sin(w) * 0.5, r * std::sin(u));
  };
  ModelPart part;
  part.base_color = {0.30f, 0.55f, 0.85f};
  const double du = 2.0 * kPi * p / tubular;
  for (int i = 0; i < tubular; ++i) {
    const double u = i * du;
    const glm::dvec3 centre = curve(u);
    // A frame around the curve from its tangent and the direction away
    // from the torus's centre; it turns smoothly and comes back to itself
    // after one lap, because it depends on u alone.
    const glm::dvec3 tangent = glm::normalize(curve(u + 1e-4) - curve(u - 1e-4));
    const glm::dvec3 binormal = glm::normalize(glm::cross(tangent, centre));
    const glm::dvec3 normal = glm::cross(binormal, tangent);
    for (int j = 0; j < radial; ++j) {
      const double v = 2.0 * kPi * j / radial;
      const glm::dvec3 out = std::cos(v) * normal + std::sin(v) * binormal;
      part.positions.emplace_back(centre + tube * out);
      part.normals.emplace_back(out);
    }
  }
  // Rings and the points on them wrap around: the grid's last row and
  // column are its first, which is what makes the surface closed.
  const auto vertex = [&](int i, int j) { return std::uint32_t((i % tubular) * radial + j % radial); };
  for (int i = 0; i < tubular; ++i)
    for (int j = 0; j < radial; ++j) {
      const std::uint32_t a = vertex(i, j), b = vertex(i + 1, j), d = vertex(i, j + 1), e = vertex(i + 1, j + 1);
      // b - a runs along the tangent T and d - a turns `out` from N towards
      // B; with N = B x T, T x (dout/dv) = -out: (d - a) x (b - a) faces out.
      part.indices.insert(part.indices.end(), {a, d, b, b, d, e});
    }
  auto model = std::make_shared<TriangleModel>();
  model->parts.push_back(std::move(part));
  finish_model(*model);
  return model;
}

const std::vector<BuiltinModel>& builtin_models() {
  static const std::vector<BuiltinModel> models = [] {
    std::vector<BuiltinModel> list;
    const auto add = [&](std::string name, std::string description, std::shared_ptr<const TriangleModel> model) {
      std::string id = model_geometry_id(*model);
      list.push_back({std::move(name), std::move(description), std::move(id), std::move(model)});
    };
    add("teapot", "Newell's Utah teapot, 102,400 triangles, open (6.5 wide, 3.15 high, standing on y = 0)",
        utah_teapot(40));
    add("torus-knot", "A (2, 3) torus knot, 16,384 triangles, closed (about 3 across, centred on the origin)",
        torus_knot(1.0, 0.22, 256, 32));
    return list;
  }();
  return models;
}

const BuiltinModel* find_builtin_model(const std::string& id_or_name) {
  for (const BuiltinModel& m : builtin_models())
    if (m.name == id_or_name || m.id == id_or_name) return &m;
  return nullptr;
}

}  // namespace umbra
