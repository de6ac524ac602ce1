// GLSL programs built from the shader files embedded at build time.
#pragma once

#include <string>
#include <string_view>

#include "objects.hpp"

namespace umbra::gl {

/// Compiles and links `vertex_file` + `fragment_file` (names under shaders/).
/// Throws std::runtime_error carrying the GLSL compile or link log.
Program build_program(std::string_view vertex_file, std::string_view fragment_file);

/// The same from sources in memory; the names only label error messages.
Program build_program_from_sources(std::string_view vertex_name, std::string_view vertex_source,
                                   std::string_view fragment_name, std::string_view fragment_source);

/// A uniform's location; throws if the program has no active uniform of that
/// name, so a typo fails loudly at start-up instead of drawing silently wrong.
GLint uniform_location(const Program& program, const char* name);

}  // namespace umbra::gl
