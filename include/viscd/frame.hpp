#pragma once
/// \file frame.hpp
/// What a detector reports for one frame.

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "viscd/types.hpp"

namespace viscd {

/// Pipeline stages timed by detectors (docs/architecture.md, stages 1-9; stage 0, simulation, is
/// the caller's).
enum class Stage : std::uint8_t {
  visibility,  ///< 1: id map + depth + normal
  count,       ///< 2: pixels per object
  cull,        ///< 3: active set and mu
  layout,      ///< 4: bit count m, axis order, bounds of the active centres
  codes,       ///< 5: Morton codes
  sort,        ///< 6: radix sort of (key, index)
  build,       ///< 7a: Karras hierarchy
  fit,         ///< 7b: bottom-up AABB fit
  query,       ///< 8: traversal, exact sphere tests, pair sort, object states
  shade,       ///< 9: shaded image
  count_       ///< number of stages (not a stage)
};
inline constexpr std::size_t kStageCount = static_cast<std::size_t>(Stage::count_);

/// Short lowercase name of a stage ("visibility", "sort", ...).
[[nodiscard]] std::string_view stage_name(Stage s);

/// Numbers describing one frame.
struct FrameStats {
  std::uint32_t objects = 0;                   ///< N, all input spheres
  std::uint32_t active = 0;                    ///< objects given to the broadphase (N when culling is off)
  bool has_camera = false;                     ///< false: no visibility stages ran and mu is undefined
  double mean_pixels = 0;                      ///< mu: total covered screen pixels / N (0 without camera)
  int bits = 0;                                ///< Morton width m used this frame: 16, 32 or 64
  std::string layout;                          ///< e.g. "x(7)→z(6)→y(3)"
  std::uint64_t pairs = 0;                     ///< number of colliding pairs
  std::array<double, kStageCount> stage_ms{};  ///< wall (cpu) or GPU (gl) milliseconds per stage
  [[nodiscard]] double total_ms() const;
};

/// Result of one frame. Reuse one FrameResult across frames: its buffers keep their capacity,
/// so a steady state allocates nothing.
struct FrameResult {
  /// Every overlapping pair among active objects, (i < j), sorted, unique.
  std::vector<Pair> pairs;
  /// State of each of the N objects.
  std::vector<ObjectState> state;
  /// Screen pixels covered by each object (after map-to-screen scaling); empty without camera.
  std::vector<float> pixels;
  /// Shaded RGBA8 image (stage 9), image_width x image_height, rows top to bottom; filled only
  /// when Config::shade is set and a camera is given.
  std::vector<std::uint8_t> image;
  int image_width = 0;
  int image_height = 0;
  FrameStats stats;
};

}  // namespace viscd
