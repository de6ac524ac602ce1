#include "program.hpp"

#include <stdexcept>

#include "../embedded_shaders.hpp"

namespace umbra::gl {

namespace {

// The info log of a shader or program, through the matching GL getters.
template <class GetIv, class GetLog>
std::string info_log(GLuint object, GetIv get_iv, GetLog get_log) {
  GLint length = 0;
  get_iv(object, GL_INFO_LOG_LENGTH, &length);
  std::string log(std::size_t(length > 0 ? length : 1), '\0');
  get_log(object, GLsizei(log.size()), nullptr, log.data());
  return log;
}

Shader compile(GLenum stage, std::string_view file, std::string_view source) {
  Shader shader(glCreateShader(stage));
  const GLchar* text = source.data();
  const GLint length = GLint(source.size());
  glShaderSource(shader.id(), 1, &text, &length);
  glCompileShader(shader.id());
  GLint ok = GL_FALSE;
  glGetShaderiv(shader.id(), GL_COMPILE_STATUS, &ok);
  if (ok != GL_TRUE)
    throw std::runtime_error("GLSL compile error in shaders/" + std::string(file) + ":\n" +
                             info_log(shader.id(), glGetShaderiv, glGetShaderInfoLog));
  return shader;
}

std::string_view embedded(std::string_view file) {
  const std::string_view source = shader_source(file);
  if (source.empty()) throw std::runtime_error("shader not embedded: " + std::string(file));
  return source;
}

}  // namespace

Program build_program(std::string_view vertex_file, std::string_view fragment_file) {
  return build_program_from_sources(vertex_file, embedded(vertex_file), fragment_file, embedded(fragment_file));
}

Program build_program_from_sources(std::string_view vertex_file, std::string_view vertex_source,
                                   std::string_view fragment_file, std::string_view fragment_source) {
  const Shader vertex = compile(GL_VERTEX_SHADER, vertex_file, vertex_source);
  const Shader fragment = compile(GL_FRAGMENT_SHADER, fragment_file, fragment_source);
  Program program(glCreateProgram());
  glAttachShader(program.id(), vertex.id());
  glAttachShader(program.id(), fragment.id());
  glLinkProgram(program.id());
  GLint ok = GL_FALSE;
  glGetProgramiv(program.id(), GL_LINK_STATUS, &ok);
  if (ok != GL_TRUE)
    throw std::runtime_error("GLSL link error in " + std::string(vertex_file) + " + " + std::string(fragment_file) +
                             ":\n" + info_log(program.id(), glGetProgramiv, glGetProgramInfoLog));
  return program;
}

GLint uniform_location(const Program& program, const char* name) {
  const GLint location = glGetUniformLocation(program.id(), name);
  if (location < 0) throw std::runtime_error(std::string("no active uniform '") + name + "'");
  return location;
}

}  // namespace umbra::gl
