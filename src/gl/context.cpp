#include "gl/context.hpp"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string_view>
#include <utility>

namespace viscd::gl {
namespace {

std::string egl_error(const char* what) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%s failed (EGL error 0x%04x)", what, static_cast<unsigned>(eglGetError()));
  return buf;
}

bool has_extension(const char* list, std::string_view name) {
  if (!list) return false;
  for (std::string_view rest(list); !rest.empty();) {
    const std::size_t end = rest.find(' ');
    if (rest.substr(0, end) == name) return true;
    if (end == std::string_view::npos) break;
    rest.remove_prefix(end + 1);
  }
  return false;
}

// A display to try: a GPU through EGL_EXT_platform_device (NVIDIA's way to render without a
// window system), or Mesa's surfaceless platform (llvmpipe, or a Mesa GPU driver).
struct Candidate {
  EGLenum platform;
  void* native;
  std::string name;
};

std::vector<Candidate> candidates(const char* client) {
  std::vector<Candidate> out;
  if (has_extension(client, "EGL_EXT_platform_device") && has_extension(client, "EGL_EXT_device_enumeration")) {
    EGLDeviceEXT devices[16];
    EGLint count = 0;
    if (eglQueryDevicesEXT(16, devices, &count)) {
      for (EGLint i = 0; i < count; ++i) {
        // Mesa lists its software rasterizer as a device too; the surfaceless platform below
        // reaches it already.
        if (has_extension(eglQueryDeviceStringEXT(devices[i], EGL_EXTENSIONS), "EGL_MESA_device_software")) continue;
        out.push_back({EGL_PLATFORM_DEVICE_EXT, devices[i], "EGL device " + std::to_string(i)});
      }
    }
  }
  if (has_extension(client, "EGL_MESA_platform_surfaceless"))
    out.push_back({EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, "surfaceless"});
  return out;
}

}  // namespace

Result<std::unique_ptr<Context>> Context::create(bool debug) {
  using R = Result<std::unique_ptr<Context>>;
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!client || !has_extension(client, "EGL_EXT_platform_base"))
    return R::failure(ErrorKind::backend_failure,
                      "OpenGL: EGL has no platform extensions (EGL_EXT_platform_base); install libegl1 and a driver "
                      "(libegl-mesa0, or the GPU vendor's)");
  const std::vector<Candidate> tries = candidates(client);
  if (tries.empty())
    return R::failure(ErrorKind::backend_failure,
                      "OpenGL: EGL offers neither a GPU device (EGL_EXT_platform_device) nor a surfaceless platform "
                      "(EGL_MESA_platform_surfaceless; install libegl-mesa0)");
  std::string failures;
  for (const Candidate& c : tries) {
    std::unique_ptr<Context> ctx(new Context());
    std::string why = ctx->open(c.platform, c.native, debug);
    if (why.empty()) return ctx;
    failures += (failures.empty() ? "" : "; ") + c.name + ": " + why;
  }
  return R::failure(ErrorKind::backend_failure,
                    "OpenGL: no EGL display gave an OpenGL 4.5 core context (" + failures + ")");
}

std::string Context::open(EGLenum platform, void* native, bool debug) {
  display_ = eglGetPlatformDisplayEXT(platform, native, nullptr);
  if (display_ == EGL_NO_DISPLAY) return egl_error("eglGetPlatformDisplayEXT");
  EGLint major = 0, minor = 0;
  if (!eglInitialize(display_, &major, &minor)) {
    display_ = EGL_NO_DISPLAY;
    return egl_error("eglInitialize");
  }
  if (!eglBindAPI(EGL_OPENGL_API)) return egl_error("eglBindAPI(EGL_OPENGL_API)");
  const EGLint attribs[] = {EGL_CONTEXT_MAJOR_VERSION,
                            4,
                            EGL_CONTEXT_MINOR_VERSION,
                            5,
                            EGL_CONTEXT_OPENGL_PROFILE_MASK,
                            EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                            EGL_CONTEXT_OPENGL_DEBUG,
                            debug ? EGL_TRUE : EGL_FALSE,
                            EGL_NONE};
  // EGL_KHR_no_config_context: a context without surfaces needs no config. Where the display
  // lacks it, any config that renders OpenGL will do (nothing is ever drawn to its surfaces).
  EGLConfig config = EGL_NO_CONFIG_KHR;
  if (!has_extension(eglQueryString(display_, EGL_EXTENSIONS), "EGL_KHR_no_config_context")) {
    const EGLint want[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLint found = 0;
    if (!eglChooseConfig(display_, want, &config, 1, &found) || found < 1) return egl_error("eglChooseConfig(OpenGL)");
  }
  context_ = eglCreateContext(display_, config, EGL_NO_CONTEXT, attribs);
  if (context_ == EGL_NO_CONTEXT)
    return egl_error("eglCreateContext(OpenGL 4.5 core)") + ": the driver offers no OpenGL 4.5 core context";
  if (!make_current()) return egl_error("eglMakeCurrent(no surface)");
  if (epoxy_gl_version() < 45) return "the context is older than OpenGL 4.5";
  description_ = std::string(reinterpret_cast<const char*>(glGetString(GL_RENDERER))) + " | " +
                 reinterpret_cast<const char*>(glGetString(GL_VERSION));
  if (debug) {
    glEnable(GL_DEBUG_OUTPUT);
    glEnable(GL_DEBUG_OUTPUT_SYNCHRONOUS);  // messages arrive inside the offending call
    glDebugMessageCallback(&Context::on_debug, this);
    glDebugMessageControl(GL_DONT_CARE, GL_DONT_CARE, GL_DONT_CARE, 0, nullptr, GL_TRUE);
  }
  return {};
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
