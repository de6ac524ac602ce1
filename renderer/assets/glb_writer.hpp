// A TriangleModel as a glTF binary: what a format converted in this
// process (CityJSON) is held and stored as, so that it is loaded, limited
// and written to --model-store as an uploaded .glb is. Pure.
#pragma once

#include <string>
#include <string_view>

#include "core/model.hpp"

namespace umbra {

/// One mesh of one primitive per part (POSITION, NORMAL, 32-bit indices,
/// the part's base colour as its material), under one node.
std::string write_glb(const TriangleModel& model);

/// A GLB container: its 12-byte header, `json` as its JSON chunk (padded
/// with spaces), then `chunks`, the chunks that follow as they are (a BIN
/// chunk with its own 8-byte header, or nothing).
std::string glb_container(std::string json, std::string_view chunks);

}  // namespace umbra
