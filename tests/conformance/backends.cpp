// The backends the conformance suite runs on, and how each is created. To add a backend, add one
// VISCD_CONFORMANCE_BACKEND line below (inside the #ifdef of its build flag when it is optional)
// and its name to conformance_backends in tests/CMakeLists.txt; make_backend() reaches it
// through make_detector(), and a backend that cannot run on some machines (no device) gets an
// entry in unavailable() so that its cases skip there with the reason.
#include "conformance/conformance.hpp"

namespace viscd::conformance {

VISCD_CONFORMANCE_BACKEND(reference);
VISCD_CONFORMANCE_BACKEND(cpu);
#ifdef VISCD_HAVE_GL
VISCD_CONFORMANCE_BACKEND(gl);
#endif
#ifdef VISCD_HAVE_CUDA
VISCD_CONFORMANCE_BACKEND(cuda);
#endif

std::optional<std::string> unavailable(const std::string& backend) {
  if (backend == "gl") {
    // A plain context, created once: tells "no OpenGL 4.5 here" (skip) apart from a backend that
    // has a context but fails to build its programs (a failure of the test).
    static const Result<std::string> device = gl_device();
    if (!device) return "no OpenGL 4.5 context: " + device.error();
  }
  if (backend == "cuda") {
    static const Result<std::string> device = cuda_device();
    if (!device) return device.error();
  }
  return std::nullopt;
}

Result<std::unique_ptr<Detector>> make_backend(const std::string& backend, const Config& config) {
  if (backend == "gl") {
    // As tests/gl/gl_test_util.hpp: a debug context, so that any GL error fails the frame.
    GlOptions options;
    options.debug = true;
    return make_gl_detector(config, options);
  }
  return make_detector(backend, config);
}

}  // namespace viscd::conformance
