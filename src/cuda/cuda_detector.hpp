#pragma once
// What the cuda backend tells the bench beyond FrameStats: the GPU time of each part of its
// last frame (cuda/gpu.hpp Times), uploads and downloads apart.

#include "cuda/gpu.hpp"
#include "viscd/detector.hpp"

namespace viscd::detail {

/// The last frame's GPU times of a cuda detector's broadphase and splat (zero on a frame without
/// a map); null for a detector of another backend.
[[nodiscard]] const cuda::Times* cuda_times(const Detector& detector);
[[nodiscard]] const cuda::SplatTimes* cuda_splat_times(const Detector& detector);

/// A test hook: the longest chunk list the splat plans (0 forces its fallback, a warp an object).
/// False for a detector of another backend.
bool set_cuda_chunk_limit(Detector& detector, unsigned long long limit);

}  // namespace viscd::detail
