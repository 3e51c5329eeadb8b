#pragma once
// Shader programs built from the embedded sources, every compile and link checked with its log.

#include <array>
#include <initializer_list>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "gl/objects.hpp"
#include "viscd/result.hpp"

namespace viscd::gl {

/// Makes every write of the passes before visible to every read of the passes after. The
/// compute passes of a frame depend on each other in sequence, so one full barrier between them
/// is what the backend uses (docs/gl.md).
inline void barrier() { glMemoryBarrier(GL_ALL_BARRIER_BITS); }

/// A linked program. Compute programs know their work-group size (GL_COMPUTE_WORK_GROUP_SIZE).
class Program {
 public:
  Program() = default;
  /// A compute program from one embedded shader. `defines` (e.g. "#define X 3\n") is inserted
  /// after the #version line.
  [[nodiscard]] static Result<Program> compute(std::string_view name, std::string_view defines = {});
  /// A graphics program from an embedded vertex and fragment shader.
  [[nodiscard]] static Result<Program> graphics(std::string_view vert, std::string_view frag,
                                                std::string_view defines = {});

  [[nodiscard]] GLuint get() const { return handle_.get(); }
  [[nodiscard]] explicit operator bool() const { return static_cast<bool>(handle_); }
  /// Local size x of a compute program.
  [[nodiscard]] GLuint local_size() const { return local_size_; }
  /// Work groups covering n elements: ceil(n / local size).
  [[nodiscard]] GLuint groups_for(std::uint64_t n) const {
    return static_cast<GLuint>((n + local_size_ - 1) / local_size_);
  }
  /// Location of an active uniform, from the table read once at link time (no GL call). An
  /// array is named without "[0]". Asserts that the program has it: a misspelt name, or a
  /// uniform the shader does not use, is a bug.
  [[nodiscard]] GLint uniform(std::string_view name) const;
  /// Whether the program has this active uniform (for one shared by some programs only).
  [[nodiscard]] bool has_uniform(std::string_view name) const;
  /// Binds the program and dispatches ceil(n / local size) groups (nothing when n == 0).
  void dispatch(std::uint64_t n) const;

 private:
  void read_uniforms();

  ProgramHandle handle_;
  GLuint local_size_ = 1;
  std::vector<std::pair<std::string, GLint>> uniforms_;  // active uniforms: name, location
};

/// Builds compute programs without defines: each `*first` from the embedded shader named
/// `second`, in the order given; stops at the first that fails and returns its error.
[[nodiscard]] Status build_compute_programs(std::initializer_list<std::pair<Program*, const char*>> programs);

}  // namespace viscd::gl
