// CityJSON (1.0, 1.1, 2.0), the JSON encoding of CityGML that city model
// tools write (3DBAG, cjio, FME...): every city object's surfaces at one
// level of detail, triangulated, in Umbra's frame. Pure: no GL, no HTTP.
//
// Conventions (docs/api.md, "CityJSON"): CityJSON's coordinates are a
// projected reference system's, in metres, z up and y north; Umbra's
// scenes are y up with north at -z. A vertex (x, y, z) becomes
// (x - cx, z - z0, -(y - cy)), where (cx, cy) is the middle of the chosen
// geometry's plan bounds and z0 its lowest point: the model stands on
// y = 0 about the origin, north at -z, and keeps its real sizes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "core/model.hpp"

namespace umbra {

/// JSON values a CityJSON file may hold (parsed, each costs tens of bytes).
constexpr std::size_t kMaxCityJsonValues = std::size_t(4) << 20;
constexpr std::size_t kMaxCityJsonDepth = 32;

struct CityJsonOptions {
  /// The level of detail read ("2.2", "1"): each object's geometry of that
  /// LoD, objects without one left out. Empty: each object's highest.
  std::string lod;
  std::size_t max_triangles = std::size_t(4) << 20;
  /// As LoadOptions::admit: asked with the model's size bound and triangle
  /// count before its triangles are built; non-zero refuses with `why`.
  std::function<int(std::uint64_t bytes, std::size_t triangles, std::string& why)> admit;
};

struct CityJsonResult {
  std::shared_ptr<TriangleModel> model;  ///< set on success
  int status = 0;                        ///< 0, 400 (not valid CityJSON) or 422 (beyond what is taken)
  std::string error;
  std::vector<std::string> lods;   ///< the levels of detail the file has, ascending
  std::size_t objects = 0;         ///< city objects with a surface at the LoD read
  std::size_t left_out = 0;        ///< geometries not read: points and lines (or templates of them)
  std::size_t fell_back = 0;       ///< surfaces ear clipping could not finish (fanned)
  bool ok() const { return model != nullptr; }
};

CityJsonResult load_cityjson(std::string_view bytes, const CityJsonOptions& options);

}  // namespace umbra
