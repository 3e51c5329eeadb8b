// The backends by name (make_detector()), and the entry points of the backends this build leaves
// out, which say so.
#include <string>

#include "viscd/cuda.hpp"
#include "viscd/detector.hpp"
#include "viscd/gl.hpp"

namespace viscd {

#ifndef VISCD_HAVE_GL
// Without the gl backend (VISCD_ENABLE_GL=OFF) its entry points exist and say so; src/gl defines
// them otherwise.
Result<std::unique_ptr<Detector>> make_gl_detector(const Config&, const GlOptions&) {
  return Result<std::unique_ptr<Detector>>::failure(ErrorKind::unsupported_input,
                                                    "backend 'gl' is not built in (configure with VISCD_ENABLE_GL=ON)");
}

Result<std::string> gl_device() {
  return Result<std::string>::failure(ErrorKind::unsupported_input,
                                      "viscd was built without the gl backend (VISCD_ENABLE_GL=OFF)");
}

Result<unsigned> make_gl_id_texture(int, int) {
  return Result<unsigned>::failure(ErrorKind::unsupported_input,
                                   "viscd was built without the gl backend (VISCD_ENABLE_GL=OFF)");
}
#endif

#ifndef VISCD_HAVE_CUDA
// Without the cuda backend (no nvcc found, or VISCD_ENABLE_CUDA=OFF) its entry points say so;
// src/cuda defines them otherwise.
Result<std::unique_ptr<Detector>> make_cuda_detector(const Config&) {
  return Result<std::unique_ptr<Detector>>::failure(
      ErrorKind::unsupported_input,
      "backend 'cuda' is not built in (configure with VISCD_ENABLE_CUDA=ON where nvcc is installed)");
}

Result<std::string> cuda_device() {
  return Result<std::string>::failure(ErrorKind::unsupported_input,
                                      "viscd was built without the cuda backend (VISCD_ENABLE_CUDA=OFF or no nvcc)");
}

Result<std::unique_ptr<CudaBroadphase>> make_cuda_broadphase(const Config&) {
  return Result<std::unique_ptr<CudaBroadphase>>::failure(
      ErrorKind::unsupported_input, "viscd was built without the cuda backend (VISCD_ENABLE_CUDA=OFF or no nvcc)");
}
#endif

bool is_software_renderer(std::string_view device) {
  for (std::string_view soft : {"llvmpipe", "softpipe", "swrast", "lavapipe", "Software Rasterizer"})
    if (device.find(soft) != std::string_view::npos) return true;
  return false;
}

Result<std::unique_ptr<Detector>> make_detector(std::string_view backend, const Config& config) {
  if (backend == "reference") return make_reference_detector(config);
  if (backend == "cpu") return make_cpu_detector(config);
  if (backend == "gl") return make_gl_detector(config);
  if (backend == "cuda") return make_cuda_detector(config);
  return Result<std::unique_ptr<Detector>>::failure(
      ErrorKind::invalid_input, "unknown backend '" + std::string(backend) + "': expected reference, cpu, gl or cuda");
}

}  // namespace viscd
