#include "gpu/program.hpp"

#include <algorithm>
#include <optional>
#include <stdexcept>

#include "gpu/embedded_shaders.hpp"
#include "gpu/shader_interface.hpp"

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

// Links `program` (its shaders attached); throws with GL's log, naming `files`.
void link(const Program& program, const std::string& files) {
  glLinkProgram(program.id());
  GLint ok = GL_FALSE;
  glGetProgramiv(program.id(), GL_LINK_STATUS, &ok);
  if (ok != GL_TRUE)
    throw std::runtime_error("GLSL link error in " + files + ":\n" +
                             info_log(program.id(), glGetProgramiv, glGetProgramInfoLog));
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

// `file`'s text with each line `#include "name"` replaced by the embedded
// file `name` (one level: GLSL has no includes of its own), line numbers
// kept for compile errors.
std::string with_includes(std::string_view file) {
  const std::string_view text = embedded(file);
  std::string out;
  std::size_t line = 1, at = 0;
  while (at < text.size()) {
    const std::size_t end = std::min(text.find('\n', at), text.size());
    const std::string_view current = text.substr(at, end - at);
    constexpr std::string_view kInclude = "#include \"";
    if (current.substr(0, kInclude.size()) == kInclude && current.back() == '"') {
      out += embedded(current.substr(kInclude.size(), current.size() - kInclude.size() - 1));
      out += "\n#line " + std::to_string(line + 1) + "\n";
    } else {
      out += current;
      out += '\n';
    }
    ++line;
    at = end + 1;
  }
  return out;
}

}  // namespace

Program build_program(std::string_view vertex_file, std::string_view fragment_file, const std::string& prelude) {
  return build_program(vertex_file, "", fragment_file, prelude);
}

Program build_program(std::string_view vertex_file, std::string_view geometry_file, std::string_view fragment_file,
                      const std::string& prelude) {
  Program program = build_program_from_sources(
      vertex_file, prelude + with_includes(vertex_file), fragment_file, prelude + with_includes(fragment_file),
      geometry_file, geometry_file.empty() ? std::string() : prelude + with_includes(geometry_file));
  check_block_layout(program);
  check_bindings(program);
  return program;
}

Program build_compute_program(std::string_view compute_file, const std::string& prelude) {
  const Shader compute = compile(GL_COMPUTE_SHADER, compute_file, prelude + with_includes(compute_file));
  Program program(glCreateProgram());
  glAttachShader(program.id(), compute.id());
  link(program, std::string(compute_file));
  check_block_layout(program);
  check_bindings(program);
  return program;
}

const Program& ProgramVariants::get(const std::string& defines) {
  for (auto it = kept_.begin(); it != kept_.end(); ++it) {
    if (it->first != defines) continue;
    kept_.splice(kept_.begin(), kept_, it);
    return kept_.front().second;
  }
  Program built = build_program(vertex_file_, geometry_file_, fragment_file_, glsl_prelude(defines));
  // Room first, so the program returned is never the one evicted.
  while (!kept_.empty() && kept_.size() >= capacity_) kept_.pop_back();
  kept_.emplace_front(defines, std::move(built));
  return kept_.front().second;
}

void check_block_layout(const Program& program) {
  const GLuint block = glGetUniformBlockIndex(program.id(), "FrameBlock");
  if (block == GL_INVALID_INDEX) return;  // not used
  GLint size = 0;
  glGetActiveUniformBlockiv(program.id(), block, GL_UNIFORM_BLOCK_DATA_SIZE, &size);
  if (size <= 0 || std::size_t(size) > sizeof(FrameBlock))
    throw std::runtime_error("FrameBlock is " + std::to_string(size) + " bytes in GL, " +
                             std::to_string(sizeof(FrameBlock)) + " in C++");
  std::size_t count = 0;
  const BlockMember* members = frame_block_members(count);
  for (std::size_t i = 0; i < count; ++i) {
    const BlockMember& m = members[i];
    GLuint index = GL_INVALID_INDEX;
    glGetUniformIndices(program.id(), 1, &m.gl_name, &index);
    GLint offset = -1, stride = -1;
    if (index != GL_INVALID_INDEX) {
      glGetActiveUniformsiv(program.id(), 1, &index, GL_UNIFORM_OFFSET, &offset);
      glGetActiveUniformsiv(program.id(), 1, &index, GL_UNIFORM_ARRAY_STRIDE, &stride);
    }
    if (offset != GLint(m.offset) || stride != GLint(m.array_stride))
      throw std::runtime_error(std::string("FrameBlock member ") + m.gl_name + " is at GL offset " +
                               std::to_string(offset) + " stride " + std::to_string(stride) + ", C++ has " +
                               std::to_string(m.offset) + " stride " + std::to_string(m.array_stride));
  }
}

Program build_program_from_sources(std::string_view vertex_file, std::string_view vertex_source,
                                   std::string_view fragment_file, std::string_view fragment_source,
                                   std::string_view geometry_file, std::string_view geometry_source) {
  const Shader vertex = compile(GL_VERTEX_SHADER, vertex_file, vertex_source);
  const Shader fragment = compile(GL_FRAGMENT_SHADER, fragment_file, fragment_source);
  Program program(glCreateProgram());
  glAttachShader(program.id(), vertex.id());
  glAttachShader(program.id(), fragment.id());
  std::optional<Shader> geometry;
  if (!geometry_source.empty()) {
    geometry.emplace(compile(GL_GEOMETRY_SHADER, geometry_file, geometry_source));
    glAttachShader(program.id(), geometry->id());
  }
  link(program, std::string(vertex_file) + " + " + std::string(fragment_file));
  return program;
}

void check_bindings(const Program& program) {
  const GLuint id = program.id();
  const auto refuse = [](const std::string& what, GLint gl, int cxx) {
    throw std::runtime_error(what + " is " + std::to_string(gl) + " in GL, " + std::to_string(cxx) +
                             " in C++ (shader_interface.hpp)");
  };
  for (const VertexAttribute& a : kVertexAttributes) {
    const GLint location = glGetAttribLocation(id, a.glsl_name);
    if (location >= 0 && location != a.location) refuse(std::string("attribute ") + a.glsl_name, location, a.location);
  }
  const GLint output = glGetFragDataLocation(id, "o_color");
  if (output >= 0 && output != kFragOutputColor) refuse("output o_color", output, kFragOutputColor);
  const GLint layer = glGetUniformLocation(id, "u_layer");
  if (layer >= 0 && layer != kUniformLocationLayer) refuse("uniform u_layer's location", layer, kUniformLocationLayer);
  for (const auto& [name, cxx] : {std::pair{"o_certificate", kFragOutputCertificate}, std::pair{"o_unlit", kFragOutputUnlit}}) {
    const GLint at = glGetFragDataLocation(id, name);
    if (at >= 0 && at != cxx) refuse(std::string("output ") + name, at, cxx);
  }
  const GLint ring = glGetUniformLocation(id, "u_ring");
  if (ring >= 0 && ring != kUniformLocationCastRing) refuse("uniform u_ring's location", ring, kUniformLocationCastRing);
  const GLint base = glGetUniformLocation(id, "u_triangle_base");
  if (base >= 0 && base != kUniformLocationTriangleBase)
    refuse("uniform u_triangle_base's location", base, kUniformLocationTriangleBase);
  // A sampler's or an image's uniform holds its unit.
  const auto check_units = [&](const auto& units, const char* what) {
    for (const TextureUnit& u : units) {
      const GLint uniform = glGetUniformLocation(id, u.glsl_name);
      if (uniform < 0) continue;
      GLint unit = -1;
      glGetUniformiv(id, uniform, &unit);
      if (unit != u.unit) refuse(std::string(u.glsl_name) + "'s " + what, unit, u.unit);
    }
  };
  check_units(kTextureUnits, "texture unit");
  check_units(kImageUnits, "image unit");
  const GLuint list = glGetProgramResourceIndex(id, GL_SHADER_STORAGE_BLOCK, "CastList");
  if (list != GL_INVALID_INDEX) {
    const GLenum property = GL_BUFFER_BINDING;
    GLint binding = -1;
    glGetProgramResourceiv(id, GL_SHADER_STORAGE_BLOCK, list, 1, &property, 1, nullptr, &binding);
    if (binding != kStorageBufferCastList) refuse("CastList's buffer binding", binding, kStorageBufferCastList);
  }
  const GLuint block = glGetUniformBlockIndex(id, "FrameBlock");
  if (block != GL_INVALID_INDEX) {
    GLint binding = -1;
    glGetActiveUniformBlockiv(id, block, GL_UNIFORM_BLOCK_BINDING, &binding);
    if (binding != kUniformBufferFrameBlock) refuse("FrameBlock's buffer binding", binding, kUniformBufferFrameBlock);
  }
}

GLint uniform_location(const Program& program, const char* name) {
  const GLint location = glGetUniformLocation(program.id(), name);
  if (location < 0) throw std::runtime_error(std::string("no active uniform '") + name + "'");
  return location;
}

}  // namespace umbra::gl
