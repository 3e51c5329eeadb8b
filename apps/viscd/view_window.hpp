#pragma once
// The window side of `viscd view`, each piece owned by a small RAII type so that every way out of
// the viewer (the window closed, an error, an exception) tears down in the right order: GLFW
// (GlfwLibrary), its window and OpenGL 3.3 core context (GlfwWindow), Dear ImGui's context and
// backends (ImGuiLayer), a texture of the window's context (GlTexture). Made in that order (the
// texture last, inside the viewer), they are destroyed in the reverse one: texture, ImGui (which
// needs the window's context and callbacks), window, GLFW. DetectorGuard brackets calls into a gl detector, whose EGL
// context must not be current together with the window's GLX one.
#include <epoxy/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <string>

namespace viscd::app {

/// GLFW for this process: glfwInit() when made (its error callback installed first),
/// glfwTerminate() when it goes, which also destroys any window still open. One at a time.
class GlfwLibrary {
 public:
  GlfwLibrary();
  ~GlfwLibrary();
  GlfwLibrary(const GlfwLibrary&) = delete;
  GlfwLibrary& operator=(const GlfwLibrary&) = delete;
  /// Whether glfwInit() succeeded (it fails without a display).
  [[nodiscard]] bool ok() const { return ok_; }
  /// The last message GLFW reported, empty if none.
  [[nodiscard]] static const std::string& last_error();

 private:
  bool ok_ = false;
};

/// A GLFW window with an OpenGL 3.3 core (forward-compatible) context, made current on this
/// thread; destroyed when it goes. Needs a GlfwLibrary that outlives it.
class GlfwWindow {
 public:
  GlfwWindow(int width, int height, const char* title);
  ~GlfwWindow();
  GlfwWindow(const GlfwWindow&) = delete;
  GlfwWindow& operator=(const GlfwWindow&) = delete;
  /// The window, or nullptr when it could not be opened.
  [[nodiscard]] GLFWwindow* get() const { return window_; }

 private:
  GLFWwindow* window_ = nullptr;
};

/// Dear ImGui on a window: its context (no imgui.ini, dark style), then the GLFW and OpenGL3
/// backends; when it goes, the backends that started are shut down and then the context is
/// destroyed. The window's context must be current when it is made and when it goes, and the
/// window must outlive it (the GLFW backend restores the window's callbacks).
class ImGuiLayer {
 public:
  explicit ImGuiLayer(GLFWwindow* window);
  ~ImGuiLayer();
  ImGuiLayer(const ImGuiLayer&) = delete;
  ImGuiLayer& operator=(const ImGuiLayer&) = delete;
  /// Whether both backends started.
  [[nodiscard]] bool ok() const { return glfw_ && opengl_; }

 private:
  bool glfw_ = false, opengl_ = false;
};

/// A 2D texture of the window's context, linear filtering, clamped to the edge; deleted when it
/// goes. That context must be current when it is made and when it goes.
class GlTexture {
 public:
  GlTexture();
  ~GlTexture();
  GlTexture(const GlTexture&) = delete;
  GlTexture& operator=(const GlTexture&) = delete;
  [[nodiscard]] GLuint id() const { return id_; }

 private:
  GLuint id_ = 0;
};

/// Brackets a call into a gl detector (create, detect, destroy): the window's context off before,
/// the detector's context off and the window's back after. A no-op when `gl` is false (cpu).
class DetectorGuard {
 public:
  DetectorGuard(GLFWwindow* window, bool gl);
  ~DetectorGuard();
  DetectorGuard(const DetectorGuard&) = delete;
  DetectorGuard& operator=(const DetectorGuard&) = delete;

 private:
  GLFWwindow* window_;
  bool gl_;
};

}  // namespace viscd::app
