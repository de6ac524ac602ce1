// GLSL programs built from the shader files embedded at build time.
#pragma once

#include <list>
#include <string>
#include <utility>
#include <string_view>

#include "gpu/objects.hpp"

namespace umbra::gl {

/// Compiles and links `vertex_file` + `fragment_file` (names under shaders/),
/// each preceded by `prelude` (the #version line, #defines and the uniform
/// block: see glsl_prelude in shader_interface.hpp; the files have none of
/// their own). Throws std::runtime_error carrying the GLSL compile or link
/// log, or naming a FrameBlock member whose layout differs from C++'s, or
/// a binding that differs from C++'s (check_bindings).
/// A line `#include "name"` in a file is replaced by the embedded file `name`.
Program build_program(std::string_view vertex_file, std::string_view fragment_file, const std::string& prelude);
/// The same with a geometry shader (none if `geometry_file` is empty).
Program build_program(std::string_view vertex_file, std::string_view geometry_file, std::string_view fragment_file,
                      const std::string& prelude);

/// A compute program from `compute_file`, preceded by `prelude`; checked
/// as build_program's are.
Program build_compute_program(std::string_view compute_file, const std::string& prelude);

/// The same from sources in memory; the names only label error messages.
Program build_program_from_sources(std::string_view vertex_name, std::string_view vertex_source,
                                   std::string_view fragment_name, std::string_view fragment_source,
                                   std::string_view geometry_name = {}, std::string_view geometry_source = {});

/// The variants of one vertex + fragment pair, built when first asked for,
/// each selected by its #define lines; the `capacity` most recently used are
/// kept (a software rasteriser's compiled program is large).
class ProgramVariants {
 public:
  ProgramVariants(std::string vertex_file, std::string fragment_file, std::size_t capacity)
      : vertex_file_(std::move(vertex_file)), fragment_file_(std::move(fragment_file)), capacity_(capacity) {}
  /// With a geometry shader.
  ProgramVariants(std::string vertex_file, std::string geometry_file, std::string fragment_file, std::size_t capacity)
      : vertex_file_(std::move(vertex_file)),
        geometry_file_(std::move(geometry_file)),
        fragment_file_(std::move(fragment_file)),
        capacity_(capacity) {}
  /// The program for `defines`, built with glsl_prelude(defines) if it is
  /// not kept; throws as build_program does.
  const Program& get(const std::string& defines);
  std::size_t size() const { return kept_.size(); }

 private:
  std::string vertex_file_, geometry_file_, fragment_file_;
  std::size_t capacity_;
  std::list<std::pair<std::string, Program>> kept_;  // most recently used first
};

/// Throws unless every member of the program's FrameBlock (if it uses one)
/// sits at the offset, with the array stride, that the C++ struct has.
void check_block_layout(const Program& program);

/// Throws unless every input, output and uniform of the program that the
/// C++ side binds by number (shader_interface.hpp: vertex attributes, the
/// colour output, u_layer, u_shadow_map's texture unit, FrameBlock's
/// buffer binding) sits at that number: a shader that names its own number,
/// or none, for one of them fails to build instead of reading the wrong
/// input. Names a program does not use are not checked.
void check_bindings(const Program& program);

/// A uniform's location; throws if the program has no active uniform of that
/// name, so a typo fails loudly at start-up instead of drawing silently wrong.
GLint uniform_location(const Program& program, const char* name);

}  // namespace umbra::gl
