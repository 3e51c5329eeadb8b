#pragma once
// What the cuda backend tells the bench beyond FrameStats: the GPU time of each part of its
// last frame (cuda/gpu.hpp Times), uploads and downloads apart.

#include "cuda/gpu.hpp"
#include "viscd/detector.hpp"

namespace viscd::detail {

/// The last frame's GPU times of a cuda detector; null for a detector of another backend.
[[nodiscard]] const cuda::Times* cuda_times(const Detector& detector);

}  // namespace viscd::detail
