// The viewer's window, Dear ImGui and texture owners, and the context bracket of the gl detector.
#include "view_window.hpp"

#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <epoxy/egl.h>
#include <imgui.h>

namespace viscd::app {
namespace {

std::string glfw_error_text;

void on_glfw_error(int code, const char* message) {
  glfw_error_text = message ? message : ("GLFW error " + std::to_string(code));
}

}  // namespace

GlfwLibrary::GlfwLibrary() {
  glfwSetErrorCallback(on_glfw_error);  // before glfwInit, so that its failure is explained
  ok_ = glfwInit() == GLFW_TRUE;
}

GlfwLibrary::~GlfwLibrary() {
  if (ok_) glfwTerminate();
}

const std::string& GlfwLibrary::last_error() { return glfw_error_text; }

GlfwWindow::GlfwWindow(int width, int height, const char* title) {
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  window_ = glfwCreateWindow(width, height, title, nullptr, nullptr);
  if (window_) glfwMakeContextCurrent(window_);
}

GlfwWindow::~GlfwWindow() {
  if (window_) glfwDestroyWindow(window_);
}

ImGuiLayer::ImGuiLayer(GLFWwindow* window) {
  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini in the working folder
  ImGui::StyleColorsDark();
  glfw_ = ImGui_ImplGlfw_InitForOpenGL(window, true);
  if (glfw_) opengl_ = ImGui_ImplOpenGL3_Init("#version 330 core");
}

ImGuiLayer::~ImGuiLayer() {
  // Each backend asserts when shut down without having started.
  if (opengl_) ImGui_ImplOpenGL3_Shutdown();
  if (glfw_) ImGui_ImplGlfw_Shutdown();
  ImGui::DestroyContext();
}

GlTexture::GlTexture() {
  glGenTextures(1, &id_);
  glBindTexture(GL_TEXTURE_2D, id_);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
}

GlTexture::~GlTexture() { glDeleteTextures(1, &id_); }

DetectorGuard::DetectorGuard(GLFWwindow* window, bool gl) : window_(window), gl_(gl) {
  if (gl_) glfwMakeContextCurrent(nullptr);
}

DetectorGuard::~DetectorGuard() {
  if (!gl_) return;
  // libglvnd refuses to make the window's GLX context current while the detector's EGL one is.
  if (eglGetCurrentContext() != EGL_NO_CONTEXT)
    eglMakeCurrent(eglGetCurrentDisplay(), EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  glfwMakeContextCurrent(window_);
}

}  // namespace viscd::app
