#include "gl/context.hpp"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <utility>

namespace viscd::gl {
namespace {

std::string egl_error(const char* what) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%s failed (EGL error 0x%04x)", what, static_cast<unsigned>(eglGetError()));
  return buf;
}

}  // namespace

Result<std::unique_ptr<Context>> Context::create(bool debug) {
  using R = Result<std::unique_ptr<Context>>;
  std::unique_ptr<Context> ctx(new Context());
  // Client extensions: EGL_EXT_platform_base and EGL_MESA_platform_surfaceless.
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!client || std::string_view(client).find("EGL_MESA_platform_surfaceless") == std::string_view::npos)
    return R::failure(ErrorKind::backend_failure,
                      "OpenGL: EGL has no surfaceless platform (EGL_MESA_platform_surfaceless; install libegl-mesa0)");
  ctx->display_ = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
  if (ctx->display_ == EGL_NO_DISPLAY)
    return R::failure(ErrorKind::backend_failure, "OpenGL: " + egl_error("eglGetPlatformDisplayEXT(surfaceless)"));
  EGLint major = 0, minor = 0;
  if (!eglInitialize(ctx->display_, &major, &minor)) {
    ctx->display_ = EGL_NO_DISPLAY;
    return R::failure(ErrorKind::backend_failure, "OpenGL: " + egl_error("eglInitialize"));
  }
  if (!eglBindAPI(EGL_OPENGL_API))
    return R::failure(ErrorKind::backend_failure, "OpenGL: " + egl_error("eglBindAPI(EGL_OPENGL_API)"));
  const EGLint attribs[] = {EGL_CONTEXT_MAJOR_VERSION,
                            4,
                            EGL_CONTEXT_MINOR_VERSION,
                            5,
                            EGL_CONTEXT_OPENGL_PROFILE_MASK,
                            EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                            EGL_CONTEXT_OPENGL_DEBUG,
                            debug ? EGL_TRUE : EGL_FALSE,
                            EGL_NONE};
  // EGL_KHR_no_config_context: surfaceless contexts need no config.
  ctx->context_ = eglCreateContext(ctx->display_, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attribs);
  if (ctx->context_ == EGL_NO_CONTEXT)
    return R::failure(ErrorKind::backend_failure, "OpenGL: " + egl_error("eglCreateContext(OpenGL 4.5 core)") +
                                                      ": the driver offers no OpenGL 4.5 core context");
  if (!ctx->make_current())
    return R::failure(ErrorKind::backend_failure, "OpenGL: " + egl_error("eglMakeCurrent(surfaceless)"));
  if (epoxy_gl_version() < 45) return R::failure(ErrorKind::backend_failure, "OpenGL: context is older than 4.5");
  ctx->description_ = std::string(reinterpret_cast<const char*>(glGetString(GL_RENDERER))) + " | " +
                      reinterpret_cast<const char*>(glGetString(GL_VERSION));
  if (debug) {
    glEnable(GL_DEBUG_OUTPUT);
    glEnable(GL_DEBUG_OUTPUT_SYNCHRONOUS);  // messages arrive inside the offending call
    glDebugMessageCallback(&Context::on_debug, ctx.get());
    glDebugMessageControl(GL_DONT_CARE, GL_DONT_CARE, GL_DONT_CARE, 0, nullptr, GL_TRUE);
  }
  return ctx;
}

Result<std::unique_ptr<Context>> Context::adopt_current() {
  using R = Result<std::unique_ptr<Context>>;
  std::unique_ptr<Context> ctx(new Context());
  ctx->adopted_ = true;
  const GLubyte* version = glGetString(GL_VERSION);
  if (!version)
    return R::failure(ErrorKind::backend_failure,
                      "OpenGL: GlOptions::use_current_context is set, but no OpenGL context is current on this thread");
  if (epoxy_gl_version() < 45 || !epoxy_is_desktop_gl())
    return R::failure(ErrorKind::backend_failure,
                      std::string("OpenGL: the current context is ") + reinterpret_cast<const char*>(version) +
                          "; the gl backend needs OpenGL 4.5 (desktop, core or compatibility)");
  ctx->description_ = std::string(reinterpret_cast<const char*>(glGetString(GL_RENDERER))) + " | " +
                      reinterpret_cast<const char*>(version);
  return ctx;
}

Context::~Context() {
  if (display_ != EGL_NO_DISPLAY) {
    if (context_ != EGL_NO_CONTEXT) {
      eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
      eglDestroyContext(display_, context_);
    }
    // No eglTerminate: the display is shared by every context of the process (EGL returns the
    // same display for the same platform), and terminating it would break other detectors.
  }
}

bool Context::make_current() const {
  if (adopted_) return glGetString(GL_VERSION) != nullptr;
  if (eglGetCurrentContext() == context_) return true;
  return eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, context_) == EGL_TRUE;
}

std::vector<std::string> Context::take_errors() {
  std::lock_guard lock(mutex_);
  return std::exchange(errors_, {});
}

void GLAPIENTRY Context::on_debug(GLenum source, GLenum type, GLuint id, GLenum severity, GLsizei length,
                                  const GLchar* message, const void* user) {
  auto* self = static_cast<Context*>(const_cast<void*>(user));
  // Mesa reports every shader compiler message with high severity, warnings included (they
  // appear only when a shader is compiled, not when it comes from the shader cache): from the
  // compiler, only errors count. Programs check their own compile and link status as well.
  const bool error =
      type == GL_DEBUG_TYPE_ERROR || (severity == GL_DEBUG_SEVERITY_HIGH && source != GL_DEBUG_SOURCE_SHADER_COMPILER);
  if (!error) return;  // performance and other notes are not failures
  std::string text = "GL debug (id " + std::to_string(id) +
                     "): " + std::string(message, length > 0 ? static_cast<std::size_t>(length) : std::strlen(message));
  std::fprintf(stderr, "viscd: %s\n", text.c_str());
  std::lock_guard lock(self->mutex_);
  self->errors_.push_back(std::move(text));
}

}  // namespace viscd::gl
