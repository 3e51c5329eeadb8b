#pragma once
// A headless OpenGL 4.5 core context through EGL, with debug output captured: a GPU found through
// EGL_EXT_platform_device (how NVIDIA's driver renders without a window system) first, else
// Mesa's surfaceless platform (llvmpipe on machines without a GPU, or a Mesa GPU driver).

#include <epoxy/egl.h>
#include <epoxy/gl.h>

#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "viscd/result.hpp"

namespace viscd::gl {

/// Owns an EGL display connection and a GL 4.5 core context without any surface.
/// Not thread-safe; make it current on the thread that uses it (make_current()).
class Context {
 public:
  /// Creates the context. `debug`: a debug context with synchronous debug output, whose
  /// errors are collected (take_errors()). Fails with a message naming the step that failed.
  [[nodiscard]] static Result<std::unique_ptr<Context>> create(bool debug);
  /// The caller's context, current on this thread (any window system): used, never made current,
  /// destroyed or given a debug callback by viscd. Fails when none is current or it is older
  /// than OpenGL 4.5.
  [[nodiscard]] static Result<std::unique_ptr<Context>> adopt_current();
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  /// Makes this context current on the calling thread (an adopted one: checks that a context
  /// is current, which the caller keeps so).
  [[nodiscard]] bool make_current() const;
  /// "llvmpipe (LLVM 15.0.6, 256 bits) | 4.5 (Core Profile) Mesa 22.3.6"
  [[nodiscard]] const std::string& description() const { return description_; }
  /// Debug messages of type error (and high-severity messages) since the last call.
  [[nodiscard]] std::vector<std::string> take_errors();

 private:
  Context() = default;
  // Opens a display of `platform` and a context on it; an empty string on success, else why not.
  std::string open(EGLenum platform, void* native, bool debug);
  static void GLAPIENTRY on_debug(GLenum source, GLenum type, GLuint id, GLenum severity, GLsizei length,
                                  const GLchar* message, const void* user);

  EGLDisplay display_ = EGL_NO_DISPLAY;
  EGLContext context_ = EGL_NO_CONTEXT;
  bool adopted_ = false;
  std::string description_;
  std::mutex mutex_;
  std::vector<std::string> errors_;
};

}  // namespace viscd::gl
