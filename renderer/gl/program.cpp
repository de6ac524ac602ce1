#include "program.hpp"

#include <stdexcept>

#include "../embedded_shaders.hpp"

namespace umbra::gl {

namespace {

Shader compile(GLenum stage, std::string_view file) {
  const std::string_view source = shader_source(file);
  if (source.empty()) throw std::runtime_error("shader not embedded: " + std::string(file));
  Shader shader(glCreateShader(stage));
  const GLchar* text = source.data();
  const GLint length = GLint(source.size());
  glShaderSource(shader.id(), 1, &text, &length);
  glCompileShader(shader.id());
  GLint ok = GL_FALSE;
  glGetShaderiv(shader.id(), GL_COMPILE_STATUS, &ok);
  if (ok != GL_TRUE) {
    GLint log_length = 0;
    glGetShaderiv(shader.id(), GL_INFO_LOG_LENGTH, &log_length);
    std::string log(std::size_t(log_length > 0 ? log_length : 1), '\0');
    glGetShaderInfoLog(shader.id(), GLsizei(log.size()), nullptr, log.data());
    throw std::runtime_error("GLSL compile error in shaders/" + std::string(file) + ":\n" + log);
  }
  return shader;
}

}  // namespace

Program build_program(std::string_view vertex_file, std::string_view fragment_file) {
  const Shader vertex = compile(GL_VERTEX_SHADER, vertex_file);
  const Shader fragment = compile(GL_FRAGMENT_SHADER, fragment_file);
  Program program(glCreateProgram());
  glAttachShader(program.id(), vertex.id());
  glAttachShader(program.id(), fragment.id());
  glLinkProgram(program.id());
  GLint ok = GL_FALSE;
  glGetProgramiv(program.id(), GL_LINK_STATUS, &ok);
  if (ok != GL_TRUE) {
    GLint log_length = 0;
    glGetProgramiv(program.id(), GL_INFO_LOG_LENGTH, &log_length);
    std::string log(std::size_t(log_length > 0 ? log_length : 1), '\0');
    glGetProgramInfoLog(program.id(), GLsizei(log.size()), nullptr, log.data());
    throw std::runtime_error("GLSL link error in " + std::string(vertex_file) + " + " +
                             std::string(fragment_file) + ":\n" + log);
  }
  return program;
}

GLint uniform_location(const Program& program, const char* name) {
  const GLint location = glGetUniformLocation(program.id(), name);
  if (location < 0) throw std::runtime_error(std::string("no active uniform '") + name + "'");
  return location;
}

}  // namespace umbra::gl
