#include "gl/program.hpp"

#include <vector>

#include "viscd/assert.hpp"

#include "gl/shader_sources.hpp"

namespace viscd::gl {
namespace {

// Inserts `defines` after the first line (#version ...).
std::string with_defines(std::string_view src, std::string_view defines) {
  const std::size_t eol = src.find('\n');
  std::string s;
  s.reserve(src.size() + defines.size() + 1);
  s.append(src.substr(0, eol + 1));
  s.append(defines);
  if (!defines.empty() && defines.back() != '\n') s.push_back('\n');
  s.append(src.substr(eol + 1));
  return s;
}

std::string shader_log(GLuint s) {
  GLint len = 0;
  glGetShaderiv(s, GL_INFO_LOG_LENGTH, &len);
  std::string log(static_cast<std::size_t>(std::max(len, 1)), '\0');
  glGetShaderInfoLog(s, len, nullptr, log.data());
  return log.c_str();
}

std::string program_log(GLuint p) {
  GLint len = 0;
  glGetProgramiv(p, GL_INFO_LOG_LENGTH, &len);
  std::string log(static_cast<std::size_t>(std::max(len, 1)), '\0');
  glGetProgramInfoLog(p, len, nullptr, log.data());
  return log.c_str();
}

Result<Shader> compile(GLenum stage, std::string_view name, std::string_view defines) {
  const std::string_view src = find_shader(name);
  if (src.empty())
    return Result<Shader>::failure(ErrorKind::backend_failure,
                                   "OpenGL: no embedded shader named '" + std::string(name) + "'");
  const std::string text = with_defines(src, defines);
  Shader s(glCreateShader(stage));
  const char* ptr = text.c_str();
  glShaderSource(s.get(), 1, &ptr, nullptr);
  glCompileShader(s.get());
  GLint ok = GL_FALSE;
  glGetShaderiv(s.get(), GL_COMPILE_STATUS, &ok);
  if (ok != GL_TRUE)
    return Result<Shader>::failure(ErrorKind::backend_failure, "OpenGL: shader " + std::string(name) +
                                                                   " does not compile:\n" + shader_log(s.get()));
  return s;
}

Result<ProgramHandle> link(std::initializer_list<GLuint> shaders, std::string_view what) {
  ProgramHandle p(glCreateProgram());
  for (GLuint s : shaders) glAttachShader(p.get(), s);
  glLinkProgram(p.get());
  GLint ok = GL_FALSE;
  glGetProgramiv(p.get(), GL_LINK_STATUS, &ok);
  for (GLuint s : shaders) glDetachShader(p.get(), s);
  if (ok != GL_TRUE)
    return Result<ProgramHandle>::failure(ErrorKind::backend_failure, "OpenGL: program " + std::string(what) +
                                                                          " does not link:\n" + program_log(p.get()));
  return p;
}

}  // namespace

Result<Program> Program::compute(std::string_view name, std::string_view defines) {
  auto s = compile(GL_COMPUTE_SHADER, name, defines);
  if (!s) return Result<Program>::failure(s.status());
  auto p = link({s.value().get()}, name);
  if (!p) return Result<Program>::failure(p.status());
  Program prog;
  prog.handle_ = std::move(p.value());
  GLint size[3] = {1, 1, 1};
  glGetProgramiv(prog.get(), GL_COMPUTE_WORK_GROUP_SIZE, size);
  prog.local_size_ = static_cast<GLuint>(size[0]);
  prog.read_uniforms();
  return prog;
}

Result<Program> Program::graphics(std::string_view vert, std::string_view frag, std::string_view defines) {
  auto v = compile(GL_VERTEX_SHADER, vert, defines);
  if (!v) return Result<Program>::failure(v.status());
  auto f = compile(GL_FRAGMENT_SHADER, frag, defines);
  if (!f) return Result<Program>::failure(f.status());
  auto p = link({v.value().get(), f.value().get()}, std::string(vert) + " + " + std::string(frag));
  if (!p) return Result<Program>::failure(p.status());
  Program prog;
  prog.handle_ = std::move(p.value());
  prog.read_uniforms();
  return prog;
}

void Program::read_uniforms() {
  GLint count = 0, longest = 0;
  glGetProgramiv(handle_.get(), GL_ACTIVE_UNIFORMS, &count);
  glGetProgramiv(handle_.get(), GL_ACTIVE_UNIFORM_MAX_LENGTH, &longest);
  std::string name(static_cast<std::size_t>(std::max(longest, 1)), '\0');
  uniforms_.clear();
  for (GLint k = 0; k < count; ++k) {
    GLsizei length = 0;
    GLint size = 0;
    GLenum type = 0;
    glGetActiveUniform(handle_.get(), static_cast<GLuint>(k), longest, &length, &size, &type, name.data());
    std::string n(name.data(), static_cast<std::size_t>(length));
    if (n.ends_with("[0]")) n.resize(n.size() - 3);
    const GLint location = glGetUniformLocation(handle_.get(), n.c_str());
    if (location >= 0) uniforms_.emplace_back(std::move(n), location);  // uniform blocks' members have none
  }
}

bool Program::has_uniform(std::string_view name) const {
  for (const auto& u : uniforms_)
    if (u.first == name) return true;
  return false;
}

GLint Program::uniform(std::string_view name) const {
  for (const auto& [n, location] : uniforms_)
    if (n == name) return location;
  VISCD_ASSERT(false, "the program has no active uniform of this name");
  return -1;
}

void Program::dispatch(std::uint64_t n) const {
  if (n == 0) return;
  glUseProgram(handle_.get());
  glDispatchCompute(groups_for(n), 1, 1);
}

Status build_compute_programs(std::initializer_list<std::pair<Program*, const char*>> programs) {
  for (const auto& [program, name] : programs) {
    auto p = Program::compute(name);
    if (!p) return p.status();
    *program = std::move(p.value());
  }
  return {};
}

}  // namespace viscd::gl
