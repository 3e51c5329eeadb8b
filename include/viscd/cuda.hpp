#pragma once
/// \file cuda.hpp
/// The cuda backend (docs/gpu.md): the visibility map as an analytic splat on the GPU (each
/// object's pixels, in chunks of 32 a warp, ray-tested as the CPU rasterizers do, the nearest
/// kept by a 64-bit atomicMin of depth and id), and stages 4-8 on the GPU: Morton codes, CUB radix sort over the key
/// width m, Karras build, bottom-up fit, traversal with a pair buffer that counts, grows and re-runs (never drops a
/// pair), CUB sort of the pairs. Counting, culling, the filters' pre-pass, states and shading run on the host, as in
/// the cpu backend. Spheres and boxes, static sets, filters, always-active objects and the caller's id map, like every
/// backend.
///
/// Built when CMake finds nvcc (VISCD_ENABLE_CUDA, default ON); needs an NVIDIA GPU of compute
/// capability 9.0 (Hopper) at run time, for which the build compiles its code (configure with
/// CMAKE_CUDA_ARCHITECTURES for others).

#include <memory>
#include <string>

#include "viscd/config.hpp"
#include "viscd/detector.hpp"
#include "viscd/result.hpp"

namespace viscd {

/// A detector on the first CUDA device. Fails (ErrorKind::unsupported_input) when viscd was
/// built without CUDA, and (ErrorKind::backend_failure) when there is no usable device, saying
/// why: no driver, no device, or a device this build has no code for.
[[nodiscard]] Result<std::unique_ptr<Detector>> make_cuda_detector(const Config& config = {});

/// The device the cuda backend would run on ("NVIDIA H100 80GB HBM3, sm_90, 132 SMs, 79 GiB"),
/// or why there is none (the same errors as make_cuda_detector()).
[[nodiscard]] Result<std::string> cuda_device();

}  // namespace viscd
