// A TriangleModel as a glTF binary: what a format converted in this
// process (CityJSON) is held and stored as, so that it is loaded, limited
// and written to --model-store as an uploaded .glb is. Pure.
#pragma once

#include <string>

#include "core/model.hpp"

namespace umbra {

/// One mesh of one primitive per part (POSITION, NORMAL, 32-bit indices,
/// the part's base colour as its material), under one node.
std::string write_glb(const TriangleModel& model);

}  // namespace umbra
